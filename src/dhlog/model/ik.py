"""Inverse kinematics of a DH chain: the joint vectors that put a tool frame at given poses.

A damped least-squares (Levenberg–Marquardt) solver on the analytic spatial Jacobian
(:func:`dhlog.model.fk.spatial_jacobian`), many targets at once, pure numpy. The tool frame is the
last frame translated to ``tool`` (a point in the last frame; its axes are the last frame's).
The error of a pose is the 6-vector (position difference in m, divided by ``length``; the
rotation vector of ``R Rᵍᵀ`` in rad), and each step solves ``(JᵀJ + μ I) δ = −Jᵀ e`` with ``μ``
shrunk after a step that lowers the error and grown (the step refused) after one that does not:
Gauss–Newton near the solution, a bounded gradient step near a singularity or far from it.
Converged: position within ``tol`` m and rotation within ``tol`` rad. Joints are kept within
``limits`` when given (each step clipped). Fewer than six joints: the least-squares pose, its
residual reported (not converged unless the pose is reachable).

``dhlog.cell.compensate`` keeps its own Newton solver: it inverts the calibrated model with its
terms beyond the geometry (a central-difference Jacobian of that whole map), not a DH table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import StandardDH
from dhlog.model.fk import DHTable, fk_frames

#: The pose error (m and rad) at which a target has converged.
TOLERANCE = 1e-12


@dataclass(frozen=True)
class IKSettings:
    """How :func:`solve` iterates: ``tol`` the pose error (m and rad) at which a target has
    converged, at most ``max_iterations`` steps, and ``damping`` the first steps' μ (relative
    to the mean of JᵀJ's diagonal; small when the start is near the goal)."""

    tol: float = TOLERANCE
    max_iterations: int = 200
    damping: float = 1e-3


@dataclass(frozen=True)
class IKSolution:
    """Joint vectors ``q`` (m, n), the remaining position error (m) and rotation error (rad)
    per target (m,), and ``converged`` (m,): both within the tolerance."""

    q: FloatArray
    position_error: FloatArray
    rotation_error: FloatArray
    converged: np.ndarray


def tool_poses(
    table: DHTable, q: ArrayLike, tool: ArrayLike, *, T_base: ArrayLike | None = None
) -> FloatArray:
    """The tool frame (..., 4, 4): the last frame moved to the point ``tool`` (in the last
    frame), its axes the last frame's, in the world frame of ``T_base``."""
    T = np.array(fk_frames(table, q, T_base=T_base)[..., -1, :, :])
    t = np.asarray(tool, dtype=np.float64)
    T[..., :3, 3] = T[..., :3, :3] @ t + T[..., :3, 3]
    return T


def rotation_vector(R: ArrayLike) -> FloatArray:
    """The rotation vectors (..., 3) of rotation matrices (..., 3, 3), through the unit
    quaternion (Shepperd's branch choice): exact near a half turn, where the skew part vanishes."""
    M = np.asarray(R, dtype=np.float64)
    tr = np.trace(M, axis1=-2, axis2=-1)
    diag = np.stack([tr, M[..., 0, 0], M[..., 1, 1], M[..., 2, 2]], axis=-1)
    k = np.argmax(diag, axis=-1)
    qs = np.empty((*M.shape[:-2], 4))
    # each branch divides by its largest component: 4 w², 4 x², 4 y² or 4 z² ≥ 1
    w = np.sqrt(np.maximum(1.0 + tr, 0.0)) / 2
    x = np.sqrt(np.maximum(1.0 + 2 * M[..., 0, 0] - tr, 0.0)) / 2
    y = np.sqrt(np.maximum(1.0 + 2 * M[..., 1, 1] - tr, 0.0)) / 2
    z = np.sqrt(np.maximum(1.0 + 2 * M[..., 2, 2] - tr, 0.0)) / 2
    a, b, c = M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0], M[..., 1, 0] - M[..., 0, 1]
    e, f, g = M[..., 0, 1] + M[..., 1, 0], M[..., 0, 2] + M[..., 2, 0], M[..., 1, 2] + M[..., 2, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        branches = [
            np.stack([w, a / (4 * w), b / (4 * w), c / (4 * w)], axis=-1),
            np.stack([a / (4 * x), x, e / (4 * x), f / (4 * x)], axis=-1),
            np.stack([b / (4 * y), e / (4 * y), y, g / (4 * y)], axis=-1),
            np.stack([c / (4 * z), f / (4 * z), g / (4 * z), z], axis=-1),
        ]
    for i, branch in enumerate(branches):
        qs = np.where((k == i)[..., None], branch, qs)
    qs = np.where(qs[..., :1] < 0, -qs, qs)  # w ≥ 0: the angle within [0, π]
    v = qs[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2 * np.arctan2(s, qs[..., 0])
    # small angles: angle / s → 2 (the series of 2 atan(s/w)/s with w → 1)
    factor = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0)
    return np.asarray(v * factor[..., None], dtype=np.float64)


def _error(T: FloatArray, goal: FloatArray, length: float) -> FloatArray:
    """The 6-vectors (m, 6): position difference / ``length``, rotation vector of R Rᵍᵀ."""
    dp = (T[:, :3, 3] - goal[:, :3, 3]) / length
    dr = rotation_vector(np.einsum("mij,mkj->mik", T[:, :3, :3], goal[:, :3, :3]))
    return np.asarray(np.concatenate([dp, dr], axis=1), dtype=np.float64)


def _pose_and_jacobian(
    table: DHTable,
    q: ArrayLike,
    tool: ArrayLike,
    T_base: ArrayLike | None,
    length: float,
) -> tuple[FloatArray, FloatArray]:
    """The tool frame (..., 4, 4) and :func:`tool_jacobian` (..., 6, n) from one pass of the
    link frames (the spatial Jacobian of seed 004, Eq. 5–6, moved to the tool point)."""
    frames = fk_frames(table, q, T_base=T_base)
    T = np.array(frames[..., -1, :, :])
    t = np.asarray(tool, dtype=np.float64)
    T[..., :3, 3] = T[..., :3, :3] @ t + T[..., :3, 3]
    axis = frames[..., :-1, :, :] if isinstance(table, StandardDH) else frames[..., 1:, :, :]
    points, dirs = axis[..., :3, 3], axis[..., :3, 2]  # (..., n, 3)
    revolute = table.revolute[:, None]
    # a revolute joint moves the tool point by ω × (p − q_i), a prismatic one along its axis
    v = revolute * np.cross(dirs, T[..., None, :3, 3] - points) + (1.0 - revolute) * dirs
    w = revolute * dirs
    J = np.concatenate([v / length, w], axis=-1)  # (..., n, 6)
    return T, np.asarray(np.swapaxes(J, -1, -2), dtype=np.float64)


def tool_jacobian(
    table: DHTable,
    q: ArrayLike,
    tool: ArrayLike,
    *,
    T_base: ArrayLike | None = None,
    length: float = 1.0,
) -> FloatArray:
    """The Jacobian (..., 6, n) of the tool point's velocity (rows 0–2, divided by ``length``)
    and the tool frame's angular velocity (rows 3–5), in the world frame: the spatial Jacobian
    (:func:`dhlog.model.fk.spatial_jacobian`) moved to the tool point."""
    return _pose_and_jacobian(table, q, tool, T_base, length)[1]


def condition(
    table: DHTable,
    q: ArrayLike,
    tool: ArrayLike,
    *,
    T_base: ArrayLike | None = None,
    length: float = 1.0,
) -> FloatArray:
    """The condition number (...,) of :func:`tool_jacobian` (its translational rows divided by
    ``length``, so that both halves are dimensionless): the largest singular value over the
    smallest of the min(6, n) there are; inf at a singularity."""
    s = np.linalg.svd(tool_jacobian(table, q, tool, T_base=T_base, length=length), compute_uv=False)
    small = s[..., -1]
    with np.errstate(divide="ignore"):
        return np.asarray(np.where(small > 0, s[..., 0] / np.where(small > 0, small, 1), np.inf))


def solve(
    table: DHTable,
    goal: ArrayLike,
    start: ArrayLike,
    tool: ArrayLike,
    *,
    T_base: ArrayLike | None = None,
    limits: ArrayLike | None = None,
    length: float = 1.0,
    settings: IKSettings = IKSettings(),
) -> IKSolution:
    """The joint vectors (m, n) that put the tool frame (``tool``: a point in the last frame) at
    ``goal`` (m, 4, 4, world frame of ``T_base``), from ``start`` (m, n) — see the module
    docstring. ``limits`` (n, 2): every step is clipped into them. ``length`` (m): the scale
    that makes a position error comparable to a rotation (the robot's reach). ``settings``:
    the tolerance, the most steps and the first damping (:class:`IKSettings`)."""
    tol, max_iterations, damping = settings.tol, settings.max_iterations, settings.damping
    G = np.asarray(goal, dtype=np.float64)
    q = np.array(start, dtype=np.float64)
    m, n = q.shape
    lim = None if limits is None else np.asarray(limits, dtype=np.float64)
    if lim is not None:
        q = np.clip(q, lim[:, 0], lim[:, 1])
    T, J = _pose_and_jacobian(table, q, tool, T_base, length)
    err = _error(T, G, length)
    cost = np.sum(err**2, axis=1)
    mu = np.full(m, damping)
    eye = np.eye(n)

    def done(e: FloatArray) -> np.ndarray:
        return np.asarray(
            (np.max(np.abs(e[:, :3]), axis=1) * length <= tol)
            & (np.max(np.abs(e[:, 3:]), axis=1) <= tol)
        )

    active = ~done(err)
    for _ in range(max_iterations):
        rows = np.flatnonzero(active)
        if not rows.size:
            break
        Jr = J[rows]
        JtJ = np.einsum("mki,mkj->mij", Jr, Jr)
        g = np.einsum("mki,mk->mi", Jr, err[rows])
        scale = np.trace(JtJ, axis1=1, axis2=2)[:, None, None] / n
        A = JtJ + (mu[rows][:, None, None] * scale) * eye
        delta = -np.linalg.solve(A, g[..., None])[..., 0]
        trial = q[rows] + delta
        if lim is not None:
            trial = np.clip(trial, lim[:, 0], lim[:, 1])
        Tt, Jt = _pose_and_jacobian(table, trial, tool, T_base, length)
        e = _error(Tt, G[rows], length)
        c = np.sum(e**2, axis=1)
        better = c < cost[rows]
        take = rows[better]
        q[take], err[take], cost[take], J[take] = trial[better], e[better], c[better], Jt[better]
        mu[take] = np.maximum(mu[take] / 10.0, 1e-15)
        mu[rows[~better]] *= 10.0
        # converged, or no step lowers the error any more (a least-squares pose, or stuck)
        active[rows] = ~done(err[rows]) & (mu[rows] <= 1e12)
    pos = np.linalg.norm(err[:, :3], axis=1) * length
    rot = np.linalg.norm(err[:, 3:], axis=1)
    return IKSolution(q, pos, rot, (pos <= tol * np.sqrt(3)) & (rot <= tol * np.sqrt(3)))
