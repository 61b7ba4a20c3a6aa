"""The ``dhlog`` command line: a thin layer over the library.

This module builds the typer ``app`` from the commands of :mod:`dhlog.cli.simulate`,
:mod:`~dhlog.cli.process`, :mod:`~dhlog.cli.robot`, :mod:`~dhlog.cli.logs`,
:mod:`~dhlog.cli.results`, :mod:`~dhlog.cli.cell`, :mod:`~dhlog.cli.compensate` and
:mod:`~dhlog.cli.batch` (none of which imports it), and :func:`run` turns signals, a closed
output and the parser's usage errors into the exit codes ``EXIT_CODES`` lists
(:mod:`dhlog.cli.common`).
"""

from __future__ import annotations

import os
import sys
from typing import Annotated

import typer

from dhlog._version import __version__
from dhlog.cli.batch import batch
from dhlog.cli.cell import plan
from dhlog.cli.common import (
    EXIT_CODES,
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    EXIT_OUTPUT_CLOSED,
    EXIT_TERMINATED,
    EXIT_USAGE,
    Command,
    Ended,
    Group,
    Terminated,
    plain,
    quiet_numerics,
    stderr,
    stdout,
)
from dhlog.cli.compensate import compensate
from dhlog.cli.iso9283 import iso9283
from dhlog.cli.logs import import_, pipelines
from dhlog.cli.process import process
from dhlog.cli.results import compare_results, export, report
from dhlog.cli.robot import fk, robots, show
from dhlog.cli.simulate import simulate
from dhlog.errors import DhlogError, warnings_printed_by_caller

app = typer.Typer(
    name="dhlog",
    help="Exact Denavit-Hartenberg parameters from robot calibration logs (MCAP).",
    epilog=EXIT_CODES,
    cls=Group,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        stdout.print(f"dhlog {__version__}")
        raise typer.Exit(0)


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Exact Denavit-Hartenberg parameters from robot calibration logs (MCAP)."""
    quiet_numerics()  # every command, however the app is called (run() or the app itself)


# in the order dhlog --help lists them
app.command(cls=Command)(simulate)
app.command(cls=Command, epilog=EXIT_CODES)(process)
app.command(cls=Command)(fk)
app.command(cls=Command)(pipelines)
app.command(cls=Command)(export)
app.command(cls=Command, epilog=EXIT_CODES)(report)
app.command(cls=Command, epilog=EXIT_CODES)(compensate)
app.command(cls=Command, epilog=EXIT_CODES)(plan)
app.command(cls=Command, epilog=EXIT_CODES)(batch)
app.command(cls=Command, epilog=EXIT_CODES)(iso9283)
app.command(name="import", cls=Command)(import_)
app.command(name="compare", cls=Command)(compare_results)
app.command(cls=Command)(show)
app.command(cls=Command)(robots)


def _stdout_replaced() -> bool:
    """Whether the standard output was found closed and replaced (by /dev/null, or typer's
    wrapper that swallows its errors), as rich and typer do on a broken pipe."""
    if type(sys.stdout).__name__ == "PacifyFlushWrapper":
        return True
    try:
        out, null = os.fstat(1), os.stat(os.devnull)
    except OSError:
        return False
    return (out.st_dev, out.st_ino) == (null.st_dev, null.st_ino)


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def run() -> None:
    """Entry point: exit codes as ``EXIT_CODES`` lists them (0 success, 1 usage error,
    2 unusable input or output, 3 partial result, 130 interrupted (SIGINT), 141 the standard
    output closed, 143 terminated (SIGTERM))."""
    import signal

    quiet_numerics()
    signal.signal(signal.SIGTERM, _on_sigterm)
    if len(sys.argv) <= 1:  # no arguments: the help, and success
        sys.argv.append("--help")
    try:
        with warnings_printed_by_caller():  # each command prints its warnings, once
            code = app(standalone_mode=False)
    except Ended as end:  # its message is printed
        sys.exit(end.code)
    except SystemExit as exc:  # rich and typer end a closed output (their help) with exit 1
        if exc.code == 1 and _stdout_replaced():
            sys.exit(EXIT_OUTPUT_CLOSED)
        raise
    except typer.Abort as exc:
        if isinstance(exc.__cause__ or exc.__context__, KeyboardInterrupt):
            stderr.print("interrupted: no output was written (finished files stay as they were).")
            sys.exit(EXIT_INTERRUPTED)
        sys.exit(EXIT_USAGE)
    except KeyboardInterrupt:
        stderr.print("interrupted: no output was written (finished files stay as they were).")
        sys.exit(EXIT_INTERRUPTED)
    except Terminated:
        stderr.print("terminated: no output was written (finished files stay as they were).")
        sys.exit(EXIT_TERMINATED)
    except DhlogError as exc:  # pragma: no cover - commands catch their own
        stderr.print(f"error: {plain(exc)}")
        sys.exit(EXIT_INPUT)
    except Exception as exc:
        # usage errors of the command-line parser carry their own message and exit code
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):
            stderr.print(f"error: {plain(exc.format_message())} (see dhlog --help)")
            sys.exit(EXIT_USAGE)
        raise
    if code == EXIT_INTERRUPTED:  # typer's own ending of a KeyboardInterrupt
        stderr.print("interrupted: no output was written (finished files stay as they were).")
    # the work is done: a signal now (while the recording library shuts down) changes nothing
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sys.exit(code if isinstance(code, int) else 0)
