"""Blocks of (times, values) as the polars tables of :class:`dhlog.io.reader.LogData`: the
target's ``t_ns, x, y, z`` (with its orientation and covariance columns), a spherical stream
turned Cartesian, the joints in chain order in SI units, and every table cleaned of non-finite
and out-of-range samples (counted by reason)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import JointNamesError, PipelineError
from dhlog.io.decode.blocks import Block
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
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.zeros(0, dtype=dtype)


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
        return values if scale == 1.0 else values * scale

    cols: dict[str, Any] = {"t_ns": t, "x": scaled(0), "y": scaled(1), "z": scaled(2)}
    if with_cov:
        for k, name in enumerate(COVARIANCE_COLUMNS):
            cols[name] = pl.Series(name, column(first_cov + k) * scale**2, nan_to_null=True)
    if orientation:
        quat = np.column_stack([column(3 + k) for k in range(4)]) if blocks else np.zeros((0, 4))
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        for k, name in enumerate(ORIENTATION_COLUMNS):
            cols[name] = quat[:, k]
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
    time."""
    value_cols = [c for c in frame.columns if c != "t_ns"]
    finite = (
        pl.all_horizontal(
            [
                pl.col(c).is_finite().fill_null(c in COVARIANCE_COLUMNS)  # no covariance: kept
                for c in value_cols
            ]
        )
        if value_cols
        else pl.lit(True)
    )
    mask = frame.select(finite).to_series()
    kept = frame if mask.all(ignore_nulls=False) else frame.filter(mask)  # a clean log: no copy
    dropped = frame.height - kept.height
    if dropped:
        set_aside[f"non_finite_{stream}"] = dropped
    # values no measurement has (beyond 100 km, or 10⁶ rad of encoder travel) and stamps
    # outside 1970-2262 are damage, not data: set aside before any arithmetic overflows
    ranged = [c for c in value_cols if c in ("x", "y", "z") or c.startswith("q_")]
    sane = (
        pl.all_horizontal([pl.col(c).is_between(-MAX_VALUE, MAX_VALUE, "none") for c in ranged])
        if ranged
        else True
    )
    before = kept.height
    mask = kept.select(sane & (pl.col("t_ns") >= 0)).to_series()
    if not mask.all(ignore_nulls=False):
        kept = kept.filter(mask)
        set_aside[f"out_of_range_{stream}"] = before - kept.height
    if kept["t_ns"].is_sorted():
        return kept
    return kept.sort("t_ns", maintain_order=True)


def joints_frame(
    path: str, topic: str, blocks: list[Block], pipeline: Pipeline
) -> tuple[pl.DataFrame, list[str]]:
    """The joints table in chain order from blocks of (times, (names, positions))."""
    seen: list[str] = []
    for _, (names, _) in blocks:
        seen.extend(n for n in names if n not in seen)
    expected = list(pipeline.joint_names) if pipeline.joint_names else seen
    missing = [n for n in expected if n not in seen]
    if missing or not expected:
        raise JointNamesError(path, topic, expected, seen)
    column = {n: i for i, n in enumerate(expected)}
    t = _joined([b[0] for b in blocks], np.int64)
    if len(blocks) == 1 and list(blocks[0][1][0]) == expected:  # one layout, in chain order
        q = [_column(blocks[0][1][1], j) for j in range(len(expected))]
        fresh = False
    else:
        q = [np.full(t.size, np.nan) for _ in expected]
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
            q[j] = q[j] * scale
    offset_ns = round(pipeline.segmentation.clock_offset * 1e9)
    data: dict[str, Any] = {"t_ns": t + offset_ns if offset_ns else t}
    data.update({f"q_{j + 1}": q[j] for j in range(len(expected))})
    return pl.DataFrame(data), expected
