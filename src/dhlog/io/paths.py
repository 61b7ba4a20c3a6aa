"""Whether two paths name one file: an output that is one of a command's inputs is refused before
anything is written (``dhlog import``, ``export``, ``compare``, ``batch``;
:func:`refuse_inputs_as_outputs`)."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from dhlog.errors import InputError


class InputIsOutputError(InputError):
    """An output path is one of the command's inputs."""

    def __init__(self, input_path: object, what: str, output_path: object) -> None:
        super().__init__(
            f"{input_path}: the {what} is also an output of this command ({output_path}) and "
            "would be overwritten; choose another output path (or folder). Nothing was written."
        )


def resolved(path: str | Path) -> str:
    """``path`` absolute with its symbolic links followed (a loop left where it starts); a name
    the system refuses (a NUL byte) only made absolute."""
    try:
        return os.path.realpath(path)
    except (OSError, ValueError, RuntimeError):
        return os.path.abspath(path)


def inode(path: str | Path) -> tuple[int, int] | None:
    """The device and inode of the file at ``path``, or None when there is none."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino)


class SameFiles:
    """Paths by what they name: the path once resolved, and the file (device and inode) where it
    exists, so that a symbolic or a hard link to one of them is found."""

    def __init__(self, paths: Iterable[Path]) -> None:
        self.by_path: dict[str, Path] = {}
        self.by_inode: dict[tuple[int, int], Path] = {}
        for path in paths:
            self.by_path.setdefault(resolved(path), path)
            found = inode(path)
            if found is not None:
                self.by_inode.setdefault(found, path)

    def find(self, path: str | Path) -> Path | None:
        """The first of the paths that names the same file as ``path`` (by path before by
        inode), or None."""
        hit = self.by_path.get(resolved(path))
        if hit is None:
            found = inode(path)
            hit = self.by_inode.get(found) if found is not None else None
        return hit


def same_file(a: str | Path, b: str | Path) -> bool:
    """True when ``a`` and ``b`` name one file: the same path once resolved (a symbolic-link
    loop resolves without an error), or the same file by device and inode (a hard link)."""
    return SameFiles([Path(b)]).find(a) is not None


def refuse_inputs_as_outputs(inputs: Iterable[tuple[Path, str]], outputs: Iterable[Path]) -> None:
    """:class:`InputIsOutputError` when an input (path, what it is) is one of ``outputs``: the
    same path once resolved (symbolic links followed), or the same file (hard links)."""
    written = SameFiles(outputs)
    for path, what in inputs:
        hit = written.find(path)
        if hit is not None:
            raise InputIsOutputError(path, what, hit)
