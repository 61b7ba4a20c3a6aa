"""Blocks of (times, values) as the polars tables of :class:`dhlog.io.reader.LogData`: the
target's ``t_ns, x, y, z`` (with its orientation and covariance columns), a spherical stream
turned Cartesian, the joints in chain order in SI units, and every table cleaned of non-finite
and out-of-range samples (counted by reason)."""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import JointNamesError, PipelineError
from dhlog.io import scratch
from dhlog.io.decode.blocks import Block
from dhlog.io.jointnames import ChainOrder, chain_order
from dhlog.io.pipeline import Pipeline
from dhlog.model.dh import JointType

#: Columns of the position covariance (m²) in the point frames and the measurement table.
COVARIANCE_COLUMNS = ("cxx", "cxy", "cxz", "cyy", "cyz", "czz")
#: Columns of the target frame's orientation (unit quaternion) with ``orientation = true``.
ORIENTATION_COLUMNS = ("rot_x", "rot_y", "rot_z", "rot_w")
#: Larger coordinates (m) or encoder values (rad, m) are not measurements.
MAX_VALUE = 1e5


def _width(values: Any) -> int:
    """Values per sample of a block's values: an (m, k) array or a tuple of k columns."""
    return len(values) if isinstance(values, tuple) else int(values.shape[1])


def _column(values: Any, j: int) -> NDArray[np.float64]:
    column: NDArray[np.float64] = values[j] if isinstance(values, tuple) else values[:, j]
    return column


def _joined(parts: list[NDArray[Any]], dtype: type[np.generic]) -> NDArray[Any]:
    """``parts`` end to end (one part as it is: no copy)."""
    if len(parts) == 1:
        return np.asarray(parts[0], dtype=dtype)
    out = scratch.empty(sum(p.shape[0] for p in parts), dtype)
    at = 0
    for part in parts:
        out[at : at + part.shape[0]] = part
        at += part.shape[0]
    return out


def points_frame(blocks: list[Block], scale: float, orientation: bool = False) -> pl.DataFrame:
    """``t_ns, x, y, z`` (m), with ``orientation`` the target frame's orientation
    (``ORIENTATION_COLUMNS``, a unit quaternion), and the position covariance (m²,
    ``COVARIANCE_COLUMNS``) when any channel carries one (null for samples of channels that do
    not). Block values (an (m, k) array or a tuple of k columns): ``x, y, z``, then with
    ``orientation`` the quaternion (4), then the covariance (6) where the channel has one."""
    t = _joined([b[0] for b in blocks], np.int64)
    first_cov = 7 if orientation else 3
    with_cov = any(_width(b[1]) == first_cov + 6 for b in blocks)

    def column(j: int) -> NDArray[np.float64]:
        """Value ``j`` of every block (NaN where a block has none)."""
        return _joined(
            [_column(v, j) if j < _width(v) else np.full(t_.shape[0], np.nan) for t_, v in blocks],
            np.float64,
        )

    def scaled(j: int) -> NDArray[np.float64]:
        values = column(j)  # (× 1 changes no value that clean keeps: no copy)
        return values if scale == 1.0 else scratch.mapped(values, lambda v: v * scale)

    cols: dict[str, Any] = {"t_ns": t, "x": scaled(0), "y": scaled(1), "z": scaled(2)}
    if with_cov:
        for k, name in enumerate(COVARIANCE_COLUMNS):
            cols[name] = pl.Series(name, column(first_cov + k) * scale**2, nan_to_null=True)
    if orientation:
        parts = [column(3 + k) for k in range(4)]
        unit = [scratch.empty(t.shape[0]) for _ in range(4)]
        for start in range(0, t.shape[0], scratch.BLOCK):
            sl = slice(start, start + scratch.BLOCK)
            norm = np.sqrt(sum(p[sl] * p[sl] for p in parts))
            for k in range(4):
                unit[k][sl] = parts[k][sl] / norm
        for k, name in enumerate(ORIENTATION_COLUMNS):
            cols[name] = unit[k]
    return pl.DataFrame(cols)


def cartesian(values: NDArray[np.float64], pipeline: Pipeline) -> NDArray[np.float64]:
    """A spherical stream's (horizontal angle, vertical angle, distance) as x, y, z in the
    tracker's own frame (length unit unchanged): the horizontal angle turns from +x towards +y
    about +z, the vertical angle is from the zenith (+z) or, with ``vertical = "elevation"``,
    from the horizon; angles in the pipeline's ``angle_unit``."""
    scale = pipeline.angle_scale
    hz, v, d = values[:, 0] * scale, values[:, 1] * scale, values[:, 2]
    if pipeline.streams["point"].vertical == "elevation":
        v = math.pi / 2 - v
    out = values.copy()
    out[:, 0] = d * np.sin(v) * np.cos(hz)
    out[:, 1] = d * np.sin(v) * np.sin(hz)
    out[:, 2] = d * np.cos(v)
    return out


def clean(frame: pl.DataFrame, stream: str, set_aside: dict[str, int]) -> pl.DataFrame:
    """``frame`` without its non-finite samples (a missing covariance kept), values no
    measurement has and stamps before 1970, each counted in ``set_aside`` by reason; sorted by
    time. Judged a block at a time; a long table's kept rows go to scratch files
    (:mod:`dhlog.io.scratch`)."""
    value_cols = [c for c in frame.columns if c != "t_ns"]
    # values no measurement has (beyond 100 km, or 10⁶ rad of encoder travel) and stamps
    # outside 1970-2262 are damage, not data: set aside before any arithmetic overflows
    ranged = {c for c in value_cols if c in ("x", "y", "z") or c.startswith("q_")}
    keep = scratch.empty(frame.height, np.bool_)
    non_finite = out_of_range = 0
    for start in range(0, frame.height, scratch.BLOCK):
        part = frame.slice(start, scratch.BLOCK)
        finite = np.ones(part.height, dtype=bool)
        sane = np.asarray(part["t_ns"].to_numpy()) >= 0
        for c in value_cols:
            series = part[c]
            values = np.asarray(series.to_numpy())
            ok = np.isfinite(values) if values.dtype.kind == "f" else np.ones(values.size, bool)
            if series.null_count():  # no covariance: kept
                ok = np.where(np.asarray(series.is_null().to_numpy()), c in COVARIANCE_COLUMNS, ok)
            finite &= ok
            if c in ranged:
                with np.errstate(invalid="ignore"):
                    sane &= (values > -MAX_VALUE) & (values < MAX_VALUE)
        keep[start : start + part.height] = finite & sane
        non_finite += int(np.count_nonzero(~finite))
        out_of_range += int(np.count_nonzero(finite & ~sane))
    if non_finite:
        set_aside[f"non_finite_{stream}"] = non_finite
    if out_of_range:
        set_aside[f"out_of_range_{stream}"] = out_of_range
    t = np.asarray(frame["t_ns"].to_numpy())
    if not (non_finite or out_of_range):
        if _in_order(t):
            return frame  # a clean log: no copy
        rows = None
    else:
        rows = scratch.flatnonzero(keep)
    del keep
    if rows is None or not _in_order(t[rows]):
        kept_t = t if rows is None else t[rows]
        order = np.argsort(kept_t, kind="stable")
        rows = order if rows is None else rows[order]
    return taken(frame, rows)


def _in_order(t: NDArray[np.int64]) -> bool:
    """Whether the stamps ``t`` never decrease (checked a block at a time)."""
    for start in range(0, t.size, scratch.BLOCK):
        part = t[max(start - 1, 0) : start + scratch.BLOCK]
        if np.any(part[1:] < part[:-1]):
            return False
    return True


def taken(frame: pl.DataFrame, rows: NDArray[np.integer]) -> pl.DataFrame:
    """The rows ``rows`` of ``frame``: each column without nulls gathered into an array (a
    scratch file when long) a block at a time; a column with nulls by polars."""
    index = pl.Series(rows)
    columns: list[pl.Series] = []
    for c in frame.columns:
        series = frame[c]
        if not _plain(series):
            columns.append(series.gather(index))
            continue
        source = np.asarray(series.to_numpy())
        out = scratch.empty(rows.size, source.dtype)
        for start in range(0, rows.size, scratch.BLOCK):
            out[start : start + scratch.BLOCK] = source[rows[start : start + scratch.BLOCK]]
        columns.append(pl.Series(c, out, dtype=series.dtype))
    return pl.DataFrame(columns)


def spilled(frame: pl.DataFrame) -> pl.DataFrame:
    """``frame`` with its numeric columns without nulls in scratch files whatever their size (a
    bag's split files, each under the spill limit, would otherwise all stay in memory until they
    are joined); the others, and those beyond the limit (the reader put them in scratch files
    already), as they are."""
    columns = []
    for series in frame.get_columns():
        if _plain(series) and series.len():
            values = np.asarray(series.to_numpy())
            if not scratch.spills(values.nbytes):
                moved = scratch.moved(values, always=True)
                series = pl.Series(series.name, moved, dtype=series.dtype)
        columns.append(series)
    return pl.DataFrame(columns)


def _plain(series: pl.Series) -> bool:
    """Whether ``series`` is a numpy array of numbers as it is: numeric (not Decimal), without
    nulls — what the block-at-a-time copies take; the others go through polars."""
    dtype = series.dtype
    return dtype.is_numeric() and dtype != pl.Decimal and not series.null_count()


def _rows_of(parts: list[NDArray[Any]], f: int, rows: slice) -> NDArray[Any]:
    return parts[f][rows]


def merged(frames: list[pl.DataFrame], label: str | None = None) -> pl.DataFrame:
    """``frames``, each sorted by ``t_ns``, as one table sorted by ``t_ns`` — stable: rows of
    equal stamps in the order of the frames — with every frame's columns (null where a frame
    has none, as polars' diagonal concatenation gives); with ``label``, an Int32 column of that
    name giving each row's frame (0, 1, …), placed as if each frame had it last.

    Merged a block at a time: a row's place is its own index plus the rows of the other frames
    before it (a search of each), and each column is scattered to those places in an array (a
    scratch file when long), so long frames are never copied whole into memory; frames already
    one after the other (a bag's split files) are put end to end. A column with nulls, or not
    in every frame, or of different types, is gathered by polars."""
    if len(frames) == 1 and label is None:
        return frames[0]
    ts = [np.asarray(f["t_ns"].to_numpy()) for f in frames]
    starts = np.cumsum([0, *(t.size for t in ts)]).astype(np.int64)
    total = int(starts[-1])
    filled = [t for t in ts if t.size]
    places: list[NDArray[np.int64]] | None = None
    if any(a[-1] > b[0] for a, b in itertools.pairwise(filled)):
        places = []
        for f, t in enumerate(ts):
            place = scratch.empty(t.size, np.int64)
            for a in range(0, t.size, scratch.BLOCK):
                x = t[a : a + scratch.BLOCK]
                at = np.arange(a, a + x.size, dtype=np.int64)
                for g, u in enumerate(ts):
                    if g != f:  # earlier frames' equal stamps go first, later frames' after
                        at += np.searchsorted(u, x, side="right" if g < f else "left")
                place[a : a + x.size] = at
            places.append(place)

    def scattered(block: Callable[[int, slice], NDArray[Any]], dtype: Any) -> NDArray[Any]:
        """The merged column whose frame ``f``'s rows ``rows`` are ``block(f, rows)``."""
        out = scratch.empty(total, dtype)
        for f, t in enumerate(ts):
            for a in range(0, t.size, scratch.BLOCK):
                rows = slice(a, min(a + scratch.BLOCK, t.size))
                if places is None:
                    out[starts[f] + rows.start : starts[f] + rows.stop] = block(f, rows)
                else:
                    out[places[f][rows]] = block(f, rows)
        return out

    names: list[str] = []  # in the order of a concatenation of the frames, each labelled
    for frame in frames:
        for c in (*frame.columns, label):
            if c is not None and c not in names:
                names.append(c)
    source: pl.Series | None = None  # each merged row's row among the frames end to end
    columns: list[pl.Series] = []
    for c in names:
        if c == label:
            marks = scattered(
                lambda f, rows: np.full(rows.stop - rows.start, f, np.int32), np.int32
            )
            columns.append(pl.Series(label, marks, dtype=pl.Int32))
            continue
        series = [f[c] for f in frames if c in f.columns]
        dtype = series[0].dtype
        if len(series) == len(frames) and all(s.dtype == dtype and _plain(s) for s in series):
            parts = [np.asarray(s.to_numpy()) for s in series]
            values = scattered(functools.partial(_rows_of, parts), parts[0].dtype)
            columns.append(pl.Series(c, values, dtype=dtype))
            continue
        pieces = [
            f[c] if c in f.columns else pl.Series(c, [None] * f.height, dtype=dtype) for f in frames
        ]
        whole = pl.concat([p.to_frame(c) for p in pieces], how="vertical_relaxed")[c]
        if places is not None:
            if source is None:
                source = pl.Series(
                    scattered(
                        lambda f, rows: starts[f] + np.arange(rows.start, rows.stop), np.int64
                    )
                )
            whole = whole.gather(source)
        columns.append(whole)
    return pl.DataFrame(columns)


def joints_frame(
    path: str,
    topic: str,
    blocks: list[Block],
    pipeline: Pipeline,
    model: Sequence[str] | None = None,
    source: str = "model",
) -> tuple[pl.DataFrame, list[str], ChainOrder]:
    """The joints table in chain order from blocks of (times, (names, positions)): the chain
    as :func:`dhlog.io.jointnames.chain_order` finds it in the stream's names for a model whose
    joints are named ``model`` (its ``source`` for messages); messages that carry none of the
    chain's joints (a gripper's own joint states) are left out."""
    seen: list[str] = []
    for _, (names, _) in blocks:
        seen.extend(n for n in names if n not in seen)
    if not seen:
        raise JointNamesError(path, topic, list(pipeline.joint_names or []), seen)
    order = chain_order(
        seen, model, path=path, topic=topic, source=source, pipeline=pipeline.joint_names
    )
    expected = list(order.names)
    missing = [n for n in expected if n not in seen]
    if missing or not expected:
        raise JointNamesError(path, topic, expected, seen)
    column = {n: i for i, n in enumerate(expected)}
    kept = [b for b in blocks if any(n in column for n in b[1][0])]
    if len(kept) < len(blocks):
        dropped = sorted({n for b in blocks for n in b[1][0]} - set(column))
        blocks = kept
        order = replace(
            order,
            note=" ".join(
                filter(
                    None,
                    [
                        order.note,
                        f"{topic}'s messages naming none of the chain's joints were left out"
                        + (f" ({', '.join(dropped)})." if dropped else "."),
                    ],
                )
            ),
        )
    t = _joined([b[0] for b in blocks], np.int64)
    if len(blocks) == 1 and list(blocks[0][1][0]) == expected:  # one layout, in chain order
        q = [_column(blocks[0][1][1], j) for j in range(len(expected))]
        fresh = False
    else:
        q = [scratch.full(t.size, np.nan, np.float64) for _ in expected]
        row = 0
        for times, (names, values) in blocks:
            for k, n in enumerate(names):
                if n in column:
                    q[column[n]][row : row + times.size] = _column(values, k)
            row += times.size
        fresh = True
    types = pipeline.joint_types or (None,) * len(expected)
    if len(types) != len(expected):
        raise PipelineError(
            pipeline.source,
            f"[joints] types lists {len(types)} joint(s) but {path} has {len(expected)} on "
            f"{topic} ({', '.join(expected)}); give one type per joint.",
        )
    for j, jt in enumerate(types):  # prismatic in the length unit, the rest in the angle unit
        scale = pipeline.length_scale if jt is JointType.PRISMATIC else pipeline.angle_scale
        if fresh:
            q[j] *= scale
        elif scale != 1.0:  # (× 1 changes no value that clean keeps: no copy)
            q[j] = scratch.mapped(q[j], functools.partial(np.multiply, scale))
    offset_ns = round(pipeline.segmentation.clock_offset * 1e9)
    data: dict[str, Any] = {"t_ns": scratch.mapped(t, lambda v: v + offset_ns) if offset_ns else t}
    data.update({f"q_{j + 1}": q[j] for j in range(len(expected))})
    return pl.DataFrame(data), expected, order
