"""Rigid motions of joints given as lines: the product of exponentials about measured axes.

A revolute joint turning by ``δ`` about the line (point ``c``, unit direction ``ω``) moves points
by ``p ↦ R(ω, δ)(p − c) + c``; a prismatic joint sliding by ``δ`` along ``e`` by ``p ↦ p + δ e``.
With the axes known at a reference pose ``q_ref``, link k's pose at ``q`` relative to its pose at
``q_ref`` is ``M_k(q) = T_1(q_1 − q_ref,1) ⋯ T_k(q_k − q_ref,k)`` (seed 004, Eq. 5–6 give the
same twists).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from dhlog.geometry._checks import FloatArray, rotation_about
from dhlog.geometry.lines import Line
from dhlog.model.dh import JointType


def joint_motion(axis: Line, joint_type: JointType, delta: float) -> FloatArray:
    """4x4 motion of a joint about/along ``axis`` by ``delta`` (rad or m)."""
    T = np.eye(4)
    if joint_type is JointType.PRISMATIC:
        T[:3, 3] = delta * axis.direction
        return T
    R = rotation_about(axis.direction, delta)
    T[:3, :3] = R
    T[:3, 3] = axis.point - R @ axis.point
    return T


def chain_motion(
    axes: Sequence[Line], types: Sequence[JointType], q: ArrayLike, q_ref: ArrayLike
) -> FloatArray:
    """``M_k(q)``: motion of the link after the last of ``axes`` from ``q_ref`` to ``q`` (4x4)."""
    dq = np.asarray(q, dtype=np.float64) - np.asarray(q_ref, dtype=np.float64)
    M = np.eye(4)
    for axis, jt, d in zip(axes, types, dq, strict=False):
        M = M @ joint_motion(axis, jt, float(d))
    return M


def chain_motions(
    axes: Sequence[Line], types: Sequence[JointType], Q: ArrayLike, q_ref: ArrayLike
) -> FloatArray:
    """``M_n(q)`` for each row of ``Q`` (m, n) at once, shape (m, 4, 4)."""
    dq = np.asarray(Q, dtype=np.float64) - np.asarray(q_ref, dtype=np.float64)
    m = dq.shape[0]
    M = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
    for j, (axis, jt) in enumerate(zip(axes, types, strict=False)):
        T = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
        if jt is JointType.PRISMATIC:
            T[:, :3, 3] = dq[:, j, None] * axis.direction
        else:
            k = axis.direction
            K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
            s, c = np.sin(dq[:, j]), np.cos(dq[:, j])
            R = np.eye(3) + s[:, None, None] * K + (1.0 - c)[:, None, None] * (K @ K)
            T[:, :3, :3] = R
            T[:, :3, 3] = axis.point - R @ axis.point
        M = M @ T
    return M


def motions_back(
    axes: Sequence[Line], types: Sequence[JointType], Q: ArrayLike, q_ref: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Rotations ``Rᵀ`` (m, 3, 3) and translations ``t`` (m, 3) of ``M_n(q)`` for each row of
    ``Q``: a point ``p`` measured at ``q`` sits at ``Rᵀ (p − t)`` at the reference pose."""
    M = chain_motions(axes, types, Q, q_ref)
    return np.swapaxes(M[:, :3, :3], 1, 2), M[:, :3, 3]


def points_at_reference(
    axes: Sequence[Line],
    types: Sequence[JointType],
    Q: ArrayLike,
    P: ArrayLike,
    q_ref: ArrayLike,
) -> FloatArray:
    """Points ``P`` (m, 3) measured at the joint vectors ``Q`` (m, n), moved back to the
    reference pose through the axes: ``M_n(q)⁻¹ p``."""
    Rt, t = motions_back(axes, types, Q, q_ref)
    return np.asarray(np.einsum("mij,mj->mi", Rt, np.asarray(P) - t), dtype=np.float64)
