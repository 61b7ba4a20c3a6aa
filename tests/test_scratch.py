"""A long log out of memory (issue 21): arrays beyond the spill limit live in unlinked scratch
files whose pages are handed back as the passes move on; the results are the in-memory ones."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from dhlog.errors import InputError
from dhlog.identify.run import process_log
from dhlog.io import scratch
from dhlog.io.decode.frames import COVARIANCE_COLUMNS, clean, merged
from dhlog.result.document import result_document

SAMPLES = Path(__file__).parents[1] / "sample_logs"


def _in_scratch(array: np.ndarray) -> bool:
    return scratch._mapped_view(array)


def test_arrays_beyond_the_limit_live_in_scratch_files(tmp_path: Path) -> None:
    with scratch.spill_above(1000):
        small, large = scratch.empty(100), scratch.empty((300, 2), np.int32)
        assert not _in_scratch(small) and _in_scratch(large) and large.shape == (300, 2)
        assert not np.any(scratch.zeros(5000, np.int64))  # a new file reads as zeros
        assert np.all(scratch.full(4000, 7, np.int16) == 7)
        values = np.arange(5000.0)
        assert _in_scratch(scratch.moved(values)) and not _in_scratch(scratch.moved(values[:10]))
        np.testing.assert_array_equal(scratch.moved(values), values)
        copy = scratch.moved(values, copy=True)
        assert not np.shares_memory(copy, values)
    # the files are unlinked at once: nothing is left in the scratch directory
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(scratch.SCRATCH_ENV, str(tmp_path))
        with scratch.spill_above(0):
            kept = scratch.empty(10_000)
            kept[:] = 1.0
        assert list(tmp_path.iterdir()) == []
        assert kept.sum() == 10_000.0


def test_a_grown_column_keeps_every_value_across_the_spill(monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(3)
    parts = [rng.normal(size=int(rng.integers(1, 5000))) for _ in range(60)]
    with scratch.spill_above(20_000):  # in memory for the first few parts, then a file grown
        column = scratch.Growing(np.float64)
        for p in parts:
            column.extend(p)
        out = column.done()
    assert _in_scratch(out)
    np.testing.assert_array_equal(out, np.concatenate(parts))


def test_pages_handed_back_stay_in_the_file_and_leave_the_process() -> None:
    def resident() -> int:
        status = Path("/proc/self/status").read_text().splitlines()
        return next(int(line.split()[1]) for line in status if line.startswith("RssFile")) * 1024

    with scratch.spill_above(0):
        values = scratch.empty(8 << 20, np.int64)  # 64 MiB
    before = resident()
    values[:] = np.arange(values.size) % 1009  # every page touched
    scratch.release()
    after = resident()
    assert after - before < 16 << 20  # of 64 MiB written, the pages left the process …
    assert int(values[::4096].sum()) == int((np.arange(0, values.size, 4096) % 1009).sum())


def test_flatnonzero_and_gathers_a_block_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(scratch, "BLOCK", 7)
    rng = np.random.default_rng(4)
    mask = rng.random(1000) < 0.3
    with scratch.spill_above(100):
        rows = scratch.flatnonzero(mask, np.int32)
        assert rows.dtype == np.int32
        np.testing.assert_array_equal(rows, np.flatnonzero(mask))
        source = rng.normal(size=(1000, 3))
        np.testing.assert_array_equal(scratch.gathered(source, rows), source[rows])
        np.testing.assert_array_equal(scratch.mapped(source[:, 0], np.exp), np.exp(source[:, 0]))


def test_bad_scratch_settings_are_one_line_errors(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(scratch.SPILL_ENV, "lots")
    with pytest.raises(InputError, match="DHLOG_SPILL_BYTES='lots'"):
        scratch.empty(10)
    monkeypatch.setenv(scratch.SPILL_ENV, "0")
    monkeypatch.setenv(scratch.SCRATCH_ENV, str(tmp_path / "missing"))
    with pytest.raises(InputError, match="set DHLOG_SCRATCH"):
        scratch.empty(10)


def _polars_clean(frame: pl.DataFrame) -> pl.DataFrame:
    """What ``clean`` keeps, by polars alone: finite values (a missing covariance kept), within
    ±1e5 and stamps from 1970, sorted by time (stable)."""
    finite = pl.all_horizontal(
        [
            pl.col(c).is_finite().fill_null(c in COVARIANCE_COLUMNS)
            for c in frame.columns
            if c != "t_ns"
        ]
    )
    sane = pl.all_horizontal([pl.col(c).is_between(-1e5, 1e5, "none") for c in ("x", "y", "z")])
    return (
        frame.filter(finite).filter(sane & (pl.col("t_ns") >= 0)).sort("t_ns", maintain_order=True)
    )


@pytest.mark.parametrize("limit", [None, 0])
def test_clean_a_block_at_a_time_keeps_what_polars_keeps(
    limit: int | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Non-finite samples, a missing covariance, values beyond 100 km, stamps before 1970 and
    stamps out of order, across blocks, in memory and with every column spilled."""
    monkeypatch.setattr(scratch, "BLOCK", 64)
    rng = np.random.default_rng(6)
    m = 1000
    x, y, z = (rng.normal(size=m) for _ in range(3))
    x[rng.choice(m, 30)] = np.nan
    y[rng.choice(m, 10)] = np.inf
    z[rng.choice(m, 5)] = 3e5
    t = np.cumsum(rng.integers(1, 10, m))
    t[rng.choice(m, 40)] = rng.integers(0, t[-1], 40)  # out of order
    t[rng.choice(m, 3)] = -5
    cxx = pl.Series("cxx", np.where(rng.random(m) < 0.2, np.nan, 1e-10), nan_to_null=True)
    frame = pl.DataFrame({"t_ns": t, "x": x, "y": y, "z": z}).with_columns(cxx)
    set_aside: dict[str, int] = {}
    with scratch.spill_above(limit):
        kept = clean(frame, "point", set_aside)
    want = _polars_clean(frame)
    assert kept.equals(want)
    finite = frame.filter(
        pl.all_horizontal([pl.col(c).is_finite() for c in ("x", "y", "z")])
    ).height
    assert set_aside["non_finite_point"] == m - finite
    assert set_aside["out_of_range_point"] == finite - want.height
    clean_frame = want
    assert clean(clean_frame, "point", {}) is clean_frame  # a clean log: no copy


def test_a_log_processed_out_of_memory_gives_the_in_memory_result() -> None:
    """Every array of the run spilled (limit 0): the result document is the in-memory one,
    number for number."""
    path = SAMPLES / "kr5_real.mcap"

    def document() -> str:
        doc = result_document(process_log(path))
        doc.pop("created", None)
        return json.dumps(doc, sort_keys=True, default=str)

    in_memory = document()
    with scratch.spill_above(0):
        spilled = document()
    assert spilled == in_memory


def test_a_frame_of_several_blocks_in_mm_with_orientation_is_the_in_memory_one() -> None:
    """Blocks joined, lengths scaled from mm, quaternions made unit and joint states of two
    layouts with a clock offset: the same tables with every column spilled as in memory."""
    from dataclasses import replace

    from dhlog.io.decode.frames import joints_frame, points_frame
    from dhlog.io.pipeline import pipeline_by_name

    rng = np.random.default_rng(8)
    blocks = [
        (np.arange(k, dtype=np.int64) + 1000 * b, rng.normal(size=(k, 7)))
        for b, k in enumerate((50, 70, 30))
    ]
    pipeline = pipeline_by_name("ros2_tracker")
    segmentation = replace(pipeline.segmentation, clock_offset=0.002)
    pipeline = replace(pipeline, segmentation=segmentation, joint_names=("a", "b"))
    joints = [
        (np.arange(40, dtype=np.int64), (["a", "b"], rng.normal(size=(40, 2)))),
        (np.arange(40, 90, dtype=np.int64), (["b", "a"], rng.normal(size=(50, 2)))),
    ]

    def frames() -> tuple[pl.DataFrame, pl.DataFrame]:
        points = points_frame(blocks, 1e-3, orientation=True)
        table, _, _ = joints_frame("log", "/joint_states", joints, pipeline)
        return points, table

    in_memory = frames()
    with scratch.spill_above(0):
        spilled = frames()
    assert spilled[0].equals(in_memory[0]) and spilled[1].equals(in_memory[1])
    quat = in_memory[0].select(["rot_x", "rot_y", "rot_z", "rot_w"]).to_numpy()
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(in_memory[0]["x"].to_numpy()[:50], blocks[0][1][:, 0] * 1e-3)
    assert in_memory[1]["t_ns"][0] == 2_000_000


def test_a_spread_gather_goes_a_span_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """With scratch arrays live, rows spread over more than SPAN samples are gathered in
    pieces of at most SPAN samples (ascending rows) or 1024 rows (any order), the pages handed
    back after each; the result is the gather at once."""
    monkeypatch.setattr(scratch, "SPAN", 100)
    with scratch.spill_above(0):
        source = scratch.empty(5000)
    source[:] = np.arange(5000.0)
    spans: list[int] = []
    released: list[int] = []
    monkeypatch.setattr(scratch, "release", lambda: released.append(1))

    def gather(r: np.ndarray) -> np.ndarray:
        spans.append(int(r.max() - r.min()) if r.size else 0)
        return np.asarray(source[r])

    rows = np.arange(0, 5000, 7)
    np.testing.assert_array_equal(scratch.in_spans(rows, gather), source[rows])
    assert len(spans) > 1 and max(spans) <= 100 and len(released) == len(spans)
    shuffled = np.random.default_rng(9).permutation(5000)[:3000]
    spans.clear()
    np.testing.assert_array_equal(scratch.in_spans(shuffled, gather), source[shuffled])
    assert len(spans) == 3  # 1024 rows a piece
    spans.clear()
    assert scratch.in_spans(np.arange(10, 90), gather).size == 80 and spans == [79]  # one piece


@pytest.mark.parametrize("limit", [None, 0])
def test_frames_merged_a_block_at_a_time_are_polars_concat_and_stable_sort(
    limit: int | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Several targets' frames interleaved in time (equal stamps across frames, a frame with a
    covariance column with nulls the others lack, an empty frame) merge as polars' diagonal
    concatenation sorted stably by time, labelled by frame; a bag's split files, one after the
    other, end to end — in memory and with every column spilled."""
    monkeypatch.setattr(scratch, "BLOCK", 64)
    rng = np.random.default_rng(8)

    def frame(m: int, cov: bool = False, start: int = 0) -> pl.DataFrame:
        t = start + np.sort(rng.integers(0, 2000, m))  # ties within and across frames
        out = pl.DataFrame({"t_ns": t, "x": rng.normal(size=m), "y": rng.normal(size=m)})
        if cov:
            cxx = np.where(rng.random(m) < 0.3, np.nan, 1e-10)
            out = out.with_columns(pl.Series("cxx", cxx, nan_to_null=True))
        return out

    targets = [frame(700), frame(500, cov=True), frame(0), frame(300)]
    splits = [frame(400, start=0), frame(400, start=2000), frame(400, start=4000)]
    with scratch.spill_above(limit):
        got = merged(targets, label="target")
        ends = merged(splits)
        alone = merged(targets[:1])
    labelled = [
        f.with_columns(pl.lit(k, dtype=pl.Int32).alias("target")) for k, f in enumerate(targets)
    ]
    want = pl.concat(labelled, how="diagonal").sort("t_ns", maintain_order=True)
    assert got.equals(want)
    assert got.columns == want.columns and got.dtypes == want.dtypes
    assert ends.equals(pl.concat(splits, how="diagonal").sort("t_ns", maintain_order=True))
    assert alone is targets[0]
    # a frame that already has the label's column: the label is the frame's, as with_columns
    labelled_first = targets[0].with_columns(pl.lit(9, dtype=pl.Int32).alias("target"))
    with scratch.spill_above(limit):
        relabelled = merged([labelled_first, *targets[1:]], label="target")
    assert relabelled.equals(got)
