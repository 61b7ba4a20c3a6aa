"""Shape and finiteness validators for plain arrays (the ``check_*`` family)."""

from __future__ import annotations

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


def wrap_angle(angle: float) -> float:
    """``angle`` wrapped to (-pi, pi]."""
    wrapped = float(np.arctan2(np.sin(angle), np.cos(angle)))
    return np.pi if wrapped <= -np.pi + 1e-15 else wrapped


def matrices_from_quaternions(q: FloatArray) -> FloatArray:
    """Rotation matrices (m, 3, 3) of unit quaternions ``x, y, z, w`` (m, 4) (ROS order)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )


def quaternions_from_matrices(R: FloatArray) -> FloatArray:
    """Unit quaternions ``x, y, z, w`` (m, 4) of rotation matrices (m, 3, 3), ``w ≥ 0``."""
    m = R.shape[0]
    out = np.empty((m, 4))
    tr = np.trace(R, axis1=1, axis2=2)
    for k in range(m):  # Shepperd: the largest of w, x, y, z first
        r = R[k]
        cand = np.array([tr[k], r[0, 0], r[1, 1], r[2, 2]])
        i = int(np.argmax(cand))
        if i == 0:
            w = np.sqrt(1 + tr[k]) / 2
            q = [
                (r[2, 1] - r[1, 2]) / (4 * w),
                (r[0, 2] - r[2, 0]) / (4 * w),
                (r[1, 0] - r[0, 1]) / (4 * w),
                w,
            ]
        elif i == 1:
            x = np.sqrt(1 + 2 * r[0, 0] - tr[k]) / 2
            q = [
                x,
                (r[0, 1] + r[1, 0]) / (4 * x),
                (r[0, 2] + r[2, 0]) / (4 * x),
                (r[2, 1] - r[1, 2]) / (4 * x),
            ]
        elif i == 2:
            y = np.sqrt(1 + 2 * r[1, 1] - tr[k]) / 2
            q = [
                (r[0, 1] + r[1, 0]) / (4 * y),
                y,
                (r[1, 2] + r[2, 1]) / (4 * y),
                (r[0, 2] - r[2, 0]) / (4 * y),
            ]
        else:
            z = np.sqrt(1 + 2 * r[2, 2] - tr[k]) / 2
            q = [
                (r[0, 2] + r[2, 0]) / (4 * z),
                (r[1, 2] + r[2, 1]) / (4 * z),
                z,
                (r[1, 0] - r[0, 1]) / (4 * z),
            ]
        qa = np.asarray(q)
        out[k] = qa if qa[3] >= 0 else -qa
    return out
