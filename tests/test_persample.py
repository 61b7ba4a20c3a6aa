"""Samples read a block at a time (issue 21): the per-sample arrays read on demand, the encoder
values interpolated from the joint-state stream as the design's ``join_asof`` gives them, and a
recording that draws every k-th sample of a long log while the fit and the check use all."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import dhlog.identify.check.validate as validate
from dhlog.identify.run import process_log
from dhlog.identify.segment.persample import PerSample, blocks
from dhlog.identify.segment.segment import Encoders
from dhlog.io import scratch
from dhlog.model.fk import fk_point
from dhlog.present.recording import residual_parts
from dhlog.result.document import result_document

SAMPLES = Path(__file__).parents[1] / "sample_logs"


def _array_like(values: np.ndarray) -> PerSample:
    return PerSample(values.shape, lambda index: values[index].copy())


def test_a_persample_reads_rows_as_numpy_does() -> None:
    values = np.arange(60.0).reshape(20, 3)
    rows = _array_like(values)
    assert rows.shape == (20, 3) and len(rows) == 20
    mask = values[:, 0] % 9 == 0
    for index in (slice(3, 11), slice(None, None, 4), slice(-5, None), np.array([4, -1, 0]), mask):
        np.testing.assert_array_equal(rows[index], values[index])
    np.testing.assert_array_equal(rows[np.array([2, 7]), 1], values[[2, 7], 1])
    np.testing.assert_array_equal(rows[5:9][:, 2], values[5:9, 2])
    np.testing.assert_array_equal(rows.map(lambda v: 2 * v, (20, 3))[::3], 2 * values[::3])
    assert [(s.start, s.stop) for s in blocks(20, 8)] == [(0, 8), (8, 16), (16, 20)]


def test_a_persample_is_never_made_whole_by_accident() -> None:
    rows = _array_like(np.ones((10, 2)))
    with pytest.raises(TypeError):
        np.asarray(rows)
    with pytest.raises(TypeError):
        rows - np.zeros(2)  # type: ignore[operator]
    with pytest.raises(IndexError):
        rows[np.array([10])]
    with pytest.raises(IndexError):
        rows[np.ones(9, dtype=bool)]


def test_a_filled_persample_computes_each_row_once_and_reads_as_before() -> None:
    """Filled, the rows are computed once (a block at a time) and every later read — slices,
    strides, index arrays, masks — gives what the source gives, from an array that cannot be
    written to; spilled, that array is a scratch file's."""
    values = np.arange(3000.0).reshape(1000, 3)
    asked: list[int] = []

    def fetch(index: slice | np.ndarray) -> np.ndarray:
        out = values[index].copy()
        asked.append(out.shape[0])
        return out

    source = PerSample(values.shape, fetch)
    mask = values[:, 0] % 7 == 0
    with scratch.spill_above(0):
        rows = source.filled()
        assert sum(asked) == 1000
        for index in (slice(3, 911), slice(None, None, 40), np.array([4, -1, 0, 999]), mask):
            np.testing.assert_array_equal(rows[index], values[index])
        assert sum(asked) == 1000  # read from the array, not computed again
        view = rows[10:20]
        with pytest.raises(ValueError, match="read-only"):
            view[0, 0] = -1.0
        assert np.shares_memory(view, rows[0:1000])


@pytest.mark.parametrize("kept", [True, False])
def test_the_encoder_values_of_the_samples_are_interpolated_once(
    monkeypatch: pytest.MonkeyPatch, kept: bool
) -> None:
    """``samples_with_encoders`` interpolates the encoder stream once, at every target sample,
    and the passes over the samples read those values afterwards; beyond ``FILL_BYTES`` (here
    made small) each pass interpolates its blocks again. The values are the interpolation's."""
    from dhlog.identify.joints.sweeps import samples_with_encoders
    from dhlog.identify.segment import persample
    from dhlog.identify.segment.segment import segment_log
    from dhlog.io.reader import read_log

    seg = segment_log(read_log(SAMPLES / "kr5_0.01mm.mcap"))
    assert seg.encoders is not None
    if not kept:
        monkeypatch.setattr(persample, "FILL_BYTES", 8 * 6 * 100)
    calls: list[int] = []
    at = Encoders.at

    def counted(self: Encoders, t: np.ndarray, cols: list[int] | None = None) -> np.ndarray:
        calls.append(np.asarray(t).size)
        return at(self, t, cols)

    monkeypatch.setattr(Encoders, "at", counted)
    rows, Q, _ = samples_with_encoders(seg)
    assert sum(calls) == seg.height
    for _ in range(3):
        got = np.concatenate([Q[sl] for sl in blocks(Q.shape[0], 5000)])
    assert sum(calls) == seg.height + (0 if kept else 3 * rows.size)
    np.testing.assert_array_equal(got, at(seg.encoders, seg.t_ns[rows]))


def _join_asof_reference(t: np.ndarray, t_enc: np.ndarray, q: np.ndarray, tol: int) -> np.ndarray:
    """The encoder values of the design, as ``join_asof`` backward within ``tol`` and the next
    encoder sample within ``tol`` give them (null → NaN)."""
    enc = pl.DataFrame({"t_ns": t_enc, "i": np.arange(t_enc.size)})
    prev = pl.DataFrame({"t_ns": t}).join_asof(enc, on="t_ns", strategy="backward", tolerance=tol)
    i_prev = prev["i"].fill_null(-1).to_numpy()
    out = np.full((t.size, q.shape[1]), np.nan)
    for k in range(t.size):
        i = i_prev[k]
        if i < 0:
            continue
        if t_enc[i] == t[k]:
            j = i
        elif i + 1 < t_enc.size and t_enc[i + 1] - t[k] <= tol:
            j = i + 1
        else:
            continue
        span = t_enc[j] - t_enc[i]
        w = (t[k] - t_enc[i]) / span if span > 0 else 0.0
        out[k] = q[i] + (q[j] - q[i]) * w
    return out


def test_encoder_values_are_the_join_asof_ones() -> None:
    """Interpolated on demand, the encoder values equal the design's join (gaps beyond the
    tolerance, samples before and after the stream, stamps equal to an encoder's, and at the
    tolerance's edge), bit for bit."""
    rng = np.random.default_rng(3)
    t_enc = np.sort(rng.choice(np.arange(0, 10_000_000, 1000), 4000, replace=False))
    t_enc = np.delete(t_enc, np.s_[1500:1530])  # a gap longer than the tolerance
    q = rng.normal(size=(t_enc.size, 3))
    tol = 4000
    t = np.sort(
        np.concatenate(
            [
                rng.integers(-50_000, 10_050_000, 3000),
                t_enc[::97],  # exactly at an encoder sample
                t_enc[::89] + tol,  # at the tolerance's edge
            ]
        )
    )
    enc = Encoders(t_enc, tuple(np.ascontiguousarray(q[:, j]) for j in range(3)), tol)
    got = enc.at(t)
    want = _join_asof_reference(t, t_enc, q, tol)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_array_equal(got[~np.isnan(got)], want[~np.isnan(want)])
    np.testing.assert_array_equal(enc.at(t, [2])[:, 0], got[:, 2])


def test_a_long_log_is_drawn_every_kth_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    """With more samples than the viewer shows (here 400), the validation keeps the residual
    vectors of every k-th row only, the recording draws those, the result says how many; the
    fit and the FK check still use every sample."""
    path = SAMPLES / "kr5_0.01mm.mcap"
    full = process_log(path)
    monkeypatch.setattr(validate, "SHOWN_SAMPLES", 400)
    result = process_log(path)
    height = result.segmentation.height
    every = validate.shown_stride(height)
    assert every > 1
    v, w = result.validation, full.validation
    assert v is not None and w is not None
    # the check's figures are every sample's, whatever is drawn
    assert v.n_points == w.n_points and v.rms == pytest.approx(w.rms, rel=1e-12)
    assert v.per_joint.keys() == w.per_joint.keys()
    assert np.all(v.rows % every == 0) and set(v.rows) <= set(w.rows)
    assert v.rows.size == np.count_nonzero(w.rows % every == 0)
    # the kept vectors are the FK residuals at those rows
    ex = result.extraction
    assert ex is not None
    seg = result.segmentation
    Q = seg.table.select([f"q_{i + 1}" for i in range(6)]).to_numpy()[v.rows]
    P = seg.xyz(v.rows)
    fk = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    np.testing.assert_allclose(P - fk, v.vectors, atol=1e-12)
    for part in residual_parts(result):
        assert np.all(part.rows % every == 0)
    doc = result_document(result)["segmentation"]
    assert doc["samples"] == height and doc["recording_every"] == every
    assert doc["recording_samples"] == -(-height // every)
    assert any(f"every {every}th sample" in note for note in result.info)
    assert not any("every" in note and "th sample" in note for note in full.info)


def test_joint_speeds_are_np_interp_of_the_differences() -> None:
    """The joints' speeds, differenced where asked for, equal np.interp of the stream's finite
    differences at their midpoints (0 outside), value for value: repeated stamps, samples
    before, between and after, at a midpoint and at the last one."""
    from dhlog.identify.segment.timing import JointRates

    rng = np.random.default_rng(5)
    for _ in range(10):
        k = int(rng.integers(3, 2000))
        t = np.sort(rng.integers(0, 10**9, k)) * 2  # even: the midpoints are whole ns
        t[4:7] = t[4]
        q = tuple(np.cumsum(rng.normal(size=k)) for _ in range(3))
        rates = JointRates(Encoders(t, q, 10**6))
        tf = t.astype(np.float64)
        dt = np.diff(tf) * 1e-9
        ok = dt > 0
        mid = (tf[1:] + tf[:-1])[ok] / 2.0
        speeds = [np.diff(c)[ok] / dt[ok] for c in q]
        x = np.concatenate(
            [
                rng.integers(-(10**7), 21 * 10**8, 3000),
                t[:40],
                mid[:40].astype(np.int64),
                [int(mid[-1])],
            ]
        )
        want = np.column_stack(
            [np.interp(x.astype(np.float64), mid, s, left=0.0, right=0.0) for s in speeds]
        )
        np.testing.assert_array_equal(rates.at(x), want)
        np.testing.assert_array_equal(rates.at(x, [2])[:, 0], want[:, 2])


def test_the_start_reads_only_the_further_targets_samples_it_moves_back(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The whole model's start moves at most ``START_TARGET_POINTS`` samples of each further
    target back to the reference pose: it reads those rows only (it gathered every sample of
    the target before), and gives the mean of the evenly strided ones as before."""
    from dhlog.geometry.lines import Line
    from dhlog.identify.fit import samples
    from dhlog.identify.fit.data import FitData
    from dhlog.model.dh import JointType
    from dhlog.model.screws import points_at_reference

    monkeypatch.setattr(samples, "START_TARGET_POINTS", 50)
    rng = np.random.default_rng(9)
    m = 3000
    Q = rng.uniform(-1.0, 1.0, (m, 2))
    P = rng.normal(size=(m, 3))
    which = rng.integers(0, 3, m).astype(np.int64)
    axes = [
        Line(np.zeros(3), np.array([0.0, 0.0, 1.0])),
        Line(np.ones(3), np.array([1.0, 0.0, 0.0])),
    ]
    types = (JointType.REVOLUTE, JointType.REVOLUTE)
    ref = np.zeros(2)
    read: list[int] = []

    def counted(values: np.ndarray) -> PerSample:
        def fetch(index: slice | np.ndarray) -> np.ndarray:
            out = values[index]
            read.append(out.shape[0])
            return out

        return PerSample(values.shape, fetch)

    data = FitData(counted(Q), counted(P), which=which)
    model = samples.start_model(axes, types, np.zeros(3), ref, data)
    assert sum(read) < 2 * 2 * 100  # Q and P, two further targets, under 2 x 50 each (of ~1000)
    for k in (1, 2):
        Qk, Pk = Q[which == k], P[which == k]
        stride = max(1, Qk.shape[0] // 50)
        want = points_at_reference(axes, types, Qk[::stride], Pk[::stride], ref).mean(axis=0)
        np.testing.assert_array_equal(model.extra_targets[k - 1], want)
