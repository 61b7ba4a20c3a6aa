"""Shape and finiteness validators for plain arrays (the ``check_*`` family)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dhlog.errors import ShapeError

FloatArray = NDArray[np.float64]


def check_vector3(name: str, value: ArrayLike) -> FloatArray:
    """Return ``value`` as a finite float64 array of shape (3,), or raise :class:`ShapeError`."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ShapeError(name, "a 3-vector", f"shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ShapeError(name, "finite", arr.tolist())
    return arr


def check_unit_direction(name: str, value: ArrayLike, *, min_norm: float = 1e-12) -> FloatArray:
    """Return ``value`` normalised to unit length; raise if it is (nearly) zero."""
    arr = check_vector3(name, value)
    norm = float(np.linalg.norm(arr))
    if norm < min_norm:
        raise ShapeError(name, "a non-zero direction", arr.tolist())
    return arr / norm


def check_points(name: str, value: ArrayLike) -> FloatArray:
    """Return ``value`` as a float64 array of shape (m, 3) (finiteness is checked by the fits)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ShapeError(name, "an (m, 3) array of points", f"shape {arr.shape}")
    return arr


def check_transform(name: str, value: ArrayLike, *, tol: float = 1e-9) -> FloatArray:
    """Return ``value`` as a (4, 4) rigid transform; raise if the rotation is not orthonormal."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (4, 4):
        raise ShapeError(name, "a 4x4 homogeneous transform", f"shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ShapeError(name, "finite", "non-finite entries")
    rot = arr[:3, :3]
    if (
        not np.allclose(rot @ rot.T, np.eye(3), atol=tol)
        or abs(np.linalg.det(rot) - 1.0) > tol
        or not np.allclose(arr[3], [0.0, 0.0, 0.0, 1.0])
    ):
        raise ShapeError(
            name, "a rigid transform (orthonormal rotation, last row 0 0 0 1)", "other"
        )
    return arr


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of two 3-vectors (without the general machinery of ``np.cross``)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def perpendicular_basis(direction: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors ``u, v`` with ``(u, v, direction)`` right-handed and orthonormal.

    Deterministic: ``u`` is the measurement axis least aligned with ``direction``, made orthogonal.
    """
    e = direction / np.linalg.norm(direction)
    seed = np.zeros(3)
    seed[int(np.argmin(np.abs(e)))] = 1.0
    u = seed - (seed @ e) * e
    u /= np.linalg.norm(u)
    v = cross3(e, u)
    return u, v


def rotation_about(axis: FloatArray, angle: float) -> FloatArray:
    """Rotation matrix of ``angle`` (rad) about the unit vector ``axis`` (Rodrigues)."""
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R = np.eye(3) + np.sin(angle) * kx + (1.0 - np.cos(angle)) * (kx @ kx)
    return np.asarray(R, dtype=np.float64)


def nearest_rotation(A: FloatArray) -> FloatArray:
    """The rotation nearest the 3×3 matrix ``A`` (its polar factor by SVD, as in Kabsch's
    algorithm): ``A = Bᵀ C`` of two sets of centred vectors gives the rotation carrying C's onto
    B's."""
    U, _, Vt = np.linalg.svd(A)
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(U @ Vt)))])
    return np.asarray(U @ D @ Vt, dtype=np.float64)


def rotation_from_vector(w: FloatArray) -> FloatArray:
    """Rotation matrix of the rotation vector ``w`` (axis × angle, rad); identity for zero."""
    angle = float(np.linalg.norm(w))
    return rotation_about(w, angle) if angle > 0 else np.eye(3)


def roll_pitch_yaw(R: FloatArray) -> tuple[float, float, float]:
    """Roll, pitch, yaw of the rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (URDF's fixed-axis
    x, y, z; the same as Z-Y-X Euler angles); at pitch ±90° all of the turn is put in yaw."""
    pitch = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    if abs(math.cos(pitch)) > 1e-9:
        roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
        yaw = math.atan2(float(R[1, 0]), float(R[0, 0]))
    else:
        roll, yaw = 0.0, math.atan2(-float(R[0, 1]), float(R[1, 1]))
    return roll, pitch, yaw


def wrap_angle(angle: float) -> float:
    """``angle`` wrapped to (-pi, pi]."""
    wrapped = float(np.arctan2(np.sin(angle), np.cos(angle)))
    return np.pi if wrapped <= -np.pi + 1e-15 else wrapped
