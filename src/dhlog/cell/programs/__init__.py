"""Robot programs read and written with only their targets' numbers changed: a reader per
controller language returns a :class:`~dhlog.cell.programs.common.Program` (the literals it
may change, the motions that use them, in order), :func:`~dhlog.cell.programs.common.filtered`
corrects it through :mod:`dhlog.cell.sequence` and writes the same text with the new numbers;
:mod:`~dhlog.cell.programs.formats` says which format a file is and reads it.

- :mod:`~dhlog.cell.programs.urscript`: URScript (``.script``, ``.urscript``);
- :mod:`~dhlog.cell.programs.rapid`: ABB RAPID (``.mod``, ``.modx``, ``.prg``).
"""

from __future__ import annotations

from dhlog.cell.programs.common import Program, ProgramError, filtered
from dhlog.cell.programs.formats import FORMATS, format_of, read

__all__ = ["FORMATS", "Program", "ProgramError", "filtered", "format_of", "read"]
