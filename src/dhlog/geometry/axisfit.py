"""What every fit of a joint axis returns (:class:`AxisFit`), and the checks of its samples.

The fits themselves: circles in :mod:`dhlog.geometry.circles` (seed 002, Sec. 2.3), planes and lines
in :mod:`dhlog.geometry.fitting`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import NonFiniteError, TooFewPointsError
from dhlog.geometry._checks import FloatArray, check_points
from dhlog.geometry.lines import Line

#: Smallest swept angle a circle fit accepts by default (rad).
MIN_SWEEP = math.radians(5.0)
#: Smallest travel a line fit accepts by default (m).
MIN_TRAVEL = 1e-3


@dataclass(frozen=True, eq=False)
class AxisFit:
    """An oriented joint axis recovered from one sweep.

    Shapes: ``center`` (3,), ``residuals`` (m, 3) sample minus model point, ``positions`` (m,) the
    per-sample angle about the axis (rad, circles) or position along it (m, lines), ``basis`` (2, 3)
    the unit vectors ``u, v`` perpendicular to the axis in which ``axis_covariance`` (4, 4) is
    expressed, for ``[δe·u, δe·v, δc·u, δc·v]``: the tilt of the direction (rad) and the shift of
    the axis at ``center`` (m).
    """

    axis: Line
    kind: Literal["circle", "line"]
    method: str
    n_points: int
    center: FloatArray
    radius: float
    residuals: FloatArray
    rms: float
    sweep: float
    sigma: float
    positions: FloatArray
    basis: FloatArray
    axis_covariance: FloatArray
    encoder_scale: float | None = None
    warnings: tuple[str, ...] = field(default=())

    @property
    def direction_std(self) -> float:
        """RMS tilt of the axis direction expected from the covariance (rad)."""
        return math.sqrt(float(self.axis_covariance[0, 0] + self.axis_covariance[1, 1]))

    @property
    def position_std(self) -> float:
        """RMS shift of the axis perpendicular to itself at ``center`` (m)."""
        return math.sqrt(float(self.axis_covariance[2, 2] + self.axis_covariance[3, 3]))

    def point_direction_covariance(self) -> FloatArray:
        """Covariance (6, 6) of ``[point, direction]`` of :attr:`axis` in the measurement frame."""
        u, v = self.basis
        B = np.zeros((6, 4))
        B[3:, 0], B[3:, 1], B[:3, 2], B[:3, 3] = u, v, u, v
        return np.asarray(B @ self.axis_covariance @ B.T, dtype=np.float64)


def check_samples(points: ArrayLike, what: str, needed: int = 3) -> FloatArray:
    pts = check_points(f"{what} points", points)
    bad = int(np.count_nonzero(~np.isfinite(pts).all(axis=1)))
    if bad:
        raise NonFiniteError(what, bad)
    stride = max(1, pts.shape[0] // 1000)  # a strided thousand decides almost always
    n_distinct = int(np.unique(pts[::stride], axis=0).shape[0])
    if n_distinct < needed and stride > 1:
        n_distinct = int(np.unique(pts, axis=0).shape[0])
    if n_distinct < needed:
        raise TooFewPointsError(what, n_distinct, needed)
    return pts


def check_encoder(encoder: ArrayLike | None, m: int, what: str) -> FloatArray | None:
    if encoder is None:
        return None
    q = np.asarray(encoder, dtype=np.float64).reshape(-1)
    if q.shape != (m,):
        raise TooFewPointsError(f"{what} encoder values ({q.shape[0]} for {m} points)", 0, m)
    bad = int(np.count_nonzero(~np.isfinite(q)))
    if bad:
        raise NonFiniteError(f"{what} encoder values", bad)
    return q


def sense(values: FloatArray, key: FloatArray) -> float:
    """Sign of the least-squares slope of ``values`` against ``key``."""
    kc = key - key.mean()
    return 1.0 if float(kc @ (values - values.mean())) >= 0.0 else -1.0
