"""Joint states whose clock is seconds off the tracker's — two computers without a common time,
a bridge that stamps with its own — moved onto the tracker's clock before the log is segmented
(:func:`on_one_clock`). The fine estimate (:mod:`dhlog.identify.segment.timing`) models the lag
linearly and needs a start within a fraction of a second; here each stream's motion is found on
a grid — the target's speed from its samples, the joints' from their states; a tracker
triggered at the stops is silent while the robot moves — and the offset at which they agree
best is taken (:func:`coarse_offset`), where the agreement stands out, or the nominal placed on
the points (or the sweeps' points on their curves) tells the near-equal candidates apart.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.segment.segment import Segmentation
from dhlog.identify.segment.timing import (
    DRIFT_NEAR,
    MOVING_SPEED,
    Drift,
    SweepPhase,
    phase_drift,
    phase_lag,
    sweep_phases,
)
from dhlog.io.reader import LogData
from dhlog.model.dh import JointType

#: The grid (s) the streams' motion is compared on (at least the tracker's interval), and the
#: half-window (s, at least a step) of the central difference that gives each one's speed.
COARSE_STEP = 0.01
COARSE_HALF = 0.05
#: Steps of the running median the target's positions go through (its gross outliers out).
COARSE_MEDIAN = 5
#: The largest offset looked for (s), and at most this share of the span either stream covers;
#: an offset is judged where the streams, moved by it, overlap in COARSE_OVERLAP of the
#: steps the shorter one is known at.
COARSE_RANGE = 60.0
#: The seconds of the target's samples matched (and the joint states around them), from
#: COARSE_RANGE before the joints first move by COARSE_FIRST (rad or m).
COARSE_WINDOW = 300.0
COARSE_FIRST = 1e-2
COARSE_SHARE = 0.5
COARSE_OVERLAP = 0.8
#: The streams' motion must agree this well at the offset found (a correlation), and better by
#: this than at any offset more than COARSE_APART from it, for it to be taken.
COARSE_AGREE = 0.5
COARSE_MARGIN = 0.1
COARSE_APART = 0.5
#: The target moves where its speed is above this share of its 95th percentile, or where
#: the tracker is silent for longer than COARSE_SILENT (s; at least ten of its intervals).
COARSE_MOVING = 0.005
COARSE_SILENT = 0.2
#: ... and above this many times the speed the points' noise alone gives.
COARSE_NOISE = 5.0
#: A stretch in which one joint alone moves for this long (s) judges an offset by its points;
#: of the offsets whose motion agrees within COARSE_MARGIN of the best, the one the nominal (or
#: the sweeps' curves) misses COARSE_CLEARER times less than the next is taken.
COARSE_SWEEP = 0.5
COARSE_CLEARER = 3.0
#: Offsets found below this (s) are left to the fine estimate (:func:`clock_start`), which
#: needs no more start than that.
COARSE_BELOW = 0.1
#: A drifting clock's stamps are mapped by the drift their sweeps show at most this many times
#: (each reading of the sweeps' lags is blurred by the drift within each sweep).
DRIFT_MAPS = 4
#: A held-out log's own offset is looked for within this (s) of where the coarse match left
#: it (beyond COARSE_BELOW: a sweep's misjoin at its ends, past the linear range), on a grid of
#: FINE_STEP, to FINE_TOLERANCE, and taken where the model misses the points FINE_CLEARER times
#: less than there: 0.1 ms misjoins a target moving at 0.2 m/s by 20 µm, which stands out of
#: a tracker's noise by more than that.
FINE_REACH = 0.15
FINE_STEP = 0.03
FINE_TOLERANCE = 1e-6
FINE_CLEARER = 1.1


def on_one_clock(
    log: LogData, judge: Callable[[float], float] | None = None
) -> tuple[LogData, float, tuple[Note, ...]]:
    """``log`` with its joint states (and commanded joints) moved onto the tracker's clock
    where :func:`coarse_offset` finds them :data:`COARSE_BELOW` or more off it, the move
    (s), and the note that says so; ``log`` itself where the pipeline fixes the offset or none
    is found. ``judge``: :func:`coarse_offset`'s."""
    if log.pipeline.segmentation.clock_offset_fixed or log.joints is None:
        return log, 0.0, ()
    found = coarse_offset(log, judge)
    if found is None or abs(found) < COARSE_BELOW:
        return log, 0.0, ()
    given = log.pipeline.segmentation.clock_offset
    said = (
        f"the joint states' stamps ran {abs(found):.2f} s "
        f"{'behind' if found > 0 else 'ahead of'} the tracker's clock (where each stream moves, "
        "matched from the joints' first move; a step-and-measure tracker's silences are the "
        f"moves): {found:+.2f} s were added to them before the sweeps were found (the Clock "
        "line gives the offset used). A clock this far apart — two computers without a common "
        "time — is better fixed at the source, or given as [segmentation] clock_offset = "
        f"{given + found:.2f}."
    )
    return shifted(log, found), found, (Note.info(said, "clock-coarse"),)


def shifted(log: LogData, seconds: float) -> LogData:
    """``log`` with ``seconds`` added to the stamps of its joint states (and commanded
    joints)."""
    step = round(seconds * 1e9)

    def moved(frame: pl.DataFrame | None) -> pl.DataFrame | None:
        return None if frame is None else frame.with_columns(pl.col("t_ns") + step)

    return replace(log, joints=moved(log.joints), commanded=moved(log.commanded))


def drifted(log: LogData, rate: float, t_ref_ns: int) -> LogData:
    """``log`` with its joint states' (and commanded joints') stamps ``t`` moved by
    ``rate (t − t_ref)``: onto the tracker's clock where theirs runs ``rate`` s a second off
    it (:func:`~dhlog.identify.segment.timing.phase_drift`)."""

    def moved(frame: pl.DataFrame | None) -> pl.DataFrame | None:
        if frame is None:
            return None
        since = (pl.col("t_ns") - t_ref_ns).cast(pl.Float64)
        return frame.with_columns(pl.col("t_ns") + (since * rate).round().cast(pl.Int64))

    return replace(log, joints=moved(log.joints), commanded=moved(log.commanded))


def at_one_rate(
    log: LogData,
    seg: Segmentation,
    phases: list[SweepPhase],
    segment: Callable[[LogData], Segmentation],
    joint_types: Sequence[JointType | None] | None = None,
) -> tuple[LogData, Segmentation, list[SweepPhase], Drift | None]:
    """``log``, its segmentation ``seg`` and its sweeps' ``phases``; where those show the joint
    states' clock drifting (:func:`~dhlog.identify.segment.timing.phase_drift`), its joint states'
    stamps mapped onto the tracker's clock and the log segmented and its sweeps read again, the
    drift refined so up to :data:`DRIFT_MAPS` times, each refinement about the first reading's
    time (so an offset estimated after holds there): the log, its segmentation, its sweeps'
    phases and the drift (None: none found, or the pipeline fixes the clock)."""
    drift = None
    for _ in range(0 if log.pipeline.segmentation.clock_offset_fixed else DRIFT_MAPS):
        found = _drift_read(log, seg, phases, joint_types, refine=drift is not None)
        if found is None:
            break
        drift = (
            found
            if drift is None
            else replace(drift, rate=(1 + drift.rate) * (1 + found.rate) - 1, std=found.std)
        )
        log = drifted(log, found.rate, drift.t_ref_ns)
        seg = segment(log)
        phases = sweep_phases(seg, log, joint_types)
    return log, seg, phases, drift


def _drift_read(
    log: LogData,
    seg: Segmentation,
    phases: list[SweepPhase],
    joint_types: Sequence[JointType | None] | None,
    *,
    refine: bool,
) -> Drift | None:
    """The drift the sweeps show, read with the encoders joined near the sweeps' mean lag: each
    lag is read by a model linear in it, which misreads a misjoin of tens of ms by a different
    amount for each joint — swept in turn, a slope (11 ppm at 50 ms off, none in time). Only
    the encoders are moved (not the sweeps' labels, which the phases do not need), so no pass
    over every sample is made."""
    lag = phase_lag(seg, log, phases)
    if lag is not None and abs(lag[0]) > DRIFT_NEAR and seg.encoders is not None:
        near = replace(seg, encoders=seg.encoders.shifted(round(lag[0] * 1e9)))
        phases = sweep_phases(near, log, joint_types)
    return phase_drift(phases, refine=refine)


def nearest_offset(
    miss: Callable[[float], float], around: float = 0.0, *, clearer: float = FINE_CLEARER
) -> float | None:
    """The clock offset (s) within :data:`FINE_REACH` of ``around`` at which ``miss(offset)``
    — a model's miss of the points joined at it (``fit.register.clock_judge``) — is least:
    the best of a grid of :data:`FINE_STEP`, refined by Brent's method within a step of it to
    :data:`FINE_TOLERANCE`; None where it does not miss ``clearer`` times less than
    at ``around`` (the log is on one clock as it stands, or the model cannot be placed on its
    samples). Another session's log, scored by a calibration, has a clock of its own: its
    offset can be anything the fine estimate of its own session would have found."""
    from scipy.optimize import minimize_scalar  # scipy.optimize costs 0.35 s to import

    grid = around + np.arange(-FINE_REACH, FINE_REACH + FINE_STEP / 2, FINE_STEP)
    misses = np.array([miss(float(t)) for t in grid])
    if not np.any(np.isfinite(misses)):
        return None
    best = float(grid[int(np.argmin(misses))])
    found = minimize_scalar(
        miss,
        bounds=(best - FINE_STEP, best + FINE_STEP),
        method="bounded",
        options={"xatol": FINE_TOLERANCE},
    )
    at, there = float(found.x), float(found.fun)
    if not there <= float(np.min(misses)):
        at, there = best, float(np.min(misses))
    kept = miss(around)
    if math.isfinite(there) and (not math.isfinite(kept) or there * clearer <= kept):
        return at
    return None


def coarse_offset(log: LogData, judge: Callable[[float], float] | None = None) -> float | None:
    """The clock offset (s, added to the joint-state stamps) at which the joints' motion and
    the target's line up best, where the points confirm it: whether each stream moves on a
    grid of :data:`COARSE_STEP` or the tracker's interval (the target's from the means of its
    samples in each step through a running median, a tracker triggered at the stops moving
    where it is silent; the joints' fastest), and their correlation (Pearson's) at every
    offset within :data:`COARSE_RANGE`. Offsets the motion cannot tell apart (the seed
    method's sweeps are alike: one sweep's time off matches nearly as well) are told by
    ``judge(offset)`` — the nominal's miss of the points joined at it (m) — or else by how far
    the points of each single-joint sweep miss a circle (a line) in its joint: one
    :data:`COARSE_CLEARER` times better than the next. An offset of :data:`COARSE_BELOW` or
    more is returned only where the same measure puts it :data:`COARSE_CLEARER` times better
    than none. None where neither stream shows motion, they barely overlap, nothing stands out
    (:data:`COARSE_AGREE`, :data:`COARSE_MARGIN`) or nothing confirms it. A clock seconds off
    — a tracker's computer and the robot's without a common time — leaves the fine estimate's
    linear model (:mod:`dhlog.identify.segment.timing`) far behind: sweeps labelled with
    another joint's samples."""
    match = _motion_match(log)
    if match is None:
        return None
    close, joints, t_p, xyz, t_j = match.close, match.joints, match.t_p, match.xyz, match.t_j
    if len(close) == 1 and abs(close[0]) < COARSE_BELOW:
        return close[0]
    # what the points say of an offset: the nominal placed on them (m), else the single-joint
    # sweeps' points off their curves; None where neither can
    said: dict[float, float] = {}
    sweeps = [] if judge is not None else _single_joint_moves(joints, t_j)

    def scored(lag: float) -> float:
        if lag not in said:
            said[lag] = judge(lag) if judge is not None else _arc_misfit(t_p, xyz, t_j, sweeps, lag)
        return said[lag]

    score = scored if judge is not None or sweeps else None
    if len(close) > 1:  # a motion of even sweeps cannot tell these apart (a sweep's time off)
        if score is None:
            return None
        misfit = [score(lag) for lag in close]
        order = np.argsort(misfit)
        if not misfit[order[0]] * COARSE_CLEARER <= misfit[order[1]]:
            return None
        close = [close[int(order[0])]]
    found = close[0]
    if abs(found) < COARSE_BELOW:
        return found
    # a move is taken only where the points say it is better than none: the motion alone has
    # matched a coupled session's stops ten seconds off
    if score is None:
        return None
    moved, kept = score(found), score(0.0)
    if math.isfinite(moved) and math.isfinite(kept) and moved * COARSE_CLEARER <= kept:
        return found
    return None


@dataclass(frozen=True)
class _Match:
    """The offsets (s) at which the two streams' motion agrees within :data:`COARSE_MARGIN` of
    the best (the best first), and what the points' judgement of them reads: the joint states
    around the matched samples, the samples' times (s) and positions, the joints' times (s)."""

    close: list[float]
    joints: pl.DataFrame
    t_p: FloatArray
    xyz: list[FloatArray]
    t_j: FloatArray


def _motion_match(log: LogData) -> _Match | None:
    """:func:`coarse_offset`'s match of the streams' motion, before the points judge it."""
    joints = log.joints
    points = matched_points(log)
    if joints is None or joints.height < 4 or points is None or points.height < 4:
        return None
    # the tracker's silences from every target's stamps (reflectors measured in turn)
    every = log.points["t_ns"].to_numpy()
    ns, ns_j = points["t_ns"].to_numpy(), joints["t_ns"].to_numpy()
    reach_ns = round(COARSE_RANGE * 1e9)
    a, b = np.searchsorted(ns_j, [ns[0] - reach_ns, ns[-1] + reach_ns])
    joints = joints.slice(int(a), int(b - a))
    if joints.height < 4:
        return None
    a, b = np.searchsorted(every, [ns[0], ns[-1]], side="right")
    t_p = ns * 1e-9
    t_j = joints["t_ns"].to_numpy() * 1e-9
    lo, hi = min(t_p[0], t_j[0]), max(t_p[-1], t_j[-1])
    span = min(t_p[-1], t_j[-1]) - max(t_p[0], t_j[0])
    gaps = np.diff(t_p)
    every_t = every[max(int(a) - 1, 0) : int(b)] * 1e-9
    # a step of the grid holds a sample of the target at least, about
    step = max(COARSE_STEP, float(np.median(gaps)))
    if not span > 0.0 or hi - lo > 1e6 or (hi - lo) / step > 1 << 26:
        return None
    size = int((hi - lo) / step) + 1
    # the target's mean position in each step (NaN without a sample), its gross outliers
    # taken out by a running median
    k = np.minimum(((t_p - lo) / step).astype(np.int64), size - 1)
    count = np.bincount(k, minlength=size).astype(np.float64)
    xyz = [np.asarray(points[c].to_numpy(), dtype=np.float64) for c in ("x", "y", "z")]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.column_stack(
            [_running_median(np.bincount(k, weights=v, minlength=size) / count) for v in xyz]
        )
    target = _speed(mean, step)
    grid = lo + np.arange(size) * step
    q = np.column_stack(
        [
            np.interp(
                grid, t_j, np.asarray(joints[c].to_numpy(), np.float64), left=np.nan, right=np.nan
            )
            for c in joints.columns
            if c != "t_ns"
        ]
    )
    # whether each stream moves, not how fast: the target's speed is the joints' times a lever
    # that differs from sweep to sweep, and would pull the match towards another sweep
    known_t = np.isfinite(target)
    if not np.any(known_t):
        return None
    top = float(np.percentile(target[known_t], 95))
    floor = COARSE_NOISE * _noise_speed(mean, step)
    moves_t = np.where(
        known_t, (target > max(COARSE_MOVING * top, floor)).astype(np.float64), np.nan
    )
    # a tracker triggered at the stops (step-and-measure) is silent while the robot moves: its
    # long silences count as motion
    long = max(COARSE_SILENT, 10.0 * float(np.median(gaps)))
    del gaps
    for k in np.flatnonzero(np.diff(every_t) > long):
        first = int((every_t[k] - lo) / step) + _half(step) + 1
        last = int((every_t[k + 1] - lo) / step) - _half(step)
        moves_t[max(first, 0) : max(last, 0)] = 1.0
    joint = _speed(q, step, each=True)
    moves_j = np.where(np.isfinite(joint), (joint > MOVING_SPEED).astype(np.float64), np.nan)
    if not (_varies(moves_t) and _varies(moves_j)):
        return None
    reach = int(min(COARSE_RANGE, COARSE_SHARE * (hi - lo)) / step)
    corr = _masked_correlation(moves_t, moves_j, reach)
    if corr is None:
        return None
    lags = np.arange(-reach, reach + 1) * step
    peaks = _peaks(corr, int(COARSE_APART / step))
    if not peaks or corr[peaks[0]] < COARSE_AGREE:
        return None
    close = [float(lags[k]) for k in peaks if corr[k] >= corr[peaks[0]] - COARSE_MARGIN]
    return _Match(close, joints, t_p, xyz, t_j)


def motion_lags(log: LogData) -> list[float]:
    """The offsets (s) at which the joints' motion and the target's line up within
    :data:`COARSE_MARGIN` of the best, confirmed or not (:func:`coarse_offset` takes one only
    where the points confirm it), the best first: what a run that went wrong can name as a
    likely cause. Empty where the motion does not line up."""
    match = _motion_match(log)
    return [] if match is None else match.close


def matched_points(log: LogData) -> pl.DataFrame | None:
    """The first target's samples the match reads: :data:`COARSE_WINDOW` s from
    :data:`COARSE_RANGE` before the joints first move (an idle start — set-up, a tracker started
    early — tells nothing, and would outvote the samples that do); None without joint states or
    a first target's samples."""
    joints, points = log.joints, log.points
    if joints is None or joints.height < 2:
        return None
    if "target" in points.columns:
        points = points.filter(pl.col("target") == 0)
    if points.height == 0:
        return None
    ns = points["t_ns"].to_numpy()
    start = max(int(ns[0]), first_move(joints) - round(COARSE_RANGE * 1e9))
    a, b = np.searchsorted(ns, [start, start + round(COARSE_WINDOW * 1e9)])
    return points.slice(int(a), int(b - a))


def first_move(joints: pl.DataFrame) -> int:
    """The stamp (ns) of the first joint state at which a joint has moved from the first by
    more than :data:`COARSE_FIRST` (rad or m); the last stamp where none has."""
    t = joints["t_ns"].to_numpy()
    for c in joints.columns[1:]:
        q = np.asarray(joints[c].to_numpy(), dtype=np.float64)
        away = np.flatnonzero(np.abs(q - q[0]) > COARSE_FIRST)
        if away.size:
            t = t[: int(away[0]) + 1]
    return int(t[-1])


def _peaks(corr: FloatArray, apart: int) -> list[int]:
    """The highest values of ``corr`` (NaN: none there), each at least ``apart`` steps from a
    higher one kept, highest first (at most eight)."""
    order = np.argsort(np.nan_to_num(corr, nan=-np.inf))[::-1]
    taken: list[int] = []
    for k in order.tolist():
        if not np.isfinite(corr[k]) or len(taken) >= 8:
            break
        if all(abs(k - j) > apart for j in taken):
            taken.append(k)
    return taken


def _single_joint_moves(
    joints: pl.DataFrame, t_j: FloatArray
) -> list[tuple[float, float, int, FloatArray]]:
    """The stretches (start, end in s on the joints' clock; the joint; its values at the joint
    states' times) of at least :data:`COARSE_SWEEP` s in which one joint alone moves."""
    q = np.column_stack([joints[c].to_numpy().astype(np.float64) for c in joints.columns[1:]])
    if q.shape[0] < 3:
        return []
    dt = np.diff(t_j)
    with np.errstate(invalid="ignore", divide="ignore"):
        rate = np.abs(np.diff(q, axis=0)) / dt[:, None]
    moving = rate > MOVING_SPEED
    alone = np.where(moving.sum(axis=1) == 1, np.argmax(moving, axis=1), -1)
    out = []
    cuts = np.flatnonzero(np.diff(alone)) + 1
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, alone.size], strict=True):
        j = int(alone[a])
        if j >= 0 and t_j[b] - t_j[a] >= COARSE_SWEEP:
            out.append((float(t_j[a]), float(t_j[b]), j, q[:, j]))
    return out


def _arc_misfit(
    t_p: FloatArray,
    xyz: list[FloatArray],
    t_j: FloatArray,
    sweeps: list[tuple[float, float, int, FloatArray]],
    lag: float,
) -> float:
    """With the joint states moved by ``lag`` s: the median over ``sweeps`` of the RMS (m) by
    which the target's samples (``xyz``: its x, y, z columns) at ``t_p`` (s, in time order) in
    each miss the best
    curve through them in its joint ``q`` — ``c + u cos q + v sin q + w q`` (a circle about
    any axis, or a line for a prismatic joint), fitted by least squares; inf without a sweep
    to judge."""
    misses = []
    for start, end, _, values in sweeps:
        a, b = np.searchsorted(t_p, [start + lag, end + lag], side="left")
        if b - a < 20:
            continue
        inside = np.arange(a, b, -(-(b - a) // 2000))
        q = np.interp(t_p[inside] - lag, t_j, values)
        basis = np.column_stack([np.ones(q.size), np.cos(q), np.sin(q), q])
        at = np.column_stack([c[inside] for c in xyz])
        coef, *_ = np.linalg.lstsq(basis, at, rcond=None)
        misses.append(float(np.sqrt(np.mean((at - basis @ coef) ** 2))))
    return float(np.median(misses)) if misses else math.inf


def _speed(x: FloatArray, step: float, *, each: bool = False) -> FloatArray:
    """The speed (per s) of the rows of ``x`` (grid of ``step`` s, d) by central differences
    over :data:`COARSE_HALF` each side: the length of the move (a point's), or with ``each``
    the largest column's (the joints'); NaN where a row it needs is."""
    h = _half(step)
    out = np.full(x.shape[0], np.nan)
    if x.shape[0] > 2 * h:
        move = x[2 * h :] - x[: -2 * h]
        size = np.max(np.abs(move), axis=1) if each else np.sqrt(np.sum(move**2, axis=1))
        out[h:-h] = size / (2 * h * step)
    return out


def _running_median(x: FloatArray) -> FloatArray:
    """``x`` through a running median of :data:`COARSE_MEDIAN` steps (NaN: no value; NaN where
    the window holds none)."""
    series = pl.Series(x, nan_to_null=True)
    kept = series.rolling_median(COARSE_MEDIAN, min_samples=1, center=True)
    return np.asarray(kept.fill_null(np.nan).to_numpy(), dtype=np.float64)


def _noise_speed(x: FloatArray, step: float) -> float:
    """The speed :func:`_speed` reads off the noise of the points ``x`` (grid, 3) alone: their
    σ per coordinate from the median second difference of consecutive steps (which a steady
    motion cancels; σ √6 for white noise), carried through the central difference."""
    second = x[2:] - 2.0 * x[1:-1] + x[:-2]
    ok = np.all(np.isfinite(second), axis=1)
    if not np.any(ok):
        return 0.0
    sigma = float(np.median(np.abs(second[ok]))) / (0.6745 * math.sqrt(6.0))
    return math.sqrt(3.0 * 2.0) * sigma / (2 * _half(step) * step)


def _half(step: float) -> int:
    """:data:`COARSE_HALF` in steps of ``step`` s (one at least)."""
    return max(1, round(COARSE_HALF / step))


def _varies(s: FloatArray) -> bool:
    """Whether ``s`` (NaN: unknown) takes two values at ten steps or more."""
    v = s[np.isfinite(s)]
    return v.size >= 10 and float(np.min(v)) != float(np.max(v))


def _masked_correlation(a: FloatArray, b: FloatArray, reach: int) -> FloatArray | None:
    """Per lag L in −reach … reach steps, the correlation (Pearson's) of ``a(t)`` with
    ``b(t − L)`` over the steps where both are known (NaN: unknown), by FFT; NaN where they
    overlap in fewer than :data:`COARSE_OVERLAP` of the steps the shorter one is known at."""
    n = a.size
    size = 1 << int(np.ceil(np.log2(2 * n)))
    ma, mb = np.isfinite(a).astype(np.float64), np.isfinite(b).astype(np.float64)
    a0, b0 = np.nan_to_num(a), np.nan_to_num(b)
    fa, fb = np.fft.rfft(a0, size), np.fft.rfft(b0, size)
    fma, fmb = np.fft.rfft(ma, size), np.fft.rfft(mb, size)
    faa, fbb = np.fft.rfft(a0 * a0, size), np.fft.rfft(b0 * b0, size)

    def lagged(u: NDArray[np.complex128], v: NDArray[np.complex128]) -> FloatArray:
        full = np.fft.irfft(u * np.conj(v), size)
        return np.r_[full[-reach:], full[: reach + 1]] if reach else full[:1]

    count = lagged(fma, fmb)
    with np.errstate(invalid="ignore", divide="ignore"):
        sa, sb = lagged(fa, fmb) / count, lagged(fma, fb) / count
        cov = lagged(fa, fb) / count - sa * sb
        va = lagged(faa, fmb) / count - sa * sa
        vb = lagged(fma, fbb) / count - sb * sb
        corr = cov / np.sqrt(va * vb)
    corr[(count < COARSE_OVERLAP * min(ma.sum(), mb.sum())) | ~(va > 1e-9) | ~(vb > 1e-9)] = np.nan
    return None if not np.any(np.isfinite(corr)) else corr
