"""Denavit–Hartenberg tables in the two conventions, their link transforms and conversions.

Standard (distal; seeds 000, 002, 003): frame i+1 is attached to link i and
``A_i = Rz(θ_i) · Tz(d_i) · Tx(a_i) · Rx(α_i)``. Modified (proximal, Craig; seeds 001, 004):
frame i is attached to link i and ``T_i = Rx(α_{i−1}) · Tx(a_{i−1}) · Rz(θ_i) · Tz(d_i)``.
A revolute joint adds its encoder value to ``θ``, a prismatic one to ``d``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import ShapeError
from dhlog.geometry._checks import FloatArray


class JointType(enum.StrEnum):
    """Kind of a single-degree-of-freedom joint."""

    REVOLUTE = "revolute"
    PRISMATIC = "prismatic"

    @classmethod
    def parse(cls, value: str) -> JointType:
        """Accept ``revolute``/``prismatic`` and the short forms ``r``/``p`` (any case)."""
        text = value.strip().lower()
        if text in ("r", "revolute"):
            return cls.REVOLUTE
        if text in ("p", "prismatic"):
            return cls.PRISMATIC
        raise ShapeError("joint type", "'revolute' or 'prismatic'", repr(value))


def _row_array(name: str, value: ArrayLike, n: int) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ShapeError(name, f"{n} finite values", np.asarray(value).tolist())
    return arr


@dataclass(frozen=True, eq=False)
class _DHTable:
    joint_types: tuple[JointType, ...]
    theta_offset: FloatArray
    d_offset: FloatArray
    a: FloatArray
    alpha: FloatArray

    def __init__(
        self,
        joint_types: tuple[JointType, ...] | list[JointType] | tuple[str, ...] | list[str],
        theta_offset: ArrayLike,
        d_offset: ArrayLike,
        a: ArrayLike,
        alpha: ArrayLike,
    ) -> None:
        types = tuple(JointType.parse(str(t)) for t in joint_types)
        n = len(types)
        if n == 0:
            raise ShapeError("DH table", "at least one row", "none")
        object.__setattr__(self, "joint_types", types)
        object.__setattr__(self, "theta_offset", _row_array("theta_offset", theta_offset, n))
        object.__setattr__(self, "d_offset", _row_array("d_offset", d_offset, n))
        object.__setattr__(self, "a", _row_array("a", a, n))
        object.__setattr__(self, "alpha", _row_array("alpha", alpha, n))

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.joint_types)

    @property
    def revolute(self) -> FloatArray:
        """1.0 for revolute joints, 0.0 for prismatic ones; shape (n,)."""
        return np.array([t is JointType.REVOLUTE for t in self.joint_types], dtype=np.float64)

    def check_q(self, q: ArrayLike) -> FloatArray:
        """``q`` as float64 of shape (..., n), or raise :class:`ShapeError`."""
        arr = np.asarray(q, dtype=np.float64)
        if arr.ndim == 0 or arr.shape[-1] != self.n:
            raise ShapeError("joint vector q", f"of length {self.n}", f"shape {arr.shape}")
        return arr

    def theta(self, q: ArrayLike) -> FloatArray:
        """Joint angles ``θ = θ_offset + q`` for revolute joints (constant otherwise), (..., n)."""
        return self.theta_offset + self.check_q(q) * self.revolute

    def d(self, q: ArrayLike) -> FloatArray:
        """Offsets ``d = d_offset + q`` for prismatic joints (constant otherwise), (..., n)."""
        return self.d_offset + self.check_q(q) * (1.0 - self.revolute)


@dataclass(frozen=True, init=False, eq=False)
class StandardDH(_DHTable):
    """Standard (distal) DH table: row i is ``A_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)`` (seed 000).

    Row i maps frame i+1 (on link i) into frame i. ``theta_offset``/``d_offset`` are the values at
    encoder zero; lengths in metres, angles in radians; all arrays (n,).
    """

    def link_transforms(self, q: ArrayLike) -> FloatArray:
        """``A_1 … A_n`` at the joint vector(s) ``q`` (..., n), shape (..., n, 4, 4)."""
        return standard_dh_transform(self.theta(q), self.d(q), self.a, self.alpha)


@dataclass(frozen=True, init=False, eq=False)
class ModifiedDH(_DHTable):
    """Modified (proximal, Craig) DH table: row i is ``Rx(α_{i−1}) Tx(a_{i−1}) Rz(θ_i) Tz(d_i)``.

    ``alpha[i]`` and ``a[i]`` hold ``α_{i−1}``, ``a_{i−1}`` of row i (seed 001; seed 004, Eq. 1).
    """

    def link_transforms(self, q: ArrayLike) -> FloatArray:
        """``T_1 … T_n`` at the joint vector(s) ``q`` (..., n), shape (..., n, 4, 4)."""
        return modified_dh_transform(self.alpha, self.a, self.theta(q), self.d(q))


@dataclass(frozen=True, init=False, eq=False)
class HayatiDH(StandardDH):
    """Standard DH in which the rows of nearly parallel pairs take the Hayati–Mirmirani form.

    Row i is ``A_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)``, or, where ``hayati[i]``,
    ``Rz(θ_i) Tx(a_i) Rx(α_i) Ry(β_i)`` (Hayati & Mirmirani 1985: no ``d``, which is
    ill-conditioned when axes i and i+1 are nearly parallel; ``d_offset[i]`` is 0 there). Only
    revolute joints carry such a row. ``beta`` (n,) is 0 on the DH rows.
    """

    beta: FloatArray
    hayati: tuple[bool, ...]

    def __init__(
        self,
        joint_types: tuple[JointType, ...] | list[JointType] | tuple[str, ...] | list[str],
        theta_offset: ArrayLike,
        d_offset: ArrayLike,
        a: ArrayLike,
        alpha: ArrayLike,
        beta: ArrayLike,
        hayati: tuple[bool, ...] | list[bool],
    ) -> None:
        super().__init__(joint_types, theta_offset, d_offset, a, alpha)
        flags = tuple(bool(h) for h in hayati)
        if len(flags) != self.n:
            raise ShapeError("hayati", f"{self.n} flags", str(len(flags)))
        types = self.joint_types
        if any(h and t is JointType.PRISMATIC for h, t in zip(flags, types, strict=True)):
            raise ShapeError("hayati", "rows of revolute joints only", "a prismatic row")
        object.__setattr__(self, "beta", _row_array("beta", beta, self.n))
        object.__setattr__(self, "hayati", flags)
        object.__setattr__(self, "d_offset", np.where(flags, 0.0, self.d_offset))

    def link_transforms(self, q: ArrayLike) -> FloatArray:
        """The rows' transforms at the joint vector(s) ``q`` (..., n), shape (..., n, 4, 4)."""
        T = standard_dh_transform(self.theta(q), self.d(q), self.a, self.alpha)
        rows = [i for i, h in enumerate(self.hayati) if h]
        if rows:
            cb, sb = np.cos(self.beta[rows]), np.sin(self.beta[rows])
            Ry = np.zeros((len(rows), 4, 4))
            Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1] = cb, sb, 1.0
            Ry[:, 2, 0], Ry[:, 2, 2], Ry[:, 3, 3] = -sb, cb, 1.0
            T[..., rows, :, :] = T[..., rows, :, :] @ Ry
        return T


def _stack_transform(R: FloatArray, p: FloatArray) -> FloatArray:
    shape = R.shape[:-2]
    T = np.zeros((*shape, 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def standard_dh_transform(
    theta: ArrayLike, d: ArrayLike, a: ArrayLike, alpha: ArrayLike
) -> FloatArray:
    """``Rz(θ) Tz(d) Tx(a) Rx(α)`` for broadcast arrays of parameters, shape (..., 4, 4)."""
    th, dd, aa, al = np.broadcast_arrays(
        *(np.asarray(x, dtype=np.float64) for x in (theta, d, a, alpha))
    )
    ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
    R = np.stack(
        [
            np.stack([ct, -st * ca, st * sa], axis=-1),
            np.stack([st, ct * ca, -ct * sa], axis=-1),
            np.stack([np.zeros_like(ct), sa, ca], axis=-1),
        ],
        axis=-2,
    )
    p = np.stack([aa * ct, aa * st, dd], axis=-1)
    return _stack_transform(R, p)


def modified_dh_transform(
    alpha: ArrayLike, a: ArrayLike, theta: ArrayLike, d: ArrayLike
) -> FloatArray:
    """``Rx(α) Tx(a) Rz(θ) Tz(d)`` (seed 004, Eq. 1), shape (..., 4, 4)."""
    al, aa, th, dd = np.broadcast_arrays(
        *(np.asarray(x, dtype=np.float64) for x in (alpha, a, theta, d))
    )
    ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
    R = np.stack(
        [
            np.stack([ct, -st, np.zeros_like(ct)], axis=-1),
            np.stack([st * ca, ct * ca, -sa], axis=-1),
            np.stack([st * sa, ct * sa, ca], axis=-1),
        ],
        axis=-2,
    )
    p = np.stack([aa, -sa * dd, ca * dd], axis=-1)
    return _stack_transform(R, p)


def standard_to_modified(table: StandardDH) -> tuple[ModifiedDH, FloatArray]:
    """The modified table of the same chain and the fixed transform it leaves at the tool end.

    ``∏ A_i = ∏ T_i · Tx(a_n) Rx(α_n)``, with modified row i holding
    ``(α_{i−1}, a_{i−1}, θ_i, d_i)``
    of the standard table and ``α_0 = a_0 = 0``. Returns ``(modified, T_n_tool)``, (4, 4).
    """
    modified = ModifiedDH(
        table.joint_types,
        table.theta_offset,
        table.d_offset,
        np.r_[0.0, table.a[:-1]],
        np.r_[0.0, table.alpha[:-1]],
    )
    T_post = standard_dh_transform(0.0, 0.0, table.a[-1], table.alpha[-1])
    return modified, T_post


def modified_to_standard(table: ModifiedDH) -> tuple[FloatArray, StandardDH]:
    """The standard table of the same chain and the fixed transform it needs at the base end.

    ``∏ T_i = Rx(α_0) Tx(a_0) · ∏ A_i`` with standard row i holding ``(θ_i, d_i, a_i, α_i)`` of the
    modified rows i and i+1 (``a_n = α_n = 0``). Returns ``(T_base_frame1, standard)``.
    """
    standard = StandardDH(
        table.joint_types,
        table.theta_offset,
        table.d_offset,
        np.r_[table.a[1:], 0.0],
        np.r_[table.alpha[1:], 0.0],
    )
    T_pre = modified_dh_transform(table.alpha[0], table.a[0], 0.0, 0.0)
    return T_pre, standard
