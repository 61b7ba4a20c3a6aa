"""A step of the joint states' clock in the middle of a session (:func:`at_one_step`): a time
daemon (ntpd beyond 128 ms, chrony's ``makestep``, Windows' time service) sets the clock of the
computer that stamps them, and every stamp after it is that much off those before. The sweeps'
lags (:func:`~dhlog.identify.segment.timing.sweep_phases`) then fall in two groups about no one
line; the stamps themselves show where, as an interval unlike the stream's others (a stamp
before the last one where the clock went back). The stamps from there on are moved by the
difference of the lags either side, where that leaves the lags on a line.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import polars as pl

from dhlog.errors import Note
from dhlog.identify.segment.segment import Segmentation
from dhlog.identify.segment.timing import (
    MOVING_SPEED,
    SweepPhase,
    set_by,
    sweep_phases,
    timed_phases,
)
from dhlog.io.reader import LogData
from dhlog.model.dh import JointType

#: The sweeps' lags scatter about their line by more than this (s, RMS) before a step
#: is looked for: in time they differ one joint from another by up to 0.05 ms, and a drift is
#: a line.
STEP_FLOOR = 1e-3
#: ... and a step is taken where, the stamps moved by it, they scatter this many times less.
STEP_CLEARER = 5.0
#: The stream's intervals most unlike the others tried as the step's place (a dropout is one
#: too: the lags either side of it agree, and it is not taken).
STEP_CANDIDATES = 3
#: Fewest timed sweeps either side of a step.
STEP_SWEEPS = 1
#: The interval's own step is taken for the lags' where the stream's intervals scatter less than
#: the lags' step is known, and the two agree within this many of its σ (at least 0.1 ms).
STEP_AGREE = 5.0
#: The step read by the lags is sized again (by the fit, or a held-out log's by the
#: calibrated model) within this (s) of where they put it.
STEP_REACH = 1e-3
#: A gap of this many of the stream's intervals or more, across which the joint states'
#: values run on by one interval's motion and after which this many intervals run at the
#: stream's rate, is the clock set on (a step of a second leaves the sweeps after it untimed:
#: their encoders' slopes read far from 1).
STEP_GAP = 3.0
STEP_RUN = 20
#: A clock set back in a stream sorted by stamp leaves a stretch as long as the step this many
#: times denser than the stream's rate (twice, where both sides run at it).
STEP_DENSER = 1.5
#: Readings of the step's size: the lags read a misjoin of tens of ms a little short, and a
#: sweep the step falls in between the two.
STEP_READINGS = 3


@dataclass(frozen=True)
class ClockStep:
    """A step of the joint states' clock: ``seconds`` added to their stamps from the
    ``index``-th (0-based, in the order logged), whose stamp as logged is ``at_ns``."""

    index: int
    at_ns: int
    seconds: float
    #: how it was told: ``lags`` (the sweeps' lags either side), ``gap`` (a gap the joints'
    #: values run on across), ``retimed`` (the sweeps after it timed only without it),
    #: ``interleaved`` (set back in a stream sorted by stamp: the stretch holding both sides
    #: left out) or ``set back`` (the stamps fell in the order logged)
    told: str = "lags"

    @property
    def described(self) -> str:
        """The step in words: how far the clock was set, and which way."""
        return f"was {set_by(self.seconds)}"


def _lag(phase: SweepPhase) -> tuple[float, float]:
    """A sweep's lag (s) and its σ read without its gross outliers where it has them
    (``drift_delta``: 5 % of outliers bend the plain reading by up to 1.6 ms), else as read."""
    if phase.drift_delta is not None and phase.drift_std:
        return phase.drift_delta, phase.drift_std
    assert phase.delta is not None and phase.std is not None
    return phase.delta, phase.std


def lag_misfit(phases: list[SweepPhase]) -> float | None:
    """The RMS (s) of the timed sweeps' lags about their weighted line in time, each sweep
    counted alike (the line goes through the sweeps whose lags are sharpest: those the others
    miss it by are the step's); None with fewer than three."""
    timed = timed_phases(phases)
    if len(timed) < 3:
        return None
    t = np.array([p.t_ns for p in timed], dtype=np.float64) * 1e-9
    d, sd = np.array([_lag(p) for p in timed], dtype=np.float64).T
    w = 1.0 / sd**2
    x = t - float(np.sum(w * t) / np.sum(w))
    sxx = float(np.sum(w * x**2))
    mean = float(np.sum(w * d) / np.sum(w))
    rate = float(np.sum(w * x * d) / sxx) if sxx > 0.0 else 0.0
    return math.sqrt(float(np.mean((d - mean - rate * x) ** 2)))  # each sweep alike


@dataclass(frozen=True)
class _Place:
    """Where the stream's stamps may step: the index of the joint state after an odd interval
    (in the order logged), the interval less the stream's median (s) and the intervals'
    scatter (s, robust σ: how sharply one interval tells a step)."""

    index: int
    odd: float
    jitter: float
    #: the stream's median interval (s)
    interval: float = 0.0


def _places(log: LogData) -> list[_Place]:
    """The joint states after the :data:`STEP_CANDIDATES` intervals least like the stream's
    median one, beyond :data:`STEP_FLOOR` from it."""
    assert log.joints is not None
    t = log.joints["t_ns"].to_numpy()
    if t.size < 3:
        return []
    gaps = np.diff(t).astype(np.float64) * 1e-9
    odd = gaps - float(np.median(gaps))
    jitter = 1.4826 * float(np.median(np.abs(odd)))
    order = np.argsort(-np.abs(odd))[:STEP_CANDIDATES]
    median = float(np.median(gaps))
    return [
        _Place(int(k) + 1, float(odd[k]), jitter, median) for k in order if abs(odd[k]) > STEP_FLOOR
    ]


def _runs_on(log: LogData, place: _Place) -> bool:
    """Whether the joint states across a gap of ``place`` (:data:`STEP_GAP` intervals or more)
    are consecutive — their values change across it by one interval's motion, not the gap's,
    and the stamps after it run on at the stream's rate (no burst catching up a delay) —: the
    clock set on there, not messages lost. Unknown (False) where the fastest joint does not
    move steadily across it (still, or a move begun in the gap: lost messages then change it by
    little too)."""
    assert log.joints is not None
    i, dt = place.index, place.interval
    t = log.joints["t_ns"].to_numpy()
    if dt <= 0 or place.odd < (STEP_GAP - 1.0) * dt or not 2 <= i < t.size - STEP_RUN:
        return False
    if abs((t[i + STEP_RUN] - t[i]) * 1e-9 - STEP_RUN * dt) > dt:
        return False
    q = log.joints.select(log.joints.columns[1:]).slice(i - 2, 4).to_numpy()
    before, across, after = q[1] - q[0], q[2] - q[1], q[3] - q[2]
    speed = 0.5 * (before + after)  # the motion of one interval about the gap
    j = int(np.argmax(np.abs(speed)))
    if not min(abs(before[j]), abs(after[j])) > MOVING_SPEED * dt:
        return False
    if abs(before[j] - after[j]) > 0.5 * abs(speed[j]):  # not steady: a move begun or ended
        return False
    intervals = (t[i] - t[i - 1]) * 1e-9 / dt  # what a gap of lost messages would move
    return bool(abs(across[j]) < 0.5 * (1.0 + intervals) * abs(speed[j]))


def _size(phases: list[SweepPhase], at_ns: int) -> tuple[float, float] | None:
    """What the timed sweeps' lags from ``at_ns`` on are off those before (s) and its σ: the
    step of a line with one (least squares, each sweep alike: a drift is the line); None with
    fewer than :data:`STEP_SWEEPS` sweeps either side or four in all. A sweep the step falls in
    reads a lag between the two; moved at the step's place, it reads as the others, and the
    next reading takes up what it bent. The σ is the lags' scatter about the model: they differ
    one joint from another by up to 0.05 ms in time."""
    timed = [p for p in timed_phases(phases) if p.delta is not None]
    after = np.array([p.t_ns >= at_ns for p in timed])
    if len(timed) < 4 or min(np.count_nonzero(after), np.count_nonzero(~after)) < STEP_SWEEPS:
        return None
    t = np.array([p.t_ns for p in timed], dtype=np.float64) * 1e-9
    d = np.array([_lag(p)[0] for p in timed], dtype=np.float64)
    A = np.column_stack([np.ones_like(t), t - t.mean(), after.astype(np.float64)])
    x, *_ = np.linalg.lstsq(A, d, rcond=None)
    var = float(np.sum((d - A @ x) ** 2)) / (len(timed) - 3)
    cov = np.linalg.pinv(A.T @ A) * var
    return float(x[2]), math.sqrt(max(float(cov[2, 2]), 0.0))


def stepped(log: LogData, index: int, seconds: float) -> LogData:
    """``log`` with ``seconds`` added to its joint states' stamps from the ``index``-th on (in
    the order logged), and to its commanded joints' after the last stamp before it."""
    assert log.joints is not None
    step = round(seconds * 1e9)
    last = int(log.joints["t_ns"][index - 1]) if index > 0 else int(log.joints["t_ns"][0]) - 1
    joints = log.joints.with_columns(
        pl.when(pl.int_range(pl.len()) >= index)
        .then(pl.col("t_ns") + step)
        .otherwise(pl.col("t_ns"))
        .alias("t_ns")
    )
    commanded = log.commanded
    if commanded is not None:
        commanded = commanded.with_columns(
            pl.when(pl.col("t_ns") > last)
            .then(pl.col("t_ns") + step)
            .otherwise(pl.col("t_ns"))
            .alias("t_ns")
        )
    return replace(log, joints=joints, commanded=commanded)


def at_one_step(
    log: LogData,
    seg: Segmentation,
    phases: list[SweepPhase],
    segment: Callable[[LogData], Segmentation],
    joint_types: Sequence[JointType | None] | None = None,
) -> tuple[LogData, Segmentation, list[SweepPhase], ClockStep | None]:
    """``log``, its segmentation ``seg`` and its sweeps' ``phases``; where the lags scatter
    about their line beyond :data:`STEP_FLOOR` and one of the stream's odd intervals
    (:func:`_places`) explains it — the stamps after it moved by the lags' difference either
    side (read :data:`STEP_READINGS` times), the lags scatter :data:`STEP_CLEARER` times less —
    the log so mapped, segmented and its sweeps read again, and the step (None: none found, or
    the pipeline fixes the clock). The lags are read without their sweeps' gross outliers
    (:func:`_lag`). A step the lags cannot read — a gap the joints' values run on across
    (:func:`_runs_on`), or one that leaves sweeps after it untimed (:func:`_retimed`) — is
    taken at the gap's own size."""
    if log.pipeline.segmentation.clock_offset_fixed or log.joints is None:
        return log, seg, phases, None
    if log.clock_set_back is not None:  # the stamps fell as logged: moved on reading
        return _set_back(log, seg, phases, segment, joint_types)
    for place in _places(log):  # a gap the joint states' values run on across: the clock
        if _runs_on(log, place):
            mapped = stepped(log, place.index, -place.odd)
            new_seg = segment(mapped)
            at_ns = int(log.joints["t_ns"][place.index])
            step = ClockStep(place.index, at_ns, -place.odd, "gap")
            return mapped, new_seg, sweep_phases(new_seg, mapped, joint_types), step
    found = _retimed(log, phases, segment, joint_types)
    if found is not None:
        return found
    misfit = lag_misfit(phases)
    if misfit is None or misfit <= STEP_FLOOR:
        return log, seg, phases, None
    best: tuple[float, LogData, Segmentation, list[SweepPhase], ClockStep] | None = None
    for place in _places(log):
        index = place.index
        at_ns = int(log.joints["t_ns"][index])
        mapped, got, total, sd = log, (seg, phases), 0.0, math.inf
        for _ in range(STEP_READINGS):
            read = _size(got[1], at_ns)
            if read is None:
                break
            total += read[0]  # a lag is what the stamps need added: theirs after, less before
            sd = read[1]
            if place.jitter < sd and abs(-place.odd - total) <= STEP_AGREE * max(sd, 1e-4):
                total = -place.odd  # the interval tells the step sharper than the lags do
            mapped = stepped(log, index, total)
            new_seg = segment(mapped)
            got = (new_seg, sweep_phases(new_seg, mapped, joint_types))
        left = lag_misfit(got[1])
        if total and left is not None and left * STEP_CLEARER <= misfit:
            if best is None or left < best[0]:
                best = (left, mapped, got[0], got[1], ClockStep(index, at_ns, total))
    if best is None:
        return log, seg, phases, None
    if best[4].seconds > 0:  # set back, in a stream the store gave sorted by stamp
        unmixed = _unmixed(log, best[4], segment, joint_types)
        if unmixed is not None:
            return unmixed
    return best[1], best[2], best[3], best[4]


def _unmixed(
    log: LogData,
    step: ClockStep,
    segment: Callable[[LogData], Segmentation],
    joint_types: Sequence[JointType | None] | None,
) -> tuple[LogData, Segmentation, list[SweepPhase], ClockStep] | None:
    """A clock set back ``step.seconds`` whose stamps the store gave sorted (rosbags reads a
    sqlite3 bag by stamp): the stretch that long about the lags' place where the stream is
    denser than :data:`STEP_DENSER` times its rate holds the joint states of both sides,
    interleaved, and no one place moves them apart. Its joint states are left out (the
    tracker's samples there have none: set aside), those after it moved by the step; None
    where no stretch is so dense (the lags' place stands)."""
    assert log.joints is not None
    t = log.joints["t_ns"].to_numpy()
    width = round(step.seconds * 1e9)
    if t.size < 3 or width <= 0:
        return None
    interval = float(np.median(np.diff(t)))
    # the stretches that long about the lags' place (its odd interval lies in the stretch)
    lo = int(np.searchsorted(t, t[step.index] - width, side="left"))
    starts = np.arange(lo, step.index + 1)
    ends = np.searchsorted(t, t[starts] + width, side="left")
    counts = ends - starts
    best = int(np.argmax(counts))
    k, end = int(starts[best]), int(ends[best])
    if interval <= 0 or counts[best] < STEP_DENSER * width / interval or end <= step.index:
        return None
    rows = pl.int_range(pl.len())
    joints = log.joints.with_columns(
        pl.when(rows >= end).then(pl.col("t_ns") + width).otherwise(pl.col("t_ns")).alias("t_ns")
    ).filter((rows < k) | (rows >= end))
    mapped = replace(log, joints=joints)
    new_seg = segment(mapped)
    found = ClockStep(k, int(t[k]), step.seconds, "interleaved")
    return mapped, new_seg, sweep_phases(new_seg, mapped, joint_types), found


def _untimed(phases: list[SweepPhase]) -> int:
    """The sweeps that read a lag but do not time it (their encoders' slope far from 1: a
    sweep misjoined by a second reads its joint half still), where some sweeps time theirs."""
    timed = timed_phases(phases)
    lagged = sum(p.delta is not None and p.std is not None for p in phases)
    return lagged - len(timed) if timed else 0


def _retimed(
    log: LogData,
    phases: list[SweepPhase],
    segment: Callable[[LogData], Segmentation],
    joint_types: Sequence[JointType | None] | None,
) -> tuple[LogData, Segmentation, list[SweepPhase], ClockStep] | None:
    """Where some sweeps do not time their lag and the stream has a gap of :data:`STEP_GAP`
    intervals or more: the stamps after it moved back by the gap, taken where more sweeps then
    time their lag and the lags lie on their line within :data:`STEP_FLOOR` (a clock set on a
    second while the robot stood still: no lag after it to read the step, and no motion across
    the gap to tell it from lost messages); else None. Lost messages moved so misjoin the
    sweeps after them, and fewer time their lag."""
    assert log.joints is not None
    untimed = _untimed(phases)
    if not untimed:
        return None
    for place in _places(log):
        if place.odd < (STEP_GAP - 1.0) * place.interval:
            continue
        mapped = stepped(log, place.index, -place.odd)
        new_seg = segment(mapped)
        got = sweep_phases(new_seg, mapped, joint_types)
        left = lag_misfit(got)
        if _untimed(got) < untimed and left is not None and left <= STEP_FLOOR:
            at_ns = int(log.joints["t_ns"][place.index])
            return mapped, new_seg, got, ClockStep(place.index, at_ns, -place.odd, "retimed")
    return None


def _set_back(
    log: LogData,
    seg: Segmentation,
    phases: list[SweepPhase],
    segment: Callable[[LogData], Segmentation],
    joint_types: Sequence[JointType | None] | None,
) -> tuple[LogData, Segmentation, list[SweepPhase], ClockStep]:
    """A clock set back, its stamps moved on reading to follow on at the stream's interval
    (:mod:`dhlog.io.decode.setback`): that is right to the intervals' jitter, a few tenths of
    a ms; where the sweeps' lags either side still differ by more than :data:`STEP_AGREE` σ
    the stamps after it are moved by that too (up to :data:`STEP_READINGS` times)."""
    assert log.clock_set_back is not None and log.joints is not None
    at_ns, added = log.clock_set_back
    index = int(np.searchsorted(log.joints["t_ns"].to_numpy(), at_ns + added))
    total, mapped = 0.0, log
    for _ in range(STEP_READINGS):
        read = _size(phases, at_ns + added)
        if read is None or abs(read[0]) <= STEP_AGREE * read[1]:
            break
        total += read[0]
        mapped = stepped(log, index, total)
        seg = segment(mapped)
        phases = sweep_phases(seg, mapped, joint_types)
    return mapped, seg, phases, ClockStep(index, at_ns, added * 1e-9 + total, "set back")


#: How a step was told, in the note's words.
_TOLD = {
    "lags": "the sweeps either side lag the tracker by that much apart",
    "gap": "the stamps jump by that much where the joints' values run on as between any two",
    "retimed": (
        "the stamps jump by that much between two sweeps, and the sweeps after it time their "
        "lag only without it"
    ),
    "interleaved": (
        "the sweeps either side lag the tracker by that much apart, and the stamps that long "
        "before it hold the joint states of both sides (a store that gives them sorted by "
        "stamp): those were left out"
    ),
    "set back": (
        "their stamps fall by that much in the order logged, and were moved to follow the one "
        "before at the stream's interval on reading, so the two stretches do not interleave"
    ),
}


def step_note(step: ClockStep) -> Note:
    """What the run says of the step of the joint states' clock it took out."""
    return Note.warning(
        f"the joint states' clock {step.described} during the session (at their stamp "
        f"{step.at_ns} ns as logged): {_TOLD[step.told]}; the stamps from there on were moved "
        f"{step.seconds * 1e3:+.1f} ms before the sweeps were read again. A time daemon "
        "setting the clock mid-session does so: let it slew (chrony's makestep only at boot) "
        "or synchronise the computers (PTP) for the next session.",
        "clock-step",
    )
