"""The nominal placed on the measured points: where the tracker stands relative to the robot.

A session of random static poses (or coupled moves, or a few stops) has no sweep to fit an axis
to, so the whole-model fit starts from a nominal table. That table's forward kinematics lives in
the robot's base frame and the points in the tracker's frame M; :func:`register_nominal` finds
the rigid transform ``T_measurement_base`` and the target's position on the flange (the tool
point in the last frame) that best carry the nominal's prediction onto the points: Kabsch on the
points (tool point taken as the nominal's), the tool point again by linear least squares, a few
alternations, then a robust (soft-L1) nonlinear least squares over all nine numbers, and plain
least squares again over the samples within :data:`OUTLIER_SCALE` robust scales of it (the
others are reported as outliers).

Pure numpy/scipy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, nearest_rotation, rotation_from_vector
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames

#: Samples beyond this many robust scales (median absolute 3-D residual / 0.6745·√3-ish) are
#: outliers of the registration.
OUTLIER_SCALE = 5.0
#: The soft-L1 loss switches from quadratic to linear at this 3-D residual (m): the nominal's own
#: error at a pose is typically a millimetre, a gross outlier (a beam break) centimetres.
ROBUST_SCALE = 2e-3
#: The robust scale is never taken below this (m): no tracker measures better.
SCALE_FLOOR = 1e-6


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


def _kabsch(A: FloatArray, B: FloatArray) -> FloatArray:
    """The rigid transform (4×4) carrying the points ``A`` (m, 3) onto ``B`` (m, 3)."""
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    T = np.eye(4)
    T[:3, :3] = nearest_rotation((B - cb).T @ (A - ca))
    T[:3, 3] = cb - T[:3, :3] @ ca
    return T


def register_nominal(
    table: StandardDH,
    Q: FloatArray,
    P: FloatArray,
    *,
    tool_point: FloatArray | None = None,
    T_base: FloatArray | None = None,
    alternations: int = 5,
    fit_tool: bool = True,
) -> Registration:
    """Place the nominal ``table`` on the points ``P`` (m, 3) measured at joint vectors ``Q``
    (m, n): see the module docstring. ``tool_point`` and ``T_base`` (the nominal's, if it has
    them) only start the search; without ``fit_tool`` the tool point is kept (a calibrated
    model placed again after the tracker moved). Raises :class:`DegenerateGeometryError` when
    the poses do not fix a rigid transform (fewer than three distinct, non-collinear target
    positions)."""
    from scipy.optimize import least_squares

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
    for _ in range(alternations):
        local = np.einsum("mij,j->mi", R_last, tool) + p_last
        T = _kabsch(local, P)
        if not fit_tool:
            continue
        # the tool point: R (R_last t + p_last) + c = P  →  (R R_last) t = P − c − R p_last
        A = np.einsum("ij,mjk->mik", T[:3, :3], R_last).reshape(-1, 3)
        b = (P - T[:3, 3] - p_last @ T[:3, :3].T).reshape(-1)
        tool, *_ = np.linalg.lstsq(A, b, rcond=None)

    def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        t = x[6:9] if fit_tool else tool
        return rotation_from_vector(x[:3]) @ T[:3, :3], x[3:6] + T[:3, 3], t

    def residual(x: FloatArray) -> FloatArray:
        R, c, t = unpack(x)
        pred = (np.einsum("mij,j->mi", R_last, t) + p_last) @ R.T + c
        return np.asarray((pred - P).reshape(-1), dtype=np.float64)

    x0 = np.r_[np.zeros(6), tool] if fit_tool else np.zeros(6)
    x = least_squares(residual, x0, loss="soft_l1", f_scale=ROBUST_SCALE, x_scale="jac").x
    inliers: NDArray[np.bool_] | None = None
    for _ in range(3):  # the robust loss still leans towards gross outliers: refit without them
        dist = np.linalg.norm(residual(x).reshape(-1, 3), axis=1)
        scale = max(float(np.median(dist)) * 1.5, SCALE_FLOOR)
        keep = dist <= OUTLIER_SCALE * scale
        if inliers is not None and np.array_equal(keep, inliers):
            break
        inliers = keep

        def on_inliers(x: FloatArray, keep: NDArray[np.bool_] = keep) -> FloatArray:
            return residual(x).reshape(-1, 3)[keep].reshape(-1)

        x = least_squares(on_inliers, x, x_scale="jac").x
    assert inliers is not None
    dist = np.linalg.norm(residual(x).reshape(-1, 3), axis=1)
    R, c, t = unpack(x)
    placed = np.eye(4)
    placed[:3, :3], placed[:3, 3] = R, c
    rms = float(np.sqrt(np.mean(dist[inliers] ** 2))) if np.any(inliers) else float("nan")
    return Registration(placed, np.asarray(t, dtype=np.float64), dist, inliers, rms)
