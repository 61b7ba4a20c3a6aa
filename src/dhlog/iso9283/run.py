"""The ISO 9283 acceptance report from tracker logs (:func:`run_logs`, :func:`iso9283_report`):
the visits and passes of :mod:`dhlog.iso9283.cycles` carried into the robot's base frame
(:mod:`dhlog.iso9283.baseframe`) and turned into the characteristics of clause 7 per pose (AP,
RP, vAP, stabilisation time and overshoot), between P2 and P4 (AD, RD) and over time (drift:
:mod:`dhlog.iso9283.poses`) and of clause 8 per path (:mod:`dhlog.iso9283.paths`), gathered in
an :class:`~dhlog.iso9283.report.Iso9283Report`.

**Before / after.** Before: the attained positions against the nominal's forward kinematics of
the commanded joints (the pose the controller, running the nominal, intended). After (with a
result): what ``dhlog compensate``'s corrected commands would attain, to first order — each
attained position minus (the calibrated model's prediction at the commanded joints − the
nominal's), against the same commanded positions; i.e. the error left is the attained position
minus the calibrated prediction. Computed, not measured: the report says so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.errors import InputError, Iso9283Error
from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import Pipeline
from dhlog.iso9283.baseframe import _base_positions, _moved
from dhlog.iso9283.cycles import ARRIVAL_RATE, ENCODER_MATCH, Segmented, segment_log
from dhlog.iso9283.dwells import DwellSettings, Visit
from dhlog.iso9283.passes import PathPass
from dhlog.iso9283.paths import _paths
from dhlog.iso9283.poses import (
    _accuracy,
    _distance,
    _drift,
    _multi_directional,
    _orientation_repeatability,
    _repeatability,
    _stabilisation,
)
from dhlog.iso9283.report import Iso9283Report as Iso9283Report
from dhlog.iso9283.report import PoseReport
from dhlog.iso9283.stops import NOT_DETERMINED
from dhlog.model.fk import fk_point


def iso9283_report(
    segmented: Sequence[Segmented],
    *,
    nominal: DHModel | None = None,
    calibrated: DHModel | None = None,
) -> Iso9283Report:
    """The report from one or more logs' visits (see the module docstring). ``nominal``: the
    model the controller runs (its FK of the commanded joints is the commanded position);
    ``calibrated``: dhlog's result (placement and the after column)."""
    if not segmented:
        raise Iso9283Error("dhlog iso9283", "no log given", "give the test's log(s)")
    seg0 = segmented[0]
    notes = [n for s in segmented for n in s.notes]
    if len(segmented) > 1:  # the logs' visits in one list, each pose's cycles numbered on
        visits: list[Visit] = []
        passes: list[PathPass] = []
        counts: dict[str, int] = {}
        for s in segmented:
            renamed = _names_as_in(seg0, s, notes)
            for v in s.visits:
                v = replace(v, pose=renamed.get(v.pose, ""))
                c = v.cycle
                if v.pose:
                    c = counts.get(v.pose, 0) + 1
                    counts[v.pose] = c
                visits.append(replace(v, cycle=c))
            for pp in s.passes:
                c = counts.get("path " + pp.path, 0) + 1
                counts["path " + pp.path] = c
                passes.append(replace(pp, cycle=c))
        seg = Segmented(
            ", ".join(s.path for s in segmented),
            visits,
            seg0.poses,
            seg0.pose_q,
            seg0.commanded_from,
            min(s.rate_hz for s in segmented),
            all(s.orientation for s in segmented),
            [],
            passes,
            seg0.paths,
            seg0.stops,
        )
    else:
        seg = seg0
    T, frame, registration = _base_positions(seg, nominal, calibrated, notes)
    n_q = None if seg.pose_q is None else seg.pose_q.shape[1]
    if nominal is not None and n_q is not None and n_q != nominal.table.n:
        raise Iso9283Error(
            "--nominal",
            f"{nominal.source} has {nominal.table.n} joints but the commanded targets have {n_q}",
            "give the robot's own model",
        )
    accuracy = T is not None and nominal is not None and seg.pose_q is not None

    def commanded_at(k: int) -> FloatArray:
        assert nominal is not None and seg.pose_q is not None
        q = seg.pose_q[k]
        return np.asarray(fk_point(nominal.table, q, nominal.tool_point, T_base=nominal.T_base))

    def correction_at(k: int) -> FloatArray:
        """The calibrated prediction − the nominal's at pose k's commanded joints (base)."""
        assert calibrated is not None and nominal is not None and seg.pose_q is not None
        q = seg.pose_q[k]
        pred_m = fk_point(
            calibrated.table,
            calibrated.joint_values(q),
            calibrated.tool_point,
            T_base=calibrated.T_base,
        )
        assert T is not None
        return _moved(T, pred_m) - commanded_at(k)

    stabilising = seg.stops is None and seg.rate_hz >= 0.99 * ARRIVAL_RATE  # 100 Hz or so
    if not stabilising and seg.stops is None:
        notes.append(
            f"the tracker samples at {seg.rate_hz:.0f} Hz: stabilisation time and overshoot need "
            f"{ARRIVAL_RATE:.0f} Hz or more and are not computed."
        )
    poses: list[PoseReport] = []
    for k, name in enumerate(seg.poses):
        vs = seg.of_pose(name)
        if not vs:
            notes.append(f"{name} was never reached (no visit matched its commanded target).")
            continue
        X = _moved(T, np.array([v.position for v in vs]))
        before = after = None
        commanded = None
        if accuracy:
            commanded = commanded_at(k)
            before = _accuracy(X, commanded)
            if calibrated is not None:
                after = _accuracy(X - correction_at(k), commanded)
        RP = l_mean = S_l = None
        if len(vs) >= 2:
            RP, l_mean, S_l = _repeatability(X)
        abc = None
        if seg.orientation and len(vs) >= 2:
            Rs = [v.rotation for v in vs if v.rotation is not None]
            if len(Rs) >= 2:
                if T is None and not any("about the tracker's axes" in n for n in notes):
                    notes.append(
                        "RP_a, RP_b, RP_c are about the tracker's axes (no model places the "
                        "base frame)."
                    )
                R_frame = np.eye(3) if T is None else T[:3, :3]
                abc = _orientation_repeatability(X[: len(Rs)], [R_frame @ R for R in Rs])
        stab = [s for s in (_stabilisation(v) for v in vs) if s is not None] if stabilising else []
        times = [s[0] for s in stab]
        overs = [s[1] for s in stab]
        vap, ndir = _multi_directional(vs, X)
        poses.append(
            PoseReport(
                name,
                len(vs),
                X.mean(axis=0),
                commanded,
                before,
                after,
                RP,
                l_mean,
                S_l,
                abc,
                float(np.mean(times)) if times else None,
                float(np.max(times)) if times else None,
                float(np.mean(overs)) if overs else None,
                float(np.max(overs)) if overs else None,
                sum(1 for v in vs if not v.settled),
                vap,
                ndir,
                X,
            )
        )
        if len(vs) < 2:
            notes.append(
                f"{name}: {len(vs)} cycle: RP needs 2 cycles or more (the standard: 30); not "
                "computed."
            )
    poses.sort(key=lambda p: _name_order(p.name))  # reported P1 … P5, whatever the cycle order
    cycles = max((p.visits for p in poses), default=0)
    if 0 < cycles < 30:
        notes.append(
            f"{cycles} cycle(s) per pose: the standard asks 30; the figures are from these."
        )
    missing = [n for n in ("P1", "P2", "P3", "P4", "P5") if n not in seg.poses]
    if missing:  # (a pose of the program never reached is named above)
        notes.append(
            f"{len(seg.poses)} test pose(s) in the log: the standard has five (P1–P5); "
            f"{', '.join(missing)} not in this log."
        )
    if not any(p.directions > 1 for p in poses):
        notes.append(
            "vAP (multi-directional accuracy variation): not in this log (every pose is "
            "approached from one direction)."
        )
    paths = [] if seg.stops is not None else _paths(seg, T, nominal, calibrated, notes)
    distance = _distance(
        seg,
        T,
        commanded_at if accuracy else None,
        correction_at if accuracy and calibrated is not None else None,
        notes,
    )
    drift = _drift(seg, T, commanded_at if accuracy else None, notes)
    after_basis = None
    if calibrated is not None and accuracy:
        after_basis = (
            "computed: each attained position minus (the calibrated model's prediction at the "
            "commanded joints − the nominal's), i.e. what dhlog compensate's corrected commands "
            "would attain to first order; not measured"
        )
    return Iso9283Report(
        [s.path for s in segmented],
        frame,
        registration,
        seg.commanded_from,
        after_basis,
        seg.rate_hz,
        len(seg.visits),
        cycles,
        poses,
        distance,
        drift,
        seg.orientation,
        notes,
        paths,
        seg.stops,
        [] if seg.stops is None else list(NOT_DETERMINED),
    )


def _name_order(name: str) -> tuple[int, str]:
    """P1 … P5 by number, other names after them as they come."""
    digits = name[1:]
    return (int(digits), "") if name[:1] == "P" and digits.isdigit() else (10**6, name)


def _names_as_in(first: Segmented, other: Segmented, notes: list[str]) -> dict[str, str]:
    """The names ``other``'s poses have in ``first`` (by their commanded joints, within
    ``SAME_TARGET``; by name where either has none); a pose of ``other`` not in ``first`` is
    left out, said."""
    if other is first or first.pose_q is None or other.pose_q is None:
        return {n: n for n in other.poses if n in first.poses}
    out = {}
    for name, q in zip(other.poses, other.pose_q, strict=True):
        hit = [
            n
            for n, fq in zip(first.poses, first.pose_q, strict=True)
            if fq.shape == q.shape and float(np.max(np.abs(fq - q))) <= ENCODER_MATCH
        ]
        if hit:
            out[name] = hit[0]
        else:
            notes.append(
                f"{other.path}: its pose {name} is none of {first.path}'s: its visits are left "
                "out (the logs of one test command the same poses)."
            )
    return out


def run_logs(
    logs: Sequence[str | Path],
    *,
    pipeline: Pipeline | None = None,
    nominal: DHModel | None = None,
    calibrated: DHModel | None = None,
    commanded_csv: str | Path | None = None,
    settings: DwellSettings | None = None,
    stops: bool | None = None,
    further_tools: Sequence[FloatArray] = (),
) -> Iso9283Report:
    """``dhlog iso9283``: read each log, find its visits and path passes, and report.
    ``commanded_csv``: the test program ``dhlog plan --iso9283`` wrote
    (:func:`dhlog.iso9283.program.read_program`); ``stops``: the logs are static measurements,
    one per stop (None: detected; :mod:`dhlog.iso9283.stops`). Several targets: the primary
    one's report, each further target's in ``further``; ``further_tools``: the result's tool
    points of targets 2, 3, … (its ``tool.further_targets``), which give their AP and AD
    (with ``calibrated``)."""
    from dhlog.io.reader import read_log
    from dhlog.iso9283.commanded import read_program
    from dhlog.iso9283.stops import synthetic_timing, target_count

    segmented = []
    further: list[list[Segmented]] = []
    program = None
    named = calibrated if calibrated is not None else nominal  # the joints matched by its names
    said: list[str] = []
    if (
        nominal is not None
        and calibrated is not None
        and not np.any(nominal.tool_point)
        and np.any(calibrated.tool_point)
    ):
        # a nominal without a tool (a DH file to the flange) scored against the target would
        # measure the tool's length, not the robot's accuracy: the result's tool, as --validate
        # gives the nominal
        nominal = replace(nominal, tool_point=np.asarray(calibrated.tool_point, np.float64))
        said.append(
            "AP before: the nominal gives no tool point, so it carries the result's "
            f"({_mm(calibrated.tool_point)} mm on the flange), as --validate does; the before "
            "and after differ only by the robot's geometry."
        )
    for log in logs:
        data = read_log(
            log,
            pipeline,
            joint_names=None if named is None else named.joint_names,
            joint_source="model" if named is None else named.source,
        )
        if commanded_csv is not None and program is None:
            n = nominal.table.n if nominal is not None else len(data.joint_names)
            if n == 0:
                raise InputError(
                    f"{log}: no joint names to read {commanded_csv} with; give --nominal."
                )
            program = read_program(commanded_csv, n)
            if nominal is not None:
                _program_is_the_nominals(program, nominal, commanded_csv)
        kw: dict[str, Any] = dict(
            settings=settings,
            program=program,
            program_source=f"the test program {commanded_csv}",
            stops=stops,
        )
        segmented.append(segment_log(data, **kw))
        for k in range(1, target_count(data.points)):
            if len(further) < k:
                further.append([])
            further[k - 1].append(segment_log(data, **kw, target=k))
    if program is not None:
        names = {n for n, k in zip(program.name, program.kind, strict=True) if k == "pose"}
        matched = {v.pose for seg in segmented for v in seg.visits} & names
        if not matched:
            raise Iso9283Error(
                "the test program",
                f"no visit in the log matches a pose of {commanded_csv}",
                "check that the program is the one the robot ran (its joints in radians, this "
                "robot's)",
            )
    if len(further) >= 2:  # three reflectors or more: the tool's orientation from them
        from dhlog.iso9283.reflectors import with_reflector_frames

        segmented = [
            with_reflector_frames(seg, [further[0][i], further[1][i]], seg.notes)
            for i, seg in enumerate(segmented)
        ]
    synthetic = all(synthetic_timing(log) for log in logs)
    report = _timed(iso9283_report(segmented, nominal=nominal, calibrated=calibrated), synthetic)
    if said:
        report = replace(report, notes=[*said, *report.notes])
    if not further:
        return report
    from dhlog.iso9283.stops import further_note

    others = []
    placed = 0
    for k, segs in enumerate(further, start=2):
        nominal_k = calibrated_k = None
        if nominal is not None and calibrated is not None and k - 2 < len(further_tools):
            tool = np.asarray(further_tools[k - 2], dtype=np.float64)
            nominal_k = replace(nominal, tool_point=tool)
            calibrated_k = replace(calibrated, tool_point=tool)
            placed += 1
        got = iso9283_report(segs, nominal=nominal_k, calibrated=calibrated_k)
        others.append(replace(_timed(got, synthetic), target=k))
    note = further_note(1 + len(others), placed)
    return replace(report, further=others, notes=[*report.notes, note])


def _mm(point: FloatArray) -> str:
    return ", ".join(f"{1e3 * v:.3f}" for v in np.asarray(point, dtype=np.float64))


def _timed(report: Iso9283Report, synthetic: bool) -> Iso9283Report:
    """Stops whose stamps are not times (``dhlog import``'s one stop every 2 s,
    :func:`dhlog.iso9283.stops.synthetic_timing`): the drift's hours and rate not known (NaN:
    null in the JSON), said in a note."""
    if report.stops is None or report.drift is None or not synthetic:
        return report
    notes = [n for n in report.notes if not n.startswith("drift: the first and last cycles")]
    notes.append(
        "drift: the stops are in the export's row order, taken as time order; their stamps are "
        "dhlog import's (one stop every 2 s), so the time between the first and last cycles is "
        "not known (hours and rate_per_hour null): dAP and dRP are the change over the test."
    )
    drift = replace(report.drift, hours=math.nan, rate=math.nan)
    return replace(report, drift=drift, notes=notes)


def _program_is_the_nominals(program: Any, nominal: DHModel, source: str | Path) -> None:
    """The program's tool points (``x, y, z``) are the nominal's forward kinematics of its
    joint targets, for some tool point (the one it was planned with, found by least squares: a
    DH file's nominal may carry none): a program of another robot, or with its joints in
    degrees, is one clear error."""
    from dhlog.model.fk import fk_frames

    if not len(program.q):
        return
    last = fk_frames(nominal.table, program.q, T_base=nominal.T_base)[:, -1]
    A = last[:, :3, :3].reshape(-1, 3)
    b = (program.xyz - last[:, :3, 3]).reshape(-1)
    tool = np.linalg.lstsq(A, b, rcond=None)[0]
    fk = np.einsum("kij,j->ki", last[:, :3, :3], tool) + last[:, :3, 3]
    worst = float(np.max(np.linalg.norm(fk - program.xyz, axis=1)))
    if worst > PROGRAM_TOLERANCE:
        raise Iso9283Error(
            "the test program",
            f"{source}'s tool points are not the nominal {nominal.source}'s forward kinematics of "
            f"its joint targets (up to {worst * 1e3:.1f} mm apart)",
            "give the program dhlog plan --iso9283 wrote for this robot's nominal (joints in "
            "radians), or the nominal it was planned with",
        )


#: How far (m) a program's tool point may lie from the nominal's FK of its joints (rounding).
PROGRAM_TOLERANCE = 1e-6
