"""The nominal placed on the measured points: where the tracker stands relative to the robot.

A session of random static poses (or coupled moves, or a few stops) has no sweep to fit an axis
to, so the whole-model fit starts from a nominal table. That table's forward kinematics lives in
the robot's base frame and the points in the tracker's frame M; :func:`register_nominal` finds
the rigid transform ``T_measurement_base`` and the target's position on the flange (the tool
point in the last frame) that best carry the nominal's prediction onto the points, through the
one placement routine every caller shares (:func:`dhlog.identify.fit.placement.place_on`:
closed-form starts, robust least squares, the outliers set aside).

Pure numpy/scipy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.placement import (
    OUTLIER_SCALE,
    ROBUST_SCALE,
    SCALE_FLOOR,
    Stand,
    place_on,
)
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames

__all__ = [
    "OUTLIER_SCALE",
    "ROBUST_SCALE",
    "SCALE_FLOOR",
    "Registration",
    "register_nominal",
]


@dataclass(frozen=True)
class Registration:
    """``T_measurement_base`` (4×4: frame 1 of the nominal table in M), the target in the last
    frame (``tool_point``, m), the residual of every sample (m, 3-D distance), the inliers and
    the RMS over them: how far the nominal is from the points before any calibration."""

    T_measurement_base: FloatArray
    tool_point: FloatArray
    residuals: FloatArray
    inliers: NDArray[np.bool_]
    rms: float


def register_nominal(
    table: StandardDH,
    Q: FloatArray,
    P: FloatArray,
    *,
    tool_point: FloatArray | None = None,
    T_base: FloatArray | None = None,
    fit_tool: bool = True,
) -> Registration:
    """Place the nominal ``table`` on the points ``P`` (m, 3) measured at joint vectors ``Q``
    (m, n): see the module docstring. ``tool_point`` and ``T_base`` (the nominal's, if it has
    them) are one start of the search and hold what the points do not determine; without
    ``fit_tool`` the tool point is kept (a calibrated model placed again after the tracker
    moved). Raises :class:`DegenerateGeometryError` when
    the poses do not fix a rigid transform (fewer than three distinct, non-collinear target
    positions)."""
    if Q.shape[0] < 3:
        raise DegenerateGeometryError(
            f"{Q.shape[0]} sample(s) with encoder values cannot place the nominal on the points; "
            "measure at least three distinct poses."
        )
    frames = fk_frames(table, Q)[:, -1]  # in the nominal's frame 1
    R_last, p_last = frames[:, :3, :3], frames[:, :3, 3]
    tool = np.zeros(3) if tool_point is None else np.asarray(tool_point, dtype=np.float64)
    spread = np.linalg.svd(p_last - p_last.mean(axis=0), compute_uv=False)
    if spread[1] < 1e-3 * max(spread[0], 1e-12):
        raise DegenerateGeometryError(
            "the poses put the flange on one line: they cannot place the nominal on the points; "
            "measure poses that spread in two directions at least."
        )
    T = np.eye(4) if T_base is None else np.asarray(T_base, dtype=np.float64)
    got = place_on(R_last, p_last, P, stand=Stand(T, tool), point=fit_tool)
    return Registration(got.T, got.tool, got.residuals, got.inliers, got.rms)
