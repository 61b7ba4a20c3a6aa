"""The first fit of the whole model as the clock leaves it (:func:`fit_clocked` →
:class:`Clocked`): from the session's start, with the clock offset the sweeps' phases estimated
carried as a parameter and the encoders joined again at the fitted offset while it moves
(:mod:`dhlog.identify.segment.timing`); a step-and-measure session's offset, which no sweep
times, found where that fit misses the samples at the stops' edges least (:func:`_at_stops`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.samples import measured_rotations, sample_covariance, start_model
from dhlog.identify.fit.variance import residual_norms
from dhlog.identify.fit.whole import CHI3_MEDIAN, WholeFit, fit_whole_model
from dhlog.identify.joints.sweeps import samples_with_encoders, target_labels
from dhlog.identify.read.extract import Extraction
from dhlog.identify.segment.clocks import FINE_REACH, nearest_offset
from dhlog.identify.segment.persample import PerSample
from dhlog.identify.segment.segment import Segmentation
from dhlog.identify.segment.steps import STEP_REACH
from dhlog.identify.segment.timing import (
    FIRST_ORDER,
    MAX_REJOINS,
    REJOIN_BELOW,
    REJOIN_FIT,
    STOPS,
    JointRates,
    Timing,
    pace,
    rejoin,
)
from dhlog.identify.stages import Session
from dhlog.model.noise import NoiseModel

#: ``stage(what, fraction)``: told as each stage advances.
Stage = Callable[[str, float], None]

#: The samples a step-and-measure session's clock is judged on (evenly strided).
STOPS_SAMPLES = 20_000
#: ... taken where it misses them this many times less than the offset as joined: only the
#: samples at the stops' edges move with it (20 ms off at stops held 1 s, 1 kHz: 8 % less).
STOPS_CLEARER = 1.02
#: A step-and-measure session's drift: its offset found in this many stretches of it in time,
#: taken where a line through them moves it by more than STOPS_DRIFT (s) and this many times
#: their scatter about the line (within the stops' margins each is found to a few ms).
STOPS_WINDOWS = 6
STOPS_DRIFT = 0.03
STOPS_DRIFT_CLEAR = 10.0
#: ... mapped by it and found again at most this many times (each line through six stretches
#: found to a few ms leaves part of a large drift: 200 ppm over 27 min read as 222).
STOPS_DRIFT_MAPS = 3
#: Fewest samples with joint states a step-and-measure session's clock is judged at.
MIN_JUDGED = 20
#: Where the least miss lies at the edge of the search's reach (the offset beyond it), the
#: search is made again around it at most this many times: a clock drifting 1 000 ppm moves
#: the offset 0.5 s over a 60-pose session, 0.08 s from one stretch of it to the next.
STOPS_FOLLOW = 4
#: A clock set mid-session, sized again within STEP_REACH of where the lags put it, is
#: fitted again so up to this many times, until it moves by less than this (s).
STEP_REFITS = 3
STEP_SETTLED = 1e-6


@dataclass(frozen=True)
class Clocked:
    """The fit as the clock left it: the fit, the segmentation and its rows the samples are
    (joined again when the offset moved), the samples and weights every later fit takes, and
    the clock."""

    whole: WholeFit
    segmentation: Segmentation
    rows: NDArray[np.intp]
    data: FitData
    options: FitOptions
    timing: Timing | None
    notes: tuple[Note, ...] = ()


def fit_clocked(
    session: Session, analytic: Extraction | None, fit_scales: bool, stage: Stage
) -> Clocked:
    """The first fit of the whole model from the session's start; with a clock offset
    estimated from the data, the encoders joined again at the fitted offset and the fit
    repeated while the offset moves (at most :data:`MAX_REJOINS` times)."""
    seg, joints, ref = session.segmentation, session.joints, session.reference_pose
    types = tuple(j.type for j in joints)
    assert session.target is not None
    rows, Q, P = session.samples()
    which = target_labels(seg, rows)
    rotations = measured_rotations(seg, rows)
    sample_cov = sample_covariance(seg, rows)
    start = start_model(
        [j.axis for j in joints],  # type: ignore[misc]
        types,  # type: ignore[arg-type]
        session.target,
        ref,
        FitData(Q, P, sample_cov, which, rotations),
        frozenset(session.parked),
    )
    noise = NoiseModel("per-sample") if sample_cov is not None else session.noise
    fit_sigmas = [j.fit.sigma**2 for j in joints if j.fit is not None]
    sigma = math.sqrt(np.mean(fit_sigmas)) if fit_sigmas else 1e-5
    stage("identifying", 0.1)
    timing = session.timing
    clocked = timing is not None and timing.source == "estimated"
    speeds = JointRates(seg.encoders) if clocked and seg.encoders is not None else None
    options = FitOptions(noise, sigma, sigma_rotation=noise.orientation, fit_scales=fit_scales)
    for attempt in range(MAX_REJOINS + 1):
        rates = None if speeds is None else _rates(speeds, seg, rows)
        data = FitData(Q, P, sample_cov, which, rotations, rates)
        whole = fit_whole_model(
            start,
            data,
            replace(options, threshold=math.inf if analytic is None else 5.0),
            progress=lambda f: stage("identifying", 0.1 + 0.9 * f),
        )
        if analytic is None:
            # started from the nominal (or a coupled move's circle): the start misses the
            # samples it did not see by far more than the noise, so the first fit judged no
            # sample an outlier; judge them at its optimum, on the noise's own scale
            if not fit_sigmas:
                norms = residual_norms(whole.model, Q, P, which=which, rates=rates)
                options = replace(options, sigma=max(float(np.median(norms)) / CHI3_MEDIAN, 1e-9))
            whole = fit_whole_model(whole.model, data, options)
        if not clocked or timing is None:
            break
        at = whole.layout.clock_at
        assert at is not None
        delta, sd = whole.model.clock, math.sqrt(max(float(whole.covariance[at, at]), 0.0))
        offset = timing.offset + delta
        timing = replace(timing, offset=offset, std=sd)
        if abs(delta) <= max(REJOIN_BELOW * sd, REJOIN_FIT) or attempt == MAX_REJOINS:
            break  # below REJOIN_FIT the encoders as joined misplace the target by microns
        # join the encoders again at the fitted offset and fit once more from there
        seg = rejoin(seg, session.log, offset - timing.pipeline - timing.coarse)
        joined, Q, P = samples_with_encoders(seg)
        which = target_labels(seg, joined)
        rotations = measured_rotations(seg, joined)
        sample_cov = sample_covariance(seg, joined)
        start = replace(whole.model, clock=0.0)
        if abs(delta) <= FIRST_ORDER and np.array_equal(joined, rows):
            # the fit moved the encoders so already, to first order: kept, on them as joined
            data = FitData(Q, P, sample_cov, which, rotations, data.rates)
            whole = replace(whole, model=start)
            break
        rows = joined
    if speeds is not None and timing is not None and timing.step:
        seg, rows, data, whole, timing = _joined_at_step(
            seg, rows, data, whole, options, timing, speeds
        )
    if timing is not None and timing.reason == "step-and-measure" and seg.encoders is not None:
        return _joined_at_stops(session, seg, rows, whole, options, timing) or Clocked(
            whole, seg, rows, data, options, timing
        )
    return Clocked(whole, seg, rows, data, options, timing)


def _joined_at_stops(
    session: Session,
    seg: Segmentation,
    rows: NDArray[np.intp],
    whole: WholeFit,
    options: FitOptions,
    timing: Timing,
) -> Clocked | None:
    """A step-and-measure session joined again at the offset, and the drift, its stops' edges
    show (:func:`_at_stops`, :func:`_drift_at_stops`) and fitted again, with the note that
    says so; None where they show none."""
    first = seg.encoders
    assert first is not None
    at = _at_stops(seg, rows, whole.model)
    rate, moved, t_ref, span, notes = 0.0, 0.0, 0, 0.0, []
    fitted = None
    for _ in range(STOPS_DRIFT_MAPS):
        found = _drift_at_stops(seg, rows, whole.model, 0.0 if rate else (at or 0.0))
        if found is None:
            break
        pace_more, shift, t_ref, span = found  # each about the last map (the same stretches)
        encoders = seg.encoders
        assert encoders is not None
        seg = replace(seg, encoders=encoders.drifted(shift, pace_more, t_ref))
        rate, moved = rate + pace_more, moved + shift
        # fitted again on the stamps as mapped, so the next search judges them by a model
        # that misjoined samples did not bend (stops held 0.3 s, 1 000 ppm: all of them)
        fitted = _fitted(seg, whole.model, options)
        whole = fitted[2]
    left = _at_stops(seg, rows, whole.model) if rate else None
    if left is not None:  # the offset the line left, found by the fit on the stamps as mapped
        encoders = seg.encoders
        assert encoders is not None
        seg = replace(seg, encoders=encoders.drifted(left, 0.0, t_ref))
        moved += left
        fitted = _fitted(seg, whole.model, options)
    if rate:
        at = moved  # the offset at the reference
        timing = replace(timing, drift=rate, drift_ref_ns=t_ref)
        said = (
            f"the joint states' clock ran {pace(rate)} against the tracker's: the offset its "
            f"stops' edges show moved {abs(rate) * span * 1e3:.1f} ms over {span:.0f} s "
            f"({STOPS_WINDOWS} stretches of them, each found as below); their stamps were "
            "mapped by it. Two computers without a common time drift so: synchronise their "
            "clocks (PTP, chrony) for the next session."
        )
        notes.append(Note.warning(said, "clock-drift"))
    elif at is not None:
        seg = rejoin(seg, session.log, first.shift_ns * 1e-9 + at)
        fitted = _fitted(seg, whole.model, options)
    if fitted is None or at is None:
        return None
    rows, data, whole = fitted
    timing = replace(timing, offset=timing.offset + at, source="estimated", reason=STOPS)
    said = (
        f"the joint states' stamps were {at * 1e3:+.1f} ms off"
        + (" at the stops' mean time" if rate else "")
        + " (beyond the pipeline's clock_offset): found where the first fit misses the "
        "tracker's samples least, those taken as the robot arrives at or leaves a stop, which "
        "an offset joins to the joints' values of the move; joined there and fitted again."
    )
    notes.append(Note.info(said, "clock-stops"))
    return Clocked(whole, seg, rows, data, options, timing, tuple(notes))


def _joined_at_step(
    seg: Segmentation,
    rows: NDArray[np.intp],
    data: FitData,
    whole: WholeFit,
    options: FitOptions,
    timing: Timing,
    speeds: JointRates,
) -> tuple[Segmentation, NDArray[np.intp], FitData, WholeFit, Timing]:
    """A clock set mid-session (``timing.step``, read from the sweeps' lags to some 10-100 µs)
    sized again where the fit misses its inliers after it least, its own clock offset
    included (:func:`_stops_miss` with the joints' speeds, within :data:`STEP_REACH`): the
    joint states from the step on moved by that and the model fitted again, up to
    :data:`STEP_REFITS` times. A misjoin of 0.1 ms moves a target swept at 1 m/s by 0.1 mm,
    ten times the noise; the fit's one clock offset takes up the mean of the two sides, not
    their difference."""
    from scipy.optimize import minimize_scalar  # scipy.optimize costs 0.35 s to import

    index, moved = timing.step_index, 0.0
    for _ in range(STEP_REFITS):
        encoders = seg.encoders
        if encoders is None or not 0 < index < encoders.t_ns.size:
            break
        later = seg.t_ns[rows] >= encoders.t_ns[index] + encoders.tol_ns
        if np.count_nonzero(later) == rows.size:
            break
        after = rows[later & whole.inliers]  # gross outliers (5 %: mm each) flatten the miss
        if after.size < MIN_JUDGED * 10:
            break
        miss = _stops_miss(seg, after, whole.model, STOPS_SAMPLES, speeds)
        found = minimize_scalar(
            miss, bounds=(-STEP_REACH, STEP_REACH), method="bounded", options={"xatol": 1e-7}
        )
        at = float(found.x)
        if not float(found.fun) < miss(0.0) or abs(at) < STEP_SETTLED:
            break
        seg = replace(seg, encoders=encoders.stepped(index, at))
        moved += at
        rows, Q, P = samples_with_encoders(seg)
        which = target_labels(seg, rows)
        data = FitData(
            Q,
            P,
            sample_covariance(seg, rows),
            which,
            measured_rotations(seg, rows),
            _rates(speeds, seg, rows),
        )
        clock = whole.model.clock
        whole = fit_whole_model(whole.model, data, options)
        at_ = whole.layout.clock_at
        sd = math.sqrt(max(float(whole.covariance[at_, at_]), 0.0)) if at_ is not None else None
        offset = timing.offset - clock + whole.model.clock
        timing = replace(timing, offset=offset, std=sd if sd is not None else timing.std)
    return seg, rows, data, whole, replace(timing, step=timing.step + moved)


def _fitted(
    seg: Segmentation, start: AxisModel, options: FitOptions
) -> tuple[NDArray[np.intp], FitData, WholeFit]:
    """The whole model fitted from ``start`` on the samples as ``seg`` joins them: their rows,
    the samples and the fit."""
    rows, Q, P = samples_with_encoders(seg)
    which = target_labels(seg, rows)
    data = FitData(Q, P, sample_covariance(seg, rows), which, measured_rotations(seg, rows))
    return rows, data, fit_whole_model(start, data, options)


def _rates(speeds: JointRates, seg: Segmentation, rows: NDArray[np.intp]) -> PerSample:
    """The joints' speeds (m, n) at the samples ``rows``, read a block at a time."""
    return PerSample(
        (rows.size, seg.n_joints), lambda index: speeds.at(seg.t_ns[rows[index]])
    ).filled()


def _at_stops(
    seg: Segmentation,
    rows: NDArray[np.intp],
    model: AxisModel,
    *,
    around: float = 0.0,
    clearer: float = STOPS_CLEARER,
    samples: int = STOPS_SAMPLES,
) -> float | None:
    """A step-and-measure session's clock offset (s) beyond the one its encoders are joined at:
    where ``model`` (its first fit) misses the samples ``rows`` (at most ``samples``, evenly
    strided) least, the RMS of every one counted, within reach of ``around``
    (:func:`~dhlog.identify.segment.clocks.nearest_offset`); None where none misses
    ``clearer`` times less than there. No sweep times the offset, but the tracker's samples as
    the robot arrives at a stop and leaves it are joined to the joints' values that long before
    or after: a KR5 off its nominal at 40 random poses held 1 s, 90 ms off, was fitted with
    2 192 of them set aside and an error against the truth 3.7x that in time."""
    miss = _stops_miss(seg, rows, model, samples)
    at = nearest_offset(miss, around, clearer=clearer)
    for _ in range(STOPS_FOLLOW):
        if at is None or abs(at - around) < FINE_REACH:
            break
        around = at  # the least miss at the edge of the reach: the offset lies beyond
        at = nearest_offset(miss, around, clearer=1.0)
    return at


def _stops_miss(
    seg: Segmentation,
    rows: NDArray[np.intp],
    model: AxisModel,
    samples: int,
    speeds: JointRates | None = None,
) -> Callable[[float], float]:
    """``miss(offset)``: the RMS (m) by which ``model`` misses the samples ``rows`` (at most
    ``samples``, evenly strided) with the encoders of ``seg`` read ``offset`` (s) later, every
    one counted — with the joints' ``speeds``, the model's own clock offset included —;
    infinite where fewer than :data:`MIN_JUDGED` have joint states there."""
    encoders = seg.encoders
    assert encoders is not None
    pick = rows[:: max(1, -(-rows.size // samples))]
    P, t = seg.xyz(pick), seg.t_ns[pick]
    which = target_labels(seg, pick)

    def miss(offset: float) -> float:
        moved = t - round(offset * 1e9)  # the stream's stamps moved by ``offset``
        Q = encoders.at(moved)
        rates = None if speeds is None else speeds.at(moved)
        ok = np.isfinite(Q).all(axis=1)
        if rates is not None:
            ok &= np.isfinite(rates).all(axis=1)
        if np.count_nonzero(ok) < MIN_JUDGED:
            return math.inf
        d = residual_norms(
            model,
            Q[ok],
            P[ok],
            which=None if which is None else which[ok],
            rates=None if rates is None else rates[ok],
        )
        return float(np.sqrt(np.mean(d**2)))

    return miss


def _drift_at_stops(
    seg: Segmentation, rows: NDArray[np.intp], model: AxisModel, around: float
) -> tuple[float, float, int, float] | None:
    """A step-and-measure session's clock drift: its offset found again in
    :data:`STOPS_WINDOWS` stretches of its samples in time (:func:`_at_stops`, the best each
    gives), a line through them against time — (rate, the offset at the reference, the
    reference stamp (ns), the span in s) — where it moves the offset by more than
    :data:`STOPS_DRIFT` across them and either :data:`STOPS_DRIFT_CLEAR` times the line's
    scatter or, mapped by it, the samples are missed :data:`STOPS_CLEARER` times less than at
    ``around`` (the one offset that joins them best); else None. Each stretch is searched
    about the line through the two before it, so the search follows a drift beyond its reach.
    A constant offset misjoins the stops' edges alike; a drifting clock (two
    computers without a common time, 10-50 ppm) misjoins the late stops by more than the
    early ones, and no one offset joins both."""
    if rows.size < STOPS_WINDOWS * MIN_JUDGED * 10:
        return None
    best = around  # the one offset that joins them best (none after a map)
    t_s: list[float] = []
    found: list[float] = []
    for part in np.array_split(rows, STOPS_WINDOWS):
        t_s.append(float(np.mean(seg.t_ns[part[[0, -1]]].astype(np.float64))) * 1e-9)
        if len(found) >= 2:  # each stretch searched about the line through the last two
            slope = (found[-1] - found[-2]) / (t_s[-2] - t_s[-3])
            around = found[-1] + slope * (t_s[-1] - t_s[-2])
        elif found:
            around = found[-1]
        at = _at_stops(
            seg, part, model, around=around, clearer=1.0, samples=STOPS_SAMPLES // STOPS_WINDOWS
        )
        if at is None:
            return None
        found.append(at)
    t, o = np.array(t_s), np.array(found)
    t_ref = float(np.mean(t))
    rate, mean = np.polyfit(t - t_ref, o, 1)
    span = float(t[-1] - t[0])
    scatter = float(np.sqrt(np.mean((o - mean - rate * (t - t_ref)) ** 2)))
    moved = abs(float(rate)) * span
    if moved <= STOPS_DRIFT:
        return None
    t_ref_ns = round(t_ref * 1e9)
    if moved <= STOPS_DRIFT_CLEAR * scatter:
        # the stretches scatter about the line (a few stops each, held briefly, judged by a
        # first fit the misjoins bent): taken where the map joins the samples better than the
        # best single offset does, on the samples' own miss
        encoders = seg.encoders
        assert encoders is not None
        mapped = replace(seg, encoders=encoders.drifted(float(mean), float(rate), t_ref_ns))
        drifted = _stops_miss(mapped, rows, model, STOPS_SAMPLES)(0.0)
        if not drifted * STOPS_CLEARER <= _stops_miss(seg, rows, model, STOPS_SAMPLES)(best):
            return None
    return float(rate), float(mean), t_ref_ns, span
