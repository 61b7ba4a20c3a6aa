"""``dhlog process``: from a calibration log to the DH model, its uncertainty and its check.

read (``io.reader``) → segment (``segment``) → per joint: pick the sweeps, decide the type, fit
the axis robustly, bring it to the reference pose → base plane, target at the reference pose →
extract (``extract``) → propagate the fits' covariance to every parameter → forward kinematics of
the result against every sample → the result document of the contract.

When some joints cannot be identified, what was identified is kept: their fits and axes, and the
DH rows that only need identified axes; the joints at fault are named with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog import __version__
from dhlog.contract import RESULT_FORMAT, dh_documents, relation_documents
from dhlog.dh import JointType, StandardDH
from dhlog.dhfile import DHModel
from dhlog.errors import DhlogError, GeometryError, InputError
from dhlog.extract import Extraction, HayatiRow, extract_dh, hayati_parameters
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.geometry.fitting import AxisFit, PlaneFit, detect_joint_type, fit_axis_robust, fit_plane
from dhlog.geometry.lines import ANGLE_TOL, DISTANCE_TOL, Line, Plane, RelationKind, classify_lines
from dhlog.geometry.screws import chain_motion, chain_motions
from dhlog.identify.noise import NoiseModel
from dhlog.identify.propagate import (
    fixed_reasons,
    frame_rotation,
    propagate,
    state_names,
    state_vector,
)
from dhlog.identify.whole import (
    AxisModel,
    WholeFit,
    axis_covariances,
    constrain_pairs,
    fit_whole_model,
)
from dhlog.io.pipeline import Pipeline
from dhlog.io.reader import LogData, read_log
from dhlog.io.writer import sha256_of
from dhlog.kinematics import fk_point, fk_points_chunked
from dhlog.segment import Segmentation, segment_log

#: Largest number of samples per joint the per-joint fits (the whole-model fit's start) use.
START_FIT_POINTS = 4000
#: Largest number of samples the target at the reference pose is averaged over for the start.
START_TARGET_POINTS = 20000
#: Correlations beyond this between free parameters are reported.
CORRELATION_WARNING = 0.95


@dataclass
class JointReport:
    """What became of one joint: its type (and where the type came from), the fit, the axis at
    the reference pose, the sweeps used, the outliers set aside, or why it failed."""

    index: int
    name: str
    type: JointType | None = None
    type_source: str = ""
    fit: AxisFit | None = None
    axis: Line | None = None
    segments: list[int] = field(default_factory=list)
    rows: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    inliers: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    lock_pose: FloatArray | None = None
    carried: bool = False
    reason: str | None = None

    @property
    def ok(self) -> bool:
        """True when the joint's axis was identified."""
        return self.axis is not None and self.reason is None

    @property
    def n_outliers(self) -> int:
        """Samples of the joint's sweeps set aside as gross outliers."""
        return int(np.count_nonzero(~self.inliers))


@dataclass
class Validation:
    """FK of the result against each assigned sample with encoder values (m), and summaries."""

    residuals: FloatArray
    per_joint: dict[int, tuple[float, float, int]]
    rms: float
    max: float
    n_points: int


@dataclass
class ProcessResult:
    """Everything ``dhlog process`` found, ready to be written and shown."""

    path: str
    sha256: str
    log: LogData
    segmentation: Segmentation
    joints: list[JointReport]
    reference_pose: FloatArray
    extraction: Extraction | None
    std: FloatArray | None
    base: PlaneFit | None
    target: FloatArray | None
    validation: Validation | None
    nominal: DHModel | None
    warnings: list[str]
    covariance: FloatArray | None = None
    hayati: list[HayatiRow] = field(default_factory=list)
    hayati_std: list[FloatArray] = field(default_factory=list)
    method: str = "analytic"
    analytic: Extraction | None = None
    whole: WholeFit | None = None
    fixed: dict[int, str] = field(default_factory=dict)
    noise: NoiseModel = field(default_factory=NoiseModel)
    sigma: float | None = None

    @property
    def complete(self) -> bool:
        """True when every joint was identified."""
        return all(j.ok for j in self.joints)

    @property
    def failed(self) -> list[JointReport]:
        """The joints that could not be identified."""
        return [j for j in self.joints if not j.ok]


def _groups_by_lock(seg: Segmentation, joint: int, tol: float) -> list[list[int]]:
    """The joint's segments grouped by compatible locked poses (each group: segment ids)."""
    rows = seg.segments.filter(pl.col("joint") == joint)
    locks = rows.select([f"lock_q_{j + 1}" for j in range(seg.n_joints)]).to_numpy()
    ids = rows["segment"].to_list()
    groups: list[tuple[FloatArray, list[int]]] = []
    for sid, lock in zip(ids, locks, strict=True):
        for pose, members in groups:
            both = ~np.isnan(pose) & ~np.isnan(lock)
            if np.all(np.abs(pose[both] - lock[both]) <= tol):
                members.append(int(sid))
                break
        else:
            groups.append((lock, [int(sid)]))
    return [members for _, members in groups]


def _lock_matches(lock: FloatArray, ref: FloatArray, joint: int, tol: float) -> bool:
    others = np.arange(lock.size) != joint - 1
    values = lock[others]
    known = ~np.isnan(values)
    return bool(np.all(np.abs(values[known] - ref[others][known]) <= tol))


def _joint_type(
    k: int, name: str, points: FloatArray, log: LogData, nominal: DHModel | None, notes: list[str]
) -> tuple[JointType, str]:
    declared = log.pipeline.joint_types
    if declared is not None and k - 1 < len(declared) and declared[k - 1] is not None:
        jt = declared[k - 1]
        assert jt is not None
        return jt, "pipeline"
    if nominal is not None:
        return nominal.table.joint_types[k - 1], "nominal"
    kind, why = detect_joint_type(points, what=f"joint {k} ({name})")
    jt = JointType(kind)
    if jt is JointType.PRISMATIC:
        notes.append(f"joint {k} ({name}): detected as prismatic ({why}).")
    return jt, f"detected: {why}"


def _fit_joint(
    report: JointReport,
    seg: Segmentation,
    log: LogData,
    ref: FloatArray,
    identified: list[JointReport],
    nominal: DHModel | None,
    fit_method: str,
    notes: list[str],
    max_points: int | None = None,
) -> None:
    k, name = report.index, report.name
    tol = log.pipeline.segmentation.lock_tolerance
    what = f"joint {k} ({name})"
    groups = _groups_by_lock(seg, k, tol)
    if not groups:
        report.reason = "it was never swept (no segment in which it alone moved)"
        return
    segments = seg.segments
    chosen = groups[0]
    for group in groups:
        lock = (
            segments.filter(pl.col("segment") == group[0])
            .select([f"lock_q_{j + 1}" for j in range(seg.n_joints)])
            .to_numpy()[0]
        )
        if _lock_matches(lock, ref, k, tol):
            chosen = group
            break
    else:
        chosen = max(
            groups, key=lambda g: int(segments.filter(pl.col("segment").is_in(g))["n"].sum())
        )
    lock = (
        segments.filter(pl.col("segment") == chosen[0])
        .select([f"lock_q_{j + 1}" for j in range(seg.n_joints)])
        .to_numpy()[0]
    )
    report.segments = chosen
    report.rows = np.flatnonzero(seg.table["segment"].is_in(chosen).fill_null(False).to_numpy())
    rows = seg.table[report.rows]
    points = rows.select(["x", "y", "z"]).to_numpy()
    encoder = rows[f"q_{k}"].to_numpy() if seg.has_encoders else None
    try:
        stride = 1 if max_points is None else max(1, points.shape[0] // max_points)
        jt, source = _joint_type(k, name, points[::stride], log, nominal, notes)
        report.type, report.type_source = jt, source
        settings = log.pipeline.segmentation
        fit, inliers = fit_axis_robust(
            points,
            kind="line" if jt is JointType.PRISMATIC else "circle",
            encoder=encoder,
            method=fit_method,  # type: ignore[arg-type]
            min_sweep=settings.min_sweep,
            max_points=max_points,
            what=what,
        )
    except GeometryError as exc:
        report.reason = str(exc).removeprefix(f"{what}: ")
        return
    report.fit, report.inliers = fit, inliers
    for w in fit.warnings:
        notes.append(w)
    report.lock_pose = np.where(np.isnan(lock), ref, lock)
    report.carried = bool(seg.has_encoders and not _lock_matches(lock, ref, k, tol))
    if report.carried:
        upstream = identified[: k - 1]
        if any(not j.ok for j in upstream):
            report.reason = (
                "it was swept only from another pose, and an upstream joint needed to carry its "
                "axis to the reference pose was not identified"
            )
            return
        notes.append(
            f"{what}: swept from another pose; its axis was carried to the reference pose "
            "through the upstream axes."
        )
    report.axis = _carried_axis(report, fit.axis, identified, ref)


def _carried_axis(
    report: JointReport, fitted: Line, joints: list[JointReport], ref: FloatArray
) -> Line:
    """The joint's axis at the reference pose: as fitted when it was swept there, else moved
    back from its locked pose through the upstream axes (product of exponentials)."""
    if not report.carried:
        return fitted
    k = report.index
    assert report.lock_pose is not None
    upstream = joints[: k - 1]
    axes = [j.axis for j in upstream]
    types = [j.type for j in upstream]
    M = chain_motion(axes, types, report.lock_pose[: k - 1], ref[: k - 1])  # type: ignore[arg-type]
    return fitted.transformed(np.linalg.inv(M))


class _TargetAtReference:
    """The target at the reference pose, from the inlier samples of all sweeps.

    With encoders: every inlier sample moved back to the reference pose through the axes
    (``M_n(q)⁻¹ p``, product of exponentials), averaged; its covariance is the scatter over the
    number of samples. Without encoders: the point nearest all fitted circles (every sweep starts
    from the same pose, so every circle passes through it).
    """

    def __init__(
        self,
        seg: Segmentation,
        joints: list[JointReport],
        ref: FloatArray,
        max_rows: int | None = None,
    ) -> None:
        self.joints, self.ref = joints, ref
        self.encoders = seg.has_encoders
        if self.encoders:
            rows = np.concatenate([j.rows[j.inliers] for j in joints])
            if max_rows is not None and rows.size > max_rows:
                rows = rows[:: -(-rows.size // max_rows)]
            cols = [f"q_{i + 1}" for i in range(seg.n_joints)]
            self.Q = seg.table.select(cols).to_numpy()[rows]
            self.P = seg.table.select(["x", "y", "z"]).to_numpy()[rows]

    def __call__(self, axes: list[Line | None] | None = None) -> tuple[FloatArray, FloatArray]:
        joints = self.joints
        if not self.encoders:
            fits = [j.fit for j in joints if j.fit is not None]
            spread = max(f.sigma for f in fits) ** 2 / len(fits)
            return _common_point_of_circles(fits), np.eye(3) * spread
        axes = [j.axis for j in joints] if axes is None else axes
        types = [j.type for j in joints]
        M = chain_motions(axes, types, self.Q, self.ref)  # type: ignore[arg-type]
        R, t = M[:, :3, :3], M[:, :3, 3]
        back = np.einsum("mji,mj->mi", R, self.P - t)  # R^T (p - t)
        return back.mean(axis=0), np.cov(back.T) / back.shape[0]


def _common_point_of_circles(fits: list[AxisFit]) -> FloatArray:
    """The point nearest (least squares) to all circles, from the best-agreeing sample."""
    from scipy.optimize import least_squares

    def distances(p: FloatArray) -> FloatArray:
        out = []
        for f in fits:
            w = p - f.center
            h = w @ f.axis.direction
            rho = np.linalg.norm(w - h * f.axis.direction)
            out += [h, rho - f.radius]
        return np.asarray(out)

    candidates = []
    for f in fits:
        u, v = f.basis
        for a in np.linspace(0, 2 * np.pi, 72, endpoint=False):
            candidates.append(f.center + f.radius * (np.cos(a) * u + np.sin(a) * v))
    start = min(candidates, key=lambda c: float(np.sum(distances(c) ** 2)))
    return np.asarray(least_squares(distances, start).x, dtype=np.float64)


def model_from_state(
    x: FloatArray, types: tuple[JointType, ...], R0: FloatArray
) -> tuple[StandardDH, FloatArray, FloatArray]:
    """Inverse of :func:`state_vector`: (table, tool point, T_measurement_base)."""
    n = len(types)
    rows = x[: 4 * n].reshape(n, 4)
    table = StandardDH(types, rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3])
    tool = x[4 * n : 4 * n + 3]
    R = frame_rotation(R0, x[4 * n + 6 : 4 * n + 9])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, x[4 * n + 3 : 4 * n + 6]
    return table, tool, T


def fk_prediction_std(result: ProcessResult, Q: FloatArray) -> FloatArray:
    """Predicted RMS position error (m) of the result's FK at each joint vector in ``Q``, from
    the propagated covariance of the model (first order)."""
    ex, cov = result.extraction, result.covariance
    assert ex is not None and cov is not None
    R0 = ex.T_measurement_base[:3, :3]
    x0 = state_vector(ex, R0)
    types = ex.standard.joint_types

    def fk(x: FloatArray) -> FloatArray:
        table, tool, T = model_from_state(x, types, R0)
        return fk_point(table, Q, tool, T_base=T)

    J = np.zeros((Q.shape[0], 3, x0.size))
    for i in range(x0.size):
        h = 1e-7
        e = np.zeros(x0.size)
        e[i] = h
        J[:, :, i] = (fk(x0 + e) - fk(x0 - e)) / (2 * h)
    var = np.einsum("mij,jk,mik->m", J, cov, J)
    return np.asarray(np.sqrt(np.clip(var, 0.0, None)), dtype=np.float64)


def _propagate(
    joints: list[JointReport],
    ref: FloatArray,
    target: FloatArray,
    target_cov: FloatArray,
    base: PlaneFit | None,
    nominal: StandardDH | None,
    extract_kwargs: dict[str, Any],
    center: Extraction,
    target_of: Callable[[list[Line | None]], FloatArray] | None = None,
) -> FloatArray:
    """First-order covariance of the identified model (:func:`state_vector`, 4n + 9).

    The Jacobian of the extraction with respect to each fitted axis's tilt and shift (4 per axis,
    carried to the reference pose with the axes downstream of it and moving the target with it),
    the base plane (3) and the target's own scatter (3) is taken by central differences; the
    inputs' covariances are the fits' own.
    """
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
    base_vec = state_vector(center, R0)
    J = np.zeros((base_vec.size, len(params)))
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
            ex = extract_dh(
                ax,  # type: ignore[arg-type]
                types,  # type: ignore[arg-type]
                target=tgt,
                reference_pose=ref,
                base_plane=plane,
                nominal=nominal,
                **extract_kwargs,
            )
            outs.append(state_vector(ex, R0))
        diff = outs[0] - outs[1]
        angles = np.zeros(base_vec.size, dtype=bool)
        angles[: 4 * n] = np.tile([True, False, False, True], n)
        diff[angles] = [wrap_angle(d) for d in diff[angles]]
        J[:, col] = diff / (2 * h)
    return np.asarray(J @ cov @ J.T, dtype=np.float64)


def _axes_with(
    joints: list[JointReport], i: int, fitted: Line, ref: FloatArray
) -> list[Line | None]:
    """The axes at the reference pose with joint ``i``'s fitted axis replaced by ``fitted``:
    joints carried through it (swept from other poses) move with it."""
    trial = [
        JointReport(
            j.index,
            j.name,
            j.type,
            j.type_source,
            j.fit,
            j.axis,
            lock_pose=j.lock_pose,
            carried=j.carried,
        )
        for j in joints
    ]
    for k, report in enumerate(trial):
        assert report.fit is not None
        base = fitted if k == i else report.fit.axis
        if k == i or (k > i and report.carried):
            report.axis = _carried_axis(report, base, trial, ref)
    return [t.axis for t in trial]


def _validate(seg: Segmentation, joints: list[JointReport], ex: Extraction) -> Validation | None:
    """FK of the result at every assigned inlier sample's own encoder values against the sample."""
    if not seg.has_encoders:
        return None
    table = seg.table
    cols = [f"q_{i + 1}" for i in range(seg.n_joints)]
    Q = table.select(cols).to_numpy()
    P = table.select(["x", "y", "z"]).to_numpy()
    residuals = np.full(table.height, np.nan)
    per_joint: dict[int, tuple[float, float, int]] = {}
    used: list[FloatArray] = []
    for j in joints:
        rows = j.rows[j.inliers]
        if rows.size == 0:
            continue
        pred = fk_point(ex.standard, Q[rows], ex.tool_point, T_base=ex.T_measurement_base)
        r = np.linalg.norm(pred - P[rows], axis=1)
        residuals[rows] = r
        per_joint[j.index] = (float(np.sqrt(np.mean(r**2))), float(r.max()), int(r.size))
        used.append(r)
    allr = np.concatenate(used) if used else np.zeros(0)
    return Validation(
        residuals=residuals,
        per_joint=per_joint,
        rms=float(np.sqrt(np.mean(allr**2))) if allr.size else float("nan"),
        max=float(allr.max()) if allr.size else float("nan"),
        n_points=int(allr.size),
    )


Stage = Callable[[str, float], None]


def process_log(
    path: str | Path,
    *,
    pipeline: Pipeline | None = None,
    nominal: DHModel | None = None,
    reference_pose: FloatArray | None = None,
    fit_method: str = "auto",
    angle_tol: float = ANGLE_TOL,
    distance_tol: float = DISTANCE_TOL,
    fast: bool = True,
    analytic_only: bool = False,
    fit_scales: bool = False,
    progress: Stage | None = None,
) -> ProcessResult:
    """Run the whole identification on the log at ``path`` (see the module docstring).

    ``progress(stage, fraction)`` is called as each stage advances."""
    log = read_log(
        path,
        pipeline,
        fast=fast,
        progress=None if progress is None else (lambda f: progress("reading", f)),
    )
    return process_data(
        log,
        sha256=sha256_of(path),
        nominal=nominal,
        reference_pose=reference_pose,
        fit_method=fit_method,
        angle_tol=angle_tol,
        distance_tol=distance_tol,
        analytic_only=analytic_only,
        fit_scales=fit_scales,
        progress=progress,
    )


def process_data(
    log: LogData,
    *,
    sha256: str = "",
    nominal: DHModel | None = None,
    reference_pose: FloatArray | None = None,
    fit_method: str = "auto",
    angle_tol: float = ANGLE_TOL,
    distance_tol: float = DISTANCE_TOL,
    analytic_only: bool = False,
    fit_scales: bool = False,
    progress: Stage | None = None,
) -> ProcessResult:
    """The identification of :func:`process_log` on streams already decoded (``LogData``).

    Default: the maximum-likelihood fit of the whole model to every sample with encoder
    values, started from the analytic result (per-joint fits + line geometry). With
    ``analytic_only`` (or without encoders), the analytic result with its propagated covariance.
    """

    def stage(what: str, fraction: float) -> None:
        if progress is not None:
            progress(what, fraction)

    name = log.path
    types_hint = list(log.pipeline.joint_types) if log.pipeline.joint_types else None
    if types_hint is None and nominal is not None:
        types_hint = list(nominal.table.joint_types)
    stage("segmenting", 0.0)
    seg = segment_log(log, joint_types=types_hint, reference_pose=reference_pose)
    n = seg.n_joints
    notes = list(seg.warnings)
    if nominal is not None and nominal.table.n != n:
        raise InputError(
            f"{nominal.source}: the nominal table has {nominal.table.n} joints but {name} "
            f"has {n}; give the nominal of this robot."
        )
    if reference_pose is not None and np.asarray(reference_pose).shape != (n,):
        raise InputError(
            f"--reference-pose has {np.asarray(reference_pose).size} values but {name} has {n} "
            "joints; give one value per joint."
        )
    ref = (
        np.asarray(reference_pose, dtype=np.float64)
        if reference_pose is not None
        else (seg.reference_pose if seg.reference_pose is not None else np.zeros(n))
    )
    if not seg.has_encoders:
        notes.append(
            "no encoders: the reference pose is the pose every sweep starts from (all zeros), "
            "and the sense of motion comes from time order."
        )
    whole_wanted = seg.has_encoders and not analytic_only
    max_points = START_FIT_POINTS if whole_wanted else None
    joints = [JointReport(k + 1, seg.joint_names[k]) for k in range(n)]
    for report in joints:
        stage("fitting", (report.index - 1) / n)
        _fit_joint(report, seg, log, ref, joints, nominal, fit_method, notes, max_points)
    for report in joints:
        if report.reason:
            notes.append(
                f"joint {report.index} ({report.name}) was not identified: {report.reason}."
            )
    base = None
    if log.base is not None and log.base.height >= 3:
        try:
            base = fit_plane(
                log.base.select(["x", "y", "z"]).to_numpy(), what=f"{name}: base plane"
            )
        except GeometryError as exc:
            notes.append(f"the base plane was not used: {exc}")
    result = ProcessResult(
        path=name,
        sha256=sha256,
        log=log,
        segmentation=seg,
        joints=joints,
        reference_pose=ref,
        extraction=None,
        std=None,
        base=base,
        target=None,
        validation=None,
        nominal=nominal,
        warnings=notes,
        noise=log.pipeline.noise,
    )
    kwargs: dict[str, Any] = {
        "angle_tol": angle_tol,
        "distance_tol": distance_tol,
        "pair_tolerances": _pair_tolerances(
            [(j.fit.axis_covariance, j.fit.center) for j in joints if j.fit is not None]
            if all(j.fit is not None for j in joints)
            else None,
            nominal,
            angle_tol,
            distance_tol,
        ),
    }
    nominal_table = nominal.table if nominal is not None else None
    if not all(j.ok for j in joints):
        if whole_wanted and nominal is not None and _from_the_nominal(result, kwargs, stage):
            return result
        result.extraction = _partial_extraction(joints, ref, base, nominal_table, kwargs)
        return result
    stage("identifying", 0.0)
    target_at = _TargetAtReference(seg, joints, ref, START_TARGET_POINTS if whole_wanted else None)
    target, target_cov = target_at()
    analytic = extract_dh(
        [j.axis for j in joints],  # type: ignore[misc]
        [j.type for j in joints],  # type: ignore[misc]
        target=target,
        reference_pose=ref,
        base_plane=base.plane if base is not None else None,
        nominal=nominal_table,
        **kwargs,
    )
    result.target = target
    if whole_wanted:
        try:
            _identify_whole(result, analytic, kwargs, fit_scales, stage)
            return result
        except GeometryError as exc:
            notes.append(f"the whole-model fit failed ({exc}); the result is the analytic one.")
    elif seg.has_encoders:
        notes.append("--analytic-only: the seed method's result (per-joint fits, line geometry).")
    else:
        notes.append(
            "no encoder values: the whole-model fit needs them; the result is the analytic one."
        )

    def target_of(axes: list[Line | None]) -> FloatArray:
        return target_at(axes)[0]

    stage("uncertainty", 0.0)
    covariance = _propagate(
        joints,
        ref,
        target,
        target_cov,
        base,
        nominal_table,
        kwargs,
        analytic,
        target_of if seg.has_encoders else None,
    )
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    fixed = std < 1e-12
    result.extraction, result.covariance = analytic, covariance
    result.fixed = fixed_reasons(
        analytic, fixed, base_plane=base is not None, nominal=nominal is not None
    )
    result.std = np.where(fixed, np.nan, std)
    result.hayati = _near_parallel([j.axis for j in joints], analytic, result.std, notes)
    stage("validating", 0.0)
    result.validation = _validate(seg, joints, analytic)
    if result.validation is not None:
        sigma = math.sqrt(np.mean([j.fit.sigma**2 for j in joints if j.fit is not None]))
        _check_residual(result.validation, sigma, notes)
    else:
        notes.append("no encoder values: FK of the result cannot be checked sample by sample.")
    return result


def _from_the_nominal(result: ProcessResult, kwargs: dict[str, Any], stage: Stage) -> bool:
    """Joints never moved alone, identified by the whole-model fit from every other sample
    (coupled moves, still poses), started from the nominal placed on the identified axes.
    Returns False (and changes nothing) when the data do not determine them."""
    from dhlog.kinematics import joint_axes

    nominal = result.nominal
    joints, ref, seg = result.joints, result.reference_pose, result.segmentation
    assert nominal is not None
    known = [j for j in joints if j.ok and j.axis is not None]
    points, dirs = joint_axes(nominal.table, ref, T_base=nominal.T_base)
    if len(known) < 2:
        return False
    T = _align_lines(
        [(points[j.index - 1], dirs[j.index - 1]) for j in known],
        [(j.axis.point, j.axis.direction) for j in known if j.axis is not None],
    )
    if T is None:
        return False
    axes = [
        j.axis
        if j.ok and j.axis is not None
        else Line(T[:3, :3] @ points[j.index - 1] + T[:3, 3], T[:3, :3] @ dirs[j.index - 1])
        for j in joints
    ]
    types = tuple(nominal.table.joint_types)
    rows, Q, P = _samples_with_encoders(seg)
    if rows.size == 0:
        return False
    nearest = int(np.argmin(np.sum((Q - ref) ** 2, axis=1)))
    M = chain_motion(axes, types, Q[nearest], ref)
    target = np.asarray(np.linalg.solve(M, np.r_[P[nearest], 1.0])[:3], dtype=np.float64)
    missing = [j for j in joints if not j.ok]
    saved = [(j.type, j.axis, j.reason, j.type_source) for j in missing]
    for j in missing:
        j.type, j.axis, j.reason, j.type_source = (
            types[j.index - 1],
            axes[j.index - 1],
            None,
            "nominal",
        )
    result.target = target
    try:
        _identify_whole(result, None, kwargs, False, stage)
    except GeometryError:
        for j, (jt, axis, reason, source) in zip(missing, saved, strict=True):
            j.type, j.axis, j.reason, j.type_source = jt, axis, reason, source
        result.target = None
        return False
    assert result.whole is not None
    for j in missing:
        j.axis = result.whole.model.axes[j.index - 1]
    names = ", ".join(f"joint {j.index} ({j.name})" for j in missing)
    result.warnings.append(
        f"{names}: never moved alone; identified by the whole-model fit from the other samples "
        "(coupled moves, still poses), started from the nominal."
    )
    return True


def _align_lines(
    nominal: list[tuple[FloatArray, FloatArray]], measured: list[tuple[FloatArray, FloatArray]]
) -> FloatArray | None:
    """The rigid transform (4×4) that best carries the nominal lines onto the measured ones:
    the rotation from the directions (Kabsch), the translation putting each nominal point on
    its measured line (least squares). None when the directions do not fix the rotation."""
    A = np.array([d for _, d in nominal])
    B = np.array([d for _, d in measured])
    U, S, Vt = np.linalg.svd(B.T @ A)
    if S[1] < 1e-3 * S[0]:
        return None
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(U @ Vt)))])
    R = U @ D @ Vt
    rows, rhs = [], []
    for (p, _), (c, e) in zip(nominal, measured, strict=True):
        perp = np.eye(3) - np.outer(e, e)
        rows.append(perp)
        rhs.append(perp @ (c - R @ p))
    t, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _check_residual(validation: Validation, sigma: float, notes: list[str]) -> None:
    expected = math.sqrt(3.0) * sigma
    if validation.rms > 1.5 * expected:
        notes.append(
            f"the FK residual RMS ({validation.rms * 1e3:.4f} mm, 3-D) is larger than the fit "
            f"noise explains ({expected * 1e3:.4f} mm): the axes disagree with one "
            "kinematic chain more than the noise allows."
        )


def _partial_extraction(
    joints: list[JointReport],
    ref: FloatArray,
    base: PlaneFit | None,
    nominal_table: StandardDH | None,
    kwargs: dict[str, Any],
) -> Extraction | None:
    """The rows that only need the identified prefix of the chain (or None)."""
    n = len(joints)
    prefix = 0
    while prefix < n and joints[prefix].ok:
        prefix += 1
    if prefix < 2:
        return None
    pre = joints[:prefix]
    last = pre[-1].fit
    assert last is not None
    return extract_dh(
        [j.axis for j in pre],  # type: ignore[misc]
        [j.type for j in pre],  # type: ignore[misc]
        target=last.center + last.radius * last.basis[0] + 0.1 * last.basis[1],
        reference_pose=ref[:prefix],
        base_plane=base.plane if base is not None else None,
        nominal=None if nominal_table is None else _prefix_table(nominal_table, prefix),
        **kwargs,
    )


def _samples_with_encoders(seg: Segmentation) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Rows of the measurement table with every encoder value (sweeps, coupled moves, still
    poses), their encoder values (m, n) and points (m, 3)."""
    table = seg.table
    Q = table.select([f"q_{i + 1}" for i in range(seg.n_joints)]).to_numpy()
    P = table.select(["x", "y", "z"]).to_numpy()
    ok = np.isfinite(Q).all(axis=1) & np.isfinite(P).all(axis=1)
    rows = np.flatnonzero(ok)
    if rows.size == table.height:
        return rows, Q, P
    return rows, Q[rows], P[rows]


def _identify_whole(
    result: ProcessResult,
    analytic: Extraction | None,
    kwargs: dict[str, Any],
    fit_scales: bool,
    stage: Stage,
) -> None:
    """The maximum-likelihood fit of the whole model, its DH model, covariance and check."""
    seg, joints, ref = result.segmentation, result.joints, result.reference_pose
    notes, base, nominal = result.warnings, result.base, result.nominal
    types = tuple(j.type for j in joints)
    assert result.target is not None and all(t is not None for t in types)
    start = AxisModel(
        tuple(j.axis for j in joints),  # type: ignore[misc]
        types,  # type: ignore[arg-type]
        result.target,
        ref,
        np.ones(len(joints)),
    )
    rows, Q, P = _samples_with_encoders(seg)
    fit_sigmas = [j.fit.sigma**2 for j in joints if j.fit is not None]
    sigma = math.sqrt(np.mean(fit_sigmas)) if fit_sigmas else 1e-5
    stage("identifying", 0.1)
    whole = fit_whole_model(
        start,
        Q,
        P,
        noise=result.noise,
        sigma=sigma,
        fit_scales=fit_scales,
        progress=lambda f: stage("identifying", 0.1 + 0.9 * f),
    )
    nominal_table = nominal.table if nominal is not None else None
    covs = axis_covariances(whole)
    kw = dict(kwargs)
    kw["pair_tolerances"] = tolerances = _pair_tolerances(
        [(c, a.point) for c, a in zip(covs, whole.model.axes, strict=True)],
        nominal,
        kwargs["angle_tol"],
        kwargs["distance_tol"],
        k_data=AIC_SIGMA_2D,
    )
    whole = _with_fixed_relations(whole, tolerances)

    def extract(axes: list[Line], target: FloatArray, plane: Plane | None) -> Extraction:
        return extract_dh(
            axes,
            types,  # type: ignore[arg-type]
            target=target,
            reference_pose=ref,
            base_plane=plane,
            nominal=nominal_table,
            **kw,
        )

    stage("uncertainty", 0.0)
    ex = extract(list(whole.model.axes), whole.model.target, None if base is None else base.plane)
    pairs = _near_parallel_pairs(ex)
    prop = propagate(whole, base, extract, ex, pairs)
    std = np.sqrt(np.clip(np.diag(prop.covariance), 0.0, None))
    result.method = "whole-model maximum likelihood"
    result.extraction, result.analytic, result.whole = ex, analytic, whole
    result.covariance, result.std = prop.covariance, np.where(prop.fixed, np.nan, std)
    result.target, result.sigma = whole.model.target, sigma * math.sqrt(whole.chi2_dof)
    result.fixed = fixed_reasons(
        ex,
        prop.fixed,
        base_plane=base is not None,
        nominal=nominal is not None,
        constrained=whole.constrained,
    )
    result.hayati = _near_parallel(list(ex.axes), ex, result.std, notes)
    result.hayati_std = [
        np.sqrt(np.clip(np.diag(prop.hayati_covariance)[4 * k : 4 * k + 4], 0.0, None))
        for k in range(len(pairs))
    ]
    notes.extend(_correlation_notes(prop.covariance, prop.fixed, len(joints)))
    if result.noise.model != "isotropic" and not 0.5 < whole.chi2_dof < 2.0:
        notes.append(
            f"χ²/dof = {whole.chi2_dof:.2f} under the {result.noise.described} noise model: the "
            "residuals contradict it; the uncertainty is scaled by the residuals."
        )
    stage("validating", 0.0)
    result.validation = _validate_samples(seg, rows, Q, P, ex, whole.inliers)
    gap = _table_gap(whole, ex, Q)
    if gap > 1e-6:
        notes.append(
            f"the DH table departs from the fitted model by up to {gap * 1e3:.4f} mm: a pair "
            "was classified (parallel / meeting) where the fitted axes are not; check the "
            "relations and the FK check."
        )
    _check_residual(result.validation, sigma, notes)


def _with_fixed_relations(
    whole: WholeFit, tolerances: list[tuple[float, float]] | None
) -> WholeFit:
    """The fit constrained to the pair relations the data cannot reject: consecutive revolute
    axes within their tolerance of parallel are made parallel (collinear: the same line), so
    that the DH conventions of those pairs hold exactly and the table equals the model."""
    if tolerances is None:
        return whole
    axes, types = whole.model.axes, whole.model.types
    parallel, collinear = [], []
    for i, (a_tol, d_tol) in enumerate(tolerances):
        if JointType.PRISMATIC in (types[i], types[i + 1]):
            continue
        kind = classify_lines(axes[i], axes[i + 1], angle_tol=a_tol, distance_tol=d_tol).kind
        if kind is RelationKind.COLLINEAR:
            collinear.append(i)
        elif kind.is_parallel:
            parallel.append(i)
    return constrain_pairs(whole, parallel, collinear)


def _table_gap(whole: WholeFit, ex: Extraction, Q: FloatArray) -> float:
    """Largest distance (m) between the fitted model and its DH table at the reference pose and
    at up to 64 of the sampled joint vectors: 0 up to rounding when the extraction is exact."""
    from dhlog.identify.whole import predict

    pick = np.unique(np.linspace(0, Q.shape[0] - 1, min(64, Q.shape[0])).astype(int))
    Qs = np.vstack([whole.model.reference_pose, Q[pick]])
    fitted, _ = predict(whole.model, Qs)
    table = fk_points_chunked(ex.standard, Qs, ex.tool_point, T_base=ex.T_measurement_base)
    return float(np.max(np.linalg.norm(fitted - table, axis=1)))


def _near_parallel_pairs(ex: Extraction) -> list[tuple[int, int]]:
    out = []
    for rel in ex.relations:
        angle = min(rel.relation.angle, math.pi - rel.relation.angle)
        if angle < NEAR_PARALLEL:
            out.append(rel.joints)
    return out


def _correlation_notes(cov: FloatArray, fixed: NDArray[np.bool_], n: int) -> list[str]:
    """One warning naming the free parameter pairs correlated beyond ``CORRELATION_WARNING``."""
    free = np.flatnonzero(~fixed)
    sd = np.sqrt(np.diag(cov)[free])
    ok = sd > 0
    free, sd = free[ok], sd[ok]
    corr = cov[np.ix_(free, free)] / np.outer(sd, sd)
    names = state_names(n)
    iu = np.triu_indices(free.size, 1)
    strong = np.abs(corr[iu]) > CORRELATION_WARNING
    if not np.any(strong):
        return []
    order = np.argsort(-np.abs(corr[iu][strong]))
    pairs = [
        f"{names[free[iu[0][strong][k]]]}–{names[free[iu[1][strong][k]]]} "
        f"{corr[iu][strong][k]:+.3f}"
        for k in order[:4]
    ]
    more = int(np.count_nonzero(strong)) - len(pairs)
    return [
        f"{int(np.count_nonzero(strong))} parameter pair(s) correlated beyond "
        f"{CORRELATION_WARNING}: {', '.join(pairs)}"
        + (f" and {more} more" if more > 0 else "")
        + " (full covariance in the JSON)."
    ]


def _validate_samples(
    seg: Segmentation,
    rows: NDArray[np.int64],
    Q: FloatArray,
    P: FloatArray,
    ex: Extraction,
    inliers: NDArray[np.bool_],
) -> Validation:
    """FK of the DH result at every sample with encoder values against the sample (per joint by
    the sweep it belongs to; coupled moves and still poses under joint 0)."""
    pred = fk_points_chunked(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    r = np.sqrt(np.sum((pred - P) ** 2, axis=1))
    residuals = np.full(seg.table.height, np.nan)
    residuals[rows[inliers]] = r[inliers]
    labels = seg.table["joint"].fill_null(0).to_numpy()[rows]
    per_joint: dict[int, tuple[float, float, int]] = {}
    for k in np.unique(labels[inliers]):
        rk = r[inliers & (labels == k)]
        per_joint[int(k)] = (float(np.sqrt(np.mean(rk**2))), float(rk.max()), int(rk.size))
    used = r[inliers]
    return Validation(
        residuals=residuals,
        per_joint=per_joint,
        rms=float(np.sqrt(np.mean(used**2))) if used.size else float("nan"),
        max=float(used.max()) if used.size else float("nan"),
        n_points=int(used.size),
    )


#: 2D 99.73 % radius (the "3σ" of a two-dimensional tilt or offset): sqrt(χ²₂(0.9973)).
THREE_SIGMA_2D = 3.44
#: With a nominal that says parallel (or meeting), the data must exceed this many σ to overrule it
#: (the analytic method).
NOMINAL_SIGMA_2D = 5.0
#: Without a nominal, the whole-model fit holds a pair parallel (collinear) only where that
#: costs less than it gains: Akaike's rule for the two (four) parameters the relation removes, a
#: Wald statistic below 2 per parameter, i.e. a 2-D tilt (offset) within 2σ. A wider band
#: (3.44σ) was measured to cost 1.20x the achievable FK error on a KR5 0.05° off its nominal swept
#: over 30° arcs. A nominal that says parallel keeps its 5σ (the user's design knowledge).
AIC_SIGMA_2D = 2.0
#: Axes closer than this to parallel (rad) also get Hayati–Mirmirani parameters; no pair
#: further from parallel is ever classified parallel, however uncertain its axes.
NEAR_PARALLEL = 0.01
#: No pair of axes further apart than this (m) is ever classified as meeting.
MAX_MEETING_DISTANCE = 1e-3


def _pair_tolerances(
    axes: list[tuple[FloatArray, FloatArray]] | None,
    nominal: DHModel | None,
    angle_floor: float,
    distance_floor: float,
    *,
    k_data: float = THREE_SIGMA_2D,
    k_nominal: float = NOMINAL_SIGMA_2D,
) -> list[tuple[float, float]] | None:
    """Per consecutive pair, the angle (rad) and distance (m) below which the data cannot tell
    the axes from parallel / meeting: 3σ (2D: 3.44σ) of the difference of the two axes, from
    their covariances (``axes``: per axis the 4×4 covariance of ``[δe·u, δe·v, δc·u, δc·v]``
    and the point ``c`` it refers to; 5σ when the nominal says parallel / meeting).
    ``angle_floor`` and ``distance_floor`` apply only when an axis has no covariance (never
    below 1e-7)."""
    if axes is None:
        return None
    out = []
    for i in range(len(axes) - 1):
        (c1, p1), (c2, p2) = axes[i], axes[i + 1]
        var_dir = (np.trace(c1[:2, :2]) + np.trace(c2[:2, :2])) / 2
        lever = float(np.linalg.norm(p1 - p2))
        var_pos = (np.trace(c1[2:, 2:]) + np.trace(c2[2:, 2:])) / 2 + var_dir * lever**2
        k_angle = k_dist = k_data
        if nominal is not None:
            if abs(math.sin(nominal.table.alpha[i])) < 1e-9:
                k_angle = k_nominal
            if abs(nominal.table.a[i]) < 1e-12:
                k_dist = k_nominal
        angle = k_angle * math.sqrt(var_dir) if var_dir > 0 else angle_floor
        distance = k_dist * math.sqrt(var_pos) if var_pos > 0 else distance_floor
        # never a convention for a relation far beyond any real robot's tolerance
        angle, distance = min(angle, NEAR_PARALLEL), min(distance, MAX_MEETING_DISTANCE)
        out.append((max(angle, 1e-7), max(distance, 1e-7)))
    return out


def _near_parallel(
    axes: list[Line | None], ex: Extraction, std: FloatArray | None, notes: list[str]
) -> list[HayatiRow]:
    """Hayati–Mirmirani rows for nearly parallel pairs, and a warning where d is ill-conditioned."""
    rows = []
    for rel in ex.relations:
        i, k = rel.joints
        angle = min(rel.relation.angle, math.pi - rel.relation.angle)
        if angle >= NEAR_PARALLEL:
            continue
        axis = axes[k - 1]
        assert axis is not None
        try:
            rows.append(hayati_parameters(ex.frames[i - 1], axis, (i, k)))
        except DhlogError:
            continue
        if not rel.relation.kind.is_parallel:
            d, sd = (
                ex.standard.d_offset[i - 1],
                float("nan") if std is None else std[4 * (i - 1) + 1],
            )
            notes.append(
                f"joints {i} and {k} are nearly parallel ({math.degrees(angle):.4f}°, beyond what "
                f"the noise explains): d{i} = {d * 1e3:.1f} mm ± {sd * 1e3:.1f} mm is "
                "ill-conditioned; the Hayati–Mirmirani parameters (β in place of d) are in the "
                "result."
            )
    return rows


def _prefix_table(table: StandardDH, k: int) -> StandardDH:
    return StandardDH(
        table.joint_types[:k],
        table.theta_offset[:k],
        table.d_offset[:k],
        table.a[:k],
        table.alpha[:k],
    )


# ---- the result document --------------------------------------------------------------------


def _fit_doc(j: JointReport, t_ns: NDArray[np.int64]) -> dict[str, Any] | None:
    f = j.fit
    if f is None:
        return None
    return {
        "method": f.method,
        "n_points": int(f.n_points),
        "n_outliers": j.n_outliers,
        "rms": float(f.rms),
        "sweep": float(f.sweep),
        "radius": float(f.radius),
        "sigma": float(f.sigma),
        "segments": j.segments,
        "outliers_t_ns": [int(t) for t in t_ns[j.rows[~j.inliers]]],
        "axis_std": {"direction": f.direction_std, "position": f.position_std},
        **({"encoder_scale": f.encoder_scale} if f.encoder_scale is not None else {}),
    }


def result_document(result: ProcessResult) -> dict[str, Any]:
    """The ``<stem>.dh.json`` document (the result contract, ``dhlog.result/1``)."""
    ex = result.extraction
    n_rows = 0 if ex is None else (ex.standard.n if result.complete else ex.standard.n - 1)
    std = result.std
    rows: list[dict[str, Any]] = []
    mod_rows: list[dict[str, Any]] = []
    relations: list[dict[str, Any]] = []
    if ex is not None:
        rows, mod_rows = dh_documents(ex.standard, ex.reference_pose, std, n_rows)
        relations = relation_documents(ex.relations)
    val = result.validation
    per_joint = {} if val is None else val.per_joint
    t_ns = result.segmentation.table["t_ns"].to_numpy()
    doc: dict[str, Any] = {
        "format": RESULT_FORMAT,
        "dhlog_version": __version__,
        "source": {
            "path": Path(result.path).name,
            "sha256": result.sha256,
            "pipeline": result.log.pipeline.name,
        },
        "units": {"length": "m", "angle": "rad"},
        "reference_pose": [float(v) for v in result.reference_pose],
        "joints": [
            {
                "index": j.index,
                "name": j.name,
                "type": j.type.value if j.type else None,
                "axis": None
                if j.axis is None
                else {"point": j.axis.point.tolist(), "direction": j.axis.direction.tolist()},
                "fit": _fit_doc(j, t_ns),
                **(
                    {
                        "validation": {
                            "fk_rms": per_joint[j.index][0],
                            "fk_max": per_joint[j.index][1],
                            "n_points": per_joint[j.index][2],
                        }
                    }
                    if j.index in per_joint
                    else {}
                ),
                **({"error": j.reason} if j.reason else {}),
            }
            for j in result.joints
        ],
        "standard_dh": rows,
        "modified_dh": mod_rows,
        "relations": relations,
        "base": {"T_measurement_base": None if ex is None else ex.T_measurement_base.tolist()},
        "tool": {"point": None if (ex is None or not result.complete) else ex.tool_point.tolist()},
        "validation": {
            "fk_rms": None if val is None else val.rms,
            "fk_max": None if val is None else val.max,
            "n_points": 0 if val is None else val.n_points,
        },
        "warnings": list(result.warnings),
    }
    if ex is not None and result.complete:
        doc["modified_dh_tool"] = {"T_n_tool": ex.T_modified_tool.tolist()}
        if std is not None:
            n = ex.standard.n
            doc["tool"]["std"] = [_num_or_none(v) for v in std[4 * n : 4 * n + 3]]
            doc["base"]["std"] = {
                "translation": [_num_or_none(v) for v in std[4 * n + 3 : 4 * n + 6]],
                "rotation": [_num_or_none(v) for v in std[4 * n + 6 : 4 * n + 9]],
            }
        _mark_fixed(doc, result)
        doc["method"] = result.method
        if result.covariance is not None:
            doc["covariance"] = _covariance_document(result)
        if result.analytic is not None and result.std is not None:
            doc["analytic"] = _analytic_document(result)
        doc["noise"] = _noise_document(result)
        if result.whole is not None:
            doc["whole_fit"] = _whole_fit_document(result)
    if result.hayati:
        q = result.reference_pose
        doc["hayati"] = []
        for k, h in enumerate(result.hayati):
            row: dict[str, Any] = {
                "joints": list(h.joints),
                "theta": h.theta,
                "theta_offset": h.theta - float(q[h.joints[0] - 1])
                if result.joints[h.joints[0] - 1].type is JointType.REVOLUTE
                else h.theta,
                "a": h.a,
                "alpha": h.alpha,
                "beta": h.beta,
            }
            if k < len(result.hayati_std):
                sd = result.hayati_std[k]
                row["std"] = dict(zip(("theta", "a", "alpha", "beta"), map(float, sd), strict=True))
            doc["hayati"].append(row)
    if result.base is not None:
        doc["base"]["plane"] = {
            "point": result.base.plane.point.tolist(),
            "normal": result.base.plane.normal.tolist(),
            "rms": result.base.rms,
            "n_points": int(result.base.residuals.size),
        }
    doc["segmentation"] = {
        "segments": result.segmentation.segments.height,
        "set_aside": dict(result.segmentation.set_aside),
    }
    return doc


def _num_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _mark_fixed(doc: dict[str, Any], result: ProcessResult) -> None:
    """``fixed`` / ``fixed_reason`` on each DH row, on the tool and on the base."""
    names = ("theta", "d", "a", "alpha")
    n = len(doc["standard_dh"])
    for i, row in enumerate(doc["standard_dh"]):
        held = [(names[p], result.fixed[4 * i + p]) for p in range(4) if 4 * i + p in result.fixed]
        if held:
            row["fixed"] = [name for name, _ in held]
            row["fixed_reason"] = "; ".join(dict.fromkeys(f"{name}: {why}" for name, why in held))
    tool = [("xyz"[p], result.fixed[4 * n + p]) for p in range(3) if 4 * n + p in result.fixed]
    if tool:
        doc["tool"]["fixed"] = [c for c, _ in tool]
        doc["tool"]["fixed_reason"] = tool[0][1]


def _covariance_document(result: ProcessResult) -> dict[str, Any]:
    """The covariance of every free parameter (names as :func:`state_names`, SI units)."""
    cov = result.covariance
    assert cov is not None
    n = len(result.joints)
    free = [k for k in range(4 * n + 9) if k not in result.fixed]
    names = state_names(n)
    return {
        "parameters": [names[k] for k in free],
        "matrix": [[float(cov[a, b]) for b in free] for a in free],
    }


def _analytic_document(result: ProcessResult) -> dict[str, Any]:
    """The seed method's table (the start of the whole-model fit) and its distance from the
    result in the result's σ."""
    an, ex, std = result.analytic, result.extraction, result.std
    assert an is not None and ex is not None and std is not None
    rows, _ = dh_documents(an.standard, an.reference_pose)
    for row in rows:
        del row["std"]
    R0 = ex.T_measurement_base[:3, :3]
    diff = state_vector(an, R0) - state_vector(ex, R0)
    n = ex.standard.n
    ang = np.zeros(diff.size, dtype=bool)
    ang[: 4 * n] = np.tile([True, False, False, True], n)
    diff[ang] = [wrap_angle(d) for d in diff[ang]]
    ratio = np.where(np.isfinite(std) & (std > 0), np.abs(diff) / np.where(std > 0, std, 1), 0)
    worst = int(np.argmax(ratio))
    return {
        "standard_dh": rows,
        "max_deviation_sigma": float(ratio[worst]),
        "max_deviation_parameter": state_names(n)[worst],
    }


def _noise_document(result: ProcessResult) -> dict[str, Any]:
    doc: dict[str, Any] = {"model": result.noise.model, **result.noise.document()}
    if result.whole is not None:
        doc["chi2_dof"] = result.whole.chi2_dof
        if result.noise.model == "isotropic":
            doc["sigma"] = result.sigma
            doc["sigma_source"] = "estimated from the residuals"
    else:
        fits = [j.fit.sigma for j in result.joints if j.fit is not None]
        doc["sigma"] = float(math.sqrt(np.mean(np.square(fits)))) if fits else None
        doc["sigma_source"] = "the per-joint fits' residuals"
    return doc


def _whole_fit_document(result: ProcessResult) -> dict[str, Any]:
    w = result.whole
    assert w is not None
    doc: dict[str, Any] = {
        "n_points": w.n_points,
        "n_outliers": int(np.count_nonzero(~w.inliers)),
        "iterations": w.iterations,
        "rms": w.rms,
    }
    if w.layout.scale_at is not None:
        k = w.layout.scale_at
        n = w.model.n
        doc["encoder_scales"] = {
            "value": [float(v) for v in w.model.scales],
            "std": [float(math.sqrt(max(w.covariance[k + i, k + i], 0.0))) for i in range(n)],
        }
    return doc


def display_scales(units: str) -> tuple[float, float, str, str]:
    """Factors and unit names for display: ``mm`` → (1e3, 180/π, "mm", "deg"), ``m`` → SI."""
    if units == "m":
        return 1.0, 1.0, "m", "rad"
    return 1e3, 180.0 / math.pi, "mm", "deg"


def display_rows(
    result: ProcessResult, units: str = "mm"
) -> list[tuple[str, list[float], list[float | None], list[bool]]]:
    """Per standard-DH row: its type, ``θ_offset, d_offset, a, α``, their σ (None when fixed)
    in display units (``display_scales``), and which of the four are held fixed."""
    length, angle, _, _ = display_scales(units)
    factors = [angle, length, length, angle]
    out = []
    for row in result_document(result)["standard_dh"]:
        s = row["std"]
        values = [row["theta_offset"], row["d_offset"], row["a"], row["alpha"]]
        stds = [s["theta"], s["d"], s["a"], s["alpha"]]
        held = row.get("fixed", [])
        out.append(
            (
                row["type"],
                [v * f for v, f in zip(values, factors, strict=True)],
                [None if v is None else v * f for v, f in zip(stds, factors, strict=True)],
                [name in held for name in ("theta", "d", "a", "alpha")],
            )
        )
    return out


def result_csv(result: ProcessResult, *, units: str = "mm") -> str:
    """The standard DH table as CSV, in mm and degrees (or m and rad), with ±1σ columns; a
    parameter held by a convention has ``fixed`` in its σ column."""
    _, _, lu, au = display_scales(units)
    lines = [
        f"joint,name,type,theta_offset_{au},d_{lu},a_{lu},alpha_{au},"
        f"std_theta_{au},std_d_{lu},std_a_{lu},std_alpha_{au}"
    ]
    for i, (kind, values, stds, held) in enumerate(display_rows(result, units)):
        cells = [str(i + 1), _csv_cell(result.joints[i].name), kind]
        cells += [f"{v:.9g}" for v in values]
        cells += [
            "fixed" if h else ("" if v is None else f"{v:.3g}")
            for v, h in zip(stds, held, strict=True)
        ]
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def _csv_cell(text: str) -> str:
    if any(c in text for c in ',"\n'):
        return '"' + text.replace('"', '""') + '"'
    return text


def nominal_difference(result: ProcessResult) -> FloatArray | None:
    """measured − nominal per row (n, 4) in SI units, angles wrapped; None without nominal."""
    if result.nominal is None or result.extraction is None:
        return None
    t, nom = result.extraction.standard, result.nominal.table
    n = t.n if result.complete else t.n - 1
    diff = np.zeros((n, 4))
    for i in range(n):
        diff[i] = [
            wrap_angle(t.theta_offset[i] - nom.theta_offset[i]),
            t.d_offset[i] - nom.d_offset[i],
            t.a[i] - nom.a[i],
            wrap_angle(t.alpha[i] - nom.alpha[i]),
        ]
    return diff
