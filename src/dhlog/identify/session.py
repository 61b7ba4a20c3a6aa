"""The run's first stages: the log segmented (:func:`segmented` → :class:`Segmented`), then each
joint fitted one by one and the base plane (:func:`session_of` →
:class:`~dhlog.identify.stages.Session`), each with the notes it adds.

segment (``identify.segment.segment``) → the units checked (``identify.joints.checks``), the
clock offset's start (``identify.segment.timing``), the joint columns' order (``identify.check
.permutation``) → the joints parked in the session (``identify.model.parked``) → per joint: pick
the sweeps, decide the type, fit the axis robustly, bring it to the reference pose
(``identify.joints.sweeps``) → the base plane (``geometry.fitting``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from dhlog.errors import GeometryError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.fitting import fit_plane
from dhlog.identify.check.permutation import suspected_permutation
from dhlog.identify.check.validate import shown_stride
from dhlog.identify.fit.register import nominal_judge
from dhlog.identify.joints.checks import check_fit_noise, check_sizes, check_units
from dhlog.identify.joints.sweeps import JointReport, fit_joint, samples_with_encoders
from dhlog.identify.model.parked import (
    encoder_spans,
    no_nominal_reason,
    parked_joints,
    parked_pose,
)
from dhlog.identify.options import ProcessOptions
from dhlog.identify.segment.clocks import at_one_rate, on_one_clock, shifted
from dhlog.identify.segment.segment import Segmentation, segment_log
from dhlog.identify.segment.steps import at_one_step, step_note
from dhlog.identify.segment.timing import (
    Drift,
    Timing,
    clock_start,
    sweep_phases,
)
from dhlog.identify.stages import Session
from dhlog.io.reader import LogData

#: Largest number of samples per joint the per-joint fits (the whole-model fit's start) use.
START_FIT_POINTS = 4000

Stage = Callable[[str, float], None]


@dataclass(frozen=True)
class Segmented:
    """The log segmented: the segmentation (joined again at the clock offset's start), the
    clock, the reference pose the table is read at, what is implausible already (a joint
    permutation the data reveal) and the notes said, in order."""

    segmentation: Segmentation
    timing: Timing | None
    reference_pose: FloatArray
    implausible: tuple[str, ...]
    notes: tuple[Note, ...]
    #: the log as segmented: its joint states moved onto the tracker's clock where they were
    #: seconds off it (:func:`~dhlog.identify.segment.clocks.coarse_offset`) and mapped where
    #: their clock drifts (:func:`~dhlog.identify.segment.timing.phase_drift`), else the log read
    log: LogData | None = None


def segmented(log: LogData, options: ProcessOptions, stage: Stage) -> Segmented:
    """``log`` segmented as ``options`` asks (the joint types of the pipeline, else of the
    nominal; its reference pose), its units checked, the clock offset's start, the joint
    columns' order against the nominal where no names decided it."""
    nominal, reference_pose = options.nominal, options.reference_pose
    types_hint = list(log.pipeline.joint_types) if log.pipeline.joint_types else None
    if types_hint is None and nominal is not None:
        types_hint = list(nominal.table.joint_types)
    stage("segmenting", 0.0)
    log, coarse, said = on_one_clock(log, None if nominal is None else nominal_judge(log, nominal))
    seg = segment_log(log, joint_types=types_hint, reference_pose=reference_pose)
    phases = sweep_phases(seg, log, types_hint) if seg.has_encoders else []
    units = check_units(seg, log, phases)  # before a drift's map: a unit slip is no drift
    log, seg, phases, step = at_one_step(
        log,
        seg,
        phases,
        lambda mapped: segment_log(mapped, joint_types=types_hint, reference_pose=reference_pose),
        types_hint,
    )
    if step is not None:
        if coarse:  # matched with the step in the stream (a second on 70 % of it): again
            unmoved = shifted(log, -coarse)
            step = replace(step, at_ns=step.at_ns - round(coarse * 1e9))  # as logged
            judge = None if nominal is None else nominal_judge(unmoved, nominal)
            log, coarse, said = on_one_clock(unmoved, judge)
            seg = segment_log(log, joint_types=types_hint, reference_pose=reference_pose)
            phases = sweep_phases(seg, log, types_hint)
        units = check_units(seg, log, phases)  # the slopes as the sweeps read without the step
    n = seg.n_joints
    notes = [*said, *seg.notes, *units]
    if step is not None:
        notes.append(step_note(step))
    log, seg, phases, drift = at_one_rate(
        log,
        seg,
        phases,
        lambda mapped: segment_log(mapped, joint_types=types_hint, reference_pose=reference_pose),
        types_hint,
    )
    if drift is not None:
        notes.append(_drift_note(drift))
    seg, timing, said = clock_start(seg, log, phases, coarse)
    if drift is not None and timing is not None:
        timing = replace(timing, drift=drift.rate, drift_ref_ns=drift.t_ref_ns)
    if step is not None and timing is not None:
        timing = replace(timing, step=step.seconds, step_at_ns=step.at_ns, step_index=step.index)
    notes.extend(said)
    check_sizes(log.path, n, nominal, reference_pose)
    implausible = []
    order = log.joint_order
    if nominal is not None and (order is None or not order.by_name):  # the data may tell
        permuted = suspected_permutation(seg, nominal)
        if permuted is not None:
            implausible.append(permuted.reason(seg.joint_names))
    every = shown_stride(seg.height)
    if every > 1:
        drawn = (
            f"the recording draws every {every}th sample ({-(-seg.height // every)} of "
            f"{seg.height}; outliers all): a viewer shows no more. Every sample enters the fit "
            "and the FK check."
        )
        notes.append(Note.info(drawn, "recording-stride"))
    ref = (
        np.asarray(reference_pose, dtype=np.float64)
        if reference_pose is not None
        else (seg.reference_pose if seg.reference_pose is not None else np.zeros(n))
    )
    if not seg.has_encoders:
        said_ref = (
            "no encoders: the reference pose is the pose every sweep starts from (all zeros), "
            "and the sense of motion comes from time order."
        )
        notes.append(Note.info(said_ref, "no-encoders"))
    return Segmented(seg, timing, ref, tuple(implausible), tuple(notes), log)


def _drift_note(drift: Drift) -> Note:
    """What the run says of the joint states' clock drift it took out."""
    return Note.warning(
        f"the joint states' clock {drift.described}, so their stamps were mapped onto the "
        "tracker's clock before the sweeps were read again (the Clock line gives the offset "
        "at the sweeps' mean time). Two computers without a common time drift so: "
        "synchronise their clocks (PTP, chrony) for the next session.",
        "clock-drift",
    )


def session_of(
    log: LogData, cut: Segmented, options: ProcessOptions, stage: Stage
) -> tuple[Session, tuple[Note, ...]]:
    """The :class:`~dhlog.identify.stages.Session` of the segmented log: the joints parked in it
    (held at the nominal's reference pose where there is one), each joint fitted one by one in
    chain order (its samples capped at :data:`START_FIT_POINTS` when the whole model is fitted
    after), the base plane; with the notes said."""
    nominal, seg, ref = options.nominal, cut.segmentation, cut.reference_pose
    n = seg.n_joints
    notes: list[Note] = []
    whole_wanted = seg.has_encoders and not options.analytic_only
    max_points = START_FIT_POINTS if whole_wanted else None
    parked: list[int] = []
    samples = None
    spans = None
    if seg.has_encoders:  # joints that never moved: held at the nominal
        samples = samples_with_encoders(seg)
        spans = encoder_spans(samples[1])
        parked = parked_joints(spans) if 0 < len(parked_joints(spans)) < n else []
        if parked and nominal is not None:
            ref = parked_pose(samples[1], ref, parked)
    joints: list[JointReport] = []  # in chain order: a joint's axis is carried by those before
    for k in range(n):
        stage("fitting", k / n)
        report, said = fit_joint(
            JointReport(k + 1, seg.joint_names[k]),
            seg,
            log,
            ref,
            joints,
            nominal,
            options.fit_method,
            max_points,
        )
        notes.extend(said)
        if k in parked and not report.ok and nominal is None and spans is not None:
            report = replace(report, reason=no_nominal_reason(spans, k, report.type))
        joints.append(report)
    notes.extend(check_fit_noise(joints))
    base = None
    if log.base is not None and log.base.height >= 3:
        try:
            base = fit_plane(
                log.base.select(["x", "y", "z"]).to_numpy(),
                what=f"{log.path}: base plane",
                sigma=options.known_noise,
            )
        except GeometryError as exc:
            notes.append(Note.warning(f"the base plane was not used: {exc}", "base-plane"))
    session = Session(
        log=log,
        segmentation=seg,
        joints=tuple(joints),
        reference_pose=ref,
        base=base,
        nominal=nominal,
        parked=tuple(parked),
        timing=cut.timing,
        noise=log.pipeline.noise,
        encoded=samples,
    )
    return session, tuple(notes)
