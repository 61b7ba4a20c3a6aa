"""``dhlog process``: from a calibration log to the DH model, its uncertainty and its check.

read (``io.reader``) → segment (``segment``) → per joint: pick the sweeps, decide the type, fit
the axis robustly, bring it to the reference pose (``identify.sweeps``) → the analytic start:
line geometry on those axes (``identify.analytic``, seed 000) → the maximum-likelihood fit of the
whole model to every sample with encoder values (``identify.whole``), pairs the data cannot tell
from parallel held parallel → the DH model read off the fitted axes, its covariance and what is
fixed by convention (``identify.propagate``) → forward kinematics of the table against every
sample (``validate``). The result document is ``result``.

``--analytic-only`` (and a log without encoders) stops at the analytic start, with its own
propagated covariance. When some joints cannot be identified, what was identified is kept: their
fits and axes, and the DH rows that only need identified axes; the joints at fault are named with
the reason — unless a nominal is given and the other samples (coupled moves) determine them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError, DhlogError, GeometryError, InputError
from dhlog.geometry._checks import FloatArray, nearest_rotation
from dhlog.geometry.fitting import PlaneFit, fit_plane
from dhlog.geometry.lines import ANGLE_TOL, DISTANCE_TOL, Line, Plane, RelationKind, classify_lines
from dhlog.identify.analytic import (
    AIC_SIGMA_2D,
    hayati_rows,
    near_parallel,
    pair_tolerances,
    partial_extraction,
    propagate_analytic,
)
from dhlog.identify.axismodel import AxisModel
from dhlog.identify.extract import (
    NEAR_PARALLEL,
    Extraction,
    HayatiRow,
    extract_dh,
    hayati_table,
    table_in_hayati_form,
)
from dhlog.identify.holdout import Holdout, cross_validate, score_poses
from dhlog.identify.prediction import predict
from dhlog.identify.propagate import (
    NOT_DETERMINED,
    fixed_reasons,
    propagate,
    state_names,
)
from dhlog.identify.register import Registration
from dhlog.identify.relations import axis_covariances, constrain_pairs, relative_tilt_variances
from dhlog.identify.segment import Segmentation, segment_log
from dhlog.identify.select import (
    AUTO,
    SELECT_FOLDS,
    ModelRequest,
    Selection,
    default_gravity,
    select_model,
    selected_terms,
    term_std,
    terms_for,
)
from dhlog.identify.start import (
    NEVER_MOVED,
    Known,
    Start,
    never_moved,
    start_from_neighbours,
    start_from_nominal,
)
from dhlog.identify.sweeps import (
    JointReport,
    TargetAtReference,
    fit_joint,
    samples_with_encoders,
    target_labels,
)
from dhlog.identify.timing import (
    JointRates,
    SweepPhase,
    Timing,
    phase_lag,
    rejoin,
    sweep_phases,
)
from dhlog.identify.validate import (
    Validation,
    check_residual,
    table_gap,
    validate_samples,
    validate_sweeps,
)
from dhlog.identify.variance import (
    Whiten,
    design_effect,
    refit_with_model_error,
    whitened_residuals,
)
from dhlog.identify.whole import CHI3_MEDIAN, WholeFit, fit_whole_model
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import Pipeline
from dhlog.io.reader import LogData, read_log
from dhlog.io.writer import sha256_of
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_frames, fk_points_chunked
from dhlog.model.noise import NoiseModel
from dhlog.model.screws import motions_back, points_at_reference
from dhlog.model.terms import Lump, Terms, table_deflection, to_table

#: Largest number of samples per joint the per-joint fits (the whole-model fit's start) use.
START_FIT_POINTS = 4000


#: Largest number of samples the target at the reference pose is averaged over for the start.
START_TARGET_POINTS = 20000


#: Correlations beyond this between free parameters are reported.
CORRELATION_WARNING = 0.95


@dataclass(frozen=True, eq=False)
class Conditioned:
    """The result's table with the rows of nearly parallel pairs in the Hayati–Mirmirani form
    (a :class:`HayatiDH`: β in place of the ill-conditioned d, same forward kinematics), each
    entry's σ (NaN where fixed, per row θ, d or β, a, α), why fixed entries are held, and the
    nominal in the same form (None without a nominal, or when it has no such form)."""

    table: StandardDH
    std: FloatArray
    fixed: dict[int, str]
    nominal: StandardDH | None


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
    extra_tool_points: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    extra_tool_std: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    tool_orientation: FloatArray | None = None
    tool_orientation_std: FloatArray | None = None
    conditioned: Conditioned | None = None
    timing: Timing | None = None
    #: the nominal placed on the points (sessions without sweeps: the fit's start)
    registration: Registration | None = None
    #: errors at poses not used to fit: K-fold cross-validation, held-out logs
    holdout: list[Holdout] = field(default_factory=list)
    #: K of the K-fold cross-validation asked for (0: none)
    folds: int = 0
    #: the terms beyond the geometry asked for, the candidates tried, and the chosen terms in
    #: the table's frames (:func:`dhlog.model.terms.to_table`) with their σ
    model_request: ModelRequest = field(default_factory=ModelRequest)
    selection: Selection | None = None
    terms: Terms | None = None
    terms_std: FloatArray = field(default_factory=lambda: np.zeros(0))
    #: the terms' largest deflection per joint (rad or m) and of the target (m) at the samples
    deflection_max: FloatArray = field(default_factory=lambda: np.zeros(0))
    deflection_target: float = 0.0
    #: up to 2000 samples: the target where the model puts it and the terms' share of that
    #: (k, 6: position, displacement; m, in M)
    deflection_vectors: FloatArray = field(default_factory=lambda: np.zeros((0, 6)))
    #: what a reader should know but need not act on (the method chosen, forms shown); the
    #: ``warnings`` are for what may need action
    info: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        """True when every joint was identified."""
        return all(j.ok for j in self.joints)

    @property
    def failed(self) -> list[JointReport]:
        """The joints that could not be identified."""
        return [j for j in self.joints if not j.ok]


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
    holdout: int = 0,
    validate: list[str | Path] | None = None,
    model: ModelRequest = AUTO,
    progress: Stage | None = None,
) -> ProcessResult:
    """Run the whole identification on the log at ``path`` (see the module docstring).

    ``holdout`` K > 1: K-fold cross-validation over the session's poses; ``validate``: further
    logs (other sessions of the same robot) whose poses score the result, each placed on its
    own when the tracker moved (:mod:`dhlog.identify.holdout`). ``progress(stage, fraction)``
    is called as each stage advances."""
    log = read_log(
        path,
        pipeline,
        fast=fast,
        progress=None if progress is None else (lambda f: progress("reading", f)),
    )
    result = process_data(
        log,
        sha256=sha256_of(path),  # 0.03 s for a 55 MB log
        nominal=nominal,
        reference_pose=reference_pose,
        fit_method=fit_method,
        angle_tol=angle_tol,
        distance_tol=distance_tol,
        analytic_only=analytic_only,
        fit_scales=fit_scales,
        holdout=holdout,
        model=model,
        progress=progress,
    )
    for other in validate or []:
        _validate_log(result, other, pipeline, fast)  # each log's own pipeline unless named
    return result


def _validate_log(
    result: ProcessResult, path: str | Path, pipeline: Pipeline | None, fast: bool
) -> None:
    """Score ``result`` at the poses of the log at ``path`` (``--validate``)."""
    ex = result.extraction
    if ex is None or not result.complete:
        result.warnings.append(f"{path}: not scored: the result is not complete.")
        return
    log = read_log(path, pipeline, fast=fast)
    seg = segment_log(log, joint_types=list(ex.standard.joint_types))
    if seg.n_joints != ex.standard.n or not seg.has_encoders:
        raise InputError(
            f"{path}: has {seg.n_joints} joints{'' if seg.has_encoders else ' and no encoders'}; "
            f"--validate needs a log of the same robot ({ex.standard.n} joints) with encoder "
            "values."
        )
    rows, Q, P = samples_with_encoders(seg)
    which = target_labels(seg, rows)
    if which is not None:
        Q, P = Q[which == 0], P[which == 0]
    nominal = result.nominal
    result.holdout.append(
        score_poses(
            (ex.standard, ex.T_measurement_base, ex.tool_point),
            Q,
            P,
            path=str(path),
            nominal=None
            if nominal is None
            else (nominal.table, nominal.T_base, nominal.tool_point),
            table_values=table_values(result, Q),
        )
    )


def table_values(result: ProcessResult, Q: FloatArray, *, deflected: bool = True) -> FloatArray:
    """The result table's joint values at encoder values ``Q`` (m, n): ``ref + s (Q − ref)``
    with fitted encoder scales, deflected by the terms beyond the geometry when chosen (and
    ``deflected``)."""
    whole, ex = result.whole, result.extraction
    Qt = Q
    if whole is not None and whole.layout.scale_at is not None:
        ref = whole.model.reference_pose
        Qt = ref + whole.model.scales * (Q - ref)
    if deflected and result.terms is not None and ex is not None:
        Qt = Qt + table_deflection(ex.standard, result.terms, Q, Qt)
    return np.asarray(Qt, dtype=np.float64)


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
    parallel_sigma: float = AIC_SIGMA_2D,
    holdout: int = 0,
    model: ModelRequest = AUTO,
    progress: Stage | None = None,
    known_noise: float | None = None,
) -> ProcessResult:
    """The identification of :func:`process_log` on streams already decoded (``LogData``).

    Default: the maximum-likelihood fit of the whole model to every sample with encoder
    values, started from the analytic result (per-joint fits + line geometry). With
    ``analytic_only`` (or without encoders), the analytic result with its propagated covariance.
    ``parallel_sigma``: pairs within this many σ (2-D) of parallel are held parallel in the
    whole-model fit, whatever the nominal says (0: never). ``holdout`` K > 1: K-fold
    cross-validation of the whole-model fit over the session's poses (``result.holdout``).
    ``model``: the terms beyond the geometry to try or force (:mod:`dhlog.identify.select`).
    ``known_noise``: the tracker's σ (m) where it is known rather than measured (a plan): the
    base plane's covariance from it.
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
    info: list[str] = []
    phases = sweep_phases(seg, log) if seg.has_encoders else []
    _check_units(seg, log, phases, notes)
    seg, timing = _clock_start(seg, log, info, phases)
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
        info.append(
            "no encoders: the reference pose is the pose every sweep starts from (all zeros), "
            "and the sense of motion comes from time order."
        )
    whole_wanted = seg.has_encoders and not analytic_only
    max_points = START_FIT_POINTS if whole_wanted else None
    joints = [JointReport(k + 1, seg.joint_names[k]) for k in range(n)]
    for report in joints:
        stage("fitting", (report.index - 1) / n)
        fit_joint(report, seg, log, ref, joints, nominal, fit_method, notes, max_points)
    unidentified = [
        f"joint {report.index} ({report.name}) was not identified: {report.reason}."
        for report in joints
        if report.reason
    ]
    _check_fit_noise(joints, notes)
    base = None
    if log.base is not None and log.base.height >= 3:
        try:
            base = fit_plane(
                log.base.select(["x", "y", "z"]).to_numpy(),
                what=f"{name}: base plane",
                sigma=known_noise,
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
        info=info,
        timing=timing,
        noise=log.pipeline.noise,
        folds=holdout,
        model_request=model,
    )
    kwargs: dict[str, Any] = {
        "angle_tol": angle_tol,
        "distance_tol": distance_tol,
        "pair_tolerances": pair_tolerances(
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
        if whole_wanted and nominal is None and _from_the_neighbours(result, kwargs, stage):
            return result
        notes.extend(unidentified)
        if whole_wanted and nominal is None:
            notes.append(
                "the joints not swept alone need a start: pass --nominal (a library robot or "
                "the robot's DH file) and the whole-model fit identifies them from the other "
                "samples (random static poses, coupled moves)."
            )
        result.extraction = partial_extraction(joints, ref, base, nominal_table, kwargs)
        return result
    stage("identifying", 0.0)
    target_at = TargetAtReference(seg, joints, ref, START_TARGET_POINTS if whole_wanted else None)
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
            _identify_whole(result, analytic, kwargs, fit_scales, stage, parallel_sigma)
            return result
        except (GeometryError, np.linalg.LinAlgError) as exc:
            result.whole, result.analytic, result.method = None, None, "analytic"
            notes.append(f"the whole-model fit failed ({exc}); the result is the analytic one.")
    elif seg.has_encoders:
        info.append("--analytic-only: the seed method's result (per-joint fits, line geometry).")
    else:
        info.append(
            "no encoder values: the whole-model fit needs them; the result is the analytic one."
        )

    # the covariance perturbs every axis: the target's derivative is taken on an evenly strided
    # subset of the samples (the mean's derivative; the target itself is from every sample)
    perturbed = (
        target_at if whole_wanted else TargetAtReference(seg, joints, ref, START_TARGET_POINTS)
    )

    def target_of(axes: list[Line | None]) -> FloatArray:
        return perturbed(axes)[0]

    stage("uncertainty", 0.0)
    rows = hayati_rows(analytic)
    nominal_rows = _nominal_rows(nominal_table, ref, rows)
    covariance, mixed_cov = propagate_analytic(
        joints,
        ref,
        target,
        target_cov,
        base,
        nominal_table,
        kwargs,
        analytic,
        target_of if seg.has_encoders else None,
        rows,
        nominal_rows,
    )
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    fixed = std < 1e-12
    result.extraction, result.covariance = analytic, covariance
    result.fixed = fixed_reasons(
        analytic, fixed, base_plane=base is not None, nominal=nominal is not None
    )
    result.std = np.where(fixed, np.nan, std)
    result.hayati = near_parallel([j.axis for j in joints], analytic, result.std, result.info)
    if mixed_cov is not None:
        mixed_std = np.sqrt(np.clip(np.diag(mixed_cov), 0.0, None))
        result.conditioned = _conditioned(
            result, analytic, rows, nominal_rows, mixed_std, mixed_std < 1e-12
        )
    stage("validating", 0.0)
    result.validation = validate_sweeps(seg, joints, analytic)
    if result.validation is not None:
        sigma = math.sqrt(np.mean([j.fit.sigma**2 for j in joints if j.fit is not None]))
        check_residual(result.validation, sigma, notes)
    else:
        notes.append("no encoder values: FK of the result cannot be checked sample by sample.")
    return result


def _known(result: ProcessResult) -> list[Known]:
    return [Known(j.index - 1, j.type, j.axis if j.ok else None) for j in result.joints]


def _from_the_nominal(result: ProcessResult, kwargs: dict[str, Any], stage: Stage) -> bool:
    """Joints never moved alone, identified by the whole-model fit from every other sample
    (coupled moves, random static poses, stops), started from the nominal
    (:func:`~dhlog.identify.start.start_from_nominal`). Returns False (and changes nothing)
    when a joint never moved, or the data do not determine them."""
    nominal = result.nominal
    assert nominal is not None
    rows, Q, P = samples_with_encoders(result.segmentation)
    if rows.size == 0 or _any_never_moved(result, Q):
        return False
    which = target_labels(result.segmentation, rows)
    primary = slice(None) if which is None else which == 0
    try:
        start = start_from_nominal(
            _known(result),
            Q[primary],
            P[primary],
            result.reference_pose,
            nominal.table,
            T_base=nominal.T_base,
            tool_point=nominal.tool_point,
        )
    except GeometryError as exc:
        result.warnings.append(f"the nominal could not be placed on the points: {exc}")
        return False
    reg = start.registration
    if reg is not None:
        result.registration = reg
        result.info.append(
            f"no joint was swept alone: the nominal was placed on the points (tracker → base "
            f"by a robust registration; the nominal's RMS there {reg.rms * 1e3:.4f} mm over "
            f"{int(np.count_nonzero(reg.inliers))} samples) and every joint identified by the "
            "whole-model fit from there."
        )
    missing = [j for j in result.joints if not j.ok]
    if not _fit_from(result, start, kwargs, stage, "the nominal"):
        result.registration = None
        return False
    if reg is None:
        names = ", ".join(f"joint {j.index} ({j.name})" for j in missing)
        result.warnings.append(
            f"{names}: never moved alone; identified by the whole-model fit from the other "
            "samples (coupled moves, still poses), started from the nominal."
        )
    return True


def _from_the_neighbours(result: ProcessResult, kwargs: dict[str, Any], stage: Stage) -> bool:
    """Without a nominal: joints moved only together with a parallel neighbour, started from
    the circle that move traces (:func:`~dhlog.identify.start.start_from_neighbours`) and
    identified by the whole-model fit. Returns False (and changes nothing) when one of them
    has no such start or the fit fails."""
    rows, Q, P = samples_with_encoders(result.segmentation)
    if rows.size == 0 or _any_never_moved(result, Q):
        return False
    which = target_labels(result.segmentation, rows)
    primary = slice(None) if which is None else which == 0
    start = start_from_neighbours(_known(result), Q[primary], P[primary], result.reference_pose)
    if start is None:
        return False
    missing = [j for j in result.joints if not j.ok]
    if not _fit_from(result, start, kwargs, stage, "the coupled moves"):
        return False
    names = ", ".join(f"joint {j.index} ({j.name})" for j in missing)
    result.warnings.append(
        f"{names}: never moved alone; started from the circle its coupled move with a parallel "
        "neighbour traces, and identified by the whole-model fit from every sample."
    )
    return True


def _any_never_moved(result: ProcessResult, Q: FloatArray) -> bool:
    """Warn about (and return True for) a joint not identified whose encoder never moved."""
    still = never_moved(Q, [j.index - 1 for j in result.joints if not j.ok])
    if still:
        names = ", ".join(f"joint {k + 1} ({result.joints[k].name})" for k in still)
        result.warnings.append(
            f"{names}: never moved in this log (its encoder values span less than "
            f"{NEVER_MOVED:g}): nothing in the samples measures it."
        )
    return bool(still)


def _fit_from(
    result: ProcessResult, start: Start, kwargs: dict[str, Any], stage: Stage, what: str
) -> bool:
    """The whole-model fit from ``start``: the joints it starts take its axes and types; on
    failure they are put back as they were, the failure is a warning, and False returned."""
    started = [result.joints[k] for k in start.sources]
    saved = [(j.type, j.axis, j.reason, j.type_source) for j in started]
    for j in started:
        k = j.index - 1
        j.type, j.axis, j.reason, j.type_source = (
            start.types[k],
            start.axes[k],
            None,
            start.sources[k],
        )
    result.target = start.target
    try:
        _identify_whole(result, None, kwargs, False, stage)
    except (GeometryError, np.linalg.LinAlgError) as exc:
        result.whole, result.method, result.target = None, "analytic", None
        for j, (jt, axis, reason, source) in zip(started, saved, strict=True):
            j.type, j.axis, j.reason, j.type_source = jt, axis, reason, source
        result.warnings.append(f"the whole-model fit from {what} failed: {exc}")
        return False
    assert result.whole is not None
    for j in started:
        j.axis = result.whole.model.axes[j.index - 1]
    return True


def _identify_whole(
    result: ProcessResult,
    analytic: Extraction | None,
    kwargs: dict[str, Any],
    fit_scales: bool,
    stage: Stage,
    parallel_sigma: float = AIC_SIGMA_2D,
) -> None:
    """The maximum-likelihood fit of the whole model, its DH model, covariance and check."""
    seg, joints, ref = result.segmentation, result.joints, result.reference_pose
    notes, base, nominal = result.warnings, result.base, result.nominal
    types = tuple(j.type for j in joints)
    assert result.target is not None and all(t is not None for t in types)
    rows, Q, P = samples_with_encoders(seg)
    which = target_labels(seg, rows)
    axes0 = [j.axis for j in joints]
    extra = np.zeros((0, 3))
    if which is not None:  # further targets: their samples moved back to the reference pose
        extra = np.array(
            [
                _mean_at_reference(axes0, types, Q[which == k], P[which == k], ref)  # type: ignore[arg-type]
                for k in range(1, int(which.max()) + 1)
            ]
        ).reshape(-1, 3)
    rotations = measured_rotations(seg, rows)
    start = AxisModel(
        tuple(axes0),  # type: ignore[arg-type]
        types,  # type: ignore[arg-type]
        result.target,
        ref,
        np.ones(len(joints)),
        extra,
        None if rotations is None else _rotation_at_reference(axes0, types, Q, rotations, ref),  # type: ignore[arg-type]
    )
    sample_cov = _sample_covariance(seg, rows)
    if sample_cov is not None:
        result.noise = NoiseModel("per-sample")
    fit_sigmas = [j.fit.sigma**2 for j in joints if j.fit is not None]
    sigma = math.sqrt(np.mean(fit_sigmas)) if fit_sigmas else 1e-5
    stage("identifying", 0.1)
    timing = result.timing
    clocked = timing is not None and timing.source == "estimated"
    speeds = JointRates(result.log, seg.n_joints) if clocked else None
    for attempt in range(MAX_REJOINS + 1):
        rates = None
        if speeds is not None:
            t_ns = seg.table["t_ns"].to_numpy()[rows]
            rates = speeds.at(t_ns)
        options: dict[str, Any] = {
            "noise": result.noise,
            "fit_scales": fit_scales,
            "sample_cov": sample_cov,
            "which": which,
            "rotations": rotations,
            "sigma_rotation": result.noise.orientation,
            "rates": rates,
        }
        whole = fit_whole_model(
            start,
            Q,
            P,
            sigma=sigma,
            threshold=math.inf if analytic is None else 5.0,
            progress=lambda f: stage("identifying", 0.1 + 0.9 * f),
            **options,
        )
        if analytic is None:
            # started from the nominal (or a coupled move's circle): the start misses the
            # samples it did not see by far more than the noise, so the first fit judged no
            # sample an outlier; judge them at its optimum, on the noise's own scale
            if not fit_sigmas:
                pred = predict(whole.model, Q, which=which, rates=rates)[0]
                norms = np.linalg.norm(P - pred, axis=1)
                sigma = max(float(np.median(norms)) / CHI3_MEDIAN, 1e-9)
            whole = fit_whole_model(whole.model, Q, P, sigma=sigma, **options)
        if not clocked or timing is None:
            break
        at = whole.layout.clock_at
        assert at is not None
        delta, sd = whole.model.clock, math.sqrt(max(float(whole.covariance[at, at]), 0.0))
        offset = timing.offset + delta
        timing = replace(timing, offset=offset, std=sd)
        if abs(delta) <= max(REJOIN_BELOW * sd, REJOIN_FIT) or attempt == MAX_REJOINS:
            break  # below REJOIN_FIT the fit's first-order move Q − δ q̇ is exact enough
        # join the encoders again at the fitted offset and fit once more from there
        seg = rejoin(seg, result.log, offset - timing.pipeline)
        rows, Q, P = samples_with_encoders(seg)
        which = target_labels(seg, rows)
        rotations = measured_rotations(seg, rows)
        sample_cov = _sample_covariance(seg, rows)
        start = replace(whole.model, clock=0.0)
        result.segmentation = seg
    result.timing = timing
    whole = _beyond_geometry(result, whole, Q, P, sigma, options)
    whole, sample_cov = _with_model_error(result, whole, Q, P, sample_cov, which, rates, rotations)
    if rotations is None:
        whole = _pose_clustered(result, whole, Q, P, sample_cov, which, rates, sigma)
    nominal_table = nominal.table if nominal is not None else None
    covs = axis_covariances(whole)
    kw = dict(kwargs)
    kw["pair_tolerances"] = tolerances = pair_tolerances(
        [(c, a.point) for c, a in zip(covs, whole.model.axes, strict=True)],
        nominal,
        kwargs["angle_tol"],
        kwargs["distance_tol"],
        k_parallel=parallel_sigma,
        # the whole-model fit holds a pair parallel by Akaike's rule also where the nominal says
        # parallel, not by the nominal's 5σ: a held pair's tilt is a bias the FK error carries
        # in full. With random static poses and 60 µm unmodelled error, 5σ held KR5's axes 2–3
        # (0.05° apart) parallel at 1.5–1.9x the FK error; with per-joint sweeps (UR5 0.05° off,
        # 100 Hz tracker, σ 15–20 µm) it held axes 2–3 or 3–4 in 2 of 10 sessions at 1.2–3.1x
        direction_variances=relative_tilt_variances(whole),
    )
    whiten = _whitening(result, sample_cov, sigma)

    def cost(fit: WholeFit) -> float:
        """The whitened sum of squares of ``whole``'s inliers under ``fit`` (positions)."""
        rw = whitened_residuals(fit, whole.inliers, Q, P, whiten, which=which, rates=rates)
        return float(np.sum(rw**2))

    whole, tolerances = _with_fixed_relations(whole, tolerances, cost, result.info)
    kw["pair_tolerances"] = tolerances

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
    h_rows = hayati_rows(ex)
    nominal_rows = _nominal_rows(nominal_table, ref, h_rows)
    prop = propagate(whole, base, extract, ex, pairs, h_rows, nominal_rows)
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
        undetermined=prop.undetermined,
    )
    result.hayati = near_parallel(list(ex.axes), ex, result.std, result.info)
    result.hayati_std = [
        np.sqrt(np.clip(np.diag(prop.hayati_covariance)[4 * k : 4 * k + 4], 0.0, None))
        for k in range(len(pairs))
    ]
    if prop.mixed_covariance is not None and prop.mixed_fixed is not None:
        mixed_std = np.sqrt(np.clip(np.diag(prop.mixed_covariance), 0.0, None))
        result.conditioned = _conditioned(
            result, ex, h_rows, nominal_rows, mixed_std, prop.mixed_fixed, prop.mixed_undetermined
        )
    result.tool_orientation = prop.tool_orientation
    result.tool_orientation_std = prop.tool_orientation_std
    result.extra_tool_points = prop.extra_tool_points
    result.extra_tool_std = np.sqrt(
        np.clip(np.diag(prop.extra_tool_covariance), 0.0, None)
    ).reshape(-1, 3)
    result.info.extend(_correlation_notes(prop.covariance, prop.fixed, len(joints)))
    _identifiability_notes(result, whole)
    declared = result.noise.model != "isotropic" or result.noise.sigma is not None
    if declared and not 0.5 < whole.chi2_dof < 2.0:
        causes = f" ({LIKELY_CAUSES})" if whole.chi2_dof >= 2.0 else " (the model's σ is too large)"
        notes.append(
            f"χ²/dof = {whole.chi2_dof:.2f} under the {result.noise.described} noise model: the "
            f"residuals contradict it{causes}; the uncertainty is scaled by the residuals."
        )
    stage("validating", 0.0)
    tools = np.vstack([ex.tool_point[None], result.extra_tool_points])
    if whole.model.terms is not None:  # the terms in the table's frames
        frames = fk_frames(ex.standard, ref, T_base=ex.T_measurement_base)
        result.terms = to_table(whole.model.terms, frames)
        result.terms_std = term_std(whole)
    # the table's joint values: ref + s (q − ref) with fitted scales, deflected by the terms
    Q_table = table_values(result, Q)
    if result.terms is not None:  # what the terms move, at the samples
        bare = table_values(result, Q, deflected=False)
        result.deflection_max = np.max(np.abs(Q_table - bare), axis=0)
        reached = fk_points_chunked(
            ex.standard, Q_table, ex.tool_point, T_base=ex.T_measurement_base
        )
        moved = reached - fk_points_chunked(
            ex.standard, bare, ex.tool_point, T_base=ex.T_measurement_base
        )
        result.deflection_target = float(np.max(np.linalg.norm(moved, axis=1)))
        pick = np.unique(np.linspace(0, Q.shape[0] - 1, min(2000, Q.shape[0])).astype(int))
        result.deflection_vectors = np.column_stack([reached[pick], moved[pick]])
    result.validation = validate_samples(seg, rows, Q_table, P, ex, whole.inliers, tools, which)
    gap = table_gap(whole, ex, Q, Q_table)
    if gap > 1e-6:
        notes.append(
            f"the DH table departs from the fitted model by up to {gap * 1e3:.4f} mm: a pair "
            "was classified (parallel / meeting) where the fitted axes are not; check the "
            "relations and the FK check."
        )
    check_residual(result.validation, sigma, notes)
    if result.folds > 1:
        stage("cross-validating", 0.0)
        result.holdout.append(
            cross_validate(
                whole,
                Q,
                P,
                result.folds,
                fit_options={
                    "noise": result.noise,
                    "sigma": sigma,
                    "fit_scales": fit_scales,
                    "sample_cov": sample_cov,
                    "rotations": rotations,
                    "sigma_rotation": result.noise.orientation,
                    "rates": rates,
                },
                nominal=None
                if nominal is None
                else (nominal.table, nominal.T_base, nominal.tool_point),
                which=which,
            )
        )


#: A condition number of the scaled Jacobian above this is worth a note naming the weakest
#: direction.
CONDITION_NOTE = 1e3


def _beyond_geometry(
    result: ProcessResult,
    whole: WholeFit,
    Q: FloatArray,
    P: FloatArray,
    sigma: float,
    options: dict[str, Any],
) -> WholeFit:
    """The terms beyond the geometry that ``--model`` asks for or the session proves
    (:func:`select_model`), fitted to every sample; the candidates in ``result.selection``."""
    request = result.model_request
    if request.mode == "geometric":
        return whole
    gravity = (
        default_gravity(whole)
        if request.gravity is None
        else np.asarray(request.gravity, dtype=np.float64)
    )
    masses: tuple[Lump, ...] = ()
    if request.masses is not None:
        masses, urdf_gravity = _link_masses(result, whole, request.masses)
        if request.gravity is None:
            gravity = urdf_gravity
    # where the declared uncertainties are far below the residuals, the candidates are weighed
    # with the model-error component as the final fit will be (U95 alone weighs badly)
    declared = options.get("sample_cov")
    if declared is None and result.noise.model == "tracker":
        declared = result.noise.covariance(P)
    weighed = options
    if declared is not None:
        found = refit_with_model_error(
            whole,
            Q,
            P,
            declared,
            {k: options[k] for k in ("noise", "fit_scales", "rotations", "sigma_rotation")},
            which=options["which"],
            rates=options["rates"],
        )
        if found is not None:
            weighed = {**options, "sample_cov": found.sample_cov}
    selection = select_model(
        request.mode,
        whole,
        Q,
        P,
        sigma=sigma,
        options=weighed,
        gravity=gravity,
        harmonic_joints=request.harmonic_joints,
        folds=result.folds if result.folds > 1 else SELECT_FOLDS,
        masses=masses,
        reuse=weighed is options,
    )
    result.selection = selection
    chosen = selection.chosen
    terms = selected_terms(selection)
    if terms is None:
        return whole
    # the lumps again on the chosen candidate's axes (the geometric fit's may sit off where the
    # terms were missing), its coefficients kept where the terms are the same
    assert chosen.fit is not None
    again = terms_for(
        chosen.fit, chosen.families, gravity, request.harmonic_joints, masses, chosen.dropped
    )
    if again is not None and again.names() == terms.names():
        again = again.with_coefficients(terms.coefficients)
    start = replace(whole.model, terms=again)
    return fit_whole_model(start, Q, P, sigma=sigma, **options)


#: The URDF's joint axes farther than this (m, RMS) from the measured ones after placing it
#: are worth a warning: its masses may not be this robot's, or not where they were placed.
URDF_MISFIT = 0.01


def _link_masses(
    result: ProcessResult, whole: WholeFit, path: str
) -> tuple[tuple[Lump, ...], FloatArray]:
    """The links' masses of the URDF at ``path`` as lumps in M (its axes placed on the fitted
    ones: ``align_lines``), and gravity along its root's −z in M."""
    from dhlog.identify.start import align_lines
    from dhlog.io.urdfmasses import read_link_masses

    names = tuple(j.name for j in result.joints)
    lm = read_link_masses(path, names, result.reference_pose)
    measured = [(a.point, a.direction) for a in whole.model.axes]
    T = align_lines(list(zip(lm.axis_points, lm.axis_dirs, strict=True)), measured)
    if T is None:
        raise InputError(
            f"{path}: its joint axes do not fix a placement on the measured ones (all parallel); "
            "give --gravity and leave --masses out for the lumped gravity terms."
        )
    R, t = T[:3, :3], T[:3, 3]
    misfit = [
        float(np.linalg.norm(np.cross(R @ p + t - a.point, a.direction)))
        for p, a in zip(lm.axis_points, whole.model.axes, strict=True)
    ]
    rms = math.sqrt(float(np.mean(np.square(misfit))))
    turned = max(
        float(np.degrees(np.arccos(np.clip(abs((R @ d) @ a.direction), -1.0, 1.0))))
        for d, a in zip(lm.axis_dirs, whole.model.axes, strict=True)
    )
    result.info.append(
        f"--masses: {len(lm.masses)} link masses ({float(np.sum(lm.masses)):.1f} kg) from "
        f"{path}, joints matched {lm.matched}, placed on the measured axes (RMS "
        f"{rms * 1e3:.2f} mm, largest turn {turned:.3f}°); gravity along its base's −z."
    )
    if rms > URDF_MISFIT:
        result.warnings.append(
            f"--masses: the URDF's axes sit {rms * 1e3:.1f} mm RMS from the measured ones once "
            "placed: is it this robot's, with its joint zero at the encoder zero?"
        )
    lumps = tuple(
        Lump(k, R @ c + t, float(m))
        for k, c, m in zip(lm.moved_by, lm.centres, lm.masses, strict=True)
    )
    return lumps, np.asarray(R @ np.array([0.0, 0.0, -1.0]), dtype=np.float64)


def _identifiability_notes(result: ProcessResult, whole: WholeFit) -> None:
    """What the poses determine: undetermined directions (a warning: held at the start, the
    parameters they move fixed), and the condition number with the weakest direction."""
    d = whole.determined
    if d is None:
        return
    names = whole.layout.names
    weakest = ", ".join(f"{c:+.2f} {k}" for k, c in d.weakest_terms(names))
    k = d.null.shape[1]
    if k:
        held = "the nominal" if result.nominal is not None else "the start"
        result.warnings.append(
            f"these poses do not determine {k} direction(s) of the model's {d.scale.size} "
            f"parameters: held at {held}, and the parameters they move are fixed (reason "
            f"'{NOT_DETERMINED}'); move every joint over more of its range, or alone."
        )
    if k or d.condition > CONDITION_NOTE:
        result.info.append(
            f"identifiability: the scaled Jacobian's condition number is {d.condition:.3g}; "
            f"its weakest determined direction is {weakest}."
        )


def _with_model_error(
    result: ProcessResult,
    whole: WholeFit,
    Q: FloatArray,
    P: FloatArray,
    sample_cov: FloatArray | None,
    which: NDArray[np.int64] | None,
    rates: FloatArray | None,
    rotations: FloatArray | None,
) -> tuple[WholeFit, FloatArray | None]:
    """The model-error component (:mod:`dhlog.identify.variance`) where the declared
    uncertainties (per-sample covariances, the tracker model) are far below the residuals,
    said in a warning. Returns the fit and the covariances it used."""
    declared = sample_cov
    if declared is None and result.noise.model == "tracker":
        declared = result.noise.covariance(P)
    if declared is None:
        return whole, sample_cov
    options = {
        "noise": result.noise,
        "fit_scales": whole.layout.scale_at is not None,
        "rotations": rotations,
        "sigma_rotation": result.noise.orientation,
    }
    found = refit_with_model_error(whole, Q, P, declared, options, which=which, rates=rates)
    if found is None:
        return whole, sample_cov
    result.noise = replace(result.noise, model_error=found.sigma)
    result.warnings.append(
        f"the residuals are {math.sqrt(found.chi2_before):.1f}x what the declared "
        f"uncertainties ({result.noise.declared}) explain (χ²/dof {found.chi2_before:.1f}): "
        f"the model (or an optimistic noise model), not the tracker, limits the fit; a "
        f"model-error σ of {found.sigma * 1e3:.4f} mm per coordinate was estimated and added "
        f"to every sample's ({MODEL_ERROR_CAUSES})."
    )
    return found.fit, found.sample_cov


def _whitening(result: ProcessResult, sample_cov: FloatArray | None, sigma: float) -> Whiten:
    """The whitening of samples ``rows`` at ``points``: their own covariances when the log
    carries them, else the noise model's."""
    from dhlog.model.noise import whitening_from_std

    def whiten(points: FloatArray, rows: NDArray[np.bool_]) -> FloatArray | float:
        if sample_cov is not None:
            return whitening_from_std(sample_cov[rows])
        return result.noise.whiten(points, sigma)

    return whiten


def _pose_clustered(
    result: ProcessResult,
    whole: WholeFit,
    Q: FloatArray,
    P: FloatArray,
    sample_cov: FloatArray | None,
    which: NDArray[np.int64] | None,
    rates: FloatArray | None,
    sigma: float,
) -> WholeFit:
    """The covariance times the design effect of several samples a pose
    (:mod:`dhlog.identify.variance`), said in a note."""
    d = design_effect(whole, Q, P, _whitening(result, sample_cov, sigma), which=which, rates=rates)
    if d is None:
        return whole
    result.info.append(
        f"{d.samples} samples at {d.poses} poses ({d.per_pose:.1f} a pose) share their pose's "
        f"error ({d.rho:.0%} of the residual variance): the uncertainty is scaled by the "
        f"design effect, σ x{math.sqrt(d.effect):.2f}."
    )
    return replace(whole, covariance=whole.covariance * d.effect)


def measured_rotations(seg: Segmentation, rows: NDArray[np.int64]) -> FloatArray | None:
    """The target frame's measured orientation (m, 3, 3) at ``rows`` when the log carries it
    (``orientation = true`` in the pipeline), else None."""
    from dhlog.io.reader import ORIENTATION_COLUMNS

    if not all(c in seg.table.columns for c in ORIENTATION_COLUMNS):
        return None
    from scipy.spatial.transform import Rotation  # 0.35 s of imports: only when needed

    quat = seg.table.select(ORIENTATION_COLUMNS).to_numpy()[rows]
    return np.asarray(Rotation.from_quat(quat).as_matrix(), dtype=np.float64)  # x, y, z, w


def _rotation_at_reference(
    axes: list[Line], types: tuple[JointType, ...], Q: FloatArray, R: FloatArray, ref: FloatArray
) -> FloatArray:
    """The target frame's orientation at the reference pose: every measured orientation moved
    back through the axes (at most 20 000, evenly strided), their chordal mean."""
    stride = max(1, Q.shape[0] // START_TARGET_POINTS)
    Rt, _ = motions_back(axes, types, Q[::stride], ref)
    return nearest_rotation(np.einsum("mij,mjk->ik", Rt, R[::stride]))


def _mean_at_reference(
    axes: list[Line], types: tuple[JointType, ...], Q: FloatArray, P: FloatArray, ref: FloatArray
) -> FloatArray:
    """A target's position at the reference pose: its samples (at most 20 000, evenly strided)
    moved back through the axes and averaged."""
    if Q.shape[0] == 0:
        raise DegenerateGeometryError("a further target has no sample with encoder values.")
    stride = max(1, Q.shape[0] // START_TARGET_POINTS)
    back = points_at_reference(axes, types, Q[::stride], P[::stride], ref)
    return np.asarray(back.mean(axis=0), dtype=np.float64)


def _sample_covariance(seg: Segmentation, rows: NDArray[np.int64]) -> FloatArray | None:
    """The position covariance (m, 3, 3) the log carries for the samples ``rows``
    (``PoseWithCovarianceStamped``), or None when any of them has none or one that is not
    positive definite (the noise model then applies to all)."""
    from dhlog.io.reader import COVARIANCE_COLUMNS

    if not all(c in seg.table.columns for c in COVARIANCE_COLUMNS):
        return None
    c = seg.table.select(COVARIANCE_COLUMNS).to_numpy()[rows]
    if not np.all(np.isfinite(c)):
        return None
    cov = np.empty((rows.size, 3, 3))
    for k, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
        cov[:, a, b] = cov[:, b, a] = c[:, k]
    if not np.all(np.linalg.eigvalsh(cov)[:, 0] > 0):
        return None
    return cov


def _with_fixed_relations(
    whole: WholeFit,
    tolerances: list[tuple[float, float]] | None,
    cost: Callable[[WholeFit], float],
    info: list[str],
) -> tuple[WholeFit, list[tuple[float, float]] | None]:
    """The fit constrained to the pair relations the data cannot reject: consecutive revolute
    axes within their tolerance of parallel are made parallel (collinear: the same line), so
    that the DH conventions of those pairs hold exactly and the table equals the model.

    The constraint is applied to first order (:func:`constrain_pairs`); where the samples'
    cost then grows by more than the relations' own χ² allows (the first order does not hold:
    parameters that only moved together, as in a coupled move, compensate far), the pairs are
    left free and their tolerances narrowed so that the extraction does not call them parallel
    either (said in a note). Returns the fit and the tolerances."""
    if tolerances is None:
        return whole, tolerances
    axes, types = whole.model.axes, whole.model.types
    parallel, collinear = [], []
    for i, (a_tol, d_tol) in enumerate(tolerances):
        kind = classify_lines(axes[i], axes[i + 1], angle_tol=a_tol, distance_tol=d_tol).kind
        if JointType.PRISMATIC in (types[i], types[i + 1]):
            if kind.is_parallel:  # a prismatic axis has only a direction to hold
                parallel.append(i)
        elif kind is RelationKind.COLLINEAR:
            collinear.append(i)
        elif kind.is_parallel:
            parallel.append(i)
    held = constrain_pairs(whole, parallel, collinear)
    if held is whole:
        return whole, tolerances
    rows = 2 * len(parallel) + 4 * len(collinear)
    # χ² of `rows` degrees of freedom beyond its mean by 10 of its σ (P < 2e-5 for one pair):
    # only a hold the first order gets badly wrong, never a truly parallel pair's noise (at
    # 4σ, 0.7 % of such sessions were left free, their d and θ far from first order)
    allowed = whole.chi2_dof * (rows + 10.0 * math.sqrt(2.0 * rows))
    grown = cost(held) - cost(whole)
    if grown <= allowed:
        return held, tolerances
    pairs = sorted(set(parallel) | set(collinear))
    narrowed = [
        (min(a, 1e-7), min(d, 1e-7)) if i in pairs else (a, d)
        for i, (a, d) in enumerate(tolerances)
    ]
    names = ", ".join(f"{i + 1}–{i + 2}" for i in pairs)
    info.append(
        f"axes {names}: within their tolerance of parallel, but holding them so costs the "
        f"samples χ² {grown:.1f} (the relation alone allows {allowed:.1f}): left free."
    )
    return whole, narrowed


#: Target samples spanning more (m) than this are not of a robot: a length unit slipped.
LARGEST_ROBOT = 100.0
#: ... nor less than this (m), with sweeps found.
SMALLEST_ROBOT = 0.005
#: The whole-model fit joins the encoders again when its clock offset moved by more than this
#: many of its σ from the offset they were joined at (at most MAX_REJOINS times).
REJOIN_BELOW = 0.25
MAX_REJOINS = 2
#: ... and by more than this (s): below it, the fit's own first-order move of the encoders
#: (``Q − δ q̇``) errs by ``δ² q̈ / 2``, under 10⁻⁸ rad at 1 rad/s².
REJOIN_FIT = 1e-4
#: The start estimate joins the encoders again only for a move beyond this (s): the fit
#: carries the rest.
REJOIN_START = REJOIN_FIT
#: The start estimate of the clock offset joins the encoders again at most this many times.
START_REJOINS = 4


#: What makes residuals exceed the noise, in the order a metrologist checks them.
LIKELY_CAUSES = (
    "likely causes: a clock offset between tracker and joint states (set clock_offset, or let "
    "dhlog estimate it), a joint of the wrong type, a joint that gives under load (compliance), "
    "or a target that slipped on the flange"
)
#: What a geometric model leaves that a tracker's stated uncertainty does not explain.
MODEL_ERROR_CAUSES = (
    "likely causes: gravity bending the joints and links (compliance), gear and encoder errors "
    "that vary with the angle, thermal drift during the session, a target that slipped on the "
    "flange, or a declared noise model more optimistic than the tracker"
)
#: A joint's fit RMS this many times the median of all joints' is worth a warning.
RMS_OUTLIER = 3.0


def _check_fit_noise(joints: list[JointReport], notes: list[str]) -> None:
    """Warn for a joint whose fit RMS is far above the other joints' (the same tracker measured
    them all), naming the likely causes."""
    rms = {j.index: j.fit.rms for j in joints if j.fit is not None and j.ok}
    if len(rms) < 3:
        return
    typical = float(np.median(list(rms.values())))
    for j in joints:
        r = rms.get(j.index)
        if r is not None and typical > 0 and r > RMS_OUTLIER * typical:
            notes.append(
                f"joint {j.index} ({j.name}): its fit RMS {r * 1e3:.4f} mm is "
                f"{r / typical:.1f}x the joints' median ({typical * 1e3:.4f} mm); {LIKELY_CAUSES}."
            )


def _check_units(
    seg: Segmentation, log: LogData, phases: list[SweepPhase], notes: list[str]
) -> None:
    """Stop on a unit slip the geometry shows, naming the pipeline key and the value that
    fits: target samples spanning more than :data:`LARGEST_ROBOT` or less than
    :data:`SMALLEST_ROBOT`, or a joint whose samples turn (move) by 1/57.3, 57.3, 10⁻³ or 10³
    per encoder unit; warn on any other encoder slope far from 1."""
    pipe = log.pipeline
    P = seg.table.select(["x", "y", "z"]).to_numpy()
    extent = float(np.linalg.norm(np.nanmax(P, axis=0) - np.nanmin(P, axis=0))) if len(P) else 0
    where = f"{log.path}: the target's samples span {extent:.4g} m"
    if extent > LARGEST_ROBOT:
        fits = "mm" if pipe.length_unit == "m" else "a unit 1000x smaller than mm"
        raise InputError(
            f"{where}, far more than any robot: the log's lengths look like {fits} read as "
            f"'{pipe.length_unit}'; set length_unit = \"mm\" in the pipeline ({pipe.source})."
        )
    if 0 < extent < SMALLEST_ROBOT and seg.segments.height:
        raise InputError(
            f"{where}, less than any robot's sweeps: the lengths look like metres read as "
            f"'{pipe.length_unit}'; set length_unit = \"m\" in the pipeline ({pipe.source})."
        )
    slips = {
        math.pi / 180.0: ("look like degrees", 'set angle_unit = "deg" in the pipeline'),
        180.0 / math.pi: ("look like radians", 'set angle_unit = "rad" in the pipeline'),
        1e-3: ("look like millimetres", 'set length_unit = "mm" and declare the type prismatic'),
        1e3: ("look like metres", 'set length_unit = "m" and declare the type prismatic'),
    }
    by_joint: dict[int, list[float]] = {}
    for p in phases:
        by_joint.setdefault(p.joint, []).append(abs(p.slope))
    for joint, slopes in sorted(by_joint.items()):
        r = float(np.median(slopes))
        name = seg.joint_names[joint - 1]
        for ratio, (looks, fix) in slips.items():
            if abs(r / ratio - 1.0) < 0.1:
                raise InputError(
                    f"{log.path}: joint {joint} ({name}): the target turns (moves) {r:.4g} per "
                    f"encoder unit: its encoder values {looks}; {fix} ({pipe.source})."
                )
        if not 0.8 < r < 1.25:
            notes.append(
                f"joint {joint} ({name}): the target turns (moves) {r:.4g} per encoder unit, "
                "not 1: check the joint's unit, type and name order in the pipeline."
            )


def _clock_start(
    seg: Segmentation, log: LogData, info: list[str], phases: list[SweepPhase] | None = None
) -> tuple[Segmentation, Timing | None]:
    """The clock offset's start estimate from the sweeps' phases (:func:`phase_lag`), the
    encoders joined again at it; the pipeline's offset where it is fixed or cannot be told."""
    pipe = log.pipeline.segmentation
    if not seg.has_encoders or log.joints is None:
        return seg, None
    if pipe.clock_offset_fixed:
        return seg, Timing(pipe.clock_offset, None, "pipeline", pipe.clock_offset, "fixed")
    total, std = 0.0, None
    for attempt in range(START_REJOINS):
        lag = phase_lag(seg, log, phases if attempt == 0 else None)
        if lag is None:
            break
        delta, std = lag
        if abs(delta) <= max(REJOIN_BELOW * std, REJOIN_START):
            break
        total += delta
        seg = rejoin(seg, log, total)
    if std is None:
        info.append(
            "no sweep moves while the tracker samples it (step-and-measure): a clock offset "
            "between tracker and joint states has no effect and is not estimated."
        )
        return seg, Timing(
            pipe.clock_offset, None, "pipeline", pipe.clock_offset, "step-and-measure"
        )
    return seg, Timing(pipe.clock_offset + total, std, "estimated", pipe.clock_offset)


def _nominal_rows(
    nominal: StandardDH | None, ref: FloatArray, rows: frozenset[int]
) -> StandardDH | None:
    """The nominal with ``rows`` in the Hayati–Mirmirani form (None without rows or nominal, or
    where the nominal's own axes have no such form: perpendicular there)."""
    if nominal is None or not rows:
        return None
    try:
        return table_in_hayati_form(nominal, ref, rows)
    except DhlogError:
        return None


def _conditioned(
    result: ProcessResult,
    ex: Extraction,
    rows: frozenset[int],
    nominal_rows: StandardDH | None,
    std: FloatArray,
    fixed: NDArray[np.bool_],
    undetermined: NDArray[np.bool_] | None = None,
) -> Conditioned:
    """The table in the Hayati form with its σ; fixed entries keep the standard table's reason
    where the row is the standard one, are not determined by the poses where ``undetermined``
    says so, and are held by a convention elsewhere."""
    table = hayati_table(ex, rows, nominal_rows)
    reasons = {
        int(k): NOT_DETERMINED
        if undetermined is not None and undetermined[k]
        else result.fixed.get(int(k), "held by a convention of the extraction")
        for k in np.flatnonzero(fixed)
    }
    return Conditioned(table, np.where(fixed, np.nan, std), reasons, nominal_rows)


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
