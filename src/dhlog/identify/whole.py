"""Maximum-likelihood fit of the whole kinematic model to every sample.

The model is held in its minimal, gauge-free form: the joint axes at the reference pose as lines
in the measurement frame M (4 numbers per revolute axis, 2 per prismatic direction: only a
prismatic direction is physical), the target point at the reference pose (3), and, as an option,
a scale per encoder. A sample with encoder values ``q`` is predicted by the product of
exponentials about those axes (seed 004, Eq. 5–6):

    p(q) = g_1(s_1 (q_1 − q_ref,1)) ⋯ g_n(s_n (q_n − q_ref,n)) · target

This parametrisation has no conventions to hold and stays well conditioned for parallel and
nearly parallel axes, where DH's ``d`` is not; the DH table is read off the fitted axes by the
line geometry of seed 000 (``extract_dh``), which is exact, so the table reproduces the fitted
model's forward kinematics.

Each axis is moved by a small rigid motion ``h = exp(η)`` (the joint's motion becomes
``h g h⁻¹``): two tilts about the perpendicular unit vectors ``u, v`` through the axis point and
two shifts along them. The Jacobian is analytic (:func:`predict_columns`): with ``R_<i`` the
rotation of joints 1 … i−1 and ``D_i`` the target relative to axis i's point as it sits at the
sample, a tilt ``w`` of axis i moves the target by ``b × D_i`` and a shift ``w`` by ``b``, where
``b = R_<i (I − R_i) w``. The normal equations ``JᵀWJ δ = −JᵀWr`` are accumulated over chunks of
samples (no per-parameter pass over the data, bounded memory) and solved by Levenberg–Marquardt.
Gross outliers are held out by a truncated quadratic at ``threshold`` times the noise scale. The
covariance of the parameters is ``(JᵀWJ)⁻¹ · χ²/dof``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, perpendicular_basis, rotation_from_vector
from dhlog.geometry.lines import Line
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.noise import NoiseModel
from dhlog.model.terms import Terms

#: Samples per chunk of the normal-equation accumulation.
CHUNK = 16384
#: Median of a 3-dof chi variable (|r|/σ of an isotropic 3-D residual).
CHI3_MEDIAN = 1.5382
#: Expected decrease of the weighted cost below which the fit has converged (a step of about
#: 1 % of σ in every parameter).
CONVERGED = 1e-3


#: Orientation residuals (in their own σ) beyond this are outliers, whatever the positions' limit.
ROTATION_LIMIT = 5.0
#: A direction of the column-scaled normal matrix ``JᵀWJ`` whose eigenvalue is below this
#: fraction of the largest (a singular value of the scaled Jacobian below 10⁻⁶ of the largest)
#: is not determined by the samples: held at the start (the nominal) and reported.
UNDETERMINED = 1e-12


@dataclass(frozen=True)
class Determined:
    """What the samples determine of the model (as in base-parameter identification: the
    eigen-decomposition of the column-scaled ``JᵀWJ``, i.e. the SVD of the scaled Jacobian).

    ``scale`` (size,): the column scales (√ of the diagonal); ``basis`` (size, r): the
    determined directions in scaled coordinates (orthonormal); ``values`` (r,) their
    eigenvalues; ``null`` (size, k): the undetermined directions (scaled, orthonormal);
    ``condition``: √(largest / smallest determined eigenvalue), the scaled Jacobian's
    condition number; ``weakest`` (size,): the least determined of the determined directions."""

    scale: FloatArray
    basis: FloatArray
    values: FloatArray
    null: FloatArray
    condition: float
    weakest: FloatArray

    @classmethod
    def of(cls, H: FloatArray) -> Determined:
        diag = np.diag(H)
        scale = np.where(diag > 0, np.sqrt(np.abs(diag)), 1.0)
        Hs = H / np.outer(scale, scale)
        lam, V = np.linalg.eigh((Hs + Hs.T) / 2)
        top = max(float(lam[-1]), 1e-300)
        keep = lam > UNDETERMINED * top
        kept = lam[keep]
        return cls(
            scale,
            V[:, keep],
            kept,
            V[:, ~keep],
            float(np.sqrt(top / kept[0])) if kept.size else math.inf,
            V[:, keep][:, 0] if kept.size else V[:, 0],
        )

    def weakest_terms(self, names: Sequence[str], count: int = 4) -> list[tuple[str, float]]:
        """The weakest determined direction's largest components (name, coefficient), in the
        scaled parameters (unit length), largest first."""
        w = self.weakest / np.linalg.norm(self.weakest)
        order = np.argsort(-np.abs(w))[:count]
        return [(names[int(k)], float(w[k])) for k in order if abs(w[k]) >= 0.05]

    def document(self, names: Sequence[str]) -> dict[str, object]:
        """For the result JSON: the parameter counts, the condition number and the weakest
        direction (the fit's own parameters: axis tilts and shifts, target, …)."""
        return {
            "parameters": int(self.scale.size),
            "determined": int(self.basis.shape[1]),
            "condition_number": self.condition,
            "weakest_direction": {k: v for k, v in self.weakest_terms(names, 6)},
            "undetermined_directions": [
                {names[int(k)]: float(c) for k, c in enumerate(col) if abs(c) >= 0.05}
                for col in self.null.T
            ],
        }

    def solve(self, H: FloatArray, g: FloatArray, damping: float = 0.0) -> FloatArray:
        """The step ``δ`` minimising ``½ δᵀ(H + damping·diag H)δ + gᵀδ`` within the determined
        directions (none along the undetermined ones)."""
        B = self.basis / self.scale[:, None]  # back to parameter units
        A = B.T @ H @ B
        A = A + damping * np.diag(np.maximum(np.diag(A), 1e-30))
        return np.asarray(B @ np.linalg.solve(A, -(B.T @ g)), dtype=np.float64)

    def inverse(self, H: FloatArray) -> FloatArray:
        """``H``'s inverse within the determined directions (zero along the others)."""
        B = self.basis / self.scale[:, None]
        return np.asarray(B @ np.linalg.solve(B.T @ H @ B, B.T), dtype=np.float64)


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
    #: :mod:`dhlog.identify.timing`); 0 unless the fit carries it
    clock: float = 0.0
    #: joint-value terms beyond the geometry (compliance, harmonics; :mod:`dhlog.model.terms`),
    #: their lumps and gravity in M at the reference pose
    terms: Terms | None = None

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


def _rotate(R: FloatArray, X: FloatArray) -> FloatArray:
    """``R X`` for per-sample rotations ``R`` (3, 3, m) and vectors ``X`` (3, m) or blocks
    (3, k, m)."""
    if X.ndim == 2:
        return np.stack([R[a, 0] * X[0] + R[a, 1] * X[1] + R[a, 2] * X[2] for a in range(3)])
    return np.stack(
        [R[a, 0][None] * X[0] + R[a, 1][None] * X[1] + R[a, 2][None] * X[2] for a in range(3)]
    )


Prefix = tuple[
    FloatArray,
    list[FloatArray | None],
    list[FloatArray],
    list[FloatArray | None],
    list[FloatArray | None],
    FloatArray | None,
]


def _prefix_motions(model: AxisModel, Q: FloatArray, rates: FloatArray | None = None) -> Prefix:
    """The joint moves ``dq`` (n, m) and the prefix motions ``g_<i`` for i = 1 … n+1:
    rotation rows (3, 3, m) (None for the identity) and translations (3, m), with each revolute
    joint's ``sin δ`` and ``1 − cos δ``; ``rates`` (m, n) the joints' speeds (clock offset); and
    the joint-value terms' functions (k, m) (None without terms). ``dq`` is the scaled encoder
    move plus the terms' deflection, whose functions (gravity torques) are taken at the pose the
    encoders give."""
    dq = (model.moves(Q, rates) * model.scales).T
    if model.terms is None or not model.terms.size:
        return (dq, *_chain(model, dq), None)
    pre_R, pre_t, _, _ = _chain(model, dq)
    m = Q.shape[0]
    points, dirs = [], []
    for i, axis in enumerate(model.axes):
        R0, t0 = pre_R[i], pre_t[i]
        points.append(
            np.broadcast_to(axis.point[:, None], (3, m))
            if R0 is None
            else _rotate(R0, _col(axis.point, m)) + t0
        )
        dirs.append(
            np.broadcast_to(axis.direction[:, None], (3, m))
            if R0 is None
            else _rotate(R0, _col(axis.direction, m))
        )
    lumps = []
    for lump in model.terms.lumps:
        k = model.n if lump.target else lump.axis
        R0, t0 = pre_R[k], pre_t[k]
        lumps.append(
            np.broadcast_to(lump.point[:, None], (3, m))
            if R0 is None
            else _rotate(R0, _col(lump.point, m)) + t0
        )
    B = model.terms.basis(Q, points, dirs, lumps)
    dq = dq + model.terms.deflection(B, model.n)
    return (dq, *_chain(model, dq), B)


def _chain(
    model: AxisModel, dq: FloatArray
) -> tuple[
    list[FloatArray | None], list[FloatArray], list[FloatArray | None], list[FloatArray | None]
]:
    """The prefix motions of the joint moves ``dq`` (n, m) (see :func:`_prefix_motions`)."""
    # prefix motions g_<i (rotation rows (3, 3, m) or None for the identity; translation (3, m))
    pre_R: list[FloatArray | None] = [None]
    pre_t: list[FloatArray] = [np.zeros((3, 1))]
    sins: list[FloatArray | None] = []
    coss: list[FloatArray | None] = []
    for i, (axis, jt) in enumerate(zip(model.axes, model.types, strict=True)):
        R0, t0 = pre_R[-1], pre_t[-1]
        if jt is JointType.PRISMATIC:
            step = axis.direction[:, None] * dq[i]
            sins.append(None)
            coss.append(None)
            pre_R.append(R0)
            pre_t.append(t0 + (step if R0 is None else _rotate(R0, step)))
            continue
        K = _skew(axis.direction)
        K2 = K @ K
        s, c1 = np.sin(dq[i]), 1.0 - np.cos(dq[i])
        sins.append(s)
        coss.append(c1)
        Ri = K[:, :, None] * s + K2[:, :, None] * c1
        Ri[0, 0] += 1.0
        Ri[1, 1] += 1.0
        Ri[2, 2] += 1.0
        ti = -((K @ axis.point)[:, None] * s + (K2 @ axis.point)[:, None] * c1)
        if R0 is None:
            pre_R.append(Ri)
            pre_t.append(t0 + ti)
        else:
            pre_R.append(_compose(R0, Ri))
            pre_t.append(t0 + _rotate(R0, ti))
    return pre_R, pre_t, sins, coss


def _tilt_move(
    axis: Line, w: FloatArray, s: FloatArray, c1: FloatArray, R0: FloatArray | None
) -> FloatArray:
    """``b = R_<i (I − R_i) w`` (3, m) for a revolute joint turned by δ (``s = sin δ``,
    ``c1 = 1 − cos δ``): ``(I − R_i) w = −(sin δ K w + (1 − cos δ) K² w)``, ``K = [ω]×``."""
    K = _skew(axis.direction)
    a = -((K @ w)[:, None] * s + (K @ (K @ w))[:, None] * c1)
    return a if R0 is None else _rotate(R0, a)


def predict_orientation(
    model: AxisModel,
    Q: FloatArray,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    prefix: Prefix | None = None,
    rates: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The target frame's predicted orientation (3, 3, m) and the Jacobian (``layout.size``,
    3, m) of a small rotation of it, in M, with respect to the local parameters: a tilt of a
    revolute axis rotates it by ``b = R_<i (I − R_i) w`` (as in :func:`predict_columns`), a shift
    or a prismatic joint not at all, the target frame's own rotation by ``R_all δ``. ``prefix``:
    the prefix motions at ``Q`` when already computed."""
    assert model.tool_rotation is not None and layout.rotation_at is not None
    m = Q.shape[0]
    _, pre_R, _, sins, coss, B = _prefix_motions(model, Q, rates) if prefix is None else prefix
    R_all = pre_R[-1]
    eye = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, m))
    R_tool = np.broadcast_to(model.tool_rotation[:, :, None], (3, 3, m))
    R_pred = np.ascontiguousarray(R_tool if R_all is None else _compose(R_all, R_tool))
    J = np.zeros((layout.size, 3, m))
    moved = model.moves(Q, rates)
    for i, (axis, jt) in enumerate(zip(model.axes, model.types, strict=True)):
        if jt is JointType.PRISMATIC:
            continue
        u, v = bases[i]
        R0 = pre_R[i]
        s, c1 = sins[i], coss[i]
        assert s is not None and c1 is not None
        k = layout.axis_at[i]
        for col, w in enumerate((u, v)):
            J[k + col] = _tilt_move(axis, w, s, c1, R0)
        if layout.scale_at is not None or layout.clock_at is not None or B is not None:
            omega = axis.direction[:, None] if R0 is None else _rotate(R0, _col(axis.direction, m))
            if layout.scale_at is not None:
                J[layout.scale_at + i] = omega * moved[:, i]
            if layout.clock_at is not None and rates is not None:
                J[layout.clock_at] -= omega * (model.scales[i] * rates[:, i])
            _term_columns(J, layout, model, B, i, omega)
    r = layout.rotation_at
    J[r : r + 3] = np.moveaxis(eye if R_all is None else R_all, 1, 0)
    return R_pred, J


def orientation_residual(R_pred: FloatArray, R_meas: FloatArray) -> FloatArray:
    """The small rotation (3, m) from the measured to the predicted orientation, in M:
    ``vee(E − Eᵀ) / 2`` of ``E = R_pred R_measᵀ`` (first order, exact as ``sin`` of the angle)."""
    E = np.einsum("ikm,jkm->ijm", R_pred, R_meas)
    return np.stack([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 2.0


def predict_columns(
    model: AxisModel,
    Q: FloatArray,
    layout: ParameterLayout | None = None,
    bases: list[tuple[FloatArray, FloatArray]] | None = None,
    which: NDArray[np.int64] | None = None,
    prefix: Prefix | None = None,
    rates: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Predicted target positions (3, m) at the joint vectors ``Q`` (m, n) and, with ``layout``,
    the Jacobian (``layout.size``, 3, m) with respect to the local parameters. Samples run along
    the last axis so that every operation is on contiguous rows. ``which`` (m,) names each
    sample's target (0 the primary one, j the j-th of ``extra_targets``; default all 0).

    With ``g_<i = (R_<i, t_<i)`` the motion of joints 1 … i−1 and ``D_i = p − g_<i(c_i)`` the
    target relative to axis i's point as it sits at this sample, a move ``η = (w, v)`` of axis i
    gives ``δp = b × D_i + R_<i (I − R_i) v`` with ``b = R_<i (I − R_i) w`` (joint i's own rotation
    leaves its axis point where it is), so a tilt column is ``b_w × D_i`` and a shift column
    ``b_w`` itself (:func:`_tilt_move`). ``prefix``: the prefix motions at ``Q`` when already
    computed."""
    m = Q.shape[0]
    dq, pre_R, pre_t, sins, coss, B = _prefix_motions(model, Q, rates) if prefix is None else prefix
    R_all, t_all = pre_R[-1], pre_t[-1]
    if which is None or not len(model.extra_targets):
        tgt = np.broadcast_to(model.target[:, None], (3, m))
    else:
        tgt = np.ascontiguousarray(model.targets()[which].T)
    p = (tgt if R_all is None else _rotate(R_all, tgt)) + t_all
    p = np.ascontiguousarray(np.broadcast_to(p, (3, m)))
    if layout is None:
        return p, None
    assert bases is not None
    J = np.empty((layout.size, 3, m))
    moved = model.moves(Q, rates)
    clock = layout.clock_at if rates is not None else None
    if layout.clock_at is not None:
        J[layout.clock_at] = 0.0
    if layout.terms_at is not None:  # a term on a joint the loop skips stays zero
        J[layout.terms_at :] = 0.0
    for i, (axis, jt) in enumerate(zip(model.axes, model.types, strict=True)):
        u, v = bases[i]
        R0, t0 = pre_R[i], pre_t[i]
        k = layout.axis_at[i]
        omega = axis.direction[:, None] if R0 is None else _rotate(R0, _col(axis.direction, m))
        if jt is JointType.PRISMATIC:
            for col, w in enumerate((u, v)):
                w_world = w[:, None] if R0 is None else _rotate(R0, _col(w, m))
                J[k + col] = _cross_rows(w_world, omega) * dq[i]
            if layout.scale_at is not None:
                J[layout.scale_at + i] = np.broadcast_to(omega, (3, m)) * moved[:, i]
            if clock is not None:
                assert rates is not None
                J[clock] -= np.broadcast_to(omega, (3, m)) * (model.scales[i] * rates[:, i])
            _term_columns(J, layout, model, B, i, np.broadcast_to(omega, (3, m)))
            continue
        s, c1 = sins[i], coss[i]
        assert s is not None and c1 is not None
        c_world = (axis.point[:, None] if R0 is None else _rotate(R0, _col(axis.point, m))) + t0
        D = p - c_world
        for col, w in enumerate((u, v)):
            b = _tilt_move(axis, w, s, c1, R0)
            J[k + col] = _cross_rows(b, D)
            J[k + 2 + col] = b
        if layout.scale_at is not None or clock is not None or B is not None:
            turn = _cross_rows(np.broadcast_to(omega, (3, m)), D)
            if layout.scale_at is not None:
                J[layout.scale_at + i] = turn * moved[:, i]
            if clock is not None:
                assert rates is not None
                J[clock] -= turn * (model.scales[i] * rates[:, i])
            _term_columns(J, layout, model, B, i, turn)
    t = layout.target_at
    rot = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, m)) if R_all is None else R_all
    J[t : t + 3] = np.moveaxis(rot, 1, 0)
    if layout.rotation_at is not None:  # the target frame's orientation does not move the point
        J[layout.rotation_at : layout.rotation_at + 3] = 0.0
    extra = len(model.extra_targets)
    if extra:  # each sample moves only its own target's columns
        J[t + 3 : t + 3 + 3 * extra] = 0.0
        if which is not None:
            for j in range(1, extra + 1):
                mask = which == j
                J[t + 3 * j : t + 3 * j + 3, :, mask] = J[t : t + 3, :, mask]
            J[t : t + 3, :, which != 0] = 0.0
    return p, J


def _term_columns(
    J: FloatArray,
    layout: ParameterLayout,
    model: AxisModel,
    B: FloatArray | None,
    joint: int,
    per_unit: FloatArray,
) -> None:
    """The columns of the terms on ``joint``: its move per unit angle (``per_unit``, (3, m))
    times each term's function (each term moves one joint: its column is set once)."""
    if B is None or layout.terms_at is None or model.terms is None:
        return
    k0 = layout.terms_at
    for k, t in enumerate(model.terms.terms):
        if t.joint == joint:
            J[k0 + k] = per_unit * B[k]


def _skew(k: FloatArray) -> FloatArray:
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def _col(x: FloatArray, m: int) -> FloatArray:
    return np.broadcast_to(x[:, None], (3, m))


def _cross_rows(a: FloatArray, b: FloatArray) -> FloatArray:
    """Row-wise ``a × b`` for (3, m) arrays (either may broadcast from (3, 1))."""
    return np.stack(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _compose(A: FloatArray, B: FloatArray) -> FloatArray:
    """Per-sample product ``A B`` of rotation rows (3, 3, m)."""
    return np.stack(
        [
            np.stack([A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c] for c in range(3)])
            for r in range(3)
        ]
    )


def predict(
    model: AxisModel,
    Q: FloatArray,
    layout: ParameterLayout | None = None,
    bases: list[tuple[FloatArray, FloatArray]] | None = None,
    which: NDArray[np.int64] | None = None,
    rates: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Predicted target positions (m, 3) at the joint vectors ``Q`` (m, n) and, with ``layout``,
    the Jacobian (m, 3, ``layout.size``) with respect to the local parameters; ``rates`` (m, n)
    the joints' speeds when the model carries a clock offset."""
    p, J = predict_columns(model, Q, layout, bases, which, rates=rates)
    return p.T.copy(), None if J is None else np.transpose(J, (2, 1, 0)).copy()


@dataclass
class WholeFit:
    """The fitted model, its covariance (``layout`` order), and what the fit saw.

    ``inliers`` is over the samples given; ``chi2_dof`` is the weighted residual variance per
    degree of freedom (1 when the noise model is right).
    """

    model: AxisModel
    layout: ParameterLayout
    covariance: FloatArray
    inliers: NDArray[np.bool_]
    chi2_dof: float
    n_points: int
    iterations: int
    bases: list[tuple[FloatArray, FloatArray]] = field(default_factory=list)
    constrained: dict[int, str] = field(default_factory=dict)
    sigma_rotation: float | None = None
    #: what the samples determine (None: not computed)
    determined: Determined | None = None


Whitening = Callable[[FloatArray, FloatArray | None], FloatArray | float]


def _truncated(
    rw: FloatArray, keep: NDArray[np.bool_], limit: float
) -> tuple[FloatArray, NDArray[np.bool_], float]:
    """Per sample of whitened residuals ``rw`` (3, c): the norm, whether it enters (allowed and
    within ``limit``), and the truncated quadratic cost of the allowed ones."""
    nrm = np.sqrt(rw[0] ** 2 + rw[1] ** 2 + rw[2] ** 2)
    use = keep & (nrm <= limit)
    return nrm, use, float(np.sum(np.minimum(nrm[keep], limit) ** 2))


def _accumulate(
    model: AxisModel,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    data: _Samples,
    limit: float,
    norms: FloatArray,
    progress: Callable[[float], None] | None = None,
) -> tuple[FloatArray, FloatArray, float, int, float]:
    """One pass over the samples at ``model`` (``progress`` is told the fraction done):
    ``JᵀWJ``, ``JᵀWr`` over the samples allowed in ``data.keep`` whose whitened residual is at
    most ``limit``, the truncated cost, the inlier count and the sum of squared whitened inlier
    residuals. Writes each sample's whitened residual norm into ``norms``."""
    m = data.Q.shape[0]

    def chunk(start: int) -> tuple[FloatArray, FloatArray, float, int, float]:
        sl = slice(start, min(start + CHUNK, m))
        rates = None if data.Qd is None else data.Qd[sl]
        prefix = _prefix_motions(model, data.Q[sl], rates)
        which = None if data.which is None else data.which[sl]
        pred, J = predict_columns(model, data.Q[sl], layout, bases, which, prefix, rates)
        assert J is not None
        r = pred - data.P[sl].T  # (3, c)
        W = data.whiten(data.P[sl], None if data.W is None else data.W[sl])
        folded = 1.0  # a scalar weight of J applied to H and g instead of to every entry
        if isinstance(W, float):
            rw, Jw = r * W, J
            if data.R is None:
                folded = W
            else:
                Jw = J * W
        else:
            Wt = np.transpose(W, (1, 2, 0))  # (3, 3, c)
            rw = _rotate(Wt, r)
            Jw = np.moveaxis(_rotate(Wt, np.moveaxis(J, 0, 1)), 1, 0)
        keep = data.keep[sl]
        nrm, use, cost = _truncated(rw, keep, limit)
        norms[sl] = nrm
        if data.R is not None:  # the target frame's orientation, weighted by 1/σ_rot
            R_pred, Jr = predict_orientation(model, data.Q[sl], layout, bases, prefix, rates)
            ro = orientation_residual(R_pred, np.moveaxis(data.R[sl], 0, 2)) / data.sigma_rot
            # σ_rot is the orientations' own scale (or declared): judged on theirs, not on
            # a position limit that declared covariances far above the residuals make tiny
            _, use_o, part = _truncated(ro, keep, max(limit, ROTATION_LIMIT))
            use &= use_o
            cost += part
            rw = np.concatenate([rw, ro])
            Jw = np.concatenate([Jw, Jr / data.sigma_rot], axis=1)
        if not np.all(use):
            Jw, rw = Jw[:, :, use], rw[:, use]
        Ju = Jw.reshape(layout.size, -1)
        ru = rw.reshape(-1)
        H = Ju @ Ju.T
        if folded != 1.0:
            H *= folded * folded
        return H, (Ju @ ru) * folded, cost, int(np.count_nonzero(use)), float(ru @ ru)

    # one thread: two were measured slower on the 2-core machine (1.6 s → 2.3 s per million
    # samples; numpy's many small operations hold the GIL between its kernels)
    starts = range(0, m, CHUNK)
    parts = []
    for k, start in enumerate(starts):
        parts.append(chunk(start))
        if progress is not None and k % 16 == 15:
            progress((k + 1) / len(starts))
    H = np.sum([p[0] for p in parts], axis=0)
    g = np.sum([p[1] for p in parts], axis=0)
    cost = float(sum(p[2] for p in parts))
    count = int(sum(p[3] for p in parts))
    chi2 = float(sum(p[4] for p in parts))
    return H, g, cost, count, chi2


def _turn(
    K: FloatArray, x: FloatArray, s: FloatArray, c1: FloatArray, sign: float = 1.0
) -> FloatArray:
    """``R x`` (``sign`` 1) or ``Rᵀ x`` (``sign`` −1) for the per-sample rotation
    ``R = I + sin δ K + (1 − cos δ) K²`` of vectors ``x`` (3, m)."""
    Kx = K @ x
    return x + (sign * s) * Kx + c1 * (K @ Kx)


def _gradient(
    model: AxisModel,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    data: _Samples,
    limit: float,
    norms: FloatArray,
    progress: Callable[[float], None] | None = None,
) -> tuple[FloatArray, float, int, float]:
    """``JᵀWr`` over every allowed inlier of ``data`` (positions only) by the adjoint of the
    chain, without forming ``J``; the truncated cost, inlier count and χ² as
    :func:`_accumulate` gives them, and each sample's whitened residual norm in ``norms``.

    With ``x_i = g_i ⋯ g_n(target)`` (the target carried back to joint i's frame at the
    reference pose) and ``ρ_i = R_<iᵀ Wᵀ W r``, the columns of :func:`predict_columns` give
    ``b × D_i · ρ = a · ((x_i − c_i) × ρ_i)`` with ``a = (I − R_i) w``, so each axis needs only
    the sums of ``sin δ``, ``1 − cos δ`` (and the encoder move) times ``(x_i − c_i) × ρ_i`` and
    ``ρ_i``: two rotations of a vector per joint and sample in place of 27 columns."""
    m, n = data.Q.shape[0], model.n
    g = np.zeros(layout.size)
    cost, count, chi2 = 0.0, 0, 0.0
    Ks = [_skew(a.direction) for a in model.axes]
    targets = model.targets()
    starts = range(0, m, CHUNK)
    for k_chunk, start in enumerate(starts):
        sl = slice(start, min(start + CHUNK, m))
        c = sl.stop - sl.start
        rates = None if data.Qd is None else data.Qd[sl]
        moves = model.moves(data.Q[sl], rates).T  # (n, c)
        dq = moves * model.scales[:, None]
        speeds = None
        if rates is not None and layout.clock_at is not None:
            speeds = rates.T * model.scales[:, None]
        sins = np.sin(dq)
        coss = 1.0 - np.cos(dq)
        which = None if data.which is None else data.which[sl]
        x = (
            np.repeat(model.target[:, None], c, axis=1)
            if which is None or not len(model.extra_targets)
            else np.ascontiguousarray(targets[which].T)
        )
        rel: list[FloatArray | None] = [None] * n
        for i in range(n - 1, -1, -1):  # inward to outward: x_i = g_i(x_{i+1})
            axis = model.axes[i]
            if model.types[i] is JointType.PRISMATIC:
                x = x + axis.direction[:, None] * dq[i]
                continue
            v = x - axis.point[:, None]
            v = _turn(Ks[i], v, sins[i], coss[i])
            rel[i] = v
            x = v + axis.point[:, None]
        r = x - data.P[sl].T
        W = data.whiten(data.P[sl], None if data.W is None else data.W[sl])
        if isinstance(W, float):
            rw = r * W
            rho = rw * W
        else:
            Wt = np.transpose(W, (1, 2, 0))  # (3, 3, c)
            rw = _rotate(Wt, r)
            rho = _rotate(np.transpose(Wt, (1, 0, 2)), rw)
        nrm, use, part = _truncated(rw, data.keep[sl], limit)
        norms[sl] = nrm
        cost += part
        count += int(np.count_nonzero(use))
        chi2 += float(np.sum(nrm[use] ** 2))
        rho = np.where(use, rho, 0.0)
        for i in range(n):  # outward to inward: ρ_{i+1} = R_iᵀ ρ_i
            axis, k = model.axes[i], layout.axis_at[i]
            u, v = bases[i]
            q_i = moves[i]
            if model.types[i] is JointType.PRISMATIC:
                t = rho @ dq[i]
                for col, w in enumerate((u, v)):
                    g[k + col] += np.cross(w, axis.direction) @ t
                if layout.scale_at is not None:
                    g[layout.scale_at + i] += axis.direction @ (rho @ q_i)
                if speeds is not None:
                    g[layout.clock_at] -= axis.direction @ (rho @ speeds[i])
                continue
            rel_i = rel[i]
            assert rel_i is not None
            z = _cross_rows(rel_i, rho)
            zs, zc, rs, rc = z @ sins[i], z @ coss[i], rho @ sins[i], rho @ coss[i]
            K = Ks[i]
            for col, w in enumerate((u, v)):
                Kw, KKw = K @ w, K @ (K @ w)
                g[k + col] -= Kw @ zs + KKw @ zc
                g[k + 2 + col] -= Kw @ rs + KKw @ rc
            if layout.scale_at is not None:
                g[layout.scale_at + i] += axis.direction @ (z @ q_i)
            if speeds is not None:
                g[layout.clock_at] -= axis.direction @ (z @ speeds[i])
            rho = _turn(K, rho, sins[i], coss[i], -1.0)
        t0 = layout.target_at
        if which is None or not len(model.extra_targets):
            g[t0 : t0 + 3] += rho.sum(axis=1)
        else:
            for j in range(len(targets)):
                g[t0 + 3 * j : t0 + 3 * j + 3] += rho[:, which == j].sum(axis=1)
        if progress is not None and k_chunk % 16 == 15:
            progress((k_chunk + 1) / len(starts))
    return g, cost, count, chi2


@dataclass(frozen=True)
class _Samples:
    Q: FloatArray
    P: FloatArray
    keep: NDArray[np.bool_]
    W: FloatArray | None
    whiten: Whitening
    which: NDArray[np.int64] | None = None
    R: FloatArray | None = None
    sigma_rot: float = 1.0
    Qd: FloatArray | None = None

    @property
    def per_sample(self) -> int:
        """Residual components per sample: 3, or 6 with the target frame's orientation."""
        return 3 if self.R is None else 6

    def strided(self, stride: int) -> _Samples:
        return _Samples(
            self.Q[::stride],
            self.P[::stride],
            self.keep[::stride],
            None if self.W is None else self.W[::stride],
            self.whiten,
            None if self.which is None else self.which[::stride],
            None if self.R is None else self.R[::stride],
            self.sigma_rot,
            None if self.Qd is None else self.Qd[::stride],
        )


@dataclass
class _State:
    model: AxisModel
    bases: list[tuple[FloatArray, FloatArray]]
    H: FloatArray
    g: FloatArray
    cost: float
    count: int
    chi2: float
    norms: FloatArray
    iterations: int = 0


def _levenberg_marquardt(
    model: AxisModel,
    layout: ParameterLayout,
    data: _Samples,
    limit: float,
    max_iterations: int,
    progress: Callable[[float], None] | None = None,
) -> _State:
    """Levenberg–Marquardt from ``model`` over ``data`` with the truncation ``limit``."""
    m = data.Q.shape[0]
    bases = model.bases()
    norms = np.zeros(m)
    st = _State(model, bases, *_accumulate(model, layout, bases, data, limit, norms), norms)
    if data.per_sample * st.count <= layout.size:
        raise DegenerateGeometryError(
            f"the whole-model fit has {st.count} usable samples ({data.per_sample} residuals "
            "each) for "
            f"{layout.size} parameters."
        )
    lam = 1e-6
    determined = Determined.of(st.H)  # the samples' symmetries: the same along the way
    for it in range(1, max_iterations + 1):
        st.iterations = it
        if progress is not None:
            progress(min(it / 3.0, 0.95))
        try:
            delta = determined.solve(st.H, st.g, lam)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        predicted = float(-(st.g @ delta))  # expected decrease of the cost (Gauss–Newton)
        if predicted < CONVERGED:  # a step far below σ: take it, keep H (same to first order)
            st.model = st.model.moved(delta, layout, st.bases)
            st.bases = st.model.bases()
            break
        trial = st.model.moved(delta, layout, st.bases)
        trial_bases = trial.bases()
        tnorms = np.zeros(m)
        H, g, cost, count, chi2 = _accumulate(trial, layout, trial_bases, data, limit, tnorms)
        if cost <= st.cost + 1e-12 * max(st.cost, 1.0):
            converged = st.cost - cost < 1e-12 * st.cost
            st = _State(trial, trial_bases, H, g, cost, count, chi2, tnorms, it)
            lam = max(lam / 10.0, 1e-12)
            if converged:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    return st


def _orientation_scale(
    start: AxisModel, layout: ParameterLayout, data: _Samples, stride: int
) -> float:
    """A robust σ (rad, per component) of the measured orientations about the start model."""
    assert data.R is not None
    R_pred, _ = predict_orientation(start, data.Q[::stride], layout, start.bases())
    r = orientation_residual(R_pred, np.moveaxis(data.R[::stride], 0, 2))
    norm = np.sqrt(np.sum(r**2, axis=0))
    return max(float(np.median(norm)) / CHI3_MEDIAN, 1e-9)


def _finish_on_all(
    sub: _State,
    layout: ParameterLayout,
    data: _Samples,
    limit: float,
    max_iterations: int,
    progress: Callable[[float], None] | None = None,
) -> tuple[_State, float]:
    """From the optimum ``sub`` of a strided subset to the optimum of every sample.

    One pass over every sample gives ``JᵀWr`` by the adjoint of the chain (:func:`_gradient`)
    and the inliers; ``JᵀWJ`` is the subset's, scaled by the ratio of inlier counts (an evenly
    strided subset of smooth sweeps integrates the information like a quadrature rule: every σ
    within 0.03 % of the full sum's, the result within 0.001 µm, on the 1 M-sample benchmark
    log). The subset's optimum lies within a few of
    its own σ of the full optimum, where the model is linear to far below the noise (lengths of
    metres against residuals of micrometres), so the Gauss–Newton step from it is the optimum.
    With orientations, or should the step be larger than the subset's uncertainty explains,
    the full ``JᵀWJ`` is accumulated (and, for the latter, the fit goes on by
    Levenberg–Marquardt over every sample). Returns the state and the χ² at the optimum.
    """
    norms = np.zeros(data.Q.shape[0])
    if data.R is None and layout.terms_at is None:
        g, cost, count, chi2 = _gradient(sub.model, layout, sub.bases, data, limit, norms, progress)
        H = sub.H * (count / max(sub.count, 1))
    else:
        H, g, cost, count, chi2 = _accumulate(
            sub.model, layout, sub.bases, data, limit, norms, progress
        )
    try:
        delta = Determined.of(H).solve(H, g)
    except np.linalg.LinAlgError:
        delta = None
    if delta is not None and float(delta @ sub.H @ delta) <= 100.0 * layout.size:
        model = sub.model.moved(delta, layout, sub.bases)
        decrease = float(-(g @ delta))  # the quadratic model's decrease: exact to first order
        state = _State(model, model.bases(), H, g, cost - decrease, count, chi2, norms, 1)
        return state, max(chi2 - decrease, 0.0)
    st = _levenberg_marquardt(sub.model, layout, data, limit, max_iterations)
    return st, st.chi2


def fit_whole_model(
    start: AxisModel,
    Q: FloatArray,
    P: FloatArray,
    *,
    noise: NoiseModel,
    sigma: float,
    keep: NDArray[np.bool_] | None = None,
    sample_cov: FloatArray | None = None,
    which: NDArray[np.int64] | None = None,
    rotations: FloatArray | None = None,
    sigma_rotation: float | None = None,
    fit_scales: bool = False,
    rates: FloatArray | None = None,
    threshold: float = 5.0,
    max_iterations: int = 30,
    subsample: int = 40000,
    progress: Callable[[float], None] | None = None,
) -> WholeFit:
    """Levenberg–Marquardt fit of ``start`` to the samples ``P`` (m, 3) at encoder values ``Q``
    (m, n), weighted by ``noise`` (isotropic σ = ``sigma`` unless the model names its own), or by
    ``sample_cov`` (m, 3) standard deviations or (m, 3, 3) covariances when the log carries them
    per sample; ``which`` (m,) each sample's target (0 primary, j the j-th extra target of
    ``start``); ``rotations`` (m, 3, 3) the measured orientation of a 6-DoF target, weighted by
    ``sigma_rotation`` (rad; default: its scale in the data). ``keep`` marks the samples that may
    enter (default: all). With ``rates`` (m, n: the joints' speeds at the samples) the residual
    clock offset is fitted too (``model.clock``).

    With more than ``subsample`` samples the fit first converges on an evenly strided subset and
    then finishes on every sample (usually one pass: the step left is far below σ)."""
    from dhlog.model.noise import whitening_from_std

    m = Q.shape[0]
    layout = ParameterLayout.of(
        start.types,
        fit_scales=fit_scales,
        extra_targets=len(start.extra_targets),
        rotation=rotations is not None,
        clock=rates is not None,
        terms=() if start.terms is None else start.terms.names(),
    )

    def whiten(points: FloatArray, W: FloatArray | None) -> FloatArray | float:
        return W if W is not None else noise.whiten(points, sigma)

    data = _Samples(
        Q,
        P,
        np.ones(m, dtype=bool) if keep is None else keep.copy(),
        None if sample_cov is None else whitening_from_std(sample_cov),
        whiten,
        which,
        rotations,
        1.0 if sigma_rotation is None else sigma_rotation,
        rates,
    )
    stride = -(-m // subsample) if m > subsample else 1
    if rotations is not None and sigma_rotation is None:
        data = replace(data, sigma_rot=_orientation_scale(start, layout, data, stride))
    first = data.strided(stride) if stride > 1 else data
    probe = np.zeros(first.Q.shape[0])
    _accumulate(start, layout, start.bases(), first, threshold, probe)
    kept = probe[first.keep]
    scale = float(np.median(kept)) / CHI3_MEDIAN if kept.size else 1.0
    # the noise model is off by more than 2x: judge outliers on the data's own scale
    limit = threshold * scale if not 0.5 < scale < 2.0 else threshold
    on_subset = None if progress is None else (lambda f: progress(0.3 * f))
    st = _levenberg_marquardt(start, layout, first, limit, max_iterations, on_subset)
    if data.R is not None and sigma_rotation is None:
        # the start's orientation scale includes the start's own error: judge it again at the
        # optimum of the subset and fit once more with it
        data = replace(data, sigma_rot=_orientation_scale(st.model, layout, data, stride))
        first = data.strided(stride) if stride > 1 else data
        st = _levenberg_marquardt(st.model, layout, first, limit, max_iterations, on_subset)
    iterations = st.iterations
    chi2 = st.chi2
    if stride > 1:
        on_all = None if progress is None else (lambda f: progress(0.3 + 0.7 * f))
        st, chi2 = _finish_on_all(st, layout, data, limit, max_iterations, on_all)
        iterations += st.iterations
    determined = Determined.of(st.H)
    if determined.basis.shape[1] == 0:
        raise DegenerateGeometryError(
            f"the samples determine none of the whole model's {layout.size} parameters: "
            "measure more poses, moving every joint."
        )
    inliers = data.keep & (st.norms <= limit)
    dof = max(data.per_sample * st.count - determined.basis.shape[1], 1)
    chi2_dof = chi2 / dof
    covariance = determined.inverse(st.H) * chi2_dof
    return WholeFit(
        model=st.model,
        layout=layout,
        covariance=np.asarray(covariance, dtype=np.float64),
        inliers=inliers,
        chi2_dof=float(chi2_dof),
        n_points=int(st.count),
        iterations=iterations,
        bases=st.bases,
        sigma_rotation=None if data.R is None else data.sigma_rot * math.sqrt(chi2_dof),
        determined=determined,
    )


def axis_covariances(fit: WholeFit) -> list[FloatArray]:
    """Per axis, the 4×4 covariance of ``[δe·u, δe·v, δc·u, δc·v]`` (the form of
    ``AxisFit.axis_covariance``): a tilt ``a`` about u moves the direction by ``−a v``, a tilt
    ``b`` about v by ``+b u``."""
    out = []
    layout = fit.layout
    for i, jt in enumerate(fit.model.types):
        k = layout.axis_at[i]
        width = 4 if jt is JointType.REVOLUTE else 2
        C = fit.covariance[k : k + width, k : k + width]
        B = np.zeros((4, width))
        B[0, 1], B[1, 0] = 1.0, -1.0
        if width == 4:
            B[2, 2], B[3, 3] = 1.0, 1.0
        out.append(np.asarray(B @ C @ B.T, dtype=np.float64))
    return out


def _relative_tilt_rows(fit: WholeFit, i: int) -> list[FloatArray]:
    """The two rows (``layout.size``,) giving ``e · (δd_{i+1} − sign δd_i)`` for ``e`` in axis
    i's perpendicular basis: the linearised change of the angle between axes i and i+1."""
    model, layout, bases = fit.model, fit.layout, fit.bases
    d1, d2 = model.axes[i].direction, model.axes[i + 1].direction
    sign = 1.0 if d1 @ d2 >= 0 else -1.0
    (u1, v1), (u2, v2) = bases[i], bases[i + 1]
    k1, k2 = layout.axis_at[i], layout.axis_at[i + 1]
    rows = []
    for e in (u1, v1):  # δd = −a v + b u for tilts (a about u, b about v)
        row = np.zeros(layout.size)
        row[k2], row[k2 + 1] = -(e @ v2), e @ u2
        row[k1], row[k1 + 1] = sign * (e @ v1), -sign * (e @ u1)
        rows.append(row)
    return rows


def relative_tilt_variances(fit: WholeFit) -> list[float]:
    """Per consecutive pair of axes, the variance (rad², per component) of the angle between
    them, from the fit's whole covariance: the two axes' own variances less what they share —
    axes that only ever moved together (a coupled move) are determined far better relative to
    each other than each alone."""
    out = []
    for i in range(fit.model.n - 1):
        rows = np.array(_relative_tilt_rows(fit, i))
        out.append(float(np.trace(rows @ fit.covariance @ rows.T)) / 2.0)
    return out


def constrain_pairs(fit: WholeFit, parallel: list[int], collinear: list[int]) -> WholeFit:
    """The fit under the constraint that axes ``i, i+1`` (0-based ``i``) are exactly parallel
    (``parallel``) or the same line (``collinear``): the relations a classification fixes when
    the data cannot reject them.

    To first order the constrained optimum and its covariance follow from the unconstrained
    ones without another pass over the samples (the model is linear far beyond these moves):
    ``x = −C Aᵀ (A C Aᵀ)⁻¹ c₀`` and ``C' = C − C Aᵀ (A C Aᵀ)⁻¹ A C`` for the linearised
    constraints ``c₀ + A x = 0``; then the constrained axes are made exactly parallel (or
    coincident), a change of second order."""
    model, layout, bases = fit.model, fit.layout, fit.bases
    rows: list[FloatArray] = []
    c0: list[float] = []
    for i in sorted(set(parallel) | set(collinear)):
        d1, d2 = model.axes[i].direction, model.axes[i + 1].direction
        sign = 1.0 if d1 @ d2 >= 0 else -1.0
        (u1, v1), (u2, v2) = bases[i], bases[i + 1]
        k1, k2 = layout.axis_at[i], layout.axis_at[i + 1]
        rows += _relative_tilt_rows(fit, i)
        c0 += [float(e @ (d2 - sign * d1)) for e in (u1, v1)]
        if i in collinear:
            c1, c2 = model.axes[i].point, model.axes[i + 1].point
            for e in (u1, v1):
                row = np.zeros(layout.size)
                row[k2 + 2], row[k2 + 3] = e @ u2, e @ v2
                row[k1 + 2], row[k1 + 3] = -(e @ u1), -(e @ v1)
                rows.append(row)
                c0.append(float(e @ (c2 - c1)))
    if not rows:
        return fit
    A, c = np.array(rows), np.array(c0)
    C = fit.covariance
    CA = C @ A.T
    S = A @ CA
    K = CA @ np.linalg.pinv(S)
    delta = -K @ c
    cov = C - K @ CA.T
    moved = model.moved(np.asarray(delta, dtype=np.float64), layout, bases)
    axes = list(moved.axes)
    for i in range(len(axes) - 1):
        if i in parallel or i in collinear:
            d1 = axes[i].direction
            sign = 1.0 if d1 @ axes[i + 1].direction >= 0 else -1.0
            point = axes[i].project(axes[i + 1].point) if i in collinear else axes[i + 1].point
            axes[i + 1] = Line(point, sign * d1)
    snapped = replace(moved, axes=tuple(axes))
    return replace(
        fit,
        model=snapped,
        covariance=np.asarray((cov + cov.T) / 2, dtype=np.float64),
        bases=snapped.bases(),
        constrained={
            **{i: "parallel" for i in parallel},
            **{i: "collinear" for i in collinear},
        },
    )
