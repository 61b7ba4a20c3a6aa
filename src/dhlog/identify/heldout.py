"""``--validate LOG``: a result scored at the poses of other sessions of the same robot, the
nominal and the calibrated model on one footing (:func:`validated`).

Each log is read with the nominal's joint names where it has them (else the calibrated log's),
segmented, and scored by :func:`~dhlog.identify.check.footing.score_poses` against the nominal
placed once on the calibrated session's inlier samples. A log that cannot be scored is a
warning; one that cannot be placed or read makes the result implausible.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError, GeometryError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.check.footing import (
    LogSamples,
    NotScoredError,
    Placed,
    Unscored,
    nominal_on_session,
    score_poses,
)
from dhlog.identify.check.holdout import Holdout
from dhlog.identify.check.named import pose_names, sample_names
from dhlog.identify.check.plausible import inlier_picks
from dhlog.identify.fit.placement import Stand
from dhlog.identify.fit.register import clock_judge, register_nominal
from dhlog.identify.fit.samples import measured_rotations
from dhlog.identify.joints.sweeps import samples_with_encoders, target_labels
from dhlog.identify.segment.clocks import at_one_rate, nearest_offset, on_one_clock, shifted
from dhlog.identify.segment.persample import blocks
from dhlog.identify.segment.segment import Segmentation, segment_log
from dhlog.identify.segment.steps import STEP_REACH, ClockStep, at_one_step, stepped
from dhlog.identify.segment.timing import (
    MOVING_SPEED,
    STEP_FRACTION,
    Drift,
    JointRates,
    sweep_phases,
)
from dhlog.identify.stages import Identification, table_values
from dhlog.io.logdata import LogData
from dhlog.io.pipeline import Pipeline
from dhlog.io.reader import read_log
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_point

#: Largest number of the session's samples the nominal is placed on.
NOMINAL_SAMPLES = 20000
#: A held-out sample is a gross outlier where the calibrated model's residual there is off the
#: running median of GROSS_WINDOW samples around it by more than GROSS_RATIO times the median
#: such distance (a tracker's noise alone reaches about 4× over thousands of samples).
GROSS_WINDOW = 5
GROSS_RATIO = 10.0
#: ... where each sample of the window is within GROSS_SPAN (rad or m, every joint) of it: a
#: sweep under a 10 Hz tracker steps 0.05 rad a sample, random poses lie a radian apart.
GROSS_SPAN = 0.2


def validated(
    result: Identification, logs: list[str | Path], pipeline: Pipeline | None, fast: bool
) -> Identification:
    """``result`` scored at the poses of each held-out log (``--validate``): a log that cannot
    be scored is a warning and a ``not_scored`` entry — and makes the result implausible when
    it could not be placed or read, since the validation asked for is missing."""
    if not logs:
        return result
    if result.extraction is None or not result.complete:
        return result.said(
            *(
                Note.warning(f"{path}: not scored: the result is not complete.", "not-scored")
                for path in logs
            )
        )
    #: the nominal on this session, placed once when a log first needs it (or why it could not
    #: be: said once, after the log that needed it)
    placed = functools.cache(lambda: _nominal_on_session(result))
    told = False
    checks: list[Holdout] = []
    notes: list[Note] = []
    not_scored: list[Unscored] = []
    implausible: list[str] = []
    for other in logs:
        try:  # each log's own pipeline unless named
            checks.append(_validate_log(result, other, pipeline, fast, placed))
        except DhlogError as exc:  # the calibration stands: the log is one line
            said_one = str(exc) if str(other) in str(exc) else f"{other}: {exc}"
            notes.append(Note.warning(f"held-out log not scored: {said_one}", "not-scored"))
            unplaced = isinstance(exc, NotScoredError) and exc.unplaced
            not_scored.append(Unscored(str(other), said_one, unplaced))
            if unplaced:
                implausible.append(
                    f"the held-out log {other} could not be placed, so the calibration has no "
                    "validation on it (it is not scored, never reported as the result's "
                    "figure): " + said_one.removeprefix(f"{other}: ")
                )
            elif not isinstance(exc, NotScoredError):  # asked for, and not read at all
                implausible.append(
                    f"the held-out log {other} could not be read, so the validation asked for "
                    "is missing: " + said_one.removeprefix(f"{other}: ")
                )
        if not told and placed.cache_info().currsize:  # said once, where it happened
            told, why = True, placed()[1]
            if why is not None:
                notes.append(Note.warning(why, "nominal-placement"))
    return replace(
        result,
        checks=replace(result.checks, holdout=(*result.holdout, *checks)),
        notes=(*result.notes, *notes),
        not_scored=(*result.not_scored, *not_scored),
        implausible=(*result.implausible, *implausible),
    )


def _validate_log(
    result: Identification,
    path: str | Path,
    pipeline: Pipeline | None,
    fast: bool,
    placed: Callable[[], tuple[Placed | None, str | None]],
) -> Holdout:
    """Score ``result`` at the poses of the log at ``path`` (``--validate``), the nominal and
    the calibrated model on one footing (:mod:`dhlog.identify.check.footing`); ``placed()``
    gives the nominal as placed on this session (placed at the first call), with the warning
    when it cannot be. Raises :class:`~dhlog.errors.DhlogError` when the log cannot be read or
    scored."""
    ex = result.extraction
    assert ex is not None
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
    calibrated = Placed(
        ex.standard, Stand(ex.T_measurement_base, ex.tool_point, result.tool_orientation)
    )
    # its joint states on a clock of their own (another session): moved, as the calibrated
    # model placed on its samples confirms
    judge = clock_judge(log, ex.standard, functools.partial(table_values, result), calibrated.stand)
    log, coarse, moved = on_one_clock(log, judge)
    seg = _segmented(log, path, ex.standard)
    types = list(ex.standard.joint_types)
    log, seg, phases, step = at_one_step(  # a clock set mid-session: the stamps after moved
        log,
        seg,
        sweep_phases(seg, log, types),
        lambda mapped: _segmented(mapped, path, ex.standard),
        types,
    )
    log, seg, _, drift = at_one_rate(  # a clock that drifts: its stamps mapped
        log,
        seg,
        phases,
        lambda mapped: _segmented(mapped, path, ex.standard),
        types,
    )
    if coarse or drift is not None or step is not None:  # judged as the log is joined now
        judge = clock_judge(
            log, ex.standard, functools.partial(table_values, result), calibrated.stand
        )
    rows, Qs, Ps = samples_with_encoders(seg)
    clock = _own_clock(log, seg, rows, judge, coarse)
    joined = shifted(log, clock.offset - coarse) if clock.offset != coarse else log
    if step is not None and clock.checked:  # the step sized again, as the log is joined
        joined, step = _step_sized(joined, step, result, calibrated.stand)
    if joined is not log:  # joined again where its clock puts the joint states
        seg = _segmented(joined, path, ex.standard)
        rows, Qs, Ps = samples_with_encoders(seg)
    which = target_labels(seg, rows)
    kept = np.ones(rows.size, dtype=bool) if which is None else which == 0
    if clock.moving is not None:  # a static-pose log: scored at its stops
        kept &= ~clock.moving
    rotations = measured_rotations(seg, rows)
    gross = _gross_outliers(result, Qs[kept], Ps[kept])
    kept[np.flatnonzero(kept)[gross]] = False
    Q, P = Qs[kept], Ps[kept]  # a session scored: its own poses, whole
    nominal = result.nominal
    own = [result.validation.rms] if result.validation is not None else []
    own += [h.calibrated.rms for h in result.holdout if h.kind == "cross-validation"]
    samples = LogSamples(
        Q,
        P,
        rotations=None if rotations is None else rotations[kept],
        table_values=table_values(result, Q),
        nominal_values=None if nominal is None else nominal.joint_values(Q),
    )
    check = score_poses(
        calibrated,
        samples,
        path=str(path),
        nominal=placed()[0],
        own_error=max(own) if own else None,
    )
    check = replace(
        check,
        notes=(
            *check.notes,
            *(note.text for note in moved),
            *(() if step is None else (_step_said(step),)),
            *(() if drift is None else (_drift_said(drift),)),
            *clock.said(which),
            *_gross_note(gross),
        ),
        clock_step=None if step is None else step.seconds,
        clock_step_at_ns=0 if step is None else step.at_ns,
        clock_drift=None if drift is None else drift.rate,
        drift_reference_ns=0 if drift is None else drift.t_ref_ns,
        clock_offset=log.pipeline.segmentation.clock_offset + clock.offset
        if clock.checked or clock.offset or drift is not None
        else None,
        moving_left_out=clock.left_out(which),
        outliers_left_out=int(np.count_nonzero(gross)),
    )
    if log.point_ids is not None:  # the session's held-out poses by the export's ids
        mine = rows[kept]
        names = sample_names(np.asarray(seg.column("t_ns", mine), np.int64), mine, log.point_ids)
        check = replace(
            check, pose_names=pose_names(np.asarray(Q), np.asarray(P), names, check.positions)
        )
    return check


def _gross_outliers(result: Identification, Q: FloatArray, P: FloatArray) -> NDArray[np.bool_]:
    """The gross outliers among a held-out log's samples ``Q``, ``P`` (time order): where the
    calibrated model's residual, placed on them (robustly: the outliers set aside; as it
    stands where the flange keeps to one line), is off the running median of its neighbours'
    (:data:`GROSS_WINDOW` samples) by more than :data:`GROSS_RATIO` times the median such
    distance, and than as many times the calibration's own FK RMS. A tracker's gross outlier
    (a beam break, a stray reflection) is one sample's;
    the model's errors, a moved tracker's and a re-mounted probe's vary smoothly along the
    log, so none of them is taken for one; a sample whose neighbours are of other poses
    (:data:`GROSS_SPAN` away) is not judged."""
    from scipy.ndimage import median_filter

    ex = result.extraction
    assert ex is not None
    if P.shape[0] < GROSS_WINDOW:
        return np.zeros(P.shape[0], dtype=bool)
    values, P = table_values(result, Q), np.asarray(P, dtype=np.float64)
    T, tool = ex.T_measurement_base, ex.tool_point
    try:  # placed robustly on the samples, so a moved tracker's rotation leaves no curvature
        reg = register_nominal(ex.standard, values, P, tool_point=tool, T_base=T)
        T, tool = reg.T_measurement_base, reg.tool_point
    except (GeometryError, np.linalg.LinAlgError):
        pass  # the flange on one line: as it stands
    residual = P - fk_point(ex.standard, values, tool, T_base=T)
    around = median_filter(residual, size=(GROSS_WINDOW, 1), mode="nearest")
    off = np.linalg.norm(residual - around, axis=1)
    # only where the neighbours are of one motion: across poses apart (one sample a pose) the
    # model's own errors jump, and a pose it misses would be taken for an outlier
    near = np.ones(P.shape[0], dtype=bool)
    for k in range(1, GROSS_WINDOW // 2 + 1):
        step = np.max(np.abs(values[k:] - values[:-k]), axis=1) <= GROSS_SPAN
        near[k:] &= step
        near[:-k] &= step
    typical = float(np.median(off[near])) if np.any(near) else 0.0
    # a tracker that rounds below its noise leaves most samples on their median: the floor
    # is the calibration's own error, which no gross outlier comes near
    own = result.validation.rms if result.validation is not None else 0.0
    return np.asarray(near & (off > GROSS_RATIO * max(typical, own)), dtype=bool)


def _step_sized(
    log: LogData, step: ClockStep, result: Identification, stand: Stand
) -> tuple[LogData, ClockStep]:
    """A held-out log's clock step, read from its sweeps' lags (as joined then: a log tens of
    ms off reads them to 0.1 ms), sized again where the calibrated model placed on the samples
    after it misses them least (within :data:`~dhlog.identify.segment.steps.STEP_REACH`): the
    log with the stamps after it moved by that, and the step."""
    from scipy.optimize import minimize_scalar  # scipy.optimize costs 0.35 s to import

    ex = result.extraction
    assert ex is not None and log.joints is not None
    margin = round(log.pipeline.segmentation.join_tolerance * 1e9)  # joint states after it only
    since = int(log.joints["t_ns"][step.index]) + margin
    later = clock_judge(
        log, ex.standard, functools.partial(table_values, result), stand, since_ns=since
    )
    if later is None:
        return log, step
    found = minimize_scalar(
        later, bounds=(-STEP_REACH, STEP_REACH), method="bounded", options={"xatol": 1e-7}
    )
    if not float(found.fun) < later(0.0):
        return log, step
    at = float(found.x)
    return stepped(log, step.index, at), replace(step, seconds=step.seconds + at)


def _step_said(step: ClockStep) -> str:
    """What a held-out log's scoring says of its clock set mid-session."""
    return (
        f"its joint states' clock {step.described} during the session (at their stamp "
        f"{step.at_ns} ns as logged): their stamps from there on were moved "
        f"{step.seconds * 1e3:+.3f} ms before it was scored."
    )


def _drift_said(drift: Drift) -> str:
    """What a held-out log's scoring says of its clock's drift."""
    return (
        f"its joint states' clock {drift.described}: their stamps were mapped by it before it "
        "was scored (its clock offset holds at the sweeps' mean time)."
    )


def _gross_note(gross: NDArray[np.bool_]) -> tuple[str, ...]:
    """What a held-out log's scoring says of the gross outliers it left out."""
    count = int(np.count_nonzero(gross))
    if not count:
        return ()
    return (
        f"{count} gross outlier(s) of the tracker left out of {gross.size} samples (each off "
        f"its neighbours along the log by more than {GROSS_RATIO:g}× the median and the "
        "calibration's own FK RMS: a beam break "
        "or a stray reflection, not the robot); both models are scored without them.",
    )


def _segmented(log: LogData, path: str | Path, table: StandardDH) -> Segmentation:
    """A held-out log segmented with the calibrated table's joint types; raises
    :class:`NotScoredError` unless it is the same robot with encoder values."""
    seg = segment_log(log, joint_types=list(table.joint_types))
    if seg.n_joints != table.n or not seg.has_encoders:
        raise NotScoredError(
            f"{path}: has {seg.n_joints} joints{'' if seg.has_encoders else ' and no encoders'}; "
            f"--validate needs a log of the same robot ({table.n} joints) with encoder "
            "values.",
            unplaced=True,
        )
    return seg


@dataclass(frozen=True)
class _OwnClock:
    """A held-out log's clock as its scoring found it: the ``offset`` (s) added to its joint
    states' stamps, whether it was ``checked`` against the calibrated model, the samples taken
    while the joints moved where the log is a static-pose one (``moving``, over the rows with
    encoder values: left out; None: a moving log, scored whole) and what to say of it."""

    offset: float
    checked: bool
    moving: NDArray[np.bool_] | None
    notes: tuple[str, ...]

    def left_out(self, which: NDArray[np.int64] | None) -> int:
        """The first target's samples left out as taken while the joints moved."""
        if self.moving is None:
            return 0
        return int(np.count_nonzero(self.moving if which is None else self.moving & (which == 0)))

    def said(self, which: NDArray[np.int64] | None) -> tuple[str, ...]:
        """What the scoring says of the log's clock."""
        left = self.left_out(which)
        if not left:
            return self.notes
        return (
            *self.notes,
            f"scored at its stops: the {left} sample(s) taken while the joints moved were left "
            "out (a static-pose log's moves are transit between its poses, and an offset "
            "between the joint states' clock and the tracker's misjoins them).",
        )


def _own_clock(
    log: LogData,
    seg: Segmentation,
    rows: NDArray[np.intp],
    judge: Callable[[float], float] | None,
    coarse: float,
) -> _OwnClock:
    """Where a held-out log's joint states join its points. A log taken mostly at stops
    (fewer than :data:`~dhlog.identify.segment.timing.STEP_FRACTION` of its samples while the
    joints move) is scored at them: its samples taken in motion are transit, which an offset
    between the clocks misjoins — left out. A moving log is joined at its own clock offset:
    the one at which the calibrated model placed on its samples misses them least
    (:func:`~dhlog.identify.segment.clocks.nearest_offset`), where the pipeline does not fix
    it."""
    assert seg.encoders is not None
    speeds = JointRates(seg.encoders)
    moving = np.zeros(rows.size, dtype=bool)
    for sl in blocks(rows.size):
        moving[sl] = np.max(np.abs(speeds.at(seg.t_ns[rows[sl]])), axis=1) > MOVING_SPEED
    if np.count_nonzero(moving) < STEP_FRACTION * rows.size:
        return _OwnClock(coarse, False, moving, ())
    if log.pipeline.segmentation.clock_offset_fixed:
        return _OwnClock(coarse, False, None, ())
    if judge is None:
        said = (
            "its joint states' clock could not be checked against the tracker's (too few of its "
            "first target's samples have joint states to place the calibrated model on): "
            "scored as joined."
        )
        return _OwnClock(coarse, False, None, (said,))
    fine = nearest_offset(judge)  # the judge reads the log as it is joined now
    if fine is None:
        if math.isfinite(judge(0.0)):
            return _OwnClock(coarse, True, None, ())
        said = (
            "its joint states' clock could not be checked against the tracker's (the calibrated "
            "model cannot be placed on its samples alone: poses on one line?): scored as joined, "
            "where a clock offset shows as an error along the motion."
        )
        return _OwnClock(coarse, False, None, (said,))
    found, given = coarse + fine, log.pipeline.segmentation.clock_offset
    beyond = [
        *([f"the coarse match's {coarse:+.2f} s"] if coarse else []),
        *([f"the pipeline's clock_offset of {given * 1e3:+.3f} ms"] if given else []),
    ]
    before = judge(0.0)
    misses = (
        f"{before * 1e3:.4f} → {judge(fine) * 1e3:.4f} mm RMS"
        if math.isfinite(before)
        else f"{judge(fine) * 1e3:.4f} mm RMS; as joined it could not be placed"
    )
    said = (
        f"its joint states' stamps ran {abs(fine) * 1e3:.3f} ms "
        f"{'behind' if fine > 0 else 'ahead of'} the tracker's clock"
        + (f" beyond {' and '.join(beyond)}" if beyond else "")
        + " (a session's clock is its own): the offset at which the calibrated model, placed on "
        f"its samples, misses them least ({misses}), taken out before it was scored."
    )
    return _OwnClock(found, True, None, (said,))


def _nominal_on_session(result: Identification) -> tuple[Placed | None, str | None]:
    """The nominal placed on the session's samples (the fit's inliers of the primary target, at
    most :data:`NOMINAL_SAMPLES`, evenly strided): the "before" a held-out log scores. None
    without a nominal or a whole-model fit, or when it cannot be placed (with the warning)."""
    nominal, whole, seg = result.nominal, result.whole, result.segmentation
    if nominal is None or whole is None:
        return None, None
    rows, Q, P = samples_with_encoders(seg)
    pick = inlier_picks(seg, rows, whole, NOMINAL_SAMPLES)
    try:
        placed = nominal_on_session(
            nominal.table,
            nominal.joint_values(Q[pick]),
            P[pick],
            measured_rotations(seg, rows[pick]),
            tool_point=nominal.tool_point,
            T_base=nominal.T_base,
        )
    except GeometryError as exc:
        return None, (
            f"the nominal could not be placed on this session ({exc}): held-out logs score "
            "the calibrated model alone."
        )
    return placed, None
