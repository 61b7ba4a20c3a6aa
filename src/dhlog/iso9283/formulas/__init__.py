"""The ISO 9283:1998 performance characteristics, each as the standard defines it, on plain
arrays: pose accuracy and repeatability (7.2.1, 7.2.2), multi-directional pose accuracy
variation (7.2.3), distance accuracy and repeatability (7.3), drift of pose characteristics
(7.6): :mod:`~dhlog.iso9283.formulas.poses`; pose stabilisation time and overshoot (7.4, 7.5):
:mod:`~dhlog.iso9283.formulas.settling`; path accuracy and repeatability (8.2) and path
velocity characteristics (8.4): :mod:`~dhlog.iso9283.formulas.paths`; the orientation
components a, b, c: :mod:`~dhlog.iso9283.formulas.orientation`.

Units are SI throughout: positions in m, orientation components in rad, times in s (mm and °
only where the results are shown). Every standard deviation is the sample one (divisor n − 1),
as the standard writes it. Where the standard leaves a choice (how the orientation components
a, b, c are taken from a rotation, the stabilisation band, which deviation is the overshoot) the
function's docstring says what is done here; docs/iso9283.md ("The formulas") lists the choices.
Every name of :data:`__all__` is importable from ``dhlog.iso9283.formulas``.
"""

from dhlog.iso9283.formulas.orientation import (
    matrix_from_abc,
    orientation_abc,
    orientation_deviation,
)
from dhlog.iso9283.formulas.paths import (
    PathCharacteristics,
    PathVelocity,
    path_accuracy,
    path_velocity,
    speeds_from_positions,
)
from dhlog.iso9283.formulas.poses import (
    DistanceCharacteristics,
    Drift,
    MultiDirectional,
    PoseAccuracy,
    PoseRepeatability,
    distance_accuracy,
    drift,
    multi_directional,
    pose_accuracy,
    pose_repeatability,
)
from dhlog.iso9283.formulas.settling import (
    Stabilisation,
    stabilisation,
    stabilisation_over_cycles,
)

__all__ = [
    "DistanceCharacteristics",
    "Drift",
    "MultiDirectional",
    "PathCharacteristics",
    "PathVelocity",
    "PoseAccuracy",
    "PoseRepeatability",
    "Stabilisation",
    "distance_accuracy",
    "drift",
    "matrix_from_abc",
    "multi_directional",
    "orientation_abc",
    "orientation_deviation",
    "path_accuracy",
    "path_velocity",
    "pose_accuracy",
    "pose_repeatability",
    "speeds_from_positions",
    "stabilisation",
    "stabilisation_over_cycles",
]
