"""ISO 9283 (Manipulating industrial robots — performance criteria and related test methods)
from tracker logs: the test program (``program``: the test cube, the poses P1–P5, the test paths,
the cycle program), the characteristics as the standard defines them (``formulas``), the cycles
found in a log (``cycles``) and the acceptance report (``run``)."""
