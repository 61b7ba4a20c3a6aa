"""The orientation components a, b, c of ISO 9283:1998 clause 5.2 (fixed-axis X-Y-Z angles,
``R = Rz(c) Ry(b) Rx(a)``), a rotation from them, the deviation of one orientation from another
in the base frame, and the chordal mean of rotations.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import ShapeError
from dhlog.geometry._checks import FloatArray, nearest_rotation
from dhlog.iso9283.formulas.checks import (
    _finite,
    _rotations,
)


def orientation_abc(R: ArrayLike) -> FloatArray:
    """The orientation components a, b, c (rad) of rotation matrices ``R`` (…, 3, 3): rotations
    about the base frame's x, y and z axes, ISO 9283:1998 clause 5.2 (a, b, c), taken here as
    fixed-axis X-Y-Z angles, ``R = Rz(c) Ry(b) Rx(a)`` (the standard names the axes but not the
    sequence: this choice is documented in docs/iso9283.md). Returns (…, 3) with
    b ∈ [−π/2, π/2], a, c ∈ (−π, π]; at b = ±π/2 the whole turn about z is put in c (a = 0)."""
    Rm = _rotations("orientation_abc: R", R)
    b = np.arcsin(np.clip(-Rm[..., 2, 0], -1.0, 1.0))
    a = np.arctan2(Rm[..., 2, 1], Rm[..., 2, 2])
    c = np.arctan2(Rm[..., 1, 0], Rm[..., 0, 0])
    gimbal = np.abs(np.cos(b)) < 1e-9
    a = np.where(gimbal, 0.0, a)
    c = np.where(gimbal, np.arctan2(-Rm[..., 0, 1], Rm[..., 1, 1]), c)
    return np.asarray(np.stack([a, b, c], axis=-1), dtype=np.float64)


def matrix_from_abc(abc: ArrayLike) -> FloatArray:
    """The rotation ``Rz(c) Ry(b) Rx(a)`` of orientation components ``abc`` (…, 3) (rad): the
    inverse of :func:`orientation_abc`."""
    v = _finite("matrix_from_abc: abc", np.asarray(abc, dtype=np.float64))
    if v.shape[-1:] != (3,):
        raise ShapeError("matrix_from_abc: abc", "(..., 3) angles (rad)", f"shape {v.shape}")
    ca, sa = np.cos(v[..., 0]), np.sin(v[..., 0])
    cb, sb = np.cos(v[..., 1]), np.sin(v[..., 1])
    cc, sc = np.cos(v[..., 2]), np.sin(v[..., 2])
    R = np.empty((*v.shape[:-1], 3, 3))
    R[..., 0, 0] = cc * cb
    R[..., 0, 1] = cc * sb * sa - sc * ca
    R[..., 0, 2] = cc * sb * ca + sc * sa
    R[..., 1, 0] = sc * cb
    R[..., 1, 1] = sc * sb * sa + cc * ca
    R[..., 1, 2] = sc * sb * ca - cc * sa
    R[..., 2, 0] = -sb
    R[..., 2, 1] = cb * sa
    R[..., 2, 2] = cb * ca
    return R


def orientation_deviation(R: ArrayLike, R_ref: ArrayLike) -> FloatArray:
    """The orientation components a, b, c (rad) of ``R`` (…, 3, 3) relative to ``R_ref`` (3, 3)
    or (…, 3, 3), in the base frame: :func:`orientation_abc` of ``ΔR = R R_refᵀ`` (so that
    ``R = ΔR R_ref``). For the small deviations of a robot these are the rotations about the
    base's x, y, z that carry the reference orientation onto the attained one.

    This is what every orientation characteristic here is computed from (AP_a = mean of the
    attained orientations' deviations from the commanded one, S_a of their deviations from the
    mean orientation, …). ISO 9283 writes AP_a = ā − a_c of the components themselves; taken
    literally on Euler angles, a difference of angles is a rotation about the base's x only at
    the identity (the angles' rates mix elsewhere, and wrap at ±π), so the deviation is taken
    first: the same to first order in the deviation where the reference is the identity, and a
    rotation about the named axis everywhere."""
    Rm = _rotations("orientation_deviation: R", R)
    Rr = _rotations("orientation_deviation: R_ref", R_ref)
    dR = np.einsum("...ij,...kj->...ik", Rm, Rr)
    return orientation_abc(dR)


def _mean_rotation(R: FloatArray) -> FloatArray:
    """The chordal mean of rotations (n, 3, 3): the rotation nearest their arithmetic mean."""
    return nearest_rotation(np.asarray(R.mean(axis=0), dtype=np.float64))
