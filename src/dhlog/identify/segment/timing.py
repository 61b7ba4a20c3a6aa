"""The clock offset between the tracker and the joint states, estimated from the data.

The pipeline's ``clock_offset`` (seconds added to the joint-state stamps) puts both streams on
the tracker's clock; a residual offset ``δ`` makes the encoder value joined to a target sample at
time t the one of ``t + δ``: ``Q(t) = q(t + δ) ≈ q(t) + δ q̇(t)``. While the joints move, that
is an error proportional to their speed — a lag the geometry of the sweeps exposes:

1. **Start** (:func:`phase_lag`): per sweep, a circle (seed 002's algebraic fit) or line fitted
   to the points alone gives
   each sample's angle (position) ``φ``, independent of any clock; ``φ = a + b Q − b δ q̇``
   is linear in ``a, b, e = −b δ`` and gives ``δ`` with its σ; the sweeps' estimates are
   combined by their weights. The encoders are joined again at the corrected offset
   (:func:`rejoin`) before anything is fitted (:func:`clock_start`, up to
   :data:`START_REJOINS` times).
2. **Maximum likelihood**: the whole-model fit carries ``δ`` as one more parameter (the
   prediction at ``Q − δ q̇``, :mod:`dhlog.identify.fit.prediction`), so its σ and its correlations
   enter every DH parameter's uncertainty; should it move by more than a fraction of its σ,
   the encoders are joined once more and the fit repeated.

Step-and-measure logs (samples only while the robot stands still) carry no lag: the offset is
then the pipeline's, and the result says why.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import DhlogError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.circles import fit_circle_algebraic
from dhlog.geometry.fitting import fit_line
from dhlog.identify.segment.encoders import BLOCK, Encoders
from dhlog.identify.segment.persample import blocks, rows_where
from dhlog.identify.segment.segment import Segmentation
from dhlog.io import scratch
from dhlog.io.reader import LogData
from dhlog.model.dh import JointType

#: Fewest moving samples a sweep needs to estimate the lag from.
MIN_MOVING = 20
#: Points per sweep used for the start estimate (evenly strided).
START_POINTS = 3000
#: A joint moves at a sample when its speed exceeds this (rad/s or m/s).
MOVING_SPEED = 1e-3
#: Below this fraction of sweep samples taken while moving, a log is step-and-measure.
STEP_FRACTION = 0.5
#: The whole-model fit joins the encoders again when its clock offset moved by more than this
#: many of its σ from the offset they were joined at (at most MAX_REJOINS times).
REJOIN_BELOW = 0.25
MAX_REJOINS = 2
#: ... and by more than this (s): the fit carries a smaller lag in its clock term
#: (``Q − δ q̇``), but the per-joint fits and the FK check read the encoders as joined, and a
#: target moving at 1 m/s is misjoined by 2 µm here, a fifth of a 10 µm tracker's noise (2 %
#: in quadrature). At 0.1 ms, as it was, KR5 sessions 50-90 ms off were fitted from a start
#: 70 µs off: the per-joint fits' σ 23 µm for 10, the FK check 0.032 mm for 0.0175 and the
#: error against the truth up to 3x that of the session in time.
REJOIN_FIT = 2e-6
#: Below this (s) the fit's own first-order move of the encoders errs by ``δ² q̈ / 2``, under
#: 10⁻⁸ rad at 1 rad/s²: a fit whose offset moved less is kept, its samples joined again at it
#: and its clock term set to none, not fitted again.
FIRST_ORDER = 1e-4
#: The start estimate joins the encoders again for a move beyond :data:`REJOIN_FIT` that
#: stands this many of its σ clear of none, or beyond :data:`FIRST_ORDER` (a start read on
#: a few thousand samples a sweep can be tens of µs uncertain where the fit is one).
START_SIGMAS = 3.0
REJOIN_START = REJOIN_FIT
#: A drift already mapped is refined only where it moves the offset by more than this (s)
#: across the sweeps, and the sweeps' lags are read for a drift with the encoders joined near
#: their mean lag where it is more than this off (:func:`~dhlog.identify.segment.clocks
#: .at_one_rate`).
DRIFT_NEAR = 1e-4
#: ``Timing.reason`` of a step-and-measure session's offset found at its stops' edges
#: (:func:`~dhlog.identify.clocked.fit_clocked`; ``std`` None).
STOPS = "stops"
#: The start estimate of the clock offset joins the encoders again at most this many times.
START_REJOINS = 4
#: A sweep's samples whose angle misses its regression by more than this many robust σ are
#: gross outliers, left out of its lag.
LAG_OUTLIER = 5.0
#: A clock drift is estimated from this many sweeps that time their lag at least, and taken
#: where it stands this many σ clear of none.
DRIFT_SWEEPS = 3
DRIFT_SIGMAS = 5.0
#: ... and where it moves the offset by more than this (s) across them: the sweeps' lags of a
#: clock in time differ one joint from another by up to 0.05 ms, a slope of a few ppm over a
#: simulated 30 s session; a real one of ten minutes at 20 ppm moves it 12 ms.
DRIFT_FLOOR = 2e-4


@dataclass(frozen=True)
class Timing:
    """The clock offset (s, added to the joint-state stamps; the pipeline's sign), its σ (None
    when not estimated), where it comes from (``estimated``, ``pipeline``), the pipeline's own
    value, and why it was not estimated (empty when it was)."""

    offset: float
    std: float | None
    source: str
    pipeline: float
    reason: str = ""
    #: the offset (s) the joint states were moved by before the log was segmented, where
    #: their clock was seconds off the tracker's (:mod:`dhlog.identify.segment.clocks`); part
    #: of ``offset``
    coarse: float = 0.0
    #: the joint states' clock drift (s gained a second; :class:`Drift`) their stamps were
    #: mapped by before the log was segmented again (0: none found), ``offset`` read at
    #: ``drift_ref_ns``
    drift: float = 0.0
    drift_ref_ns: int = 0
    #: a step of the joint states' clock mid-session (:mod:`dhlog.identify.segment.steps`): s
    #: added to their stamps from the one logged at ``step_at_ns`` on (0: none found)
    step: float = 0.0
    step_at_ns: int = 0
    #: the first joint state the step moved, by its row in the joint-state table (-1: none)
    step_index: int = -1

    def document(self) -> dict[str, object]:
        """The result JSON's ``timing`` block."""
        return {
            "clock_offset": self.offset,
            "std": self.std,
            "source": self.source,
            "pipeline_clock_offset": self.pipeline,
            **({"reason": self.reason} if self.reason else {}),
            **({"coarse_offset": self.coarse} if self.coarse else {}),
            **(
                {"clock_drift": self.drift, "drift_reference_ns": self.drift_ref_ns}
                if self.drift
                else {}
            ),
            **({"clock_step": self.step, "clock_step_at_ns": self.step_at_ns} if self.step else {}),
        }


class JointRates:
    """Each joint's speed from the encoder stream (its finite differences at their midpoints),
    interpolated linearly at any times (0 outside the stream) — as ``np.interp`` does, value for
    value, but with the differences taken where they are needed: nothing of the size of the
    stream is kept beyond its midpoints and steps."""

    def __init__(self, encoders: Encoders) -> None:
        t_ns = encoders.t_ns  # as joined: the speeds are asked for at the tracker's times
        pairs = max(t_ns.size - 1, 0)
        ok = scratch.empty(pairs, np.bool_)
        for sl in blocks(pairs):
            ok[sl] = np.diff(t_ns[sl.start : sl.stop + 1].astype(np.float64)) > 0
        #: the first encoder sample of each difference (None: every pair)
        self.first = None if bool(all(np.all(ok[sl]) for sl in blocks(pairs))) else rows_where(ok)
        del ok
        count = pairs if self.first is None else self.first.size
        self.mid, self.dt = scratch.empty(count), scratch.empty(count)
        for sl in blocks(count):
            if self.first is None:
                t0 = t_ns[sl].astype(np.float64)
                t1 = t_ns[sl.start + 1 : sl.stop + 1].astype(np.float64)
            else:
                k = self.first[sl]
                t0, t1 = t_ns[k].astype(np.float64), t_ns[k + 1].astype(np.float64)
            self.mid[sl] = (t1 + t0) / 2.0
            self.dt[sl] = (t1 - t0) * 1e-9
        self.q = encoders.q

    def _speeds(self, i: int, j: NDArray[np.intp]) -> FloatArray:
        """Joint ``i``'s finite differences number ``j``."""
        k = j if self.first is None else self.first[j]
        column = self.q[i]
        return np.asarray((column[k + 1] - column[k]) / self.dt[j], dtype=np.float64)

    def at(self, t_ns: NDArray[np.int64], joints: list[int] | None = None) -> FloatArray:
        """Speeds (m, len(joints)) at ``t_ns`` of ``joints`` (0-based; default all): each
        joint's differences over the span of midpoints ``t_ns`` falls in, interpolated by
        ``np.interp`` (0 before the first midpoint and after the last)."""
        cols = range(len(self.q)) if joints is None else joints
        out = np.zeros((t_ns.size, len(cols)))
        mid = self.mid
        if mid.size < 2 or not t_ns.size:
            return out
        x = t_ns.astype(np.float64)
        # the midpoints around every time asked: those before it, and the one after
        ends = np.searchsorted(mid, [x.min(), x.max()], side="right") - 1
        lo, hi = max(int(ends[0]), 0), min(int(ends[1]) + 2, mid.size)
        span = np.arange(lo, hi)
        for k, i in enumerate(cols):
            out[:, k] = np.interp(x, mid[lo:hi], self._speeds(i, span), left=0.0, right=0.0)
        return out


def rejoin(seg: Segmentation, log: LogData, extra: float) -> Segmentation:
    """``seg`` with its encoder values joined again with the joint-state stamps moved by
    ``extra`` seconds more (labels and sweeps kept; samples of a sweep left without encoder
    values by the move leave it)."""
    assert seg.encoders is not None
    pipeline_shift = round(extra * 1e9)
    encoders = seg.encoders.shifted(pipeline_shift)
    moved = replace(seg, encoders=encoders)
    segment = seg.segment
    lost = np.zeros(0, dtype=np.intp)
    for sl in blocks(seg.height, BLOCK):
        inside = np.flatnonzero(segment[sl] > 0)
        if inside.size:
            at = sl.start + inside
            lost = np.concatenate([lost, at[~moved.has_q(at)]])
    if not lost.size:  # moved off the joint stream's ends: out of their sweeps
        return moved
    segment = scratch.moved(segment, copy=True)
    segment[lost] = 0
    aside = dict(seg.set_aside)
    aside["no_encoder"] = aside.get("no_encoder", 0) + int(lost.size)
    ids = seg.segments["segment"].to_numpy()
    counts = np.bincount(segment, minlength=int(ids.max(initial=0)) + 1)
    segments = seg.segments.with_columns(pl.Series("n", counts[ids]).cast(seg.segments["n"].dtype))
    return replace(moved, segment=segment, segments=segments, set_aside=aside)


@dataclass(frozen=True)
class SweepPhase:
    """What one sweep's points say of its encoder: the joint (1-based), the slope of the
    points' angle (position) over the encoder value (1 when both are in the same unit), and the
    lag ``δ`` with its σ (None when the sweep barely moves while sampled), when it was swept
    (``t_ns``)."""

    joint: int
    slope: float
    delta: float | None
    std: float | None
    moving: int
    samples: int
    #: the stamp (ns) its lag holds at: its samples' weighed as the regression's speed column
    t_ns: int = 0
    #: its lag and σ with the tracker's gross outliers left out (:data:`LAG_OUTLIER`), which
    #: the drift reads
    drift_delta: float | None = None
    drift_std: float | None = None


def sweep_phases(
    seg: Segmentation, log: LogData, joint_types: Sequence[JointType | None] | None = None
) -> list[SweepPhase]:
    """Per sweep: the points-only fit's angle (position) regressed on ``1, Q, q̇`` (see the
    module); at most :data:`START_POINTS` evenly strided samples per sweep, each read along a
    line or a circle by its joint's type in ``joint_types`` (None, or a None entry: unknown)."""
    if log.joints is None or seg.encoders is None:
        return []
    rates = JointRates(seg.encoders)
    out = []
    for sid, j1 in zip(seg.segments["segment"], seg.segments["joint"], strict=True):
        rows = seg.rows_in([sid])
        finite = scratch.empty(rows.size, np.bool_)
        for b in blocks(rows.size, BLOCK):
            finite[b] = np.isfinite(seg.q(rows[b])).all(axis=1)
        rows = scratch.gathered(rows, rows_where(finite))
        if rows.size < 4:
            continue
        if rows.size > START_POINTS:
            rows = rows[:: -(-rows.size // START_POINTS)]
        j = int(j1) - 1
        rate = rates.at(seg.t_ns[rows], [j])[:, 0]
        moving = int(np.count_nonzero(np.abs(rate) > MOVING_SPEED))
        kind = joint_types[j] if joint_types is not None and j < len(joint_types) else None
        prismatic = None if kind is None else kind is JointType.PRISMATIC
        points, q = seg.xyz(rows), seg.q(rows, [j])[:, 0]
        one = _sweep_lag(points, q, rate, moving >= MIN_MOVING, prismatic)
        if one is not None:
            slope, delta, std = one
            robust = _sweep_lag(points, q, rate, moving >= MIN_MOVING, prismatic, robust=True)
            # the lag is read where the joint moves: the time it holds at weighs each sample
            # as the regression's speed column does
            t = seg.t_ns[rows].astype(np.float64)
            speed2 = rate**2
            when = int(np.sum(speed2 * t) / np.sum(speed2)) if np.sum(speed2) > 0 else int(t.mean())
            _, drift_delta, drift_std = robust if robust is not None else (None, None, None)
            out.append(
                SweepPhase(
                    j + 1,
                    slope,
                    delta,
                    std,
                    moving,
                    int(rows.size),
                    when,
                    drift_delta,
                    drift_std,
                )
            )
    return out


def timed_phases(phases: list[SweepPhase]) -> list[SweepPhase]:
    """The phases that time their sweep (a lag with its σ, the encoder's slope near 1), where
    the sweeps move while the tracker samples them (not step-and-measure); else none."""
    timed = [
        p for p in phases if p.delta is not None and p.std is not None and 0.5 < abs(p.slope) < 2.0
    ]
    moving = sum(p.moving for p in phases)
    total = sum(p.samples for p in phases)
    return timed if moving >= STEP_FRACTION * total else []


@dataclass(frozen=True)
class Drift:
    """The joint states' clock running at another rate than the tracker's: the ``rate`` (s of
    offset gained a second) and its σ, from the sweeps' lags against when they were swept;
    ``t_ref_ns`` the stamp the offset is read at (the sweeps' weighted mean time), ``span`` (s)
    the time the sweeps cover."""

    rate: float
    std: float
    t_ref_ns: int
    span: float

    @property
    def described(self) -> str:
        """How the clock ran and how far its offset moved, as the notes say it."""
        return (
            f"ran {pace(self.rate)} ({self.std * 1e6:.1f} ppm σ) against the tracker's: its "
            f"offset moved {abs(self.rate) * self.span * 1e3:.2f} ms over the {self.span:.0f} s "
            "the sweeps span (their lags against when each was swept)"
        )


def pace(rate: float) -> str:
    """A clock drift ``rate`` (s added to the stamps a second, the pipeline's sign) as a clock
    running fast or slow: ``"52.3 ppm fast"``."""
    return f"{abs(rate) * 1e6:.1f} ppm {'fast' if rate < 0 else 'slow'}"


def set_by(step: float) -> str:
    """A step of the joint states' clock (s added to the stamps after it) as the clock set back
    or on: ``"set 20.0 ms back"``."""
    return f"set {abs(step) * 1e3:.1f} ms {'back' if step > 0 else 'on'}"


def phase_drift(phases: list[SweepPhase], *, refine: bool = False) -> Drift | None:
    """The clock drift the sweeps' lags show (:class:`Drift`: a line through each sweep's lag
    against its time, weighted by their σ, its σ widened by the scatter about it), where at
    least :data:`DRIFT_SWEEPS` sweeps time it, the rate stands :data:`DRIFT_SIGMAS` σ clear of
    none and it moves the offset by more than :data:`DRIFT_FLOOR` across them (the sweeps' lags
    in time differ one joint from another by up to 0.05 ms); else None. ``refine``: a drift
    already found and mapped, refined at any σ beyond :data:`DRIFT_NEAR` across them.
    Two computers' crystals differ by 10-50 ppm: 12 ms over a 10-minute session at 20 ppm,
    which misjoins a sweep's target by millimetres at its ends; a constant offset cannot."""
    timed = [p for p in timed_phases(phases) if p.drift_delta is not None and p.drift_std]
    if len(timed) < DRIFT_SWEEPS:
        return None
    t = np.array([p.t_ns for p in timed], dtype=np.float64) * 1e-9
    d = np.array([p.drift_delta for p in timed], dtype=np.float64)
    w = 1.0 / np.array([p.drift_std for p in timed], dtype=np.float64) ** 2
    t_ref = float(np.sum(w * t) / np.sum(w))
    x = t - t_ref
    sxx = float(np.sum(w * x**2))
    span = float(t.max() - t.min())
    if not sxx > 0.0 or not span > 0.0:
        return None
    rate = float(np.sum(w * x * d) / sxx)
    mean = float(np.sum(w * d) / np.sum(w))
    chi2 = (
        float(np.sum(w * (d - mean - rate * x) ** 2)) / (len(timed) - 2) if len(timed) > 2 else 1.0
    )
    std = math.sqrt(max(chi2, 1.0) / sxx)
    if refine:
        return Drift(rate, std, round(t_ref * 1e9), span) if abs(rate) * span > DRIFT_NEAR else None
    if abs(rate) < DRIFT_SIGMAS * std or abs(rate) * span <= DRIFT_FLOOR:
        return None
    return Drift(rate, std, round(t_ref * 1e9), span)


def phase_lag(
    seg: Segmentation, log: LogData, phases: list[SweepPhase] | None = None
) -> tuple[float, float] | None:
    """The residual offset ``δ`` (s) and its σ from the sweeps' phases (see the module), or
    None when no sweep moves enough samples to tell (step-and-measure)."""
    phases = sweep_phases(seg, log) if phases is None else phases
    # step-and-measure: the samples were taken at the stops; the few that the offset joins to
    # the start of the next move are not a timing signal to trust
    estimates = [(p.delta, p.std) for p in timed_phases(phases)]
    if not estimates:
        return None
    values = np.array([e[0] for e in estimates])
    weights = 1.0 / np.array([e[1] for e in estimates]) ** 2
    delta = float(np.sum(weights * values) / np.sum(weights))
    std = float(1.0 / math.sqrt(np.sum(weights)))
    if len(estimates) > 2:  # the sweeps disagree beyond their σ: widen by their scatter
        chi2 = float(np.sum(weights * (values - delta) ** 2)) / (len(estimates) - 1)
        std *= math.sqrt(max(chi2, 1.0))
    return delta, std


def _sweep_positions(points: FloatArray, prismatic: bool | None) -> FloatArray | None:
    """The points' positions along their sweep: along a line for a ``prismatic`` joint, the
    angles about the circle fitted to them (unwrapped) for a revolute one (a line where no
    circle fits); of a joint of unknown type, along the line where it fits them within 2x the
    circle's RMS (a circle fitted to a line's noisy points gives positions along an arc, not
    along the line). None where neither fits."""
    circle = line = None
    if prismatic is not True:
        try:
            circle = fit_circle_algebraic(points, min_sweep=0.0)  # phases only: no scipy needed
        except DhlogError:
            pass
    if circle is None or prismatic is None:
        try:
            line = fit_line(points, min_travel=0.0)
        except DhlogError:
            pass
    if line is not None and (circle is None or line.rms <= 2.0 * circle.rms):
        return np.asarray(line.positions, dtype=np.float64)
    if circle is None:
        return None
    return np.asarray(np.unwrap(circle.positions), dtype=np.float64)


def _sweep_lag(
    points: FloatArray,
    q: FloatArray,
    rate: FloatArray,
    timed: bool,
    prismatic: bool | None = None,
    *,
    robust: bool = False,
) -> tuple[float, float | None, float | None] | None:
    """Slope, ``δ`` and σ of one sweep: its points' angle (position) regressed on ``1, Q, q̇``
    (on ``1, Q`` alone when it barely moves while sampled: ``timed`` False); positions along
    the sweep by :func:`_sweep_positions` (``prismatic``: the joint's type, None unknown)."""
    phi = _sweep_positions(points, prismatic)
    if phi is None:
        return None
    columns = [np.ones(q.size), q - q.mean()] + ([rate] if timed else [])
    A = np.column_stack(columns)
    coef, *_ = np.linalg.lstsq(A, phi, rcond=None)
    # ``robust``: the tracker's gross outliers out (beyond LAG_OUTLIER robust σ), fitted again:
    # they widen the lag's σ, which hides a drift the sweeps' lags show
    resid = phi - A @ coef
    scale = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    keep = np.abs(resid) <= LAG_OUTLIER * scale if scale > 0 else np.ones(q.size, dtype=bool)
    if robust and A.shape[1] < np.count_nonzero(keep) < q.size:
        A, phi, q = A[keep], phi[keep], q[keep]
        coef, *_ = np.linalg.lstsq(A, phi, rcond=None)
    b = float(coef[1])
    if not timed:
        return (b, None, None) if math.isfinite(b) else None
    resid = phi - A @ coef
    dof = max(q.size - 3, 1)
    try:
        cov = np.linalg.inv(A.T @ A) * float(resid @ resid) / dof
    except np.linalg.LinAlgError:
        return (b, None, None) if math.isfinite(b) else None
    e = float(coef[2])
    if abs(b) < 1e-12 or not np.all(np.isfinite(cov)):
        return None
    delta = -e / b
    std = math.sqrt(max(float(cov[2, 2]), 0.0)) / abs(b)
    if not (math.isfinite(delta) and std > 0.0):
        return (b, None, None)
    return b, delta, std


def clock_start(
    seg: Segmentation, log: LogData, phases: list[SweepPhase] | None = None, coarse: float = 0.0
) -> tuple[Segmentation, Timing | None, tuple[Note, ...]]:
    """The clock offset's start estimate from the sweeps' phases (:func:`phase_lag`), the
    encoders joined again at it; the pipeline's offset where it is fixed or cannot be told
    (a step-and-measure log: a note, ``clock-offset``). ``coarse``: what ``log``'s joint states
    were moved by already (:mod:`dhlog.identify.segment.clocks`), part of the offset given."""
    pipe = log.pipeline.segmentation
    if not seg.has_encoders or log.joints is None:
        return seg, None, ()
    if pipe.clock_offset_fixed:
        return seg, Timing(pipe.clock_offset, None, "pipeline", pipe.clock_offset, "fixed"), ()
    total, std = 0.0, None
    for attempt in range(START_REJOINS):
        lag = phase_lag(seg, log, phases if attempt == 0 else None)
        if lag is None:
            break
        delta, std = lag
        clear = abs(delta) > START_SIGMAS * std or abs(delta) > FIRST_ORDER
        if not clear or abs(delta) <= REJOIN_START:
            break
        total += delta
        seg = rejoin(seg, log, total)
    if std is None:
        said = Note.info(
            "no sweep moves while the tracker samples it (step-and-measure): the clock offset "
            "is not estimated from the sweeps; it moves only the samples taken as the robot "
            "arrives at or leaves a stop, and is looked for there by the first fit."
            if not coarse
            else "no sweep moves while the tracker samples it (step-and-measure): the offset "
            "is not estimated finer than the match of when each stream moves.",
            "clock-offset",
        )
        timing = Timing(
            pipe.clock_offset + coarse,
            None,
            "pipeline",
            pipe.clock_offset,
            "step-and-measure",
            coarse,
        )
        return seg, timing, (said,)
    offset = pipe.clock_offset + coarse + total
    return seg, Timing(offset, std, "estimated", pipe.clock_offset, coarse=coarse), ()
