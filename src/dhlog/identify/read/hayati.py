"""DH tables read off a chain of frames, with the rows of nearly parallel pairs in the
Hayati–Mirmirani form.

A standard row is read off consecutive frames (seed 000, Eq. 21–24). Where two consecutive axes
are nearly parallel (below :data:`NEAR_PARALLEL`) the DH common normal, and so ``d``, follows the
tilt's noise; such a row takes the Hayati–Mirmirani form ``Rz(θ) Tx(a) Rx(α) Ry(β)`` (no ``d``:
the origin is where the next axis crosses the plane normal to ``z_i`` through the current origin)
and the row after it is read from that frame, so the table (a :class:`HayatiDH`) keeps the forward
kinematics. The extraction (:mod:`dhlog.identify.read.extract`) reads its table here;
:func:`~dhlog.identify.read.extract.hayati_table` puts an extraction in this form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, cross3, wrap_angle
from dhlog.geometry.lines import Line
from dhlog.model.dh import HayatiDH, JointType, StandardDH, standard_dh_transform

#: Axes closer than this to parallel (rad) have an ill-conditioned common normal: its direction
#: and feet follow the tilt's noise. Conventions never lean on it (frame 1, prismatic placement),
#: and such pairs also get the Hayati–Mirmirani form
#: (:func:`~dhlog.identify.read.extract.hayati_table`).
NEAR_PARALLEL = 0.01

#: A reference row's ``a`` (m) at or below this has no sign to follow: the Hayati branch then
#: follows its θ.
ZERO_LENGTH = 1e-9


def _near(value: float, reference: float | None) -> float:
    """``value`` wrapped to (−π, π], or to within π of ``reference`` when one is given."""
    if reference is None:
        return wrap_angle(value)
    return float(reference + wrap_angle(value - reference))


def _row_between(F: FloatArray, G: FloatArray) -> tuple[float, float, float, float]:
    """θ, d, a, α of the DH row from frame ``F`` to frame ``G`` (seed 000, Eq. 21–24): ``G``'s
    x axis meets ``F``'s z axis at a right angle."""
    o_i, x_i, z_i = F[:3, 3], F[:3, 0], F[:3, 2]
    o_n, x_n, z_n = G[:3, 3], G[:3, 0], G[:3, 2]
    d = float((o_n - o_i) @ z_i)  # Eq. 21
    theta = float(np.arctan2(cross3(x_i, x_n) @ z_i, x_i @ x_n))  # Eq. 22
    a = float((o_n - o_i) @ x_n)  # Eq. 23
    alpha = float(np.arctan2(cross3(z_i, z_n) @ x_n, z_i @ z_n))  # Eq. 24
    return theta, d, a, alpha


def table_from_frames(
    frames: FloatArray,
    types: tuple[JointType, ...],
    q_ref: FloatArray,
    nominal: StandardDH | None,
    hayati: frozenset[int] = frozenset(),
) -> StandardDH:
    """Seed 000, Eq. 21–24, from consecutive frames; offsets from the reference pose. With
    ``hayati`` (0-based rows), those rows take the Hayati–Mirmirani form toward the next axis
    (:func:`hayati_parameters`) and the row after each is read from the Hayati frame, so the
    :class:`HayatiDH` table has the same forward kinematics as the standard one. With a
    ``nominal``, each Hayati row takes the nominal row's branch (:func:`hayati_parameters`), each
    θ offset and α is within π of the nominal's."""
    n = len(types)
    theta_off, d_off, a, alpha, beta = (np.zeros(n) for _ in range(5))
    F = frames[0]
    for i in range(n):
        if i in hayati:
            G = frames[i + 1]
            h = hayati_parameters(
                F, Line(G[:3, 3], G[:3, 2]), (i + 1, i + 2), row_reference(nominal, i, q_ref)
            )
            theta_i, d_i, a[i], alpha_i, beta[i] = h.theta, 0.0, h.a, h.alpha, h.beta
            F = F @ hayati_transform(h.theta, h.a, h.alpha, h.beta)
        else:
            theta_i, d_i, a[i], alpha_i = _row_between(F, frames[i + 1])
            F = frames[i + 1]
        revolute = types[i] is JointType.REVOLUTE
        theta_off[i] = _near(
            theta_i - (q_ref[i] if revolute else 0.0),
            None if nominal is None else float(nominal.theta_offset[i]),
        )
        d_off[i] = d_i - (0.0 if revolute else q_ref[i])
        alpha[i] = _near(alpha_i, None if nominal is None else float(nominal.alpha[i]))
    if not np.all(np.isfinite(np.concatenate([theta_off, d_off, a, alpha, beta]))):
        raise DegenerateGeometryError("The joint axes give a non-finite DH table; check the fits.")
    if hayati:
        return HayatiDH(types, theta_off, d_off, a, alpha, beta, [i in hayati for i in range(n)])
    return StandardDH(types, theta_off, d_off, a, alpha)


def table_in_hayati_form(table: StandardDH, q_ref: FloatArray, rows: frozenset[int]) -> StandardDH:
    """A standard table (a nominal) with ``rows`` in the Hayati–Mirmirani form, same forward
    kinematics, θ kept on the table's own branch."""
    from dhlog.model.fk import fk_frames

    frames = fk_frames(table, q_ref)
    return table_from_frames(frames, table.joint_types, q_ref, table, rows)


def hayati_transform(theta: float, a: float, alpha: float, beta: float) -> FloatArray:
    """``Rz(θ) Tx(a) Rx(α) Ry(β)`` (4×4)."""
    cb, sb = math.cos(beta), math.sin(beta)
    Ry = np.array([[cb, 0.0, sb, 0.0], [0.0, 1.0, 0.0, 0.0], [-sb, 0.0, cb, 0.0], [0, 0, 0, 1.0]])
    return np.asarray(standard_dh_transform(theta, 0.0, a, alpha) @ Ry, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class HayatiRow:
    """Hayati–Mirmirani parameters of a nearly parallel pair: ``Rz(θ) Tx(a) Rx(α) Ry(β)``
    from frame i to the frame on axis i+1 (no ``d``: the common normal runs through ``o_i``)."""

    joints: tuple[int, int]
    theta: float
    a: float
    alpha: float
    beta: float


def row_reference(
    table: StandardDH | None, i: int, q_ref: FloatArray
) -> tuple[float, float] | None:
    """``(a, θ)`` of row ``i`` (0-based) of ``table`` at the joint values ``q_ref`` (θ offset plus
    the joint value for a revolute joint): the branch :func:`hayati_parameters` follows; None
    without a table."""
    if table is None or i >= table.n:
        return None
    revolute = table.joint_types[i] is JointType.REVOLUTE
    theta = float(table.theta_offset[i]) + (float(q_ref[i]) if revolute else 0.0)
    return float(table.a[i]), theta


def hayati_parameters(
    frame_i: FloatArray,
    line_next: Line,
    joints: tuple[int, int],
    reference: tuple[float, float] | None = None,
) -> HayatiRow:
    """The Hayati–Mirmirani parameters of axis i+1 seen from DH frame i (4x4 in M).

    ``x'`` runs from ``o_i`` to where axis i+1 crosses the plane ``z_i``-normal through ``o_i``
    (angle θ about ``z_i``, length a); then ``z_{i+1} = Rx(α) Ry(β) z_i`` in the frame
    ``(x', z_i × x', z_i)``: ``β = asin(z·x')``, ``α = atan2(−z·y', z·z_i)``. Well conditioned
    when the axes are (nearly) parallel, where the DH ``d`` is not.

    ``x'`` reversed describes the same line: ``(θ + π, −a, −α, −β)``, the frame turned by π about
    ``z_{i+1}``. Without ``reference`` ``a ≥ 0``; with one, ``(a, θ)`` of the nominal's row
    (:func:`row_reference`), the branch whose ``a`` has the reference's sign, or, where the
    reference's ``a`` is zero (:data:`ZERO_LENGTH`), whose θ is nearer the reference's.
    """
    o, x, z = frame_i[:3, 3], frame_i[:3, 0], frame_i[:3, 2]
    e = line_next.direction
    denom = float(e @ z)
    if abs(denom) < 1e-9:
        raise DegenerateGeometryError(
            f"Axes {joints[0]} and {joints[1]} are perpendicular: Hayati parameters are undefined."
        )
    t = float((o - line_next.point) @ z) / denom
    crossing = line_next.point + t * e
    offset = crossing - o
    a = float(np.linalg.norm(offset))
    xp = offset / a if a > 1e-12 else x
    yp = cross3(z, xp)
    theta = float(np.arctan2(cross3(x, xp) @ z, x @ xp))
    beta = float(np.arcsin(np.clip(e @ xp, -1.0, 1.0)))
    alpha = float(np.arctan2(-(e @ yp), e @ z))
    if reference is not None:
        a_ref, theta_ref = reference
        if abs(a_ref) > ZERO_LENGTH:
            flip = a_ref < 0.0
        else:
            flip = abs(wrap_angle(theta + math.pi - theta_ref)) < abs(wrap_angle(theta - theta_ref))
        if flip:
            theta, a, alpha, beta = wrap_angle(theta + math.pi), -a, -alpha, -beta
    return HayatiRow(joints, theta, a, alpha, beta)
