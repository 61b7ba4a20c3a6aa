"""``python -m dhlog``: the command line."""

from dhlog.entry import run

run()
