"""``python -m dhlog``: the command line."""

from dhlog.cli import run

run()
