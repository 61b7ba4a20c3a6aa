"""Segmentation on crafted tables: transitions, repeated sweeps, jitter, clock offsets, steps."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from dhlog.identify.segment.segment import segment_log, shared_locked_pose
from dhlog.io.pipeline import parse_pipeline
from dhlog.io.reader import LogData

S = 1_000_000_000
PIPE = parse_pipeline("[streams.point]\n[streams.joints]\n", "crafted.toml")


def trajectory(keys: list[tuple[float, list[float]]], t: np.ndarray) -> np.ndarray:
    kt = np.array([k[0] for k in keys])
    kq = np.array([k[1] for k in keys])
    return np.stack([np.interp(t, kt, kq[:, j]) for j in range(kq.shape[1])], axis=1)


def crafted(
    keys: list[tuple[float, list[float]]],
    *,
    tracker_hz: float = 200.0,
    joint_hz: float = 100.0,
    joint_offset_s: float = 0.0013,
    jitter: float = 0.0,
    tracker_times: np.ndarray | None = None,
    clock_error_s: float = 0.0,
    seed: int = 0,
) -> LogData:
    rng = np.random.default_rng(seed)
    end = keys[-1][0]
    t_trk = np.arange(0.0, end, 1 / tracker_hz) if tracker_times is None else tracker_times
    t_enc = np.arange(0.0, end, 1 / joint_hz) + joint_offset_s
    q_trk = trajectory(keys, t_trk)
    q_enc = trajectory(keys, t_enc) + rng.normal(scale=jitter, size=(t_enc.size, len(keys[0][1])))
    points = pl.DataFrame(
        {
            "t_ns": (t_trk * S).astype(np.int64),
            "x": q_trk[:, 0],
            "y": q_trk[:, 1],
            "z": np.zeros(t_trk.size),
        }
    )
    joints = pl.DataFrame(
        {
            "t_ns": ((t_enc + clock_error_s) * S).astype(np.int64),
            **{f"q_{j + 1}": q_enc[:, j] for j in range(q_enc.shape[1])},
        }
    )
    names = [f"j{j + 1}" for j in range(q_enc.shape[1])]
    return LogData("crafted.mcap", PIPE, points, joints, names, None, None)


# joint 1 swept, a transition moving both joints, joint 2 swept, back home
SESSION = [
    (0.0, [0.0, 0.0]),
    (1.0, [0.0, 0.0]),
    (4.0, [1.0, 0.0]),
    (5.0, [1.0, 0.0]),
    (6.0, [0.0, -0.5]),
    (7.0, [0.0, -0.5]),
    (10.0, [0.0, 0.7]),
    (11.0, [0.0, 0.7]),
]


def test_sweeps_and_transitions() -> None:
    seg = segment_log(crafted(SESSION))
    assert seg.segments["joint"].to_list() == [1, 2]
    t = seg.table
    # the transition between 5 s and 6 s moves both joints: set aside, counted
    moving_both = t.filter((pl.col("t_ns") > 5.1 * S) & (pl.col("t_ns") < 5.9 * S))
    assert moving_both["segment"].null_count() == moving_both.height
    assert seg.set_aside["transition"] >= moving_both.height
    # sweep 1 spans its dwells, sweep 2 likewise
    s1 = t.filter(pl.col("segment") == 1)
    assert s1["t_ns"].min() < 1.0 * S and s1["t_ns"].max() > 4.0 * S  # type: ignore[operator]
    np.testing.assert_allclose(seg.segments["sweep"].to_numpy(), [1.0, 1.2], atol=1e-9)
    # encoder values at target times: linear between the encoder samples, so exact for this
    # motion except within one encoder period (10 ms) of a change of speed
    assigned = t.filter(pl.col("segment").is_not_null())
    corners = np.array([k[0] for k in SESSION]) * S
    gap = np.abs(assigned["t_ns"].to_numpy()[:, None] - corners).min(axis=1)
    smooth = gap > 0.011 * S
    for q, truth in (("q_1", "x"), ("q_2", "y")):
        err = np.abs(assigned[q].to_numpy() - assigned[truth].to_numpy())
        assert err[smooth].max() < 1e-9  # stamps are whole nanoseconds: 1 ns x 1/3 rad/s
        assert err.max() < 1e-3  # at a corner: at most speed x period / 4 (1/3 rad/s x 10 ms)
    assert t.filter(pl.col("segment").is_null()).height == sum(seg.set_aside.values())


def test_repeated_sweeps_from_different_locked_poses() -> None:
    keys = [
        (0.0, [0.0, 0.0]),
        (1.0, [0.0, 0.0]),
        (3.0, [0.0, 1.0]),
        (4.0, [0.0, 1.0]),  # j2 @ j1=0
        (5.0, [0.5, 0.0]),
        (6.0, [0.5, 0.0]),
        (8.0, [0.5, 1.0]),
        (9.0, [0.5, 1.0]),  # j2 @ j1=0.5
        (10.0, [0.5, 0.3]),
        (11.0, [0.5, 0.3]),
        (13.0, [1.5, 0.3]),
        (14.0, [1.5, 0.3]),  # j1
    ]
    seg = segment_log(crafted(keys))
    rows = seg.segments
    assert rows["joint"].to_list() == [2, 2, 1]
    np.testing.assert_allclose(rows["lock_q_1"].to_numpy()[:2], [0.0, 0.5], atol=1e-9)
    assert np.isnan(rows["lock_q_2"][0]) and rows["lock_q_2"][2] == pytest.approx(0.3)
    # the j1 sweep agrees with either j2 sweep: a tie, which the earliest sweep wins
    np.testing.assert_allclose(seg.reference_pose, [0.0, 0.3], atol=1e-9)


def test_encoder_jitter_inside_the_tolerance_keeps_the_sweeps() -> None:
    seg = segment_log(crafted(SESSION, jitter=3e-6))
    assert seg.segments["joint"].to_list() == [1, 2]


def test_a_joint_drifting_beyond_the_tolerance_is_not_locked() -> None:
    keys = [(0.0, [0.0, 0.0]), (1.0, [0.0, 0.0]), (4.0, [1.0, 0.002]), (5.0, [1.0, 0.002])]
    seg = segment_log(crafted(keys))
    assert seg.segments.height == 0  # both joints move: no sweep
    assert seg.set_aside["transition"] > 0


def test_clock_offset_within_the_join_tolerance_and_its_correction() -> None:
    """Encoder stamps 4 ms late: the sweeps are still found, the interpolated values are off by
    the motion in 4 ms, and the pipeline's clock_offset removes that."""
    from dhlog.io.decode.frames import joints_frame

    late = crafted(SESSION, clock_error_s=0.004)
    seg = segment_log(late)
    assert seg.segments["joint"].to_list() == [1, 2]
    a = seg.table.filter(pl.col("segment") == 1)
    assert np.abs(a["q_1"].to_numpy() - a["x"].to_numpy()).max() > 1e-4
    assert late.joints is not None
    pipe = parse_pipeline(
        "[streams.point]\n[streams.joints]\n[segmentation]\nclock_offset = -0.004\n", "fix.toml"
    )
    blocks = [
        (late.joints["t_ns"].to_numpy(), (late.joint_names, late.joints.drop("t_ns").to_numpy()))
    ]
    late.joints, _, _ = joints_frame("crafted.mcap", "/joint_states", blocks, pipe)
    fixed = segment_log(late).table.filter(pl.col("segment") == 1)
    corners = np.array([k[0] for k in SESSION]) * S
    smooth = np.abs(fixed["t_ns"].to_numpy()[:, None] - corners).min(axis=1) > 0.011 * S
    err = np.abs(fixed["q_1"].to_numpy() - fixed["x"].to_numpy())
    assert err[smooth].max() < 1e-9


def test_target_samples_without_encoders_around_them_are_counted() -> None:
    log = crafted(SESSION, joint_hz=2.0)  # 0.5 s between encoder samples > 0.05 s join tolerance
    seg = segment_log(log)
    assert seg.set_aside.get("no_encoder", 0) > 0.8 * log.points.height


def test_step_and_measure() -> None:
    keys: list[tuple[float, list[float]]] = [(0.0, [0.0, 0.0])]
    t = 0.0
    for value in np.linspace(0.0, 1.0, 11)[1:]:
        keys += [(t + 0.5, [keys[-1][1][0], 0.0]), (t + 0.7, [float(value), 0.0])]
        t += 0.7
    keys.append((t + 0.5, [1.0, 0.0]))
    t_keys = np.array([k[0] for k in keys])
    q_keys = np.array([k[1][0] for k in keys])
    still = [
        (a, b)
        for a, b, qa, qb in zip(t_keys, t_keys[1:], q_keys, q_keys[1:], strict=False)
        if qa == qb
    ]
    tracker = np.concatenate([np.arange(a + 0.1, b - 0.1, 0.02) for a, b in still])
    seg = segment_log(crafted(keys, tracker_times=tracker))
    assert seg.segments["joint"].to_list() == [1]
    assert seg.segments["n"][0] == tracker.size
    levels = np.unique(np.round(seg.table["q_1"].to_numpy(), 9))
    assert levels.size == 11  # every stop is in the sweep


def test_shared_locked_pose_prefers_the_most_common_pose() -> None:
    rows = pl.DataFrame(
        {
            "lock_q_1": [float("nan"), 0.0, 0.0, 0.9],
            "lock_q_2": [0.2, float("nan"), 0.2, 0.2],
            "lock_q_3": [0.1, 0.1, float("nan"), 0.5],
        }
    )
    np.testing.assert_allclose(shared_locked_pose(rows, 3, 1e-5), [0.0, 0.2, 0.1])
