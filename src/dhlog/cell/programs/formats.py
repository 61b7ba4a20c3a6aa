"""The program formats: which one a file is (its suffix or ``--program-format``) and its
reader."""

from __future__ import annotations

from pathlib import Path

from dhlog.cell.programs import rapid, urscript
from dhlog.cell.programs.common import Program, ProgramError
from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray

#: The program formats by name, and the file suffixes that choose each.
FORMATS = {"urscript": (".script", ".urscript"), "rapid": (".mod", ".modx", ".prg")}


def format_of(path: Path, given: str | None) -> str:
    """The format named (``--program-format``) or chosen by ``path``'s suffix."""
    from dhlog.errors import UsageError

    if given is not None:
        if given not in FORMATS:
            raise UsageError(f"--program-format '{given[:20]}' is not one of {', '.join(FORMATS)}.")
        return given
    suffix = path.suffix.lower()
    for name, suffixes in FORMATS.items():
        if suffix in suffixes:
            return name
    known = ", ".join(s for suffixes in FORMATS.values() for s in suffixes)
    raise UsageError(
        f"{path}: its suffix '{suffix[:12]}' names no program format ({known}); give "
        f"--program-format ({', '.join(FORMATS)})."
    )


def read(path: Path, fmt: str, n: int, tcp: FloatArray | None) -> Program:
    """The program at ``path`` in format ``fmt`` for a robot of ``n`` joints; ``tcp`` (4, 4):
    the TCP in force before the program sets one (None: the flange)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(
            f"{path}: cannot be read ({exc.strerror or exc}); give the program."
        ) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ProgramError(
            str(path), line, "is not UTF-8 text; save the program as UTF-8"
        ) from None
    readers = {"urscript": urscript.read_urscript, "rapid": rapid.read_rapid}
    return readers[fmt](str(path), text, n, tcp)
