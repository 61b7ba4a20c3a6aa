"""Human-facing views of a result: the console tables and the Markdown of the recording.

Lengths in mm and angles in degrees (or m and rad with ``units="m"``); ±1σ with each value;
measured − nominal when a nominal table was given. The console tables fit an 80-column terminal,
a pipe or a file without a wrapped cell: each value stands above its σ, and the differences to
the nominal are a table of their own. Values are printed to 0.1 µm and 0.0001° (10⁻⁷ m and
10⁻⁶ rad in SI units), or finer where the σ needs it to show two significant digits.

By concern: ``layout`` (units, decimals, each value above its σ line, names), ``tables`` (the
console report, :func:`print_result`), ``notes`` (the labelled lines: method, clock, what is
held, notes and warnings), ``markdown`` (:func:`result_markdown`, for the recording).
"""

from dhlog.present.console.markdown import result_markdown
from dhlog.present.console.notes import held_lines
from dhlog.present.console.tables import print_result

__all__ = ["held_lines", "print_result", "result_markdown"]
