"""The console entry point: signals are handled before anything heavy is imported.

Ctrl-C or SIGTERM while Python imports numpy, polars and the rest ends the program with one line
and exit 130 / 143 (there is nothing to clean up yet); afterwards :func:`dhlog.cli.app.run` turns
them into the same exits after the temporary files of an unfinished run are removed.
"""

from __future__ import annotations

import os
import signal
import sys


def _early(signum: int, frame: object) -> None:
    code = 130 if signum == signal.SIGINT else 143
    what = "interrupted" if signum == signal.SIGINT else "terminated"
    sys.stderr.write(f"{what}: nothing was written.\n")
    sys.stderr.flush()
    os._exit(code)


def run() -> None:
    """``dhlog``: see :func:`dhlog.cli.app.run`."""
    signal.signal(signal.SIGINT, _early)
    signal.signal(signal.SIGTERM, _early)
    from dhlog.cli import app as cli

    signal.signal(signal.SIGINT, signal.default_int_handler)
    cli.run()
