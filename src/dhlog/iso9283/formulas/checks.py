"""The input checks every ISO 9283 formula shares: finite values, point arrays (n, 3), vectors (3,),
rotation matrices checked for orthonormality within :data:`_ROTATION_TOL`, the sample standard
deviation (divisor n − 1) and arrays as lists for a report.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import Iso9283Error, NonFiniteError, ShapeError
from dhlog.geometry._checks import FloatArray

#: tolerance of the orthonormality check of given rotation matrices
_ROTATION_TOL = 1e-6


def _finite(what: str, arr: FloatArray) -> FloatArray:
    bad = int(np.count_nonzero(~np.isfinite(arr)))
    if bad:
        raise NonFiniteError(what, bad)
    return arr


def _points(what: str, value: ArrayLike, *, at_least: int, unit: str = "cycles") -> FloatArray:
    """``value`` as a finite (n, 3) float64 array with n ≥ ``at_least``."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ShapeError(what, "an (n, 3) array of positions (m)", f"shape {arr.shape}")
    if arr.shape[0] < at_least:
        raise Iso9283Error(
            what,
            f"{arr.shape[0]} {unit} given, at least {at_least} are needed",
            f"measure at least {at_least} {unit} (the standard prescribes 30 for poses, 10 for "
            "paths)",
        )
    return _finite(what, arr)


def _vector(what: str, value: ArrayLike) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ShapeError(what, "a 3-vector (m)", f"shape {arr.shape}")
    return _finite(what, arr)


def _rotations(what: str, value: ArrayLike, n: int | None = None) -> FloatArray:
    """``value`` as finite rotation matrices (…, 3, 3) (n of them when ``n`` is given)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
        raise ShapeError(what, "rotation matrices (..., 3, 3)", f"shape {arr.shape}")
    if n is not None and arr.shape != (n, 3, 3):
        raise ShapeError(what, f"one rotation per position, ({n}, 3, 3)", f"shape {arr.shape}")
    _finite(what, arr)
    gram = np.einsum("...ji,...jk->...ik", arr, arr)
    if not np.allclose(gram, np.eye(3), atol=_ROTATION_TOL) or np.any(np.linalg.det(arr) < 0.0):
        raise ShapeError(what, "proper rotation matrices (orthonormal, det +1)", "other")
    return arr


def _sample_std(x: FloatArray) -> FloatArray:
    """The sample standard deviation along axis 0 (divisor n − 1), as ISO 9283 writes S."""
    return np.asarray(np.std(x, axis=0, ddof=1), dtype=np.float64)


def _floats(x: FloatArray | None) -> list[Any] | None:
    return None if x is None else np.asarray(x, dtype=np.float64).tolist()
