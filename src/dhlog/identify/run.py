"""``dhlog process``: from a calibration log to the DH model, its uncertainty and its check —
the run's flow, top to bottom; each step's work is in the module named.

read (``io.reader``; a camera log: ``identify.camera.flow``) → the log segmented, its units
and clock (``identify.session.segmented``) → each joint fitted and the base plane: the
:class:`~dhlog.identify.stages.Session` (``identify.session.session_of``) → the analytic
start: line geometry on those axes (``identify.read.extract``, seed 000) → the fit of the whole
model to every sample with encoder values and all read off it (``identify.wholefit``: a
:class:`~dhlog.identify.stages.ModelFit`) → the one frozen
:class:`~dhlog.identify.stages.Identification` (``_built``) → what makes it implausible
(``identify.check.plausible.judge``) → the held-out logs (``identify.heldout``). The result
document is ``result.document``.

``--analytic-only`` (and a log without encoders) stops at the analytic start, with its own
propagated covariance. When some joints cannot be identified, what was identified is kept: their
fits and axes, and the DH rows that only need identified axes; the joints at fault are named with
the reason — unless the other samples (coupled moves, static poses) determine them from a start
(``identify.fit.start``: the nominal, or a coupled move's circle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from dhlog.errors import GeometryError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line
from dhlog.identify.check.plausible import judge
from dhlog.identify.check.validate import (
    check_residual,
    validate_sweeps,
)
from dhlog.identify.fit.register import Registration
from dhlog.identify.fit.samples import (
    START_TARGET_POINTS,
)
from dhlog.identify.fit.start import start_unswept
from dhlog.identify.heldout import validated
from dhlog.identify.joints.sweeps import (
    JointReport,
    TargetAtReference,
)
from dhlog.identify.model.parked import (
    encoder_spans,
    parked_warning,
)
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.options import DEFAULTS, ProcessOptions
from dhlog.identify.read.analytic import (
    pair_tolerances,
    partial_extraction,
)
from dhlog.identify.read.extract import Extraction, Tolerances
from dhlog.identify.read.uncertainty import analytic_uncertainty
from dhlog.identify.segment.clocks import COARSE_BELOW, motion_lags
from dhlog.identify.session import Stage, segmented, session_of
from dhlog.identify.stages import (
    Checks,
    FitRequest,
    Identification,
    ModelFit,
    Readout,
    Session,
    table_values,
)
from dhlog.identify.wholefit import identify_whole
from dhlog.io.dhfile import DHModel
from dhlog.io.reader import LogData, camera_pipeline, read_log
from dhlog.io.writer import sha256_begun, sha256_of

__all__ = ["Identification", "ProcessOptions", "process_data", "process_log", "table_values"]


def process_log(
    path: str | Path,
    options: ProcessOptions = DEFAULTS,
    *,
    progress: Stage | None = None,
) -> Identification:
    """Run the whole identification on the log at ``path`` (see the module docstring), as
    ``options`` asks (:class:`~dhlog.identify.options.ProcessOptions`).

    A vision log (camera images; a camera pipeline) is calibrated from its detected board
    corners (:mod:`dhlog.identify.camera.flow`). ``options.validate``: further logs (other
    sessions of the same robot) whose poses score the result and the nominal on one footing
    (:mod:`dhlog.identify.check.footing`; a log that cannot be scored is a warning).
    ``progress(stage, fraction)`` is called as each stage advances."""
    pipeline, nominal = options.pipeline, options.nominal
    model, validate, fast = options.model, options.validate, options.fast
    camera = camera_pipeline(path, pipeline)
    if camera is not None:  # one Observations a camera
        from dhlog.identify.camera.flow import process_observations
        from dhlog.identify.camera.frames.observe import observe

        digest = sha256_begun(path)  # beside the long walk: the log as it was read
        observations = observe(
            path,
            camera,
            jobs=options.jobs,
            progress=None if progress is None else (lambda f: progress("detecting", f)),
            joint_names=None if nominal is None else nominal.joint_names,
            joint_source="model" if nominal is None else nominal.source,
        )
        found = process_observations(
            observations,
            options,
            sha256=digest(),
            progress=progress,
            start=process_poses,
            pipeline=camera.name,
        )
        if model.mode != "geometric":
            said = (
                f"--model {model.mode}: a camera calibration fits the geometric model; terms "
                "beyond the geometry (gravity, gears) are not fitted from a camera's corners yet."
            )
            found = found.said(Note.info(said, "camera-geometric"))
        if validate:
            said = (
                "--validate: held-out logs score tracker calibrations; a camera's is scored by "
                "--holdout K over its own frames (the held-out logs were not scored)."
            )
            found = found.said(Note.warning(said, "camera-validate"))
        return found
    log = read_log(
        path,
        pipeline,
        fast=fast,
        progress=None if progress is None else (lambda f: progress("reading", f)),
        joint_names=None if nominal is None else nominal.joint_names,
        joint_source="model" if nominal is None else nominal.source,
    )
    result = process_data(log, options, sha256=sha256_of(path), progress=progress)  # 0.03 s/55 MB
    result = _clock_hint(result, log)
    result = judge(result)  # implausible lengths or FK check (a camera's: in its pixel fit)
    return validated(result, list(validate), pipeline, fast)


def process_poses(
    log: LogData,
    *,
    sha256: str,
    nominal: DHModel | None,
    reference_pose: FloatArray | None,
    model: ModelRequest,
    progress: Stage | None,
) -> Identification:
    """The tracker's run on a camera's board poses (their log, as the camera flow writes it):
    the start of the pixel fit, which :func:`dhlog.identify.camera.flow.process_observations`
    takes as ``start``."""
    asked = ProcessOptions(nominal=nominal, reference_pose=reference_pose, model=model)
    return process_data(log, asked, sha256=sha256, progress=progress)


def _clock_hint(result: Identification, log: LogData) -> Identification:
    """``result`` with a warning naming the clock as a likely cause where the run went wrong —
    joints not identified, or a target turning far from once per encoder unit — the joint
    states were not moved, and the joints' motion and the target's line up only at offsets of
    :data:`~dhlog.identify.segment.clocks.COARSE_BELOW` or more, which nothing confirmed
    (without a nominal, sweeps alike in time cannot be told apart)."""
    timing = result.timing
    trouble = not result.complete or any(note.code == "encoder-slope" for note in result.notes)
    if not trouble or log.joints is None or log.pipeline.segmentation.clock_offset_fixed:
        return result
    if timing is not None and timing.coarse:
        return result
    lags = motion_lags(log)
    if not lags or any(abs(lag) < COARSE_BELOW for lag in lags):
        return result
    given = log.pipeline.segmentation.clock_offset
    said = (
        "the joints' motion and the target's line up only with the joint states' stamps moved "
        f"by {', '.join(f'{lag:+.2f}' for lag in lags)} s"
        + (f" beyond the pipeline's clock_offset of {given:+.3f} s" if given else "")
        + ", which the points could not tell apart or confirm: the two clocks may be that far "
        "apart (two computers without a common time). Give the robot's nominal (--nominal), "
        "which tells them apart, or the offset as [segmentation] clock_offset (then "
        f"{', '.join(f'{given + lag:.2f}' for lag in lags)}), or fix the clocks at the source."
    )
    return result.said(Note.warning(said, "clock-unconfirmed"))


def process_data(
    log: LogData,
    options: ProcessOptions = DEFAULTS,
    *,
    sha256: str = "",
    progress: Stage | None = None,
) -> Identification:
    """The identification of :func:`process_log` on streams already decoded (``LogData``), as
    ``options`` asks.

    Default: the maximum-likelihood fit of the whole model to every sample with encoder
    values, started from the analytic result (per-joint fits + line geometry). With
    ``analytic_only`` (or without encoders), the analytic result with its propagated covariance.
    """

    def stage(what: str, fraction: float) -> None:
        if progress is not None:
            progress(what, fraction)

    cut = segmented(log, options, stage)
    session, said = session_of(cut.log or log, cut, options, stage)
    notes = [*cut.notes, *said]  # the run's notes, in the order said
    head = _Head(sha256, options.holdout, options.model, cut.implausible)
    request = _request(session, options)
    whole_wanted = session.segmentation.has_encoders and not options.analytic_only
    if not all(j.ok for j in session.joints):
        return _partial(session, head, tuple(notes), request, whole_wanted, stage)
    stage("identifying", 0.0)
    start = _analytic_start(session, request.tolerances, whole_wanted)
    if whole_wanted:
        try:
            fit = identify_whole(
                replace(session, target=start.target), start.extraction, request, stage
            )
            return _built(session, head, tuple(notes), fit)
        except (GeometryError, np.linalg.LinAlgError) as exc:
            failed = f"the whole-model fit failed ({exc}); the result is the analytic one."
            notes.append(Note.warning(failed, "whole-fit-failed"))
    elif session.segmentation.has_encoders:
        only = "--analytic-only: the seed method's result (per-joint fits, line geometry)."
        notes.append(Note.info(only, "analytic-only"))
    else:
        only = "no encoder values: the whole-model fit needs them; the result is the analytic one."
        notes.append(Note.info(only, "analytic-only"))
    return _analytic_result(session, head, tuple(notes), start, request.tolerances, stage)


def _request(session: Session, options: ProcessOptions) -> FitRequest:
    """What the run asks of the fit of the whole model: ``options``' and the extraction's
    tolerances, per pair from the joints' fits where every joint has one."""
    joints, nominal = session.joints, session.nominal
    angle_tol, distance_tol = options.angle_tol, options.distance_tol
    tolerances = Tolerances(
        angle_tol,
        distance_tol,
        pair_tolerances(
            [(j.fit.axis_covariance, j.fit.center) for j in joints if j.fit is not None]
            if all(j.fit is not None for j in joints)
            else None,
            nominal,
            angle_tol,
            distance_tol,
        ),
    )
    return FitRequest(
        options.holdout, options.model, options.fit_scales, options.parallel_sigma, tolerances
    )


def _partial(
    session: Session,
    head: _Head,
    notes: tuple[Note, ...],
    request: FitRequest,
    whole_wanted: bool,
    stage: Stage,
) -> Identification:
    """The result of a session some joints of which the sweeps did not identify: the whole
    model fitted from a start (the nominal, a coupled move) where there is one, else what was
    identified — the rows that need only identified axes — with each joint at fault named."""
    joints, nominal = session.joints, session.nominal
    started = _from_a_start(session, request, stage) if whole_wanted else None
    if started is not None and started.fit is not None:
        return _built(
            replace(session, joints=started.joints),
            head,
            (*notes, *started.notes),
            started.fit,
            registration=started.registration,
        )
    said = [*notes, *(started.notes if started is not None else ())]
    said += [
        Note.warning(f"joint {j.index} ({j.name}) was not identified: {j.reason}.", "unidentified")
        for j in joints
        if j.reason
    ]
    if (
        whole_wanted
        and nominal is None
        and any(not j.ok and j.index - 1 not in session.parked for j in joints)
    ):
        needs = (
            "the joints not swept alone need a start: pass --nominal (a library robot or "
            "the robot's DH file) and the whole-model fit identifies them from the other "
            "samples (random static poses, coupled moves)."
        )
        said.append(Note.warning(needs, "needs-nominal"))
    extraction = partial_extraction(session.axes(request.tolerances))
    return _built(session, head, tuple(said), readout=Readout(extraction))


@dataclass(frozen=True)
class _AnalyticStart:
    """The seed method's result on a session whose joints were all identified: the target at
    the reference pose (its mean over the samples, with its covariance; ``target_at`` gives it
    for other axes, from an evenly strided subset of the samples when ``strided``) and the DH
    model line geometry reads off the axes."""

    target_at: TargetAtReference
    strided: bool
    target: FloatArray
    target_cov: FloatArray
    extraction: Extraction


def _analytic_start(session: Session, tolerances: Tolerances, whole_wanted: bool) -> _AnalyticStart:
    """The analytic start (module docstring): the target from every sample (its derivative, for
    the covariance, from an evenly strided subset when the whole model is fitted after)."""
    seg, joints, ref = session.segmentation, list(session.joints), session.reference_pose
    target_at = TargetAtReference(seg, joints, ref, START_TARGET_POINTS if whole_wanted else None)
    target, target_cov = target_at()
    extraction = session.axes(tolerances).extract(target)
    return _AnalyticStart(target_at, whole_wanted, target, target_cov, extraction)


def _analytic_result(
    session: Session,
    head: _Head,
    notes: tuple[Note, ...],
    start: _AnalyticStart,
    tolerances: Tolerances,
    stage: Stage,
) -> Identification:
    """The analytic start as the result: its covariance propagated from the joints' fits and
    the target's samples, and the FK check of its table on the sweeps."""
    seg, joints, ref = session.segmentation, list(session.joints), session.reference_pose
    # the covariance perturbs every axis: the target's derivative is taken on an evenly strided
    # subset of the samples (the mean's derivative; the target itself is from every sample)
    perturbed = (
        start.target_at
        if start.strided
        else TargetAtReference(seg, joints, ref, START_TARGET_POINTS)
    )

    def target_of(axes: list[Line | None]) -> FloatArray:
        return perturbed(axes)[0]

    stage("uncertainty", 0.0)
    found = analytic_uncertainty(
        session.axes(tolerances),
        start.target,
        start.target_cov,
        start.extraction,
        target_of if seg.has_encoders else None,
    )
    said = [*notes, *found.notes]
    stage("validating", 0.0)
    validation = validate_sweeps(seg, joints, start.extraction)
    if validation is not None:
        sigma = math.sqrt(np.mean([j.fit.sigma**2 for j in joints if j.fit is not None]))
        said.extend(check_residual(validation, sigma))
    else:
        unchecked = "no encoder values: FK of the result cannot be checked sample by sample."
        said.append(Note.warning(unchecked, "no-fk-check"))
    return _built(
        session,
        head,
        tuple(said),
        readout=Readout(start.extraction, found, start.target),
        checks=Checks(validation),
    )


@dataclass(frozen=True)
class _Head:
    """What the result carries from the run's request: the log's digest, K of the
    cross-validation, the terms asked for, and what was judged implausible before any fit."""

    sha256: str
    folds: int
    model_request: ModelRequest
    implausible: tuple[str, ...]


def _built(
    session: Session,
    head: _Head,
    notes: tuple[Note, ...],
    fit: ModelFit | None = None,
    *,
    readout: Readout | None = None,
    checks: Checks | None = None,
    registration: Registration | None = None,
) -> Identification:
    """The one result of the run: the session's; the fit's (when there is one; its notes
    after the run's), else the analytic ``readout`` and ``checks``; the nominal's
    ``registration`` on the points (a session with no sweep)."""
    if fit is not None:
        notes = (*notes, *fit.notes)
        readout = fit.readout if readout is None else readout
        checks = fit.checks if checks is None else checks
    return Identification(
        path=session.log.path,
        sha256=head.sha256,
        # one segmentation kept: the fit's (joined again at its clock offset) where there is one
        session=replace(
            session,
            encoded=None,
            segmentation=session.segmentation if fit is None else fit.segmentation,
        ),
        readout=Readout(None) if readout is None else readout,
        checks=Checks(None) if checks is None else checks,
        notes=notes,
        fit=None if fit is None else replace(fit, notes=()),
        folds=head.folds,
        model_request=head.model_request,
        implausible=head.implausible,
        registration=registration,
    )


@dataclass(frozen=True)
class _Started:
    """The joints never moved alone, identified from a start: the fit (None when it failed or
    there was no start), the joints as it left them, the nominal's registration on the points
    (a session with no sweep), and what it said before the fit's own notes."""

    fit: ModelFit | None
    joints: tuple[JointReport, ...]
    registration: Registration | None
    notes: tuple[Note, ...]


def _from_a_start(session: Session, request: FitRequest, stage: Stage) -> _Started:
    """Joints never moved alone, identified by the whole-model fit from every other sample
    (coupled moves, random static poses, stops), started from the nominal or, without one, from
    the circle a coupled move with a parallel neighbour traces
    (:func:`~dhlog.identify.fit.start.start_unswept`). Its ``fit`` is None (and the session's
    joints unchanged) when a joint never moved, there is no start, or the fit fails."""
    nominal, joints = session.nominal, session.joints
    start, said = start_unswept(
        joints, session.segmentation, session.reference_pose, nominal, session.parked
    )
    if start is None:
        return _Started(None, joints, None, said)
    notes = list(said)
    reg = start.registration
    if reg is not None:
        placed = (
            f"no joint was swept alone: the nominal was placed on the points (tracker → base "
            f"by a robust registration; the nominal's RMS there {reg.rms * 1e3:.4f} mm over "
            f"{int(np.count_nonzero(reg.inliers))} samples) and every joint identified by the "
            "whole-model fit from there."
        )
        notes.append(Note.info(placed, "nominal-placed"))
    missing = [j for j in joints if not j.ok and j.index - 1 not in session.parked]
    what = "the coupled moves" if nominal is None else "the nominal"
    # the joints the start gives take its axes and types; the fit's, if it succeeds
    started = tuple(
        replace(
            j,
            type=start.types[k],
            axis=start.axes[k],
            reason=None,
            type_source=start.sources[k],
        )
        if k in start.sources
        else j
        for k, j in enumerate(joints)
    )
    from_start = replace(request, fit_scales=False, parallel_sigma=None)
    try:
        fit = identify_whole(
            replace(session, joints=started, target=start.target), None, from_start, stage
        )
    except (GeometryError, np.linalg.LinAlgError) as exc:
        notes.append(Note.warning(f"the whole-model fit from {what} failed: {exc}", "start-failed"))
        return _Started(None, joints, None, tuple(notes))
    fitted = tuple(
        replace(j, axis=fit.whole.model.axes[k]) if k in start.sources else j
        for k, j in enumerate(started)
    )
    after: list[Note] = []  # said after the fit's own notes
    if session.parked:
        spans = encoder_spans(session.samples()[1])
        names_all = [j.name for j in joints]
        types_all = [j.type for j in started if j.type is not None]
        parked = parked_warning(names_all, session.parked, spans, types_all)
        after.append(Note.warning(parked, "parked"))
    names = ", ".join(f"joint {j.index} ({j.name})" for j in missing)
    if missing and nominal is None:
        alone = (
            f"{names}: never moved alone; started from the circle its coupled move with a "
            "parallel neighbour traces, and identified by the whole-model fit from every sample."
        )
        after.append(Note.warning(alone, "never-alone"))
    elif missing and reg is None:
        alone = (
            f"{names}: never moved alone; identified by the whole-model fit from the other "
            "samples (coupled moves, still poses), started from the nominal."
        )
        after.append(Note.warning(alone, "never-alone"))
    fit = replace(fit, notes=(*fit.notes, *after))
    return _Started(fit, fitted, reg, tuple(notes))
