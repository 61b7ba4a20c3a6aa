"""The encoder stream of a log and each encoder sample's label: :class:`Encoders` (the joint
states, their values interpolated on demand at any stamp) and the labelling
(:func:`_label_encoder_samples`): a joint is *moving* at an encoder sample when it changes by
more than the lock tolerance across a short window around it; samples where exactly one joint
moves, and the still samples next to them whose other joints keep that sweep's locked pose, form
a sweep; samples where two or more joints move are transitions (:data:`TRANSITION`). Found a
:data:`BLOCK` of samples at a time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.io import scratch
from dhlog.io.pipeline import SegmentationSettings

TRANSITION, IDLE = -1, -2


@dataclass(frozen=True)
class Encoders:
    """The joint-state stream at its own rate, sorted by time: ``t_ns`` (k,), ``q`` (k, n).

    A target sample at time t takes the values interpolated linearly between the encoder sample
    at or before t (the last, within ``tol_ns``: ``join_asof`` backward) and the next one (within
    ``tol_ns`` after t; the same one where its stamp is t); it has none when either is missing.
    The values are computed for the samples asked for, never stored per target sample."""

    t_ns: NDArray[np.int64]
    #: each joint's values (k,): views of the joint-state table's columns where they can be
    q: tuple[NDArray[np.float64], ...]
    tol_ns: int
    #: how far the stamps were moved from the log's (ns)
    shift_ns: int = 0

    @classmethod
    def of(cls, joints: pl.DataFrame, n: int, tol_ns: int) -> Encoders:
        """From a joint-state table (``t_ns, q_1 … q_n``) sorted by time."""
        t = np.asarray(joints["t_ns"].to_numpy(), dtype=np.int64)
        q = tuple(np.asarray(joints[f"q_{j + 1}"].to_numpy(), dtype=np.float64) for j in range(n))
        return cls(t, q, tol_ns)

    def shifted(self, shift_ns: int) -> Encoders:
        """The stream with its stamps moved by ``shift_ns`` from the log's."""
        step = shift_ns - self.shift_ns
        t_ns = scratch.mapped(self.t_ns, lambda t: t + step)
        return Encoders(t_ns, self.q, self.tol_ns, shift_ns)

    def drifted(self, offset: float, rate: float, t_ref_ns: int) -> Encoders:
        """The stream with each stamp ``t`` moved by ``offset + rate (t − t_ref)`` s: onto the
        tracker's clock where the joint states' clock runs ``rate`` s a second off it (its
        ``shift_ns`` kept: a later :meth:`shifted` moves it on from there)."""
        t_ns = scratch.mapped(
            self.t_ns,
            lambda t: (
                t
                + np.round(offset * 1e9 + rate * (t - t_ref_ns).astype(np.float64)).astype(np.int64)
            ),
        )
        return Encoders(t_ns, self.q, self.tol_ns, self.shift_ns)

    def stepped(self, index: int, seconds: float) -> Encoders:
        """The stream with its stamps from the ``index``-th on moved by ``seconds`` (a clock
        set mid-session, sized again: less than an interval, so they stay in order)."""
        step = round(seconds * 1e9)
        t_ns = np.concatenate([self.t_ns[:index], self.t_ns[index:] + step])
        return Encoders(t_ns, self.q, self.tol_ns, self.shift_ns)

    def neighbours(self, t: NDArray[np.int64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """The encoder samples before and after each time ``t`` (-1 where missing: then both)."""
        t_enc, tol = self.t_ns, self.tol_ns
        k = t_enc.size
        i_prev = np.searchsorted(t_enc, t, side="right") - 1
        i_prev[(i_prev >= 0) & (t - t_enc[np.maximum(i_prev, 0)] > tol)] = -1
        if k == 0:
            return i_prev, i_prev
        exact = (i_prev >= 0) & (t_enc[np.maximum(i_prev, 0)] == t)
        after = np.minimum(i_prev + 1, k - 1)
        has_next = (i_prev >= 0) & (i_prev + 1 < k) & (t_enc[after] - t <= tol)
        i_next = np.where(exact, i_prev, np.where(has_next, after, -1))
        ok = (i_prev >= 0) & (i_next >= 0)
        return np.where(ok, i_prev, -1), np.where(ok, i_next, -1)

    def at(self, t: NDArray[np.int64], cols: list[int] | None = None) -> NDArray[np.float64]:
        """The encoder values (c, n), or of joints ``cols`` (0-based), at times ``t``; NaN at
        times without encoder values."""
        lo, hi = self.neighbours(np.asarray(t, dtype=np.int64))
        ok = lo >= 0
        lo, hi = np.maximum(lo, 0), np.maximum(hi, 0)
        t_enc = self.t_ns
        which = range(len(self.q)) if cols is None else cols
        out = np.full((lo.size, len(which)), np.nan)
        if t_enc.size == 0:
            return out
        span = (t_enc[hi] - t_enc[lo]).astype(np.float64)
        w = np.divide(
            (t - t_enc[lo]).astype(np.float64), span, out=np.zeros(lo.size), where=span > 0
        )
        for k, j in enumerate(which):
            column = self.q[j]
            q_lo = column[lo]
            out[:, k] = q_lo + (column[hi] - q_lo) * w
        out[~ok] = np.nan
        return out


#: Target samples a block in the passes over the measurement table.
BLOCK = 1 << 18


def _moving(
    t: NDArray[np.int64],
    q: tuple[NDArray[np.float64], ...],
    window_ns: int,
    tol: float,
    rows: slice,
) -> NDArray[np.bool_]:
    """(b, n) mask: joint k moves by more than ``tol`` across ``[t - w, t + w]`` at each sample
    ``rows`` (``q``: each joint's column)."""
    here = t[rows]
    lo = np.searchsorted(t, here - window_ns, side="left")
    hi = np.maximum(np.searchsorted(t, here + window_ns, side="right") - 1, lo)
    out = np.empty((here.size, len(q)), dtype=bool)
    for j, column in enumerate(q):  # a joint at a time: no (b, n) float temporaries
        out[:, j] = np.abs(column[hi] - column[lo]) > tol
    return out


def _runs(state: NDArray[np.integer]) -> list[tuple[int, int, int]]:
    """Run-length encoding: (state, first index, last index + 1); the edges found a block at a
    time."""
    if state.size == 0:
        return []
    edges = []
    for start in range(0, state.size - 1, BLOCK):
        stop = min(start + BLOCK, state.size - 1)
        edges.append(start + 1 + np.flatnonzero(state[start + 1 : stop + 1] != state[start:stop]))
    starts = np.concatenate([[0], *edges])
    ends = np.concatenate([starts[1:], [state.size]])
    return [(int(state[s]), int(s), int(e)) for s, e in zip(starts, ends, strict=True)]


def _within(column: NDArray[np.float64], start: int, end: int, value: float, tol: float) -> bool:
    """Whether ``column[start:end]`` stays within ``tol`` of ``value`` (a block at a time)."""
    return all(
        bool(np.all(np.abs(column[b : min(b + BLOCK, end)] - value) <= tol))
        for b in range(start, end, BLOCK)
    )


def _label_encoder_samples(
    t: NDArray[np.int64], encoders: Encoders, settings: SegmentationSettings
) -> tuple[NDArray[np.int32], list[tuple[int, int, int, NDArray[np.float64]]]]:
    """Segment label per encoder sample (id ≥ 0, or TRANSITION / IDLE) and the segments as
    (joint index 0-based, first, last + 1, locked pose)."""
    m, n = t.size, len(encoders.q)
    window = int(settings.motion_window * 1e9)
    tol = settings.lock_tolerance
    state = scratch.empty(m, np.int16)
    for start in range(0, m, BLOCK):
        sl = slice(start, min(start + BLOCK, m))
        moving = _moving(t, encoders.q, window, tol, sl)
        count = moving.sum(axis=1, dtype=np.int16)
        state[sl] = np.where(
            count >= 2, TRANSITION, np.where(count == 1, np.argmax(moving, axis=1), IDLE)
        )
    del moving, count
    labels = scratch.full(m, TRANSITION, np.int32)
    segments: list[tuple[int, int, int, NDArray[np.float64]]] = []
    current: list[int | NDArray[np.float64]] | None = None  # [joint, start, end, lock]
    pending_idle: tuple[int, int] | None = None

    def compatible(start: int, end: int, joint: int, lock: NDArray[np.float64]) -> bool:
        return all(
            _within(encoders.q[j], start, end, float(lock[j]), tol) for j in range(n) if j != joint
        )

    def close() -> None:
        nonlocal current
        if current is not None:
            joint, start, end, lock = current
            assert isinstance(joint, int) and isinstance(start, int) and isinstance(end, int)
            assert isinstance(lock, np.ndarray)
            labels[start:end] = len(segments)
            segments.append((joint, start, end, lock))
            current = None

    for st, start, end in _runs(state):
        if st == TRANSITION:
            close()
            pending_idle = None
            continue
        if st == IDLE:
            if current is not None:
                joint, _, _, lock = current
                assert isinstance(joint, int) and isinstance(lock, np.ndarray)
                if compatible(start, end, joint, lock):
                    current[2] = end
                    continue
                close()
            labels[start:end] = IDLE
            pending_idle = (start, end)
            continue
        joint = st
        if current is not None:
            cj, _, _, clock = current
            assert isinstance(clock, np.ndarray)
            if cj == joint and compatible(start, end, joint, clock):
                current[2] = end
                continue
            close()
        first = start
        lock = np.array([column[start] for column in encoders.q], dtype=np.float64)
        if (
            pending_idle is not None
            and pending_idle[1] == start
            and compatible(*pending_idle, joint, lock)
        ):
            first = pending_idle[0]
        current = [joint, first, end, lock]
        pending_idle = None
    close()
    return labels, segments
