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

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError, GeometryError
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.placement import (
    OUTLIER_SCALE,
    ROBUST_SCALE,
    SCALE_FLOOR,
    Stand,
    place_on,
)
from dhlog.identify.segment.clocks import matched_points
from dhlog.io.dhfile import DHModel
from dhlog.io.logdata import LogData
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


#: Samples the nominal is placed on to judge a clock offset (evenly strided).
JUDGE_SAMPLES = 400
#: The share of those samples the judge's miss leaves out, the worst (the tracker's gross
#: outliers); the rest, misjoined samples among them, all count.
JUDGE_TRIM = 0.1


def clock_judge(
    log: LogData,
    table: StandardDH,
    values: Callable[[FloatArray], FloatArray],
    stand: Stand,
    *,
    samples: int = JUDGE_SAMPLES,
    since_ns: int | None = None,
) -> Callable[[float], float] | None:
    """``miss(offset)``: with the joint states moved by ``offset`` s, the model — ``table``, its
    joint values ``values(encoders)``, standing at ``stand`` (a start of the search) — placed
    on the log's first target's samples (at most ``samples``) and the RMS (m) by which it
    misses them, every sample counted but the worst :data:`JUDGE_TRIM` (the placement's own
    RMS is over its inliers, and a wrong offset makes outliers of the samples it misjoins);
    inf where too few samples have joint states or it cannot be placed. None where the log's
    joints are not the model's. The nominal judges a session's clock, the calibrated model a
    held-out log's; ``since_ns``: only the samples stamped from then on (those after a clock
    set mid-session)."""
    joints, points = log.joints, matched_points(log)  # the samples the match reads
    if joints is None or joints.width - 1 != table.n or points is None:
        return None
    if since_ns is not None:
        points = points.filter(pl.col("t_ns") >= since_ns)
    if points.height < 20:
        return None
    pick = slice(None, None, max(1, -(-points.height // samples)))
    t_p = np.asarray(points["t_ns"].to_numpy()[pick], dtype=np.float64) * 1e-9
    P = np.column_stack([np.asarray(points[c].to_numpy()[pick], np.float64) for c in "xyz"])
    stream = joints  # its columns read when first judged: an offset found, or in doubt

    def miss(offset: float) -> float:
        t_j = stream["t_ns"].to_numpy() * 1e-9
        Q = np.column_stack(
            [
                np.interp(t_p - offset, t_j, stream[c].to_numpy(), left=np.nan, right=np.nan)
                for c in stream.columns[1:]
            ]
        )
        ok = np.isfinite(Q).all(axis=1)
        if np.count_nonzero(ok) < 20:
            return math.inf
        try:
            reg = register_nominal(
                table, values(Q[ok]), P[ok], tool_point=stand.tool, T_base=stand.T
            )
        except (GeometryError, np.linalg.LinAlgError):
            return math.inf
        d = np.asarray(reg.residuals, dtype=np.float64)  # every sample's, inliers or not
        kept = np.sort(d)[: max(1, round((1.0 - JUDGE_TRIM) * d.size))]
        return float(np.sqrt(np.mean(kept**2)))

    return miss


def nominal_judge(log: LogData, nominal: DHModel) -> Callable[[float], float] | None:
    """:func:`clock_judge` with the nominal as it stands (its base and tool point)."""
    return clock_judge(
        log, nominal.table, nominal.joint_values, Stand(nominal.T_base, nominal.tool_point)
    )
