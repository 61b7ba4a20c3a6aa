"""dhlog's public Python API, re-exported at the top (``import dhlog``): the operations of the
commands (:mod:`.operations`, :mod:`.simulation`) and the calibration they give
(:mod:`.calibration`)."""

from dhlog.api.calibration import EXPORT_FORMATS, Calibration, ExportFormat, UsageError
from dhlog.api.operations import acceptance_test, load, plan, process, robot
from dhlog.api.simulation import Simulation, simulate

__all__ = [
    "EXPORT_FORMATS",
    "Calibration",
    "ExportFormat",
    "Simulation",
    "UsageError",
    "acceptance_test",
    "load",
    "plan",
    "process",
    "robot",
    "simulate",
]
