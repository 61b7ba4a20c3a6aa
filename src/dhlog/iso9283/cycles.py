"""The ISO 9283 test's cycles found in a tracker log: the visits to the test poses (dwells), each
visit's attained position, its commanded target and the samples of its arrival.

**Dwell detection.** The tracker's speed at each sample is the distance it moved over a window of
``DwellSettings.window`` s centred on it (0.2 s: at 10 µm noise per coordinate the speed's noise
is about 0.1 mm/s), divided by the window's time. A *dwell* is a run of samples slower than
``DwellSettings.speed`` (2 mm/s) lasting at least ``DwellSettings.min_time`` (0.5 s); a gap in the
stream longer than ``DwellSettings.gap`` (0.1 s) ends a run (a step-and-measure log whose tracker
records only the stops is read as well). Each dwell is a *visit*.

**Attained position** (clause 7.2.1: "the attained pose" after stabilisation). The visit's final
position is the mean of its last half; the stabilisation band (``DwellSettings.band``, default
``BAND_FACTOR`` × the 3-D RMS scatter of that half, at least ``BAND_FLOOR``) around it; the
*settled* samples are those of the dwell from ``DwellSettings.settle_margin`` (0.3 s) after the
last sample outside the band (a damped oscillation's tail inside the band would otherwise pull
the mean towards the approach: by 0.7 µm on average for the simulator's 0.1 mm, 5 Hz one). The
attained position is the mean of the settled samples, its orientation (a 6-DoF target) the mean
rotation of their orientations (the nearest rotation to their mean matrix).

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

**Path passes** (clause 8), with the test program (:func:`dhlog.iso9283.program.read_program`:
``--commanded``): each time the commanded joints (else the encoders) come nearest a path's
second target, up to the next time they come nearest its last one, the tracker's samples from
``PASS_MARGIN`` s before to as long after: one cycle's attained path, for
:func:`dhlog.iso9283.formulas.path_accuracy`.

Pure numpy on arrays; :func:`segment_log` reads :class:`dhlog.io.reader.LogData`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Iso9283Error
from dhlog.geometry._checks import FloatArray, nearest_rotation
from dhlog.io.reader import ORIENTATION_COLUMNS, LogData
from dhlog.iso9283.commanded import CommandedProgram
from dhlog.iso9283.cube import CYCLE_ORDER

#: The band is this many times the settled samples' 3-D RMS scatter (noise alone leaves a band
#: of 4·√3 σ ≈ 7 σ per coordinate about once in 10¹⁰ samples).
BAND_FACTOR = 4.0
#: The band is never below this (m).
BAND_FLOOR = 5e-6
#: Commanded joint vectors this close (rad, m; largest component) are one target.
SAME_TARGET = 1e-4
#: Below this tracker rate (Hz) stabilisation time and overshoot are not computed.
ARRIVAL_RATE = 100.0
#: The fewest settled samples a visit's attained position is the mean of (else the last half).
MIN_SETTLED = 3
#: The standard's cycle (clause 7.2.1): the order in which unnamed poses are first visited.
#: A dwell ends where its position, averaged over this window (s), has moved this many times
#: the average's noise from the dwell's middle (:func:`_departure`).
DEPART_WINDOW = 0.1
DEPART_FACTOR = 5.0
#: The encoders have stopped when every one stays this close (rad, m) to its value at the
#: end of the dwell: the stand-in for the controller's attained-pose signal (clause 7.4).
ENCODER_STOP = 1e-6
#: A visit's encoders this close (rad, m) to a program pose's joints are at that pose.
ENCODER_MATCH = 1e-3
#: A joint stream this close (rad, m) to a path's second and last targets is at them.
PASS_TOLERANCE = 1e-3
#: The tracker's samples kept before and after a pass (s).
PASS_MARGIN = 0.3
#: Approach directions within this angle (rad) are one direction (clause 7.2.3: vAP).
SAME_DIRECTION = np.radians(30.0)


@dataclass(frozen=True)
class DwellSettings:
    """How visits are found (see the module docstring): ``speed`` (m/s), ``min_time`` (s),
    ``window`` (s), ``gap`` (s), ``band`` (m; None: from each visit's scatter), ``approach``
    (s of samples kept before each dwell), ``settle_margin`` (s after settling before the
    samples averaged into the attained position begin)."""

    speed: float = 2e-3
    min_time: float = 0.5
    window: float = 0.2
    gap: float = 0.1
    band: float | None = None
    approach: float = 1.0
    settle_margin: float = 0.3


@dataclass(frozen=True)
class Visit:
    """One visit (a dwell): its ``index`` in the log, ``pose`` (P1 …; "" for a stop that is no
    test pose), ``cycle`` (1-based: the k-th visit to its pose), the dwell's start and end and
    the first settled sample's time (ns), the attained ``position`` (3,) and ``rotation``
    (3, 3; None without a 6-DoF target) in the measurement frame, ``n_settled`` samples,
    ``scatter`` (m, their 3-D RMS about the mean), the ``band`` used, the commanded joints
    ``q`` (n,) (None where nothing gives them), the arrival's times (s from the dwell's start)
    and positions ``arrival_xyz`` (k, 3), and the approach ``direction`` (3,) (unit; zeros when
    the arrival holds no motion)."""

    index: int
    pose: str
    cycle: int
    t_start_ns: int
    t_end_ns: int
    t_settled_ns: int
    position: FloatArray
    rotation: FloatArray | None
    n_settled: int
    scatter: float
    band: float
    settled: bool
    q: FloatArray | None
    arrival_t: FloatArray
    arrival_xyz: FloatArray
    direction: FloatArray
    #: the attained-pose signal's stand-in (s from the dwell's start): the encoders' stop
    #: (``ENCODER_STOP``) where the log has encoders, else None (the first sample in the band)
    arrival: float | None = None


@dataclass(frozen=True)
class PathPass:
    """One cycle's run along a test path: the ``path``'s name, its ``cycle`` (1-based), the
    first and last sample's times (ns) and the tracker's positions ``xyz`` (k, 3, measurement
    frame) in time order."""

    path: str
    cycle: int
    t_start_ns: int
    t_end_ns: int
    xyz: FloatArray


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


def sample_speed(
    t_s: FloatArray, xyz: FloatArray, *, window: float, gap: float
) -> tuple[FloatArray, NDArray[np.int64]]:
    """The speed (m/s) at each sample over ``window`` s centred on it, within its run (runs are
    split at gaps longer than ``gap``), and each sample's run number. A run of one sample has
    speed 0."""
    run = np.concatenate([[0], np.cumsum(np.diff(t_s) > gap)]).astype(np.int64)
    speed = np.zeros(t_s.size)
    starts = np.flatnonzero(np.r_[True, np.diff(run) != 0])
    ends = np.r_[starts[1:], t_s.size]
    for s, e in zip(starts, ends, strict=True):
        t = t_s[s:e]
        lo = np.searchsorted(t, t - window / 2, side="left")
        hi = np.searchsorted(t, t + window / 2, side="right") - 1
        dt = t[hi] - t[lo]
        moved = np.linalg.norm(xyz[s:e][hi] - xyz[s:e][lo], axis=1)
        speed[s:e] = np.where(dt > 0, moved / np.where(dt > 0, dt, 1.0), 0.0)
    return speed, run


def find_dwells(t_s: FloatArray, xyz: FloatArray, settings: DwellSettings) -> list[tuple[int, int]]:
    """The dwells of the stream: (first, end) sample indices (end exclusive) of each run of
    samples slower than ``settings.speed`` lasting ``settings.min_time`` or longer."""
    speed, run = sample_speed(t_s, xyz, window=settings.window, gap=settings.gap)
    still = speed < settings.speed
    # a run of still samples ends where a sample moves or the stream has a gap
    breaks = np.flatnonzero(np.diff(still.astype(np.int8)) != 0) + 1
    breaks = np.union1d(breaks, np.flatnonzero(np.diff(run) != 0) + 1)
    edges = np.r_[0, breaks, t_s.size].astype(np.int64)
    out = []
    for s, e in itertools.pairwise(edges):
        if still[s] and t_s[e - 1] - t_s[s] >= settings.min_time:
            out.append((int(s), int(e)))
    return out


def _settle(xyz: FloatArray, settings: DwellSettings) -> tuple[int, float, bool]:
    """The first settled sample of a dwell's positions ``xyz`` (k, 3), the band, and whether
    the dwell settled at all (else its last half is used)."""
    half = xyz[xyz.shape[0] // 2 :]
    final = half.mean(axis=0)
    scatter = float(np.sqrt(np.mean(np.sum((half - final) ** 2, axis=1))))
    band = settings.band if settings.band is not None else max(BAND_FACTOR * scatter, BAND_FLOOR)
    outside = np.flatnonzero(np.linalg.norm(xyz - final, axis=1) > band)
    first = 0 if outside.size == 0 else int(outside[-1]) + 1
    if xyz.shape[0] - first < MIN_SETTLED:
        return xyz.shape[0] // 2, band, False
    return first, band, True


def _encoders_stop(
    enc: tuple[NDArray[np.int64], FloatArray],
    from_ns: int,
    t_ns: NDArray[np.int64],
    s: int,
    e: int,
) -> float | None:
    """When the encoders stop at a visit (s from the dwell's first sample ``t_ns[s]``): the first
    encoder sample after ``from_ns`` from which every one up to the dwell's end lies within
    ``ENCODER_STOP`` of their value there. None when no encoder sample falls in the arrival."""
    t, Q = enc
    a, b = np.searchsorted(t, [from_ns, int(t_ns[e - 1])], side="left")
    if b - a < 2:
        return None
    final = Q[b - 1]
    moving = np.flatnonzero(np.max(np.abs(Q[a:b] - final), axis=1) > ENCODER_STOP)
    k = a + (int(moving[-1]) + 1 if moving.size else 0)
    return float((int(t[k]) - int(t_ns[s])) * 1e-9)


def _departure(t: FloatArray, xyz: FloatArray) -> int:
    """Where a dwell ends (exclusive index into its samples ``xyz`` (k, 3) at times ``t``): the
    first sample of its second half at which the position, averaged over ``DEPART_WINDOW`` s,
    has moved more than ``DEPART_FACTOR`` × that average's noise (at least ``BAND_FLOOR``)
    from the median of its middle third, less half the window; the dwell's end when it never
    does. The next move starts slower than the dwell's speed threshold, and its first
    samples would otherwise pull the attained position towards it (by 7 µm in a simulated
    test whose last pose was followed by a short move)."""
    k = int(xyz.shape[0])
    if k < 9:
        return k
    middle = xyz[k // 3 : 2 * k // 3]
    reference = np.median(middle, axis=0)
    scatter = float(np.sqrt(np.mean(np.sum((middle - middle.mean(axis=0)) ** 2, axis=1))))
    steps = np.diff(t)
    period = float(np.median(steps)) if steps.size else 1.0
    w = max(1, round(DEPART_WINDOW / period) if period > 0 else 1)
    if w >= k // 2:
        return k
    kernel = np.ones(w) / w
    smooth = np.column_stack([np.convolve(xyz[:, c], kernel, mode="valid") for c in range(3)])
    limit = max(DEPART_FACTOR * scatter / math.sqrt(w), BAND_FLOOR)
    away = np.flatnonzero(np.linalg.norm(smooth - reference, axis=1) > limit)
    away = away[away >= k // 2]
    if away.size == 0:
        return k
    return max(int(away[0]) + w // 2, k // 2)


def _mean_rotation(quats: FloatArray) -> FloatArray:
    """The mean rotation of unit quaternions (k, 4: x, y, z, w): the nearest rotation to the
    mean of their matrices."""
    from scipy.spatial.transform import Rotation

    return nearest_rotation(Rotation.from_quat(quats).as_matrix().mean(axis=0))


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


def program_parts(
    program: CommandedProgram,
) -> tuple[list[tuple[str, FloatArray]], FloatArray, list[tuple[str, FloatArray]]]:
    """The program's poses (name, joints) in order first commanded, its pose targets in order
    (k, n), and each path's joint targets along it (name, (m, n)) from its first cycle."""
    poses: dict[str, FloatArray] = {}
    sequence = []
    paths: dict[str, list[tuple[int, FloatArray]]] = {}
    first_cycle: dict[str, int] = {}
    for k, kind in enumerate(program.kind):
        name, q = program.name[k], np.asarray(program.q[k], dtype=np.float64)
        if kind == "pose":
            poses.setdefault(name, q)
            sequence.append(q)
        else:
            c = first_cycle.setdefault(name, int(program.cycle[k]))
            if int(program.cycle[k]) == c:
                paths.setdefault(name, []).append((int(program.index[k]), q))
    n = program.q.shape[1]
    return (
        list(poses.items()),
        np.array(sequence) if sequence else np.zeros((0, n)),
        [
            (name, np.array([q for _, q in sorted(rows, key=lambda r: r[0])]))
            for name, rows in paths.items()
        ],
    )


def find_passes(
    stream: tuple[NDArray[np.int64], FloatArray],
    path_q: FloatArray,
    t_ns: NDArray[np.int64],
    xyz: FloatArray,
    name: str,
    *,
    tolerance: float = PASS_TOLERANCE,
    margin: float = PASS_MARGIN,
) -> list[PathPass]:
    """The passes along a path whose joint targets are ``path_q`` (m, n), from a joint
    ``stream`` (times, (k, n): the commanded joints, or the encoders): each time the stream
    comes nearest its second point (the stream taken linearly between its samples; within
    ``tolerance``, rad in joint space, or half the smallest step between the path's targets if
    less), up to the next time it comes nearest its last point, passing
    near its targets at a quarter, half and three quarters of the way (a move between two poses
    may pass near the second target and stop at the last: not a pass); the
    tracker's samples from ``margin`` s before to ``margin`` s after (the path's ends, where the
    crossings of the first and last normal planes lie)."""
    t, Q = stream
    if path_q.shape[0] < 3 or Q.shape[1] != path_q.shape[1] or Q.shape[0] < 2:
        return []
    # below half the smallest step between targets: the second target is told from the first
    # and the last (a closed path's ends are one point)
    steps = np.linalg.norm(np.diff(path_q, axis=0), axis=1)
    tolerance = min(tolerance, 0.5 * float(steps[steps > 0].min(initial=2 * tolerance)))
    A, B = Q[:-1], Q[1:]
    AB = B - A
    length2 = np.einsum("ij,ij->i", AB, AB)

    def distance(target: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Each stream segment's distance (joint space) from ``target``, and the time of its
        nearest point (the stream linearly between its samples: a fast stream's samples may
        straddle a target)."""
        u = np.einsum("ij,ij->i", target - A, AB) / np.where(length2 > 0, length2, 1.0)
        u = np.clip(np.where(length2 > 0, u, 0.0), 0.0, 1.0)
        d = np.linalg.norm(A + u[:, None] * AB - target, axis=1)
        return d, t[:-1] + u * (t[1:] - t[:-1])

    def nearest_times(target: FloatArray) -> NDArray[np.int64]:
        d, when = distance(target)
        near = d < tolerance
        edges = np.flatnonzero(np.diff(np.r_[0, near.astype(np.int8), 0]))
        return np.array(
            [
                int(when[a + int(np.argmin(d[a:b]))])
                for a, b in zip(edges[::2], edges[1::2], strict=True)
            ],
            dtype=np.int64,
        )

    starts, ends = nearest_times(path_q[1]), nearest_times(path_q[-1])
    m = path_q.shape[0]
    inner = [distance(path_q[round(f * (m - 1))]) for f in (0.25, 0.5, 0.75)]

    def along(t1: int, t2: int) -> bool:
        """Whether the stream passes near the path's inner targets between ``t1`` and ``t2``
        (a move between two poses may pass near a path's second target and stop at its end)."""
        for d, when in inner:
            inside = (when >= t1) & (when <= t2)
            if not np.any(inside) or float(d[inside].min()) >= tolerance:
                return False
        return True

    out: list[PathPass] = []
    step = int(margin * 1e9)
    for k, t1 in enumerate(starts):
        later = ends[ends > t1]
        following = starts[k + 1] if k + 1 < len(starts) else None
        if later.size == 0 or (following is not None and later[0] > following):
            continue  # a pass not run to its end
        if not along(int(t1), int(later[0]) + 1):
            continue
        a, b = np.searchsorted(t_ns, [t1 - step, later[0] + step])
        if b - a >= 3:
            out.append(PathPass(name, len(out) + 1, int(t_ns[a]), int(t_ns[b - 1]), xyz[a:b]))
    return out
