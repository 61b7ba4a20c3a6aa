"""``--validate LOG``: a result scored at the poses of other sessions of the same robot, the
nominal and the calibrated model on one footing (:func:`validated`).

Each log is read with the nominal's joint names where it has them (else the calibrated log's),
segmented, and scored by :func:`~dhlog.identify.check.footing.score_poses` against the nominal
placed once on the calibrated session's inlier samples. A log that cannot be scored is a
warning; one that cannot be placed or read makes the result implausible.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from dhlog.errors import DhlogError, GeometryError, Note
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
from dhlog.identify.fit.register import clock_judge
from dhlog.identify.fit.samples import measured_rotations
from dhlog.identify.joints.sweeps import samples_with_encoders, target_labels
from dhlog.identify.segment.clocks import on_one_clock
from dhlog.identify.segment.segment import segment_log
from dhlog.identify.stages import Identification, table_values
from dhlog.io.pipeline import Pipeline
from dhlog.io.reader import read_log

#: Largest number of the session's samples the nominal is placed on.
NOMINAL_SAMPLES = 20000


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
    # its joint states seconds off the tracker's: moved, as the nominal placed on it confirms
    judge = None if result.nominal is None else clock_judge(log, result.nominal)
    log, _, moved = on_one_clock(log, judge)
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
    nominal = result.nominal
    own = [result.validation.rms] if result.validation is not None else []
    own += [h.calibrated.rms for h in result.holdout if h.kind == "cross-validation"]
    samples = LogSamples(
        Q,
        P,
        rotations=None if rotations is None else rotations[primary],
        table_values=table_values(result, Q),
        nominal_values=None if nominal is None else nominal.joint_values(Q),
    )
    check = score_poses(
        Placed(ex.standard, Stand(ex.T_measurement_base, ex.tool_point, result.tool_orientation)),
        samples,
        path=str(path),
        nominal=placed()[0],
        own_error=max(own) if own else None,
    )
    if moved:
        check = replace(check, notes=(*check.notes, *(note.text for note in moved)))
    if log.point_ids is not None:  # the session's held-out poses by the export's ids
        mine = rows if which is None else rows[primary]
        names = sample_names(np.asarray(seg.column("t_ns", mine), np.int64), mine, log.point_ids)
        check = replace(
            check, pose_names=pose_names(np.asarray(Q), np.asarray(P), names, check.positions)
        )
    return check


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
