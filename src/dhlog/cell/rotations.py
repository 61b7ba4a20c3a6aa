"""Orientations as robot programs and controllers write them, named explicitly.

A convention is one of:

- ``quaternion``: ``qw, qx, qy, qz``, the scalar first (ABB's ``orient``, RAPID robtargets);
- ``rotvec``: the rotation vector (axis × angle) ``rx, ry, rz`` in rad, as URScript's
  ``p[x, y, z, rx, ry, rz]`` and the UR pendant show a pose;
- ``extrinsic-ABC`` / ``intrinsic-ABC`` for any Euler sequence scipy accepts (``xyz``, ``zyx``,
  ``zyz``, …): three angles applied in the sequence's order about the fixed (extrinsic) or the
  moving (intrinsic) axes. KUKA's A, B, C are ``intrinsic-zyx`` (A about z, then B about the
  new y, then C about the newest x), in degrees; Fanuc's W, P, R are ``extrinsic-xyz``.

Every conversion is :class:`scipy.spatial.transform.Rotation`'s: nothing is hand-written here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dhlog.errors import UsageError
from dhlog.geometry._checks import FloatArray

#: The conventions that are not Euler sequences.
PLAIN = ("quaternion", "rotvec")


def check_convention(name: str) -> str:
    """``name`` when it is a convention this module reads (see the module docstring); else a
    :class:`~dhlog.errors.UsageError` naming the accepted ones."""
    if name in PLAIN:
        return name
    kind, _, axes = name.partition("-")
    ok = (
        kind in ("extrinsic", "intrinsic")
        and len(axes) == 3
        and set(axes) <= {"x", "y", "z"}
        and axes[0] != axes[1]
        and axes[1] != axes[2]
    )
    if not ok:
        shown = name if len(name) <= 30 else name[:29] + "…"
        raise UsageError(
            f"--rotation '{shown}' is not a rotation convention; give quaternion (qw first), "
            "rotvec (rad, as URScript), or extrinsic-SEQ / intrinsic-SEQ with SEQ an Euler "
            "sequence such as xyz, zyx, zyz (KUKA A, B, C: intrinsic-zyx)."
        )
    return name


def width(convention: str) -> int:
    """How many numbers the orientation takes (4 for a quaternion, else 3)."""
    return 4 if convention == "quaternion" else 3


def _sequence(convention: str) -> Any:
    """scipy's Euler sequence: lower case for extrinsic axes, upper case for intrinsic ones."""
    kind, _, axes = convention.partition("-")
    return axes if kind == "extrinsic" else axes.upper()


def matrices(values: FloatArray, convention: str, *, degrees: bool) -> FloatArray:
    """Rotation matrices (m, 3, 3) from orientations (m, 3 or 4) in ``convention``;
    ``degrees``: angles (Euler, rotation vector) in degrees, else rad. A quaternion is
    normalised (callers check its norm first)."""
    from scipy.spatial.transform import Rotation

    v = np.asarray(values, dtype=np.float64)
    if convention == "quaternion":
        R = Rotation.from_quat(v, scalar_first=True)
    elif convention == "rotvec":
        R = Rotation.from_rotvec(v, degrees=degrees)
    else:
        R = Rotation.from_euler(_sequence(convention), v, degrees=degrees)
    return np.asarray(R.as_matrix(), dtype=np.float64).reshape(-1, 3, 3)


def values(R: FloatArray, convention: str, *, degrees: bool) -> FloatArray:
    """Orientations (m, 3 or 4) in ``convention`` of rotation matrices (m, 3, 3): a quaternion
    with qw ≥ 0, a rotation vector of angle ≤ π, Euler angles in scipy's ranges."""
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_matrix(np.asarray(R, dtype=np.float64).reshape(-1, 3, 3))
    if convention == "quaternion":
        q = rot.as_quat(canonical=True, scalar_first=True)
        return np.asarray(q, dtype=np.float64)
    if convention == "rotvec":
        return np.asarray(rot.as_rotvec(degrees=degrees), dtype=np.float64)
    return np.asarray(rot.as_euler(_sequence(convention), degrees=degrees), dtype=np.float64)


def near(
    values_new: FloatArray, values_old: FloatArray, convention: str, *, degrees: bool
) -> FloatArray:
    """``values_new`` (m, k) made the representation nearest ``values_old`` of the same
    rotations where the convention has several: a quaternion's sign, a rotation vector of angle
    near π turned the other way round (θ − 2π about the same axis), Euler angles a whole turn
    apart. A program's numbers then change by the correction only."""
    new = np.array(values_new, dtype=np.float64)
    old = np.asarray(values_old, dtype=np.float64)
    turn = 360.0 if degrees else 2 * np.pi
    if convention not in PLAIN:
        return np.asarray(new + turn * np.round((old - new) / turn), dtype=np.float64)
    if convention == "quaternion":
        flip = np.sum(new * old, axis=1) < 0
        new[flip] *= -1.0
    elif convention == "rotvec":
        angle = np.linalg.norm(new, axis=1)
        safe = np.where(angle > 0, angle, 1.0)
        other = new * ((angle - turn) / safe)[:, None]
        swap = (angle > 0) & (
            np.linalg.norm(other - old, axis=1) < np.linalg.norm(new - old, axis=1)
        )
        new[swap] = other[swap]
    return new
