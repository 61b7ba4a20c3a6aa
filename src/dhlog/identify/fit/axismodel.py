"""The whole model the maximum-likelihood fit holds (:mod:`dhlog.identify.fit.whole`), and where
each of its parameters sits.

The model is held in its minimal, gauge-free form: the joint axes at the reference pose as lines
in the measurement frame M (4 numbers per revolute axis, 2 per prismatic direction: only a
prismatic direction is physical), the target point at the reference pose (3), and, as an option,
a scale per encoder. A sample with encoder values ``q`` is predicted by the product of
exponentials about those axes (seed 004, Eq. 5–6; :mod:`dhlog.identify.fit.prediction`):

    p(q) = g_1(s_1 (q_1 − q_ref,1)) ⋯ g_n(s_n (q_n − q_ref,n)) · target

This parametrisation has no conventions to hold and stays well conditioned for parallel and
nearly parallel axes, where DH's ``d`` is not; the DH table is read off the fitted axes by the
line geometry of seed 000 (``extract_dh``), which is exact, so the table reproduces the fitted
model's forward kinematics.

Each axis is moved by a small rigid motion ``h = exp(η)`` (the joint's motion becomes
``h g h⁻¹``): two tilts about the perpendicular unit vectors ``u, v`` through the axis point and
two shifts along them (:meth:`AxisModel.moved`; :class:`ParameterLayout` names them).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from dhlog.geometry._checks import FloatArray, perpendicular_basis, rotation_from_vector
from dhlog.geometry.lines import Line
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.terms import Terms


@dataclass(frozen=True, eq=False)
class AxisModel:
    """The whole model: joint axes and target at the reference pose (M), encoder scales."""

    axes: tuple[Line, ...]
    types: tuple[JointType, ...]
    target: FloatArray
    reference_pose: FloatArray
    scales: FloatArray
    extra_targets: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    tool_rotation: FloatArray | None = None
    #: residual clock offset δ (s): the encoders are read at ``Q − δ q̇`` (see
    #: :mod:`dhlog.identify.segment.timing`); 0 unless the fit carries it
    clock: float = 0.0
    #: joint-value terms beyond the geometry (compliance, harmonics; :mod:`dhlog.model.terms`),
    #: their lumps and gravity in M at the reference pose
    terms: Terms | None = None
    #: joints (0-based) whose axes the fit holds where they are (a joint parked in the session:
    #: its Jacobian columns are zero, so its parameters are undetermined and stay at the start);
    #: their motion is still applied at the encoder values
    held_axes: frozenset[int] = frozenset()

    @classmethod
    def of_table(
        cls,
        table: StandardDH,
        reference_pose: FloatArray,
        tool_point: FloatArray,
        T_base: FloatArray,
        *,
        terms: Terms | None = None,
        tool_rotation: FloatArray | None = None,
    ) -> AxisModel:
        """The model a DH table (placed by ``T_base``) is at ``reference_pose``: its axes, its
        tool point and, with ``terms`` in the table's frames, those terms in M — the table's
        forward kinematics as the whole-model fit holds it (unit encoder scales)."""
        from dhlog.model.fk import fk_frames, fk_point, joint_axes
        from dhlog.model.terms import from_table

        points, dirs = joint_axes(table, reference_pose, T_base=T_base)
        frames = fk_frames(table, reference_pose, T_base=T_base)
        return cls(
            tuple(Line(p, d) for p, d in zip(points, dirs, strict=True)),
            table.joint_types,
            fk_point(table, reference_pose, tool_point, T_base=T_base),
            np.asarray(reference_pose, dtype=np.float64),
            np.ones(table.n),
            tool_rotation=None if tool_rotation is None else frames[-1][:3, :3] @ tool_rotation,
            terms=None if terms is None else from_table(terms, frames),
        )

    def targets(self) -> FloatArray:
        """Every target at the reference pose, (k, 3): the primary one first."""
        return np.vstack([self.target[None], self.extra_targets])

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.types)

    def bases(self) -> list[tuple[FloatArray, FloatArray]]:
        """The perpendicular unit vectors ``(u, v)`` of each axis (right-handed with it)."""
        return [perpendicular_basis(a.direction) for a in self.axes]

    def moved(
        self, delta: FloatArray, layout: ParameterLayout, bases: list[tuple[FloatArray, FloatArray]]
    ) -> AxisModel:
        """The model moved by the local parameter increments ``delta`` (``layout.size``,)."""
        axes = []
        for i, (axis, jt) in enumerate(zip(self.axes, self.types, strict=True)):
            u, v = bases[i]
            k = layout.axis_at[i]
            w = delta[k] * u + delta[k + 1] * v
            shift = np.zeros(3)
            if jt is JointType.REVOLUTE:
                shift = delta[k + 2] * u + delta[k + 3] * v
            axes.append(Line(axis.point + shift, rotation_from_vector(w) @ axis.direction))
        t = layout.target_at
        target = self.target + delta[t : t + 3]
        extra = self.extra_targets + delta[t + 3 : t + 3 + 3 * len(self.extra_targets)].reshape(
            -1, 3
        )
        scales = self.scales.copy()
        if layout.scale_at is not None:
            scales = scales + delta[layout.scale_at : layout.scale_at + self.n]
        rotation = self.tool_rotation
        if layout.rotation_at is not None and rotation is not None:
            w = delta[layout.rotation_at : layout.rotation_at + 3]
            rotation = rotation_from_vector(w) @ rotation
        clock = self.clock + (float(delta[layout.clock_at]) if layout.clock_at is not None else 0.0)
        terms = self.terms
        if layout.terms_at is not None and terms is not None:
            k = layout.terms_at
            terms = terms.with_coefficients(terms.coefficients + delta[k : k + terms.size])
        return AxisModel(
            tuple(axes),
            self.types,
            target,
            self.reference_pose,
            scales,
            extra,
            rotation,
            clock,
            terms,
            self.held_axes,
        )

    def moves(self, Q: FloatArray, rates: FloatArray | None) -> FloatArray:
        """The encoder moves from the reference pose ``(Q − δ q̇) − q_ref`` (m, n), unscaled."""
        if rates is None or self.clock == 0.0:
            return Q - self.reference_pose
        return Q - self.clock * rates - self.reference_pose


@dataclass(frozen=True)
class ParameterLayout:
    """Where each parameter sits in the local parameter vector, and its name."""

    axis_at: tuple[int, ...]
    target_at: int
    scale_at: int | None
    size: int
    names: tuple[str, ...]
    rotation_at: int | None = None
    clock_at: int | None = None
    terms_at: int | None = None

    @classmethod
    def of(
        cls,
        types: Sequence[JointType],
        *,
        fit_scales: bool = False,
        extra_targets: int = 0,
        rotation: bool = False,
        clock: bool = False,
        terms: Sequence[str] = (),
    ) -> ParameterLayout:
        """Revolute axis: tilt u, tilt v, shift u, shift v; prismatic: tilt u, tilt v; then the
        target (x, y, z), each further target (x, y, z), with ``rotation`` the target frame's
        orientation (a rotation in M at the reference pose, 3), with ``fit_scales`` one encoder
        scale per joint, with ``clock`` the residual clock offset (s), then the coefficients of
        the joint-value ``terms`` (their names)."""
        at, names, k = [], [], 0
        for i, jt in enumerate(types):
            at.append(k)
            parts = ["tilt_u", "tilt_v"] + (
                ["shift_u", "shift_v"] if jt is JointType.REVOLUTE else []
            )
            names += [f"axis_{i + 1}_{p}" for p in parts]
            k += len(parts)
        target_at = k
        names += ["target_x", "target_y", "target_z"]
        k += 3
        for j in range(extra_targets):
            names += [f"target_{j + 2}_{c}" for c in "xyz"]
            k += 3
        rotation_at = None
        if rotation:
            rotation_at = k
            names += ["target_rx", "target_ry", "target_rz"]
            k += 3
        scale_at = None
        if fit_scales:
            scale_at = k
            names += [f"encoder_scale_{i + 1}" for i in range(len(types))]
            k += len(types)
        clock_at = None
        if clock:
            clock_at = k
            names.append("clock_offset")
            k += 1
        terms_at = None
        if terms:
            terms_at = k
            names += list(terms)
            k += len(terms)
        return cls(tuple(at), target_at, scale_at, k, tuple(names), rotation_at, clock_at, terms_at)
