"""The ISO 9283 test's cycles found in a tracker log: the visits to the test poses (dwells), each
visit's attained position, its commanded target and the samples of its arrival. The dwells are
:mod:`dhlog.iso9283.dwells`' (dwell detection, the attained position), the path passes
:mod:`dhlog.iso9283.passes`'.

**Arrival** (clauses 7.4, 7.5: stabilisation time and overshoot): the samples from
``DwellSettings.approach`` s (1 s) before the dwell, or the end of the previous dwell if later,
to the dwell's end, kept for :func:`dhlog.iso9283.formulas.stabilisation`. Below 100 Hz the
arrival is too coarsely sampled and the report says so.

**Commanded target** of each visit, in order of preference: the log's commanded joint stream
(``[streams.commanded]``, e.g. ``/joint_command``) at the middle of the dwell; a commanded CSV
(``dhlog plan --iso9283``'s cycle program) matched to the visits in order; else the encoders'
mean over the settled samples (the controller's joints: the servo's own error is in them, so
the commanded pose is the one the controller believes it reached — said in the report).
Visits whose commanded joints agree within ``SAME_TARGET`` (rad) are visits to one pose; a
target visited twice or more is a test pose (the five most visited, the first visited among
equals: a path's start and end are stops too); the poses are named in the standard's cycle order
P1 → P5 → P4 → P3 → P2 as first visited (the program's names where it is given).

Pure numpy on arrays; :func:`segment_log` reads :class:`dhlog.io.reader.LogData`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Iso9283Error
from dhlog.geometry._checks import FloatArray
from dhlog.io.reader import ORIENTATION_COLUMNS, LogData
from dhlog.iso9283.commanded import CommandedProgram
from dhlog.iso9283.cube import CYCLE_ORDER
from dhlog.iso9283.dwells import (
    BAND_FLOOR,
    MIN_SETTLED,
    DwellSettings,
    Visit,
    _departure,
    _encoders_stop,
    _mean_rotation,
    _settle,
    find_dwells,
)
from dhlog.iso9283.passes import PathPass, find_passes, program_parts

#: Commanded joint vectors this close (rad, m; largest component) are one target.
SAME_TARGET = 1e-4
#: Below this tracker rate (Hz) stabilisation time and overshoot are not computed.
ARRIVAL_RATE = 100.0
#: A visit's encoders this close (rad, m) to a program pose's joints are at that pose.
ENCODER_MATCH = 1e-3
#: Approach directions within this angle (rad) are one direction (clause 7.2.3: vAP).
SAME_DIRECTION = np.radians(30.0)


@dataclass(frozen=True)
class Segmented:
    """The log's visits and what they were matched to: ``poses`` (names in order) with their
    commanded joints ``pose_q`` (k, n) (None without commanded joints), where the commanded
    targets came from (``commanded_from``), the tracker's rate (Hz), whether the log has a
    6-DoF target, and ``notes`` (one line each: what is missing, what was assumed)."""

    path: str
    visits: list[Visit]
    poses: list[str]
    pose_q: FloatArray | None
    commanded_from: str
    rate_hz: float
    orientation: bool
    notes: list[str] = field(default_factory=list)
    passes: list[PathPass] = field(default_factory=list)
    #: the program's paths (name, joint targets (m, n)); empty without a program
    paths: list[tuple[str, FloatArray]] = field(default_factory=list)
    #: None: visits are dwells of a time series; else how the log was read as stops (static
    #: measurements, one per stop: :mod:`dhlog.iso9283.stops`)
    stops: str | None = None

    def of_pose(self, name: str) -> list[Visit]:
        """The visits to pose ``name``, in cycle order."""
        return [v for v in self.visits if v.pose == name]


def _cluster(vectors: list[FloatArray], tolerance: float) -> list[int]:
    """A label per vector: vectors within ``tolerance`` (largest component) of a label's first
    member share it; labels in order of first appearance."""
    reps: list[FloatArray] = []
    labels = []
    for v in vectors:
        for k, r in enumerate(reps):
            if r.shape == v.shape and float(np.max(np.abs(r - v))) <= tolerance:
                labels.append(k)
                break
        else:
            reps.append(v)
            labels.append(len(reps) - 1)
    return labels


def _value_at(t_ns: NDArray[np.int64], values: FloatArray, at_ns: int) -> FloatArray:
    """The last value at or before ``at_ns`` (the first one when none is before)."""
    k = int(np.searchsorted(t_ns, at_ns, side="right")) - 1
    return np.asarray(values[max(k, 0)], dtype=np.float64)


def _joint_columns(frame: object) -> tuple[NDArray[np.int64], FloatArray]:
    import polars as pl

    assert isinstance(frame, pl.DataFrame)
    cols = [c for c in frame.columns if c.startswith("q_")]
    t = np.asarray(frame["t_ns"].to_numpy(), dtype=np.int64)
    return t, np.column_stack([np.asarray(frame[c].to_numpy(), np.float64) for c in cols])


def segment_log(
    log: LogData,
    *,
    settings: DwellSettings | None = None,
    program: CommandedProgram | None = None,
    program_source: str = "the commanded CSV",
    stops: bool | None = None,
    target: int = 0,
) -> Segmented:
    """The visits of ``log`` and its path passes (see the module docstring). ``program``: the
    test program (:func:`dhlog.iso9283.program.read_program`, named by ``program_source``):
    visits whose commanded joints match one of its poses take its name (other stops are no
    test pose), and its paths' passes are cut out. ``stops``: the log is made of static
    measurements, one per stop (:mod:`dhlog.iso9283.stops`; None: detected); ``target``: which
    of several targets (0: the primary one). Raises :class:`Iso9283Error` when the log holds
    no dwell and is not made of stops."""
    from dhlog.iso9283.stops import stop_direction, stop_runs

    settings = settings or DwellSettings()
    name = log.path
    points = log.points
    if "target" in points.columns:  # several targets: the one asked for
        import polars as pl

        points = points.filter(pl.col("target") == target)
    t_ns = np.asarray(points["t_ns"].to_numpy(), dtype=np.int64)
    xyz = np.column_stack([np.asarray(points[c].to_numpy(), np.float64) for c in "xyz"])
    orientation = all(c in points.columns for c in ORIENTATION_COLUMNS)
    quats = (
        np.column_stack([np.asarray(points[c].to_numpy(), np.float64) for c in ORIENTATION_COLUMNS])
        if orientation
        else None
    )
    notes: list[str] = []
    if t_ns.size < 2:
        raise Iso9283Error(
            name, f"the tracker stream holds {t_ns.size} sample(s)", "record the test's cycles"
        )
    t_s = (t_ns - t_ns[0]) * 1e-9
    steps = np.diff(t_s)
    rate = float(1.0 / np.median(steps[steps > 0])) if np.any(steps > 0) else 0.0
    dwells = [] if stops else find_dwells(t_s, xyz, settings)
    measured_as = None
    if stops or (stops is None and not dwells):
        dwells, measured_as = stop_runs(
            name, t_s, gap=settings.gap, min_time=settings.min_time, explicit=bool(stops)
        )
    if not dwells:
        raise Iso9283Error(
            name,
            f"no dwell found (no {settings.min_time:g} s with the target slower than "
            f"{settings.speed * 1e3:g} mm/s)",
            "give the log of an ISO 9283 test (the robot stopping at each test pose)",
        )
    enc = None if log.joints is None else _joint_columns(log.joints)
    cmd = (
        None
        if log.commanded is None or log.commanded.height == 0
        else _joint_columns(log.commanded)
    )
    program_poses, pose_sequence, program_paths = (
        program_parts(program) if program is not None else (None, None, [])
    )
    commanded = None
    if cmd is not None:
        topic = log.pipeline.streams["commanded"].topic
        source = f"the commanded joint stream {topic}"
    elif program_poses is not None and enc is not None:
        source = (
            f"{program_source} (each visit recognised by its encoders, the program's joints its "
            "commanded target)"
        )
    elif pose_sequence is not None:
        commanded = pose_sequence
        source = f"{program_source} (its pose targets matched to the visits in order)"
    elif enc is not None:
        source = (
            "the encoders at each visit (the controller's joints, its servo error included: "
            "no commanded stream in the log and no --commanded CSV)"
        )
        notes.append(
            f"{name}: no commanded joint stream and no --commanded CSV: each visit's commanded "
            "target is the encoders' mean at the visit (accuracy is then against the pose the "
            "controller believes it reached)."
        )
    else:
        source = "nothing (no commanded stream, CSV or encoders)"
        notes.append(
            f"{name}: neither commanded joints nor encoders: the visits are grouped by their "
            "attained positions; accuracy needs the commanded poses (give --commanded)."
        )
    if commanded is not None and commanded.shape[0] != len(dwells):
        notes.append(
            f"{name}: {len(dwells)} visit(s) found against {commanded.shape[0]} commanded "
            f"target(s) in {source}: matched in order, the first "
            f"{min(len(dwells), commanded.shape[0])}."
        )
    raw: list[dict[str, object]] = []
    previous_end = -np.inf
    for k, (s, e) in enumerate(dwells):
        if measured_as is None:
            e = s + _departure(t_s[s:e], xyz[s:e])
            first, band, settled = _settle(xyz[s:e], settings)
            # the mean from settle_margin s later: a damped oscillation's tail inside the band
            # would pull it towards the approach by up to band / (ω · dwell)
            later = int(np.searchsorted(t_s[s:e], t_s[s + first] + settings.settle_margin))
            if e - s - later < MIN_SETTLED:
                later = first
        else:  # a stop: its samples are the measurement (no arrival, no settling to find)
            first, band, settled, later = 0, math.nan, True, 0
        kept = slice(s + later, e)
        position = xyz[kept].mean(axis=0)
        scatter = float(np.sqrt(np.mean(np.sum((xyz[kept] - position) ** 2, axis=1))))
        rotation = None if quats is None else _mean_rotation(quats[kept])
        a0 = max(t_s[s] - settings.approach, previous_end)
        a = int(np.searchsorted(t_s, a0, side="left")) if measured_as is None else s
        previous_end = t_s[e - 1]
        arrival_t = t_s[a:e] - t_s[s]
        arrival_xyz = xyz[a:e]
        direction = position - arrival_xyz[0]
        norm = float(np.linalg.norm(direction))
        direction = direction / norm if norm > 20 * max(scatter, BAND_FLOOR) else np.zeros(3)
        if measured_as is not None:  # a stop is approached from the stop before it
            direction = stop_direction(position, raw[-1]["position"] if raw else None)
        mid = int((t_ns[s] + t_ns[e - 1]) // 2)
        q: FloatArray | None = None
        if cmd is not None:
            q = _value_at(cmd[0], cmd[1], mid)
        elif commanded is not None:
            q = commanded[k] if k < commanded.shape[0] else None
        elif enc is not None:
            inside = (enc[0] >= t_ns[s + first]) & (enc[0] <= t_ns[e - 1])
            q = enc[1][inside].mean(axis=0) if np.any(inside) else _value_at(*enc, mid)
            if program_poses is not None:  # the program's target the encoders are at
                near = [
                    pq
                    for _, pq in program_poses
                    if pq.shape == q.shape and float(np.max(np.abs(pq - q))) <= ENCODER_MATCH
                ]
                q = near[0] if near else q
        arrival = None
        if enc is not None and measured_as is None:
            arrival = _encoders_stop(enc, int(t_ns[s]) + int(arrival_t[0] * 1e9), t_ns, s, e)
        raw.append(
            dict(
                arrival=arrival,
                index=k,
                t_start_ns=int(t_ns[s]),
                t_end_ns=int(t_ns[e - 1]),
                t_settled_ns=int(t_ns[s + first]),
                position=position,
                rotation=rotation,
                n_settled=e - s - later,
                scatter=scatter,
                band=band,
                settled=settled,
                q=q,
                arrival_t=arrival_t,
                arrival_xyz=arrival_xyz,
                direction=direction,
            )
        )
    # the poses: program poses by their joints; else each distinct target, in order first seen
    names: list[str] = []
    labels: list[str] = []
    pose_q: list[FloatArray] = []
    have_q = all(r["q"] is not None for r in raw)
    if program_poses is not None and have_q:
        for r in raw:
            q = np.asarray(r["q"])
            hit = [
                n
                for n, pq in program_poses
                if pq.shape == q.shape and float(np.max(np.abs(pq - q))) <= SAME_TARGET
            ]
            labels.append(hit[0] if hit else "")
        names = [n for n, _ in program_poses]
        pose_q = [pq for _, pq in program_poses]
    else:
        keys = (
            [np.asarray(r["q"]) for r in raw]
            if have_q
            else [np.asarray(r["position"]) for r in raw]
        )
        tol = SAME_TARGET if have_q else 5e-3  # positions: 5 mm apart at least
        clusters = _cluster(keys, tol)
        counts = np.bincount(clusters)
        # a pose is visited more than once; the five most visited are the test poses (of
        # stops, every one: a repeatability set of a tracker's, not only the standard's cube)
        order = [c for c in dict.fromkeys(clusters) if counts[c] >= 2]
        many = measured_as is not None and len(order) > 5
        if len(order) > 5 and not many:
            kept_clusters = sorted(order, key=lambda c: -counts[c])[:5]
            notes.append(
                f"{name}: {len(order)} distinct targets visited more than once; the five most "
                "visited are taken as P1–P5 (give --commanded with the program to name them)."
            )
            order = [c for c in order if c in kept_clusters]
        if not order and counts.size > 5:  # many targets, none repeated: not a test's visits
            raise Iso9283Error(
                name,
                f"none of its {counts.size} distinct targets is visited twice, so the log is "
                "not an ISO 9283 test (random poses? a calibration session?)",
                "record the test's cycle program (dhlog plan --iso9283) or a tracker's repeated "
                "stops, several visits to each pose",
            )
        if not order:
            order = list(dict.fromkeys(clusters))[:5]
            notes.append(
                f"{name}: no target is visited twice (one cycle at most): repeatability needs "
                "two cycles or more."
            )
        # named in the standard's cycle order, by first visit (clause 7.2.1); more than five
        # (stops) P1, P2, … as first visited
        label_of = {c: (f"P{i + 1}" if many else CYCLE_ORDER[i]) for i, c in enumerate(order)}
        labels = [label_of.get(c, "") for c in clusters]
        order = sorted(order, key=lambda c: int(label_of[c][1:]))
        names = [label_of[c] for c in order]
        if many:
            notes.append(
                f"{name}: {len(order)} distinct targets visited more than once: each is a test "
                f"pose, named P1 … P{len(order)} in the order first visited (AD/RD between P2 "
                "and P4, drift at P1, as the standard places them)."
            )
        elif len(order) > 1:
            notes.append(
                f"{name}: the poses are named in the standard's cycle order P1 → P5 → P4 → P3 → "
                "P2 (clause 7.2.1) as first visited; give --commanded with the test program to "
                "name them by its targets."
            )
        if have_q:
            # the mean of the pose's visits' targets (identical when commanded)
            pose_q = [
                np.mean([kv for kv, c2 in zip(keys, clusters, strict=True) if c2 == c], axis=0)
                for c in order
            ]
    cycle_count: dict[str, int] = {}
    visits = []
    for r, label in zip(raw, labels, strict=True):
        cycle = 0
        if label:
            cycle = cycle_count.get(label, 0) + 1
            cycle_count[label] = cycle
        visits.append(Visit(pose=label, cycle=cycle, **r))  # type: ignore[arg-type]
    passes: list[PathPass] = []
    stream = cmd if cmd is not None else enc
    if program_paths and stream is not None:
        for path_name, path_q in program_paths:
            found = find_passes(stream, path_q, t_ns, xyz, path_name)
            passes.extend(found)
            if not found:
                notes.append(f"{name}: the path {path_name} was never run (no pass found).")
    return Segmented(
        name,
        visits,
        names,
        np.array(pose_q) if pose_q else None,
        source,
        rate,
        orientation,
        notes,
        passes,
        program_paths,
        measured_as,
    )
