"""The dwells of an ISO 9283 test in a tracker log: the visits to its poses, each visit's attained
position and its settled samples.

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
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, nearest_rotation

#: The band is this many times the settled samples' 3-D RMS scatter (noise alone leaves a band
#: of 4·√3 σ ≈ 7 σ per coordinate about once in 10¹⁰ samples).
BAND_FACTOR = 4.0


#: The band is never below this (m).
BAND_FLOOR = 5e-6


#: The fewest settled samples a visit's attained position is the mean of (else the last half).
MIN_SETTLED = 3


#: A dwell ends where its position, averaged over this window (s), has moved this many times
#: the average's noise from the dwell's middle (:func:`_departure`).
DEPART_WINDOW = 0.1


DEPART_FACTOR = 5.0


#: The encoders have stopped when every one stays this close (rad, m) to its value at the
#: end of the dwell: the stand-in for the controller's attained-pose signal (clause 7.4).
ENCODER_STOP = 1e-6


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
