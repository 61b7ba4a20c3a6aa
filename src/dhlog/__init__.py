"""dhlog: exact Denavit–Hartenberg parameters from robot calibration logs.

The public API is what this module exports (``__all__``; ``docs/api.md``): the operations of the
commands — :func:`process`, :func:`load`, :func:`simulate`, :func:`plan`, :func:`robot` — the
:class:`Calibration` they give, and the geometry's building blocks. Everything else
(``dhlog.identify``, ``dhlog.model``, ``dhlog.io`` …) is private and may move between versions.

Names are resolved on first use: the console entry point imports nothing heavy before it
handles signals."""

from __future__ import annotations

import logging
from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from dhlog.api import (
        Calibration,
        Simulation,
        acceptance_test,
        load,
        plan,
        process,
        robot,
        simulate,
    )
    from dhlog.cell.compensate import Compensation
    from dhlog.cell.plan import Plan, Tracker
    from dhlog.errors import (
        DhlogError,
        DhlogWarning,
        ImplausibleWarning,
        InputError,
        UsageError,
    )
    from dhlog.geometry.circles import fit_circle
    from dhlog.identify.read.extract import extract_dh
    from dhlog.io.dhfile import DHModel
    from dhlog.iso9283.report import Iso9283Report
    from dhlog.model.dh import JointType, ModifiedDH, StandardDH
    from dhlog.model.fk import fk_frames, fk_point
    from dhlog.model.robots import Robot

    __version__: str

#: Every public name and the module it lives in (private; may move).
_PUBLIC = {
    "process": "dhlog.api",
    "acceptance_test": "dhlog.api",
    "Iso9283Report": "dhlog.iso9283.report",
    "load": "dhlog.api",
    "simulate": "dhlog.api",
    "plan": "dhlog.api",
    "robot": "dhlog.api",
    "Calibration": "dhlog.api",
    "Simulation": "dhlog.api",
    "UsageError": "dhlog.errors",
    "Compensation": "dhlog.cell.compensate",
    "Plan": "dhlog.cell.plan",
    "Tracker": "dhlog.cell.plan",
    "Robot": "dhlog.model.robots",
    "StandardDH": "dhlog.model.dh",
    "ModifiedDH": "dhlog.model.dh",
    "JointType": "dhlog.model.dh",
    "fk_point": "dhlog.model.fk",
    "fk_frames": "dhlog.model.fk",
    "fit_circle": "dhlog.geometry.circles",
    "extract_dh": "dhlog.identify.read.extract",
    "DhlogError": "dhlog.errors",
    "InputError": "dhlog.errors",
    "ImplausibleWarning": "dhlog.errors",
    "DhlogWarning": "dhlog.errors",
    "DHModel": "dhlog.io.dhfile",
}

#: The public names (``tests/test_public_api.py`` fails when one disappears).
__all__ = [
    "Calibration",
    "Compensation",
    "DHModel",
    "DhlogError",
    "DhlogWarning",
    "ImplausibleWarning",
    "InputError",
    "Iso9283Report",
    "JointType",
    "ModifiedDH",
    "Plan",
    "Robot",
    "Simulation",
    "StandardDH",
    "Tracker",
    "UsageError",
    "__version__",
    "acceptance_test",
    "extract_dh",
    "fit_circle",
    "fk_frames",
    "fk_point",
    "load",
    "plan",
    "process",
    "robot",
    "simulate",
]


# a library's logger: silent unless the user's logging configuration says where it goes
logging.getLogger("dhlog").addHandler(logging.NullHandler())


def __getattr__(name: str) -> object:
    if name == "__version__":
        from dhlog._version import version

        return version()
    if name not in _PUBLIC:
        raise AttributeError(f"module 'dhlog' has no attribute {name!r}")
    value = getattr(import_module(_PUBLIC[name]), name)
    globals()[name] = value  # resolved once
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
