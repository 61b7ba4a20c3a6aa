"""Segmentation: the measurement table, with each target sample assigned to one joint's sweep
(:func:`segment_log` → :class:`Segmentation`).

With encoders: the encoder samples are labelled by :mod:`dhlog.identify.segment.encoders` (a
sweep where exactly one joint moves, transitions where two or more do); target samples take the
label of the encoder samples around them and their encoder values by linear interpolation
between the encoder samples found by ``join_asof`` (backward and forward, within the join
tolerance).

Without encoders: phase markers label the time intervals between them.

Nothing is dropped silently: every target sample not in a sweep is counted under its reason.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import InputError, Note, TooFewSamplesError
from dhlog.identify.segment.encoders import BLOCK as BLOCK
from dhlog.identify.segment.encoders import IDLE, TRANSITION, _label_encoder_samples, _runs
from dhlog.identify.segment.encoders import Encoders as Encoders
from dhlog.identify.segment.persample import rows_where
from dhlog.io import scratch
from dhlog.io.pipeline import SEGMENTATION_RANGES, SegmentationSettings
from dhlog.io.reader import LogData
from dhlog.model.dh import JointType


@dataclass(frozen=True)
class Segmentation:
    """The measurement table and what was found in it.

    ``points``: the log's point stream (``t_ns, x, y, z`` and what else it carries);
    ``segment``: each target sample's sweep (0: none); ``encoders``: the joint-state stream the
    encoder values are interpolated from, sample by sample where asked (None without encoders).
    ``table`` is the measurement table of the design (``t_ns, x, y, z, q_1 … q_n, joint,
    segment``; joint 1-based, both null where a sample is in no sweep), built when asked for —
    ``dhlog process`` never builds it whole: it reads the samples a block at a time.
    ``segments``: one row per sweep: ``segment, joint, n, q_start, q_end, sweep, t_start_ns,
    t_end_ns, lock_q_1 … lock_q_n``. ``set_aside``: target samples (and other samples) not
    used, by reason. ``reference_pose``: the locked pose most sweeps share. ``notes``: what the
    reader said of the log (``log``) and the sweeps set aside (``short-sweep``).
    """

    points: pl.DataFrame
    segment: NDArray[np.int32]
    segments: pl.DataFrame
    n_joints: int
    joint_names: list[str]
    set_aside: dict[str, int]
    reference_pose: NDArray[np.float64] | None
    base: pl.DataFrame | None
    has_encoders: bool
    notes: tuple[Note, ...] = ()
    encoders: Encoders | None = None

    @property
    def height(self) -> int:
        """The number of target samples."""
        return self.points.height

    @cached_property
    def t_ns(self) -> NDArray[np.int64]:
        """Every target sample's time (a view of the point stream's column)."""
        return np.asarray(self.points["t_ns"].to_numpy(), dtype=np.int64)

    @cached_property
    def xyz_columns(self) -> tuple[NDArray[np.float64], ...]:
        """The points' x, y and z columns (views of the point stream's)."""
        return tuple(
            np.asarray(self.points[c].to_numpy(), dtype=np.float64) for c in ("x", "y", "z")
        )

    def xyz(self, rows: NDArray[np.integer] | slice) -> NDArray[np.float64]:
        """The target samples ``rows`` (c, 3)."""
        x, y, z = self.xyz_columns
        return scratch.in_spans(rows, lambda r: np.column_stack([x[r], y[r], z[r]]))

    def q(
        self, rows: NDArray[np.integer] | slice, cols: list[int] | None = None
    ) -> NDArray[np.float64]:
        """The encoder values (c, n), or of joints ``cols`` (0-based), at the samples ``rows``;
        NaN where a sample has none (and everywhere without encoders)."""
        if self.encoders is None:
            size = self.t_ns[rows].size
            return np.full((size, self.n_joints if cols is None else len(cols)), np.nan)
        encoders = self.encoders
        return scratch.in_spans(rows, lambda r: encoders.at(self.t_ns[r], cols))

    def rows_in(
        self, ids: NDArray[np.int32] | list[int], *, primary: bool = False
    ) -> NDArray[np.intp]:
        """The samples in the sweeps ``ids`` (with ``primary``, of the primary target only),
        found a block at a time."""
        wanted = np.asarray(ids, dtype=np.int32)
        target = self.points["target"].to_numpy() if "target" in self.points.columns else None
        mask = scratch.empty(self.height, np.bool_)
        for start in range(0, self.height, BLOCK):
            sl = slice(start, min(start + BLOCK, self.height))
            mask[sl] = np.isin(self.segment[sl], wanted)
            if primary and target is not None:
                mask[sl] &= target[sl] == 0
        return rows_where(mask)

    def column(self, name: str, rows: NDArray[np.integer] | slice) -> NDArray[np.generic]:
        """A further column of the point stream (``target``, orientation, covariance) at
        ``rows``."""
        column = self.points[name].to_numpy()
        return scratch.in_spans(rows, lambda r: np.asarray(column[r]))

    @cached_property
    def joint_of_segment(self) -> NDArray[np.int32]:
        """The joint (1-based) of each sweep id (0: none), indexable by ``segment``."""
        ids = self.segments["segment"].to_numpy()
        out = np.zeros(
            int(max(ids.max(), _largest(self.segment))) + 1 if ids.size else 1, dtype=np.int32
        )
        out[ids] = self.segments["joint"].to_numpy()
        return out

    def joint(self, rows: NDArray[np.integer] | slice) -> NDArray[np.int32]:
        """The joint (1-based) whose sweep each sample ``rows`` is in (0: none)."""
        of = self.joint_of_segment
        return scratch.in_spans(rows, lambda r: np.asarray(of[self.segment[r]], dtype=np.int32))

    @cached_property
    def table(self) -> pl.DataFrame:
        """The measurement table (see the class): every sample's encoder values at once —
        for a reader of the table, not for the passes over a long log."""
        n = self.n_joints
        values = []
        for j in range(n):
            column = np.empty(self.height)
            for start in range(0, self.height, BLOCK):
                sl = slice(start, min(start + BLOCK, self.height))
                column[sl] = self.q(sl, [j])[:, 0]
            series = pl.Series(f"q_{j + 1}", column)
            if self.encoders is None:
                series = pl.Series(f"q_{j + 1}", [None] * self.height, dtype=pl.Float64)
            else:
                missing = np.flatnonzero(~self.has_q(slice(None)))
                series = series.scatter(missing, None) if missing.size else series
            values.append(series)
        seg_id = self.segment
        return self.points.with_columns(
            values,
        ).with_columns(
            pl.Series("joint", self.joint(slice(None))).cast(pl.Int32).replace(0, None),
            pl.Series("segment", seg_id).cast(pl.Int32).replace(0, None),
        )

    def has_q(self, rows: NDArray[np.integer] | slice) -> NDArray[np.bool_]:
        """Whether each sample ``rows`` has encoder values (an encoder sample each side)."""
        if self.encoders is None:
            return np.zeros(self.t_ns[rows].size, dtype=bool)
        encoders = self.encoders
        return scratch.in_spans(rows, lambda r: encoders.neighbours(self.t_ns[r])[0] >= 0)


def _largest(values: NDArray[np.int32]) -> int:
    """The largest of ``values`` (0 when empty), a block at a time."""
    return max((int(values[b : b + BLOCK].max()) for b in range(0, values.size, BLOCK)), default=0)


def check_settings(settings: SegmentationSettings, where: str) -> None:
    """An :class:`InputError` naming the first setting outside its range (a negative window,
    a tolerance of 1e300, a NaN), before any of them becomes an index or a count of ns."""
    for key, (lo, hi, unit) in SEGMENTATION_RANGES.items():
        value = getattr(settings, key)
        if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
            raise InputError(
                f"{where}: [segmentation] {key} is {value!r}; it must be between {lo:g} and "
                f"{hi:g} {unit}: correct it in the pipeline."
            )


def segment_log(
    log: LogData,
    *,
    joint_types: list[JointType | None] | None = None,
    reference_pose: NDArray[np.float64] | None = None,
) -> Segmentation:
    """Build the measurement table of ``log`` and find its sweeps (see the module docstring)."""
    settings = log.pipeline.segmentation
    check_settings(settings, f"{log.path}: pipeline {log.pipeline.source}")
    points = log.points
    if points.height < 3:
        raise TooFewSamplesError(f"{log.path}: point stream", points.height, 3)
    set_aside = dict(log.set_aside)
    notes = [Note.warning(w, "log") for w in log.warnings]
    encoders = None
    if log.joints is not None and log.joints.height > 0:
        table, seg_id, segments, n, names, encoders, said = _segment_with_encoders(
            log, settings, joint_types, set_aside
        )
    elif log.phase is not None:
        table, seg_id, segments, n, names, said = _segment_with_phase(log, settings, set_aside)
    else:
        raise TooFewSamplesError(f"{log.path}: joint-state and phase streams", 0, 1)
    notes.extend(said)
    if n == 0:
        raise InputError(
            f"{log.path}: no joint is named by the log (no joint states, and no phase marker "
            "names a joint); check the joints and phase topics in the pipeline."
        )
    ref = reference_pose
    if ref is None and log.joints is not None and segments.height:
        ref = shared_locked_pose(segments, n, settings.lock_tolerance)
    return Segmentation(
        table,
        seg_id,
        segments,
        n,
        names,
        set_aside,
        ref,
        log.base,
        log.joints is not None,
        tuple(notes),
        encoders,
    )


def _segment_with_encoders(
    log: LogData,
    settings: SegmentationSettings,
    joint_types: list[JointType | None] | None,
    set_aside: dict[str, int],
) -> tuple[
    pl.DataFrame, NDArray[np.int32], pl.DataFrame, int, list[str], Encoders, tuple[Note, ...]
]:
    assert log.joints is not None
    n = len(log.joint_names)
    # the reader gives the stream sorted by time: the encoders are views of its columns
    joints = log.joints if log.joints["t_ns"].is_sorted() else log.joints.sort("t_ns")
    encoders = Encoders.of(joints, n, int(settings.join_tolerance * 1e9))
    t_enc = encoders.t_ns
    labels, found = _label_encoder_samples(t_enc, encoders, settings)
    notes: list[Note] = []
    points = log.points
    t = np.asarray(points["t_ns"].to_numpy(), dtype=np.int64)
    # a target sample takes the label of the encoder samples on both sides, if they agree;
    # without an encoder sample on each side within the join tolerance it has no encoder values
    label = scratch.empty(t.size, np.int32)
    for start in range(0, t.size, BLOCK):
        sl = slice(start, min(start + BLOCK, t.size))
        i_prev, i_next = encoders.neighbours(t[sl])
        here = np.where(labels[i_prev] == labels[i_next], labels[i_prev], TRANSITION)
        label[sl] = np.where((i_prev < 0) | (i_next < 0), IDLE - 1, here)
    seg_rows: list[dict[str, float | int]] = []
    seg_id = scratch.zeros(t.size, np.int32)
    for k, (joint, start, end, _lock) in enumerate(found):
        # its target samples lie between its first and last encoder samples
        lo = int(np.searchsorted(t, t_enc[start], side="left"))
        hi = int(np.searchsorted(t, t_enc[end - 1], side="right"))
        count, first, last = _members(label, k, lo, hi)
        q_joint = encoders.q[joint][start:end]
        jt = joint_types[joint] if joint_types and joint < len(joint_types) else None
        minimum = settings.min_travel if jt is JointType.PRISMATIC else settings.min_sweep
        if jt is None:
            minimum = min(settings.min_sweep, settings.min_travel)
        sweep = float(q_joint.max() - q_joint.min())
        name = log.joint_names[joint]
        if sweep < minimum:
            set_aside["short_sweep"] = set_aside.get("short_sweep", 0) + count
            continue
        if count < settings.min_samples:
            set_aside["too_few_samples"] = set_aside.get("too_few_samples", 0) + count
            notes.append(
                Note.warning(
                    f"joint {joint + 1} ({name}): a sweep with only {count} target sample(s) "
                    f"(minimum {settings.min_samples}) was set aside.",
                    "short-sweep",
                )
            )
            continue
        sid = len(seg_rows) + 1
        for b in range(lo, hi, BLOCK):
            part = slice(b, min(b + BLOCK, hi))
            seg_id[part][label[part] == k] = sid
        lock_pose = [float(np.median(column[start:end])) for column in encoders.q]
        seg_rows.append(
            {
                "segment": sid,
                "joint": joint + 1,
                "n": count,
                "q_start": float(q_joint[0]),
                "q_end": float(q_joint[-1]),
                "sweep": sweep,
                "t_start_ns": int(t[first]),  # the stamps are in order
                "t_end_ns": int(t[last]),
                **{
                    f"lock_q_{j + 1}": (lock_pose[j] if j != joint else float("nan"))
                    for j in range(n)
                },
            }
        )
    for key, value in (("transition", TRANSITION), ("idle", IDLE), ("no_encoder", IDLE - 1)):
        _count(set_aside, key, _tally(label, value))
    del label
    frame = _segments_frame(seg_rows, n)
    return points, seg_id, frame, n, list(log.joint_names), encoders, tuple(notes)


def _members(label: NDArray[np.int32], k: int, lo: int, hi: int) -> tuple[int, int, int]:
    """How many of ``label[lo:hi]`` are ``k``, the first and the last (-1 when none)."""
    count, first, last = 0, -1, -1
    for b in range(lo, hi, BLOCK):
        found = np.flatnonzero(label[b : min(b + BLOCK, hi)] == k)
        if found.size:
            first = b + int(found[0]) if first < 0 else first
            last = b + int(found[-1])
            count += found.size
    return count, first, last


def _tally(label: NDArray[np.int32], value: int) -> int:
    """How many labels are ``value`` (counted a block at a time)."""
    return sum(
        int(np.count_nonzero(label[b : b + BLOCK] == value)) for b in range(0, label.size, BLOCK)
    )


def _count(set_aside: dict[str, int], key: str, value: int) -> None:
    if value:
        set_aside[key] = set_aside.get(key, 0) + value


def _segments_frame(rows: list[dict[str, float | int]], n: int) -> pl.DataFrame:
    schema: dict[str, type[pl.DataType]] = {
        "segment": pl.Int32,
        "joint": pl.Int32,
        "n": pl.Int64,
        "q_start": pl.Float64,
        "q_end": pl.Float64,
        "sweep": pl.Float64,
        "t_start_ns": pl.Int64,
        "t_end_ns": pl.Int64,
    }
    schema.update({f"lock_q_{j + 1}": pl.Float64 for j in range(n)})
    return pl.DataFrame(rows, schema=schema)


def _segment_with_phase(
    log: LogData,
    settings: SegmentationSettings,
    set_aside: dict[str, int],
) -> tuple[pl.DataFrame, NDArray[np.int32], pl.DataFrame, int, list[str], tuple[Note, ...]]:
    assert log.phase is not None
    notes: list[Note] = []
    marks = log.phase.sort("t_ns")
    labelled = log.points.sort("t_ns").join_asof(marks, on="t_ns", strategy="backward")
    joint = labelled["joint"].to_numpy(allow_copy=True)
    joint = np.where(np.isnan(joint.astype(np.float64)), 0, joint).astype(np.int64)
    marked = marks["joint"].drop_nulls().to_numpy()
    n = int(marked.max()) if marked.size else 0
    names = list(log.joint_names) or [f"joint_{j + 1}" for j in range(n)]
    n = max(n, len(names))
    t = labelled["t_ns"].to_numpy()
    seg_id = np.zeros(t.size, dtype=np.int32)
    rows: list[dict[str, float | int]] = []
    for st, start, end in _runs(joint):
        if st == 0:
            _count(set_aside, "idle", end - start)
            continue
        if end - start < settings.min_samples:
            _count(set_aside, "too_few_samples", end - start)
            notes.append(
                Note.warning(
                    f"joint {st}: a sweep with only {end - start} sample(s) was set aside.",
                    "short-sweep",
                )
            )
            continue
        sid = len(rows) + 1
        seg_id[start:end] = sid
        rows.append(
            {
                "segment": sid,
                "joint": st,
                "n": end - start,
                "q_start": float("nan"),
                "q_end": float("nan"),
                "sweep": float("nan"),
                "t_start_ns": int(t[start]),
                "t_end_ns": int(t[end - 1]),
                **{f"lock_q_{j + 1}": float("nan") for j in range(n)},
            }
        )
    return labelled.drop("joint"), seg_id, _segments_frame(rows, n), n, names, tuple(notes)


def shared_locked_pose(segments: pl.DataFrame, n: int, tol: float) -> NDArray[np.float64]:
    """The locked pose most sweeps share.

    From each sweep's locked values (its own joint free), sweeps are merged greedily, in time
    order, while they agree within ``tol`` with the values merged so far; the largest group wins
    (ties: the earliest seed). A joint free in the whole group takes its median locked value.
    """
    locks = segments.select([f"lock_q_{j + 1}" for j in range(n)]).to_numpy()
    best: tuple[int, NDArray[np.float64]] | None = None
    for seed in range(locks.shape[0]):
        merged = locks[seed].copy()
        count = 1
        for k in range(locks.shape[0]):
            if k == seed:
                continue
            both = ~np.isnan(merged) & ~np.isnan(locks[k])
            if np.all(np.abs(merged[both] - locks[k][both]) <= tol):
                merged = np.where(np.isnan(merged), locks[k], merged)
                count += 1
        if best is None or count > best[0]:
            best = (count, merged)
    assert best is not None
    pose = best[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
        fallback = np.nanmedian(locks, axis=0)
    pose = np.where(np.isnan(pose), fallback, pose)
    return np.asarray(np.where(np.isnan(pose), 0.0, pose), dtype=np.float64)
