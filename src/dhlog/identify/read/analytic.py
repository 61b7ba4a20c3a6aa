"""The analytic result (seed method): pair tolerances from the axes' covariance, the extraction
of the per-joint axes, its first-order covariance, the Hayati rows of nearly parallel pairs, and
the rows kept when only a prefix of the chain was identified."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from dhlog.errors import DhlogError, Note
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.geometry.fitting import PlaneFit
from dhlog.geometry.lines import Line, Plane
from dhlog.identify.joints.sweeps import JointReport, carried_axis
from dhlog.identify.read.extract import Extraction, Tolerances
from dhlog.identify.read.hayati import (
    NEAR_PARALLEL,
    HayatiRow,
    hayati_parameters,
    row_reference,
)
from dhlog.identify.read.propagate import mixed_angles, mixed_vector, state_difference, state_vector
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import JointType, StandardDH

#: 2D 99.73 % radius (the "3σ" of a two-dimensional tilt or offset): sqrt(χ²₂(0.9973)).
THREE_SIGMA_2D = 3.44


#: With a nominal that says parallel (or meeting), the data must exceed this many σ to overrule it
#: (the analytic method).
NOMINAL_SIGMA_2D = 5.0


#: The whole-model fit holds a pair parallel (collinear) only where that costs less than it
#: gains: Akaike's rule for the two (four) parameters the relation removes, a Wald statistic
#: below 2 per parameter, i.e. a 2-D tilt (offset) within 2σ. On a KR5 0.05° off its nominal
#: swept over 30° arcs this costs 1.035x the achievable FK error, 3.44σ 1.150x
#: (``benchmarks/accuracy.py --parallel-sigma``). The same rule applies where the nominal says
#: parallel: its 5σ held a UR5 0.05° off its nominal parallel at up to 3.1x (1.29–1.46x over ten
#: sessions); the nominal's 5σ stays for the extraction's classification (the analytic method).
AIC_SIGMA_2D = 2.0


#: (:data:`dhlog.identify.read.hayati.NEAR_PARALLEL`) Axes closer than this to parallel (rad)
#: also get Hayati–Mirmirani parameters; no pair further from parallel is ever classified parallel,
#: however uncertain its axes.


#: No pair of axes further apart than this (m) is ever classified as meeting.
MAX_MEETING_DISTANCE = 1e-3


def pair_tolerances(
    axes: list[tuple[FloatArray, FloatArray]] | None,
    nominal: DHModel | None,
    angle_floor: float,
    distance_floor: float,
    *,
    k_data: float = THREE_SIGMA_2D,
    k_nominal: float = NOMINAL_SIGMA_2D,
    k_parallel: float | None = None,
    direction_variances: list[float] | None = None,
) -> list[tuple[float, float]] | None:
    """Per consecutive pair, the angle (rad) and distance (m) below which the data cannot tell
    the axes from parallel / meeting: 3σ (2D: 3.44σ) of the difference of the two axes, from
    their covariances (``axes``: per axis the 4×4 covariance of ``[δe·u, δe·v, δc·u, δc·v]``
    and the point ``c`` it refers to; 5σ when the nominal says parallel / meeting).
    ``k_parallel`` replaces the σ count of the parallel decision, also where the nominal says
    parallel, where that decision constrains the model (the whole-model fit: Akaike's 2σ).
    ``direction_variances`` (per pair, rad² per component): the variance of the angle between
    the two axes where it is known whole (the whole-model fit's covariance, correlations
    included), in place of the sum of the two axes' own. ``angle_floor`` and
    ``distance_floor`` apply only when an axis has no covariance (never below 1e-7)."""
    if axes is None:
        return None
    out = []
    for i in range(len(axes) - 1):
        (c1, p1), (c2, p2) = axes[i], axes[i + 1]
        var_dir = (
            direction_variances[i]
            if direction_variances is not None
            else (np.trace(c1[:2, :2]) + np.trace(c2[:2, :2])) / 2
        )
        lever = float(np.linalg.norm(p1 - p2))
        var_pos = (np.trace(c1[2:, 2:]) + np.trace(c2[2:, 2:])) / 2 + var_dir * lever**2
        k_angle = k_dist = k_data
        if k_parallel is not None:
            k_angle = k_parallel
        if nominal is not None:
            if abs(math.sin(nominal.table.alpha[i])) < 1e-9 and k_parallel is None:
                k_angle = k_nominal
            if abs(nominal.table.a[i]) < 1e-12:
                k_dist = k_nominal
        angle = k_angle * math.sqrt(var_dir) if var_dir > 0 else angle_floor
        distance = k_dist * math.sqrt(var_pos) if var_pos > 0 else distance_floor
        # never a convention for a relation far beyond any real robot's tolerance
        angle, distance = min(angle, NEAR_PARALLEL), min(distance, MAX_MEETING_DISTANCE)
        out.append((max(angle, 1e-7), max(distance, 1e-7)))
    return out


def hayati_rows(ex: Extraction) -> frozenset[int]:
    """The rows (0-based) to give in the Hayati–Mirmirani form: each revolute joint's row whose
    pair is nearly parallel (below :data:`NEAR_PARALLEL`) but not held parallel (a parallel pair
    has ``d`` by convention, exactly), and the held-parallel rows that follow such a row (their
    convention's origin would be the ill-conditioned one)."""
    types = ex.standard.joint_types
    kinds = {rel.joints[0] - 1: rel.relation for rel in ex.relations}
    rows: set[int] = set()
    for i in range(len(types) - 1):
        rel = kinds.get(i)
        if rel is None or types[i] is not JointType.REVOLUTE:
            continue
        angle = min(rel.angle, math.pi - rel.angle)
        if angle < NEAR_PARALLEL and not rel.kind.is_parallel:
            rows.add(i)
            k = i + 1
            while k < len(types) - 1 and types[k] is JointType.REVOLUTE:
                nxt = kinds.get(k)
                if nxt is None or not nxt.kind.is_parallel:
                    break
                rows.add(k)
                k += 1
    return frozenset(rows)


def near_parallel(
    axes: list[Line | None],
    ex: Extraction,
    std: FloatArray | None,
    nominal: StandardDH | None = None,
) -> tuple[list[HayatiRow], tuple[Note, ...]]:
    """Hayati–Mirmirani rows for nearly parallel pairs (on the ``nominal``'s branch where one is
    given), and a note (``hayati``) for each pair whose d is ill-conditioned."""
    rows = []
    notes: list[Note] = []
    for rel in ex.relations:
        i, k = rel.joints
        angle = min(rel.relation.angle, math.pi - rel.relation.angle)
        if angle >= NEAR_PARALLEL:
            continue
        axis = axes[k - 1]
        assert axis is not None
        try:
            reference = row_reference(nominal, i - 1, ex.reference_pose)
            rows.append(hayati_parameters(ex.frames[i - 1], axis, (i, k), reference))
        except DhlogError:
            continue
        if not rel.relation.kind.is_parallel:
            d, sd = (
                ex.standard.d_offset[i - 1],
                float("nan") if std is None else std[4 * (i - 1) + 1],
            )
            notes.append(
                Note.info(
                    f"joints {i} and {k} are nearly parallel ({math.degrees(angle):.4f}°, beyond "
                    f"what the noise explains): the DH d{i} ({d * 1e3:.1f} mm ± "
                    f"{sd * 1e3:.1f} mm) is ill-conditioned, so row {i} is given in the "
                    "Hayati–Mirmirani form (β in place of d; the JSON keeps both).",
                    "hayati",
                )
            )
    return rows, tuple(notes)


def prefix_table(table: StandardDH, k: int) -> StandardDH:
    return StandardDH(
        table.joint_types[:k],
        table.theta_offset[:k],
        table.d_offset[:k],
        table.a[:k],
        table.alpha[:k],
    )


@dataclass(frozen=True)
class JointAxes:
    """What the seed method reads the DH model off: each joint's report (its circle or line fit
    and its axis at the reference pose), the ``reference_pose``, the ``base`` plane's fit (None:
    none), the ``nominal`` table whose branches the extraction takes (None: none) and the
    extraction's ``tolerances``."""

    joints: tuple[JointReport, ...]
    reference_pose: FloatArray
    base: PlaneFit | None
    nominal: StandardDH | None
    tolerances: Tolerances

    def extract(self, target: FloatArray) -> Extraction:
        """The DH model line geometry reads off the axes (every joint identified), ``target``
        (m, in M) the target at the reference pose."""
        joints = self.joints
        return self.tolerances.extract(
            [j.axis for j in joints],  # type: ignore[misc]
            [j.type for j in joints],  # type: ignore[misc]
            target=target,
            reference_pose=self.reference_pose,
            base_plane=self.base.plane if self.base is not None else None,
            nominal=self.nominal,
        )


def partial_extraction(fitted: JointAxes) -> Extraction | None:
    """The rows that only need the identified prefix of the chain (or None)."""
    joints, nominal_table = fitted.joints, fitted.nominal
    n = len(joints)
    prefix = 0
    while prefix < n and joints[prefix].ok:
        prefix += 1
    if prefix < 2:
        return None
    pre = joints[:prefix]
    last = pre[-1].fit
    assert last is not None
    return fitted.tolerances.extract(
        [j.axis for j in pre],  # type: ignore[misc]
        [j.type for j in pre],  # type: ignore[misc]
        target=last.center + last.radius * last.basis[0] + 0.1 * last.basis[1],
        reference_pose=fitted.reference_pose[:prefix],
        base_plane=fitted.base.plane if fitted.base is not None else None,
        nominal=None if nominal_table is None else prefix_table(nominal_table, prefix),
    )


def propagate_analytic(
    fitted: JointAxes,
    target: FloatArray,
    target_cov: FloatArray,
    center: Extraction,
    target_of: Callable[[list[Line | None]], FloatArray] | None = None,
    rows: frozenset[int] = frozenset(),
    nominal_rows: StandardDH | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """First-order covariance of the ``center`` extraction of the ``fitted`` axes
    (:func:`state_vector`, 4n + 9) and, with ``rows``, of the table with those rows in the
    Hayati–Mirmirani form (:func:`mixed_vector`, on ``nominal_rows``' branch); ``target`` (m, in
    M) the target at the reference pose with its covariance ``target_cov``, ``target_of(axes)``
    the target for other axes (None: held).

    The Jacobian of the extraction with respect to each fitted axis's tilt and shift (4 per axis,
    carried to the reference pose with the axes downstream of it and moving the target with it),
    the base plane (3) and the target's own scatter (3) is taken by central differences; the
    inputs' covariances are the fits' own.
    """
    joints, ref, base = list(fitted.joints), fitted.reference_pose, fitted.base
    nominal, tolerances = fitted.nominal, fitted.tolerances
    n = len(joints)
    types = [j.type for j in joints]
    axes = [j.axis for j in joints]
    assert all(a is not None for a in axes)
    params: list[tuple[str, int, int]] = [("axis", i, p) for i in range(n) for p in range(4)]
    blocks: list[FloatArray] = []
    for j in joints:
        assert j.fit is not None
        blocks.append(j.fit.axis_covariance)
    if base is not None:
        params += [("plane", 0, p) for p in range(3)]
        blocks.append(base.covariance)
    params += [("target", 0, p) for p in range(3)]
    blocks.append(target_cov)
    sizes = [b.shape[0] for b in blocks]
    cov = np.zeros((sum(sizes), sum(sizes)))
    at = 0
    for b in blocks:
        cov[at : at + b.shape[0], at : at + b.shape[0]] = b
        at += b.shape[0]
    R0 = center.T_measurement_base[:3, :3]
    n_state = 4 * n + 9
    J = np.zeros((n_state + (4 * n if rows else 0), len(params)))
    wrap = mixed_angles(n, rows)
    for col, (kind, i, p) in enumerate(params):
        h = 1e-7
        outs = []
        for sign in (1.0, -1.0):
            ax = list(axes)
            plane = base.plane if base is not None else None
            tgt = target.copy()
            if kind == "axis":
                fit = joints[i].fit
                assert fit is not None
                u, v = fit.basis
                a = fit.axis
                if p < 2:
                    moved = Line(a.point, a.direction + sign * h * (u if p == 0 else v))
                else:
                    moved = Line(a.point + sign * h * (u if p == 2 else v), a.direction)
                ax = _axes_with(joints, i, moved, ref)
                if target_of is not None:
                    tgt = target_of(ax)
            elif kind == "plane":
                assert base is not None and plane is not None
                u, v = base.basis
                if p < 2:
                    plane = Plane(plane.point, plane.normal + sign * h * (u if p == 0 else v))
                else:
                    plane = Plane(plane.point + sign * h * plane.normal, plane.normal)
            else:
                tgt[p] += sign * h
            ex = tolerances.extract(
                ax,  # type: ignore[arg-type]
                types,  # type: ignore[arg-type]
                target=tgt,
                reference_pose=ref,
                base_plane=plane,
                nominal=nominal,
            )
            outs.append(state_vector(ex, R0))
            if rows:
                outs.append(mixed_vector(ex, rows, nominal_rows))
        J[:n_state, col] = state_difference(outs[0], outs[-2 if rows else 1], n) / (2 * h)
        if rows:
            diff = outs[1] - outs[3]
            diff[wrap] = [wrap_angle(d) for d in diff[wrap]]
            J[n_state:, col] = diff / (2 * h)
    full = np.asarray(J @ cov @ J.T, dtype=np.float64)
    return full[:n_state, :n_state], (full[n_state:, n_state:] if rows else None)


def _axes_with(
    joints: list[JointReport], i: int, fitted: Line, ref: FloatArray
) -> list[Line | None]:
    """The axes at the reference pose with joint ``i``'s fitted axis replaced by ``fitted``:
    joints carried through it (swept from other poses) move with it."""
    trial: list[JointReport] = []  # in chain order: each carried by those before it
    for k, j in enumerate(joints):
        report = JointReport(
            j.index,
            j.name,
            j.type,
            j.type_source,
            j.fit,
            j.axis,
            lock_pose=j.lock_pose,
            carried=j.carried,
        )
        assert report.fit is not None
        base = fitted if k == i else report.fit.axis
        if k == i or (k > i and report.carried):
            report = replace(report, axis=carried_axis(report, base, trial, ref))
        trial.append(report)
    return [t.axis for t in trial]
