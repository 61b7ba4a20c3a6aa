"""``dhlog process``: from a calibration log to the DH model, its uncertainty and its check —
the run's flow, top to bottom; each step's work is in the module named.

read (``io.reader``) → segment (``identify.segment``) → the units checked (``identify.checks``),
the clock offset's start (``identify.timing``) → per joint: pick the sweeps, decide the type,
fit the axis robustly, bring it to the reference pose (``identify.sweeps``) → the analytic start:
line geometry on those axes (``identify.extract``, seed 000) → the maximum-likelihood fit of the
whole model to every sample with encoder values (``identify.whole``, from ``identify.samples``;
the clock offset joined again if it moved; the terms beyond the geometry ``identify.beyond``;
the weights ``identify.variance``), pairs the data cannot tell from parallel held parallel
(``identify.relations``) → the DH model read off the fitted axes, its covariance and what is
fixed (``identify.uncertainty``, ``identify.conditioning``) → forward kinematics of the table
against every sample (``identify.validate``) → what makes the result implausible
(``identify.check.plausible``: ``ProcessResult.implausible``). The result document is
``result.document``.

``--analytic-only`` (and a log without encoders) stops at the analytic start, with its own
propagated covariance. When some joints cannot be identified, what was identified is kept: their
fits and axes, and the DH rows that only need identified axes; the joints at fault are named with
the reason — unless the other samples (coupled moves, static poses) determine them from a start
(``identify.start``: the nominal, or a coupled move's circle).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError, GeometryError
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.fitting import PlaneFit, fit_plane
from dhlog.geometry.lines import ANGLE_TOL, DISTANCE_TOL, Line, Plane
from dhlog.identify.check.footing import (
    NotScoredError,
    Placed,
    Unscored,
    nominal_on_session,
    score_poses,
)
from dhlog.identify.check.holdout import Holdout, cross_validate
from dhlog.identify.check.named import name_outliers, pose_names, sample_names
from dhlog.identify.check.plausible import inlier_picks, judge
from dhlog.identify.check.validate import (
    Validation,
    check_residual,
    shown_stride,
    table_gap,
    validate_samples,
    validate_sweeps,
)
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.leaveout import fold_of_poses, pose_groups
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.register import Registration
from dhlog.identify.fit.samples import (
    START_TARGET_POINTS,
    measured_rotations,
    sample_covariance,
    start_model,
)
from dhlog.identify.fit.start import Start, start_unswept
from dhlog.identify.fit.variance import (
    pose_clustered,
    residual_norms,
    whitened_cost,
    whitening,
    with_model_error,
)
from dhlog.identify.fit.whole import CHI3_MEDIAN, WholeFit, fit_whole_model
from dhlog.identify.joints.checks import (
    check_fit_noise,
    check_noise_model,
    check_sizes,
    check_units,
)
from dhlog.identify.joints.permutation import suspected_permutation
from dhlog.identify.joints.sweeps import (
    JointReport,
    TargetAtReference,
    fit_joint,
    samples_with_encoders,
    target_labels,
)
from dhlog.identify.model.beyond import (
    beyond_geometry,
    deflections,
    merge_cancelling,
    term_covariance,
)
from dhlog.identify.model.hold import hold_unseen, may_hold
from dhlog.identify.model.pairs import decided_tolerances, fold_holds
from dhlog.identify.model.parked import (
    mark_parked,
    no_nominal_reason,
    parked_joints,
    parked_pose,
    parked_warning,
    place_parked,
)
from dhlog.identify.model.relations import constrain_pairs, with_fixed_relations
from dhlog.identify.model.select import AUTO, RANGE_POINTS, ModelRequest, Selection, term_std
from dhlog.identify.read.analytic import (
    hayati_rows,
    pair_tolerances,
    partial_extraction,
)
from dhlog.identify.read.conditioning import Conditioned, identifiability_notes, nominal_rows
from dhlog.identify.read.extract import Extraction, extract_dh
from dhlog.identify.read.hayati import HayatiRow
from dhlog.identify.read.uncertainty import analytic_uncertainty, whole_uncertainty
from dhlog.identify.segment.persample import PerSample, SampleArray, blocks
from dhlog.identify.segment.segment import Segmentation, segment_log
from dhlog.identify.segment.timing import (
    MAX_REJOINS,
    REJOIN_BELOW,
    REJOIN_FIT,
    JointRates,
    Timing,
    clock_start,
    rejoin,
    sweep_phases,
)
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import Pipeline
from dhlog.io.reader import LogData, camera_pipeline, read_log
from dhlog.io.writer import sha256_of
from dhlog.model.dh import JointType
from dhlog.model.fk import fk_frames
from dhlog.model.noise import NoiseModel
from dhlog.model.terms import Terms, table_deflection, to_table

#: Largest number of samples per joint the per-joint fits (the whole-model fit's start) use.
START_FIT_POINTS = 4000


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
    #: joints (0-based) parked in the session (:mod:`dhlog.identify.model.parked`)
    parked: tuple[int, ...] = ()
    #: errors at poses not used to fit: K-fold cross-validation, held-out logs
    holdout: list[Holdout] = field(default_factory=list)
    #: the whole-model fit's gross outliers by name (the export's point ids, else ``#k``)
    outlier_names: list[str] = field(default_factory=list)
    #: ... and their rows in the segmentation's point table
    outlier_rows: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    #: held-out logs given (``--validate``) but not scored, each with the reason
    not_scored: list[Unscored] = field(default_factory=list)
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
    #: their σ at the sample where each is largest (NaN: a term it needs is undetermined)
    deflection_max_std: FloatArray = field(default_factory=lambda: np.zeros(0))
    deflection_target_std: float = 0.0
    #: up to 2000 samples: the target where the model puts it and the terms' share of that
    #: (k, 6: position, displacement; m, in M)
    deflection_vectors: FloatArray = field(default_factory=lambda: np.zeros((0, 6)))
    #: what a reader should know but need not act on (the method chosen, forms shown); the
    #: ``warnings`` are for what may need action
    info: list[str] = field(default_factory=list)
    #: a camera calibration's product (:class:`~dhlog.identify.camera.report.CameraResult`: the
    #: set-up, the camera's and the board's poses with σ, the corners' σ, the held-out check in
    #: pixels) and what the recording shows of each camera; None and empty for a tracker log
    camera: Any = None
    cameras: list[Any] = field(default_factory=list)
    #: with several cameras, each one's product (``camera`` is the first's)
    camera_results: list[Any] = field(default_factory=list)
    #: why dhlog judges this result implausible, one sentence each naming the evidence and the
    #: fix (a suspected joint permutation or unit slip, a validation session no footing could
    #: place, ...); empty when plausible. The result is still written, marked ``plausible: false``
    #: in the JSON, and ``dhlog process`` exits with ``EXIT_IMPLAUSIBLE`` (4)
    implausible: list[str] = field(default_factory=list)

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
    camera_setup: str | None = None,
    refine_intrinsics: bool = False,
    jobs: int = 1,
    frames: tuple[int | None, int | None] | None = None,
) -> ProcessResult:
    """Run the whole identification on the log at ``path`` (see the module docstring).

    A vision log (camera images; a camera pipeline) is calibrated from its detected board
    corners (:mod:`dhlog.identify.camera.flow`): ``camera_setup`` eye-to-hand / eye-in-hand (None:
    decided from the data), ``refine_intrinsics``, ``jobs`` processes decoding and detecting,
    ``frames`` the range of frames (indices on the image topic, end excluded) calibrated from.

    ``holdout`` K > 1: K-fold cross-validation over the session's poses; ``validate``: further
    logs (other sessions of the same robot) whose poses score the result and the nominal on one
    footing (:mod:`dhlog.identify.check.footing`; a log that cannot be scored is a warning).
    ``progress(stage, fraction)`` is called as each stage advances."""
    camera = camera_pipeline(path, pipeline)
    if camera is not None:  # one Observations a camera
        from dhlog.identify.camera.flow import process_observations
        from dhlog.io.observe import observe

        digest = sha256_of(path)  # before the long walk: the log as it was read
        observations = observe(
            path,
            camera,
            jobs=jobs,
            progress=None if progress is None else (lambda f: progress("detecting", f)),
            joint_names=None if nominal is None else nominal.joint_names,
            joint_source="model" if nominal is None else nominal.source,
        )
        found = cast(
            ProcessResult,
            process_observations(
                observations,
                sha256=digest,
                nominal=nominal,
                reference_pose=reference_pose,
                setup=camera_setup,
                refine_intrinsics=refine_intrinsics,
                holdout=holdout,
                frames=frames,
                progress=progress,
                start=process_data,
                pipeline=camera.name,
            ),
        )
        if model.mode != "geometric":
            found.info.append(
                f"--model {model.mode}: a camera calibration fits the geometric model; terms "
                "beyond the geometry (gravity, gears) are not fitted from a camera's corners yet."
            )
        if validate:
            found.warnings.append(
                "--validate: held-out logs score tracker calibrations; a camera's is scored by "
                "--holdout K over its own frames (the held-out logs were not scored)."
            )
        return found
    log = read_log(
        path,
        pipeline,
        fast=fast,
        progress=None if progress is None else (lambda f: progress("reading", f)),
        joint_names=None if nominal is None else nominal.joint_names,
        joint_source="model" if nominal is None else nominal.source,
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
    judge(result)  # implausible lengths or FK check (a camera's are judged in its pixel fit)
    placed: list[Placed | None] = []  # the nominal on this session, placed once
    for other in validate or []:
        try:  # each log's own pipeline unless named
            _validate_log(result, other, pipeline, fast, placed)
        except DhlogError as exc:  # the calibration stands: the log is one line
            said = str(exc) if str(other) in str(exc) else f"{other}: {exc}"
            result.warnings.append(f"held-out log not scored: {said}")
            unplaced = isinstance(exc, NotScoredError) and exc.unplaced
            result.not_scored.append(Unscored(str(other), said, unplaced))
            if unplaced:
                result.implausible.append(
                    f"the held-out log {other} could not be placed, so the calibration has no "
                    "validation on it (it is not scored, never reported as the result's "
                    "figure): " + said.removeprefix(f"{other}: ")
                )
            elif not isinstance(exc, NotScoredError):  # asked for, and not read at all
                result.implausible.append(
                    f"the held-out log {other} could not be read, so the validation asked for "
                    "is missing: " + said.removeprefix(f"{other}: ")
                )
    return result


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
    parallel_sigma: float | None = None,
    holdout: int = 0,
    model: ModelRequest = AUTO,
    progress: Stage | None = None,
    known_noise: float | None = None,
) -> ProcessResult:
    """The identification of :func:`process_log` on streams already decoded (``LogData``).

    Default: the maximum-likelihood fit of the whole model to every sample with encoder
    values, started from the analytic result (per-joint fits + line geometry). With
    ``analytic_only`` (or without encoders), the analytic result with its propagated covariance.
    ``parallel_sigma``: None, nearly parallel pairs are held parallel in the whole-model fit
    where that does not raise the error at held-out poses (:mod:`dhlog.identify.model.pairs`); K,
    those within K σ (2-D) of parallel, whatever the nominal says (0: never). ``holdout`` K > 1:
    K-fold cross-validation of the whole-model fit over the session's poses (``result.holdout``).
    ``model``: the terms beyond the geometry to try or force (:mod:`dhlog.identify.model.select`).
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
    phases = sweep_phases(seg, log, types_hint) if seg.has_encoders else []
    check_units(seg, log, phases, notes)
    seg, timing = clock_start(seg, log, info, phases)
    check_sizes(name, n, nominal, reference_pose)
    implausible = []
    order = log.joint_order
    if nominal is not None and (order is None or not order.by_name):  # the data may tell
        permuted = suspected_permutation(seg, nominal)
        if permuted is not None:
            implausible.append(permuted.reason(seg.joint_names))
    every = shown_stride(seg.height)
    if every > 1:
        info.append(
            f"the recording draws every {every}th sample ({-(-seg.height // every)} of "
            f"{seg.height}; outliers all): a viewer shows no more. Every sample enters the fit "
            "and the FK check."
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
    parked: list[int] = []
    if seg.has_encoders:  # joints that never moved: held at the nominal
        Q_all = samples_with_encoders(seg)[1][:]
        parked = parked_joints(Q_all) if 0 < len(parked_joints(Q_all)) < n else []
        if parked and nominal is not None:
            ref = parked_pose(Q_all, ref, parked)
    for report in joints:
        stage("fitting", (report.index - 1) / n)
        fit_joint(report, seg, log, ref, joints, nominal, fit_method, notes, max_points)
        if report.index - 1 in parked and not report.ok and nominal is None:
            report.reason = no_nominal_reason(Q_all, report.index - 1, report.type)
    unidentified = [
        f"joint {report.index} ({report.name}) was not identified: {report.reason}."
        for report in joints
        if report.reason
    ]
    check_fit_noise(joints, notes)
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
        parked=tuple(parked),
        implausible=implausible,
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
        if whole_wanted and _from_a_start(result, kwargs, stage):
            return result
        notes.extend(unidentified)
        if (
            whole_wanted
            and nominal is None
            and any(not j.ok and j.index - 1 not in parked for j in joints)
        ):
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
    found = analytic_uncertainty(
        joints,
        ref,
        target,
        target_cov,
        base,
        nominal_table,
        kwargs,
        analytic,
        target_of if seg.has_encoders else None,
        info,
    )
    result.extraction, result.covariance, result.std = analytic, found.covariance, found.std
    result.fixed, result.hayati, result.conditioned = found.fixed, found.hayati, found.conditioned
    stage("validating", 0.0)
    result.validation = validate_sweeps(seg, joints, analytic)
    if result.validation is not None:
        sigma = math.sqrt(np.mean([j.fit.sigma**2 for j in joints if j.fit is not None]))
        check_residual(result.validation, sigma, notes)
    else:
        notes.append("no encoder values: FK of the result cannot be checked sample by sample.")
    return result


def _from_a_start(result: ProcessResult, kwargs: dict[str, Any], stage: Stage) -> bool:
    """Joints never moved alone, identified by the whole-model fit from every other sample
    (coupled moves, random static poses, stops), started from the nominal or, without one, from
    the circle a coupled move with a parallel neighbour traces
    (:func:`~dhlog.identify.fit.start.start_unswept`). Returns False (and changes nothing but the
    warnings) when a joint never moved, there is no start, or the fit fails."""
    nominal = result.nominal
    start = start_unswept(
        result.joints,
        result.segmentation,
        result.reference_pose,
        nominal,
        result.warnings,
        result.parked,
    )
    if start is None:
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
    missing = [j for j in result.joints if not j.ok and j.index - 1 not in result.parked]
    what = "the coupled moves" if nominal is None else "the nominal"
    if not _fit_from(result, start, kwargs, stage, what):
        result.registration = None
        return False
    if result.parked:
        _, Q, _ = samples_with_encoders(result.segmentation)
        names_all = [j.name for j in result.joints]
        types_all = [j.type for j in result.joints if j.type is not None]
        result.warnings.append(parked_warning(names_all, result.parked, Q[:], types_all))
    names = ", ".join(f"joint {j.index} ({j.name})" for j in missing)
    if missing and nominal is None:
        result.warnings.append(
            f"{names}: never moved alone; started from the circle its coupled move with a "
            "parallel neighbour traces, and identified by the whole-model fit from every sample."
        )
    elif missing and reg is None:
        result.warnings.append(
            f"{names}: never moved alone; identified by the whole-model fit from the other "
            "samples (coupled moves, still poses), started from the nominal."
        )
    return True


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
    parallel_sigma: float | None = None,
) -> None:
    """The maximum-likelihood fit of the whole model, its DH model, covariance and check."""
    seg, joints, ref = result.segmentation, result.joints, result.reference_pose
    notes, base, nominal = result.warnings, result.base, result.nominal
    types = tuple(j.type for j in joints)
    assert result.target is not None and all(t is not None for t in types)
    rows, Q, P = samples_with_encoders(seg)
    which = target_labels(seg, rows)
    rotations = measured_rotations(seg, rows)
    axes0 = [j.axis for j in joints]
    start = start_model(
        axes0,  # type: ignore[arg-type]
        types,  # type: ignore[arg-type]
        result.target,
        ref,
        Q,
        P,
        which,
        rotations,
        frozenset(result.parked),
    )
    sample_cov = sample_covariance(seg, rows)
    if sample_cov is not None:
        result.noise = NoiseModel("per-sample")
    fit_sigmas = [j.fit.sigma**2 for j in joints if j.fit is not None]
    sigma = math.sqrt(np.mean(fit_sigmas)) if fit_sigmas else 1e-5
    stage("identifying", 0.1)
    timing = result.timing
    clocked = timing is not None and timing.source == "estimated"
    speeds = JointRates(seg.encoders) if clocked and seg.encoders is not None else None
    for attempt in range(MAX_REJOINS + 1):
        rates = None
        if speeds is not None:
            rates = _rates(speeds, seg, rows)
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
                norms = residual_norms(whole.model, Q, P, which=which, rates=rates)
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
        sample_cov = sample_covariance(seg, rows)
        start = replace(whole.model, clock=0.0)
        result.segmentation = seg
    result.timing = timing
    outer = None  # --holdout K: each sample's fold, the same for the selection and the check
    if result.folds > 1:
        outer = fold_of_poses(pose_groups(Q), result.folds, 0)
    request = result.model_request
    if result.parked and request.harmonic_joints is None:  # no harmonics on a parked joint
        revolute = [k for k, t in enumerate(types) if t is JointType.REVOLUTE]
        request = replace(
            request, harmonic_joints=tuple(k for k in revolute if k not in result.parked)
        )
    whole, result.selection = beyond_geometry(
        request,
        whole,
        Q,
        P,
        sigma,
        options,
        folds=result.folds,
        names=[j.name for j in joints],
        warnings=notes,
        info=result.info,
        outer=outer,
    )
    whole, sample_cov, result.noise = with_model_error(
        whole, Q, P, sample_cov, result.noise, which, rates, rotations, notes
    )
    whiten = whitening(result.noise, sample_cov, sigma)
    squares = None  # the whitened cost of the fit's inliers, where the design effect found it
    if rotations is None:
        whole, squares = pose_clustered(whole, Q, P, whiten, which, rates, result.info)

    def refit_terms(model: AxisModel) -> WholeFit:
        """The fit again from ``model`` (lumps merged), weighted and scaled as the final fit."""
        again = {**options, "noise": result.noise, "sample_cov": sample_cov}
        fit = fit_whole_model(model, Q, P, sigma=sigma, **again)
        if rotations is None:
            fit, _ = pose_clustered(fit, Q, P, whiten, which, rates, [])
        return fit

    # lumps of one joint the poses cannot tell apart (a cancelling pair): merged, said
    merged = merge_cancelling(whole, Q, refit_terms, notes)
    if merged is not whole:
        whole, squares = merged, None
    clustered = whole
    nominal_table = nominal.table if nominal is not None else None
    tolerances = decided_tolerances(
        whole,
        nominal,
        kwargs["angle_tol"],
        kwargs["distance_tol"],
        Q,
        P,
        parallel_sigma=parallel_sigma,
        sigma=sigma,
        options={**options, "noise": result.noise, "sample_cov": sample_cov},
        info=result.info,
    )

    def cost(fit: WholeFit) -> float:
        """The whitened sum of squares of ``whole``'s inliers under ``fit`` (positions)."""
        if fit is clustered and squares is not None:
            return squares
        return whitened_cost(fit, clustered.inliers, Q, P, whiten, which=which, rates=rates)

    whole, tolerances = with_fixed_relations(whole, tolerances, cost, result.info)
    kw = {**kwargs, "pair_tolerances": tolerances}

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
    plane = None if base is None else base.plane
    if result.parked and nominal is not None:  # placed by the nominal next to the fitted axes
        axes = place_parked(whole.model.axes, result.parked, nominal, ref)
        whole = replace(whole, model=replace(whole.model, axes=axes))
    ex = extract(list(whole.model.axes), whole.model.target, plane)
    # what the samples determine only beyond a physical bound: held at the nominal
    h_rows = hayati_rows(ex)
    nominal_h = nominal_rows(nominal_table, ref, h_rows)

    def refit(model: Any, within: FloatArray) -> Any:
        """The fit again from ``model`` along ``within`` only, weighted as the final fit."""
        again = {**options, "noise": result.noise, "sample_cov": sample_cov}
        return fit_whole_model(model, Q, P, sigma=sigma, within=within, **again).model

    said: list[str] = []  # the uncertainty's notes, of the fit finally kept
    found = whole_uncertainty(whole, base, extract, ex, ref, nominal_table, said)
    if may_hold(found.shown_std, h_rows):
        whole, _ = hold_unseen(
            whole, extract, plane, h_rows, nominal_table, nominal_h, cost, notes, refit
        )
        if whole.held:
            ex = extract(list(whole.model.axes), whole.model.target, plane)
            said = []
            found = whole_uncertainty(whole, base, extract, ex, ref, nominal_table, said)
    result.info.extend(said)
    mark_parked(found.fixed, found.std, result.parked)
    if found.conditioned is not None:
        mark_parked(found.conditioned.fixed, found.conditioned.std, result.parked)
    result.method = "whole-model maximum likelihood"
    result.extraction, result.analytic, result.whole = ex, analytic, whole
    result.covariance, result.std, result.fixed = found.covariance, found.std, found.fixed
    result.hayati, result.hayati_std = found.hayati, found.hayati_std
    result.conditioned = found.conditioned
    result.tool_orientation = found.tool_orientation
    result.tool_orientation_std = found.tool_orientation_std
    result.extra_tool_points, result.extra_tool_std = found.extra_tool_points, found.extra_tool_std
    result.target, result.sigma = whole.model.target, sigma * math.sqrt(whole.chi2_dof)
    identifiability_notes(whole, nominal is not None, notes, result.info)
    check_noise_model(result.noise, whole.chi2_dof, notes)
    stage("validating", 0.0)
    tools = np.vstack([ex.tool_point[None], result.extra_tool_points])
    if whole.model.terms is not None:  # the terms in the table's frames
        frames = fk_frames(ex.standard, ref, T_base=ex.T_measurement_base)
        result.terms = to_table(whole.model.terms, frames)
        result.terms_std = term_std(whole)
    # the table's joint values: ref + s (q − ref) with fitted scales, deflected by the terms
    Q_table = Q.map(lambda q: table_values(result, q), Q.shape)
    if result.terms is not None:  # what the terms move, at the samples
        bare = Q.map(lambda q: table_values(result, q, deflected=False), Q.shape)
        moved = deflections(
            ex, Q, Q_table, bare, result.terms, term_covariance(whole), result.terms_std
        )
        result.deflection_max, result.deflection_target = moved.joints, moved.target
        result.deflection_max_std, result.deflection_target_std = moved.joints_std, moved.target_std
        result.deflection_vectors = moved.vectors
    result.validation = validate_samples(seg, rows, Q_table, P, ex, whole.inliers, tools, which)
    stamps = np.asarray(seg.column("t_ns", rows), dtype=np.int64)
    names = sample_names(stamps, rows, result.log.point_ids)
    norms = residual_norms(whole.model, Q, P, which=which, rates=rates)
    out = name_outliers(names, norms, whole.inliers, result.info, notes)
    result.outlier_names, result.outlier_rows = [names[i] for i in out.tolist()], rows[out]
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
        held_in_fold: list[dict[int, str]] = []  # the pairs each fold holds, from its poses
        if parallel_sigma is None and outer is not None:
            held_in_fold = fold_holds(
                clustered,
                nominal,
                kwargs["angle_tol"],
                kwargs["distance_tol"],
                Q,
                P,
                outer=outer,
                folds=result.folds,
                sigma=sigma,
                options={**options, "noise": result.noise, "sample_cov": sample_cov},
            )

        def refine(fit: WholeFit, k: int) -> WholeFit:
            """Fold ``k``'s fit held to the pairs its own poses hold."""
            held = held_in_fold[k] if held_in_fold else {}
            if not held:
                return fit
            parallel = [i for i, kind in held.items() if kind == "parallel"]
            return constrain_pairs(fit, parallel, [i for i in held if i not in parallel])

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
                fold=outer,
                starts=() if result.selection is None else result.selection.fold_starts,
                refine=refine,
            )
        )
        if any(held_in_fold):
            said = [
                ", ".join(f"{i + 1}–{i + 2}" for i in sorted(h)) or "none" for h in held_in_fold
            ]
            result.holdout[-1].notes.append(
                "the pairs held parallel were decided again in each fold from its training "
                f"poses: {_tally(said, '; ')}."
            )
        check = result.holdout[-1]
        if check.pose_samples is not None and result.log.point_ids is not None:
            check.pose_names = [names[i] for i in check.pose_samples.tolist()]
        check.range_sd = range_sd(whole, Q)
        if check.expected_rms is not None and check.range_sd > 0.5 * check.calibrated.rms:
            check.notes.append(
                f"over every combination of the session's joint ranges, poses it may never have "
                f"visited among them, the model's own FK σ is {check.range_sd * 1e3:.4f} mm RMS: "
                f"the error to expect there is about {check.expected_rms * 1e3:.4f} mm."
            )
        nested = [] if result.selection is None else result.selection.fold_choices
        if nested:
            result.holdout[-1].notes.append(
                "--model auto chose again in each fold from its training poses alone (nested "
                f"cross-validation): {_tally(nested, ', ')}; the held-out error is that of the "
                "whole procedure."
            )
        swept = swept_share(seg, rows)
        if swept >= SWEPT_SHARE:
            result.holdout[-1].notes.append(
                f"{swept:.0%} of the samples are in sweeps of one joint alone: the held-out "
                "poses lie on the swept arcs, so an error of the joints together — at poses "
                "the session never went to — is not in this figure; --validate a log of "
                "random poses to see it."
            )


def _tally(labels: list[str], sep: str) -> str:
    """Each label with how many of ``labels`` it is, in the order met: "a in 4 of 5"."""
    counts = {c: labels.count(c) for c in dict.fromkeys(labels)}
    return sep.join(f"{c} in {k} of {len(labels)}" for c, k in counts.items())


def range_sd(whole: WholeFit, Q: SampleArray) -> float:
    """The RMS predicted FK σ (m) of ``whole`` at :data:`select.RANGE_POINTS` seeded joint
    vectors uniform in the box of the joint ranges of ``Q`` (m, n)."""
    lo, hi = np.full(Q.shape[1], np.inf), np.full(Q.shape[1], -np.inf)
    for sl in blocks(Q.shape[0]):
        q = Q[sl]
        lo, hi = np.minimum(lo, q.min(axis=0)), np.maximum(hi, q.max(axis=0))
    box = np.random.default_rng(0).uniform(lo, hi, (RANGE_POINTS, Q.shape[1]))
    _, J = predict(whole.model, box, whole.layout, whole.bases)
    assert J is not None
    var = np.einsum("mij,jk,mik->m", J, whole.covariance, J)
    return math.sqrt(max(float(np.mean(var)), 0.0))


#: Share of the fitted samples in single-joint sweeps above which the cross-validation's note
#: says its poses lie on the sweeps.
SWEPT_SHARE = 0.5


def swept_share(seg: Segmentation, rows: NDArray[np.intp]) -> float:
    """The share of the samples ``rows`` that lie in a sweep of one joint alone."""
    inside = 0
    for sl in blocks(rows.size):
        inside += int(np.count_nonzero(seg.joint(rows[sl]) > 0))
    return inside / max(rows.size, 1)


def _validate_log(
    result: ProcessResult,
    path: str | Path,
    pipeline: Pipeline | None,
    fast: bool,
    placed: list[Placed | None],
) -> None:
    """Score ``result`` at the poses of the log at ``path`` (``--validate``), the nominal and
    the calibrated model on one footing (:mod:`dhlog.identify.check.footing`); ``placed`` keeps the
    nominal as placed on this session once it is (one item)."""
    ex = result.extraction
    if ex is None or not result.complete:
        result.warnings.append(f"{path}: not scored: the result is not complete.")
        return
    # the nominal's names where it has them (a UR driver's bag validating a calibration whose
    # log numbered its joints), else the calibrated log's: matched by the reader's rules
    named = result.nominal is not None and bool(result.nominal.joint_names)
    log = read_log(
        path,
        pipeline,
        fast=fast,
        joint_names=result.nominal.joint_names
        if named and result.nominal is not None
        else result.segmentation.joint_names,
        joint_source=result.nominal.source
        if named and result.nominal is not None
        else f"{result.path} (the calibrated log)",
    )
    seg = segment_log(log, joint_types=list(ex.standard.joint_types))
    if seg.n_joints != ex.standard.n or not seg.has_encoders:
        raise NotScoredError(
            f"{path}: has {seg.n_joints} joints{'' if seg.has_encoders else ' and no encoders'}; "
            f"--validate needs a log of the same robot ({ex.standard.n} joints) with encoder "
            "values.",
            unplaced=True,
        )
    rows, Qs, Ps = samples_with_encoders(seg)
    which = target_labels(seg, rows)
    rotations = measured_rotations(seg, rows)
    primary = slice(None) if which is None else which == 0
    Q, P = Qs[primary], Ps[primary]  # a session scored: its own poses, whole
    if not placed:
        placed.append(_nominal_on_session(result))
    nominal = result.nominal
    own = [result.validation.rms] if result.validation is not None else []
    own += [h.calibrated.rms for h in result.holdout if h.kind == "cross-validation"]
    result.holdout.append(
        score_poses(
            Placed(ex.standard, ex.T_measurement_base, ex.tool_point, result.tool_orientation),
            Q,
            P,
            path=str(path),
            nominal=placed[0],
            rotations=None if rotations is None else rotations[primary],
            table_values=table_values(result, Q),
            nominal_values=None if nominal is None else nominal.joint_values(Q),
            own_error=max(own) if own else None,
        )
    )
    if log.point_ids is not None:  # the session's held-out poses by the export's ids
        mine = rows if which is None else rows[primary]
        names = sample_names(np.asarray(seg.column("t_ns", mine), np.int64), mine, log.point_ids)
        check = result.holdout[-1]
        check.pose_names = pose_names(np.asarray(Q), np.asarray(P), names, check.positions)


#: Largest number of the session's samples the nominal is placed on for ``--validate``.
NOMINAL_SAMPLES = 20000


def _nominal_on_session(result: ProcessResult) -> Placed | None:
    """The nominal placed on the session's samples (the fit's inliers of the primary target, at
    most :data:`NOMINAL_SAMPLES`, evenly strided): the "before" a held-out log scores. None
    without a nominal or a whole-model fit, or when it cannot be placed (said)."""
    nominal, whole, seg = result.nominal, result.whole, result.segmentation
    if nominal is None or whole is None:
        return None
    rows, Q, P = samples_with_encoders(seg)
    pick = inlier_picks(seg, rows, whole, NOMINAL_SAMPLES)
    try:
        return nominal_on_session(
            nominal.table,
            nominal.joint_values(Q[pick]),
            P[pick],
            measured_rotations(seg, rows[pick]),
            tool_point=nominal.tool_point,
            T_base=nominal.T_base,
        )
    except GeometryError as exc:
        result.warnings.append(
            f"the nominal could not be placed on this session ({exc}): held-out logs score "
            "the calibrated model alone."
        )
        return None


def _rates(speeds: JointRates, seg: Segmentation, rows: NDArray[np.intp]) -> PerSample:
    """The joints' speeds (m, n) at the samples ``rows``, read a block at a time."""
    return PerSample(
        (rows.size, seg.n_joints), lambda index: speeds.at(seg.t_ns[rows[index]])
    ).filled()


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
