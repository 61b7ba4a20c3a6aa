"""What every command shares: exit codes, the consoles, the help's plumbing, and the checks of
outputs made before any work.

Only the command line catches :class:`~dhlog.errors.DhlogError`; :func:`fail` prints its one-line
message and exits with 2 (unreadable or unusable input); usage errors exit with 1 (``EXIT_CODES``
lists them all, as ``dhlog --help`` prints them). User text (paths, names, option values) goes
through :func:`plain` before rich prints it: never markup, never more than one line.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, get_args, get_origin

import numpy as np
import typer
from rich.console import Console
from typer.core import TyperArgument, TyperCommand, TyperGroup

from dhlog.errors import DhlogError, OutputError

EXIT_USAGE, EXIT_INPUT, EXIT_PARTIAL = 1, 2, 3
#: the result was written but dhlog judges it implausible (``Identification.implausible``)
EXIT_IMPLAUSIBLE = 4
#: ``dhlog compare --fail-beyond SIGMA``: a parameter changed beyond SIGMA combined σ
EXIT_CHANGED = 5
EXIT_INTERRUPTED, EXIT_OUTPUT_CLOSED, EXIT_TERMINATED = 130, 141, 143

#: The epilog of ``dhlog --help``, ``process --help`` and ``batch --help`` (no square brackets:
#: the help is rich markup).
EXIT_CODES = (
    "Exit codes: 0 success; 1 usage error (a bad option or argument, an output that exists "
    "without --force, an output folder that does not exist); 2 unreadable or unusable input, or "
    "an output that cannot be written; 3 partial result (joints not identified; in a batch, "
    "logs that failed: the rest is written; in dhlog compensate, targets not corrected: each "
    "named, the rest written); 4 implausible result (written, marked plausible: "
    "false with the reasons; it wins over 3; in a batch, a log judged implausible and none "
    "failed or partial); 5 a parameter changed beyond dhlog compare --fail-beyond σ; 130 "
    "interrupted (Ctrl-C); 141 the standard output was closed (| head: the "
    "results were written first); 143 terminated (SIGTERM)."
)


class Ended(BaseException):
    """The run ends here with ``code``, its message (if any) printed: no command-line library
    in between may turn it into another exit."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


class _Console(Console):
    """A console whose closed output (``dhlog process … | head -1``) ends the run quietly with
    ``EXIT_OUTPUT_CLOSED``; rich's own ending is exit 1 without a word, the code of a usage
    error."""

    def on_broken_pipe(self) -> None:
        self.quiet = True
        try:  # what Python still flushes at exit goes nowhere, without "Exception ignored"
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self.file.fileno())
            os.close(devnull)
        except (OSError, ValueError):  # a file without a descriptor (tests)
            pass
        raise Ended(EXIT_OUTPUT_CLOSED)


def _type_metavar(param: Any) -> str | None:
    """click's name of a parameter's type (PATH, TEXT, INTEGER, FLOAT), from typer's own
    description of it; None where typer has none (older typer: click names it itself)."""
    desc = getattr(param, "type_descriptor", None)
    if desc is None:
        return None
    annotation = getattr(desc, "annotation", None)
    if get_origin(annotation) is list:
        annotation = get_args(annotation)[0]
    names: dict[Any, str] = {Path: "PATH", str: "TEXT", int: "INTEGER", float: "FLOAT"}
    return names.get(annotation, "VALUE")


class _Argument(TyperArgument):
    """An argument as click shows it: its metavar alone (``LOG``) in the usage line, ``[LOG]``
    when optional, ``LOG...`` when repeated, no type beside it in the help."""

    def display_type_rich(self, ctx: Any) -> str | None:
        return None

    def get_usage_pieces(self, ctx: Any) -> list[str]:
        name = self.metavar or (self.name or "").upper()
        if self.nargs != 1:
            name += "..."
        return [name if self.required else f"[{name}]"]


def _plain_help(params: list[Any]) -> list[Any]:
    """Metavars as a user reads them. typer 0.2x's rich help gives every parameter its Python
    type: flags show as ``--force <bool>`` (and ``--force true`` is then refused), arguments as
    ``{log}`` in the usage line, a repeated option as ``<list[Path]>``. Here a flag shows
    nothing after its name, an argument its name in capitals, an option its metavar or click's
    name of its type."""
    for p in params:
        if isinstance(p, TyperArgument):
            if type(p) is TyperArgument:
                p.__class__ = _Argument
            if p.metavar is None:
                p.metavar = (p.name or "").upper()
        elif getattr(p, "is_flag", False) or getattr(p, "count", False):
            if p.metavar is None:
                p.metavar = ""
        elif p.metavar is None:
            p.metavar = _type_metavar(p)
    return params


class Command(TyperCommand):
    """A command whose help and usage line read as click's (:func:`_plain_help`)."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain_help(super().get_params(ctx))


class Group(TyperGroup):
    """``dhlog`` itself, its help as :class:`Command`'s."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain_help(super().get_params(ctx))


#: No emoji codes: ``:a:`` in a message or a user's path is text, not 🅰.
stderr = _Console(stderr=True, highlight=False, soft_wrap=True, emoji=False)
stdout = _Console(highlight=False, emoji=False)


def plain(text: object) -> str:
    """User text (a path, a name, an option's value) as rich prints it: never markup, and on one
    line (:func:`dhlog.present.console.layout.literal`)."""
    from dhlog.present.console.layout import literal

    return literal(text)


def fail(exc: DhlogError, code: int = EXIT_INPUT) -> None:
    """One line on stderr (the message is the log's text, never markup) and the exit code (a
    :class:`~dhlog.errors.UsageError`, an argument that cannot be used: exit 1)."""
    from dhlog.errors import UsageError

    if isinstance(exc, UsageError) and code == EXIT_INPUT:
        code = EXIT_USAGE
    stderr.print(f"[bold red]error:[/] {plain(exc)}", soft_wrap=True)
    raise typer.Exit(code)


def check_folder(folder: Path) -> None:
    """A command's output folder must exist (``process --out`` and ``iso9283 --out`` create
    theirs: :func:`check_writable` before the work, the folder made before writing)."""
    _refuse_file(folder)
    if not folder.is_dir():
        stderr.print(f"error: the folder {plain(folder)} does not exist; create it first.")
        raise typer.Exit(EXIT_USAGE)
    check_writable(folder)


def _existing_above(folder: Path) -> Path:
    """``folder``, or the nearest of its parents that exists."""
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return probe


def _refuse_file(folder: Path) -> None:
    """Exit 2 (as every unwritable output) when an output folder, or the nearest existing path
    above it, is a file."""
    probe = _existing_above(folder)
    if probe.exists() and not probe.is_dir():
        stderr.print(
            f"[bold red]error:[/] cannot write into {plain(folder)}: {plain(probe)} "
            "is a file, not a folder; choose a folder, or move the file away. Nothing was "
            "written."
        )
        raise typer.Exit(EXIT_INPUT)


def check_writable(folder: Path) -> None:
    """Stop before any work when the output folder (or, if missing, the nearest existing folder
    above it) cannot be written, or is a file."""
    _refuse_file(folder)
    probe = _existing_above(folder)
    if not os.access(probe, os.W_OK | os.X_OK):
        fail(OutputError(folder, PermissionError(13, "Permission denied")))


def refuse_existing(path: Path, force: bool) -> None:
    """Exit 1 when an output exists and --force was not given."""
    if path.exists() and not force:
        stderr.print(f"error: {plain(path)} exists; pass --force to overwrite it.")
        raise typer.Exit(EXIT_USAGE)


def say_implausible(reasons: list[str] | tuple[str, ...]) -> None:
    """The last line of a command whose result dhlog judges implausible (exit 4 follows)."""
    stderr.print(
        "implausible result: " + " ".join(plain(r) for r in reasons) + " The result was "
        "written, marked plausible: false; exit 4."
    )


def quiet_numerics() -> None:
    """Floating-point warnings of numpy on damaged data are not for the user: every result is
    checked for finiteness where it matters, and what is set aside is counted. Nor are the
    API's DhlogWarnings (ImplausibleWarning among them): each command prints its warnings and
    says an implausible result in its own words, once."""
    import warnings

    from dhlog.errors import DhlogWarning

    warnings.filterwarnings("ignore", category=RuntimeWarning)
    # the commands print their warnings their own way (process's last line and exit 4)
    warnings.filterwarnings("ignore", category=DhlogWarning)
    np.seterr(all="ignore")


def viewer() -> str:
    """How to open a recording from here: ``rerun`` when it is on the PATH, else the viewer
    installed beside this Python (the README's venv flow)."""
    import shutil

    beside = Path(sys.executable).with_name("rerun")
    if shutil.which("rerun") == str(beside) or (shutil.which("rerun") and not beside.exists()):
        return "rerun"
    return str(beside) if beside.exists() else f"{sys.executable} -m rerun"


class Terminated(BaseException):
    """SIGTERM, raised where the program is (temporary files are removed on the way out)."""
