"""A model given as users give it — a library robot's name, a DH or result file, a
:class:`~dhlog.DHModel`, a :class:`~dhlog.Robot` or a :class:`~dhlog.Calibration` — as the
model forward kinematics reads (:func:`_dh_model`), and a library robot's joint limits
(:func:`_library_limits`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from dhlog.errors import UsageError

if TYPE_CHECKING:
    from dhlog.geometry._checks import FloatArray
    from dhlog.io.dhfile import DHModel
    from dhlog.model.robots import Robot


class Identified(Protocol):
    """A :class:`~dhlog.api.calibration.Calibration` as a model: what it identified."""

    def identified(self) -> DHModel: ...


def _dh_model(spec: str | Path | DHModel | Robot | Identified) -> DHModel:
    """A DH model from a library robot name, a DH file, a :class:`Robot` or a model."""
    from dhlog.io.dhfile import DHModel, dh_model_from
    from dhlog.model.robots import Robot

    if isinstance(spec, DHModel):
        return spec
    if isinstance(spec, Robot):
        names = tuple(f"joint_{i + 1}" for i in range(spec.n))
        return DHModel(spec.table, spec.T_base, spec.tool_point, names, spec.name)
    if isinstance(spec, (str, Path)):
        return dh_model_from(str(spec))
    if callable(getattr(spec, "identified", None)):  # a calibration
        return spec.identified()
    raise UsageError(
        f"a model must be a library robot name, a DH file's path or dhlog.robot(...), not "
        f"{type(spec).__name__}."
    )


def _library_limits(spec: object) -> FloatArray | None:
    """A library robot's joint limits (None for anything else)."""
    from dhlog.model.robots import Robot, robot_names

    if isinstance(spec, Robot):
        return spec.limits
    if isinstance(spec, str) and spec in robot_names():
        from dhlog.model.robots import load_robot

        return load_robot(spec).limits
    return None
