"""Forward kinematics and the spatial manipulator Jacobian of DH chains (seed 004).

All functions take a table, joint vector(s) ``q`` of shape (..., n) and an optional base transform
``T_base`` (frame 1 of a standard table, or frame 0 of a modified one, in the world/measurement
frame) and broadcast over leading dimensions of ``q``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dhlog.geometry._checks import FloatArray, check_vector3
from dhlog.model.dh import HayatiDH, ModifiedDH, StandardDH

DHTable = StandardDH | ModifiedDH


def _base(T_base: ArrayLike | None) -> FloatArray:
    return np.eye(4) if T_base is None else np.asarray(T_base, dtype=np.float64)


def fk_frames(table: DHTable, q: ArrayLike, *, T_base: ArrayLike | None = None) -> FloatArray:
    """All link frames in the world frame, shape (..., n+1, 4, 4) (seed 004, Eq. 3).

    Standard table: entry 0 is frame 1 (``T_base``) and entry i is frame i+1, whose z axis is joint
    i+1's axis (entry n is the tool-side frame n+1). Modified table: entry 0 is frame 0 and entry i
    is frame i, whose z axis is joint i's axis.
    """
    links = table.link_transforms(q)
    base = _base(T_base)
    frames = np.empty((*links.shape[:-3], table.n + 1, 4, 4))
    frames[..., 0, :, :] = base
    current = np.broadcast_to(base, (*links.shape[:-3], 4, 4))
    for i in range(table.n):
        current = current @ links[..., i, :, :]
        frames[..., i + 1, :, :] = current
    return frames


def joint_axes(
    table: DHTable, q: ArrayLike, *, T_base: ArrayLike | None = None
) -> tuple[FloatArray, FloatArray]:
    """Points and unit directions of the n joint axes in the world frame, each (..., n, 3)."""
    frames = fk_frames(table, q, T_base=T_base)
    axis_frames = frames[..., :-1, :, :] if isinstance(table, StandardDH) else frames[..., 1:, :, :]
    return axis_frames[..., :3, 3], axis_frames[..., :3, 2]


#: Joint vectors a block in :func:`fk_point`.
FK_BLOCK = 1 << 16


def fk_point(
    table: DHTable,
    q: ArrayLike,
    tool_point: ArrayLike,
    *,
    T_base: ArrayLike | None = None,
    T_tool: ArrayLike | None = None,
) -> FloatArray:
    """World position of ``tool_point`` (given in the last frame, after ``T_tool``), (..., 3).

    The result-contract check: ``T_measurement_base · A_1 ⋯ A_n · [tool, 1]``. Many joint
    vectors (m, n) go ``FK_BLOCK`` at a time, each with its own arithmetic (the same numbers):
    the link frames of every sample at once took 18 GB for a 20 M-sample simulated session.
    """
    tool = check_vector3("tool point", tool_point)
    qa = np.asarray(q, dtype=np.float64)
    if qa.ndim == 2 and qa.shape[0] > FK_BLOCK:
        return np.concatenate(
            [
                fk_point(table, qa[s : s + FK_BLOCK], tool, T_base=T_base, T_tool=T_tool)
                for s in range(0, qa.shape[0], FK_BLOCK)
            ]
        )
    T_last = fk_frames(table, qa, T_base=T_base)[..., -1, :, :]
    if T_tool is not None:
        T_last = T_last @ np.asarray(T_tool, dtype=np.float64)
    return np.asarray(T_last[..., :3, :3] @ tool + T_last[..., :3, 3], dtype=np.float64)


def spatial_jacobian(
    table: DHTable, q: ArrayLike, *, T_base: ArrayLike | None = None
) -> FloatArray:
    """Spatial manipulator Jacobian, shape (..., 6, n), rows ``[v; ω]`` (seed 004, Eq. 5–6).

    Column i is joint i's twist in the world frame: ``[−ω_i × q_i; ω_i]`` for a revolute joint
    (``ω_i`` its axis direction, ``q_i`` a point on it), ``[ω_i; 0]`` for a prismatic joint.
    """
    points, dirs = joint_axes(table, q, T_base=T_base)
    revolute = table.revolute[:, None]
    v = revolute * -np.cross(dirs, points) + (1.0 - revolute) * dirs
    w = revolute * dirs
    return np.asarray(np.swapaxes(np.concatenate([v, w], axis=-1), -1, -2), dtype=np.float64)


def fk_points_chunked(
    table: StandardDH,
    Q: ArrayLike,
    tool_point: ArrayLike,
    *,
    T_base: ArrayLike | None = None,
    chunk: int = 65536,
) -> FloatArray:
    """``fk_point`` of a standard table (Hayati rows included) for many joint vectors ``Q``
    (m, n) → (m, 3), without building the link frames: the tool point is carried back through
    ``A_n … A_1`` (each ``Rz(θ) Tz(d) Tx(a) Rx(α)``, Hayati rows ``… Ry(β)``) one joint at a
    time, in chunks of samples, so memory stays bounded and every operation is on contiguous
    rows."""
    tool = check_vector3("tool point", tool_point)
    Qa = table.check_q(Q)
    if Qa.ndim != 2:
        raise ValueError("fk_points_chunked takes a 2-D array of joint vectors")
    base = _base(T_base)
    m = Qa.shape[0]
    out = np.empty((m, 3))
    ca, sa = np.cos(table.alpha), np.sin(table.alpha)
    beta = table.beta if isinstance(table, HayatiDH) else np.zeros(table.n)
    cb, sb = np.cos(beta), np.sin(beta)
    for start in range(0, m, chunk):
        q = Qa[start : start + chunk].T
        theta = table.theta_offset[:, None] + q * table.revolute[:, None]
        d = table.d_offset[:, None] + q * (1.0 - table.revolute[:, None])
        x = np.full(q.shape[1], tool[0])
        y = np.full(q.shape[1], tool[1])
        z = np.full(q.shape[1], tool[2])
        for i in range(table.n - 1, -1, -1):
            # Ry(β) (Hayati rows), Rx(α), then Tx(a) and Tz(d), then Rz(θ)
            if beta[i] != 0.0:
                x, z = cb[i] * x + sb[i] * z, -sb[i] * x + cb[i] * z
            y, z = ca[i] * y - sa[i] * z, sa[i] * y + ca[i] * z
            x = x + table.a[i]
            z = z + d[i]
            c, s = np.cos(theta[i]), np.sin(theta[i])
            x, y = c * x - s * y, s * x + c * y
        R, t = base[:3, :3], base[:3, 3]
        out[start : start + q.shape[1]] = np.column_stack(
            [R[a, 0] * x + R[a, 1] * y + R[a, 2] * z + t[a] for a in range(3)]
        )
    return out
