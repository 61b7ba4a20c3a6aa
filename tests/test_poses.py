"""A session's still poses (:func:`dhlog.identify.fit.leaveout.still_poses`), the unit of the
design effect: a run of consecutive samples whose joint values stay within ``SAME_POSE`` of
its first sample's — a still pose however long it is held, and poses of ``SAME_POSE`` each
along a joint that moves slowly under a fast instrument (a tracker at 1 kHz steps far below
``SAME_POSE``). Chaining step to step (``pose_groups``, the folds' poses) made a whole 1 kHz
sweep session one pose: its σ were scaled by a design effect of a million samples a pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

import dhlog.identify.fit.leaveout as leaveout
from dhlog.errors import InputError
from dhlog.identify.fit.leaveout import SAME_POSE, still_poses
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.memory import log_data_from_session
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def _one_by_one(Q: np.ndarray) -> np.ndarray:
    """The definition, sample by sample: a new pose where a joint moves SAME_POSE or more from
    the previous sample or from the pose's first."""
    out, pose, first, previous = np.empty(len(Q), np.int64), -1, Q[0], None
    for i, q in enumerate(Q):
        if previous is None or max(np.max(np.abs(q - previous)), np.max(np.abs(q - first))) >= (
            SAME_POSE
        ):
            pose, first = pose + 1, q
        out[i], previous = pose, q
    return out


def _session(rng: np.random.Generator, m: int) -> np.ndarray:
    """Still poses with encoder jitter, slow moves (steps far below SAME_POSE, some back and
    forth), fast moves (steps above it), one after another."""
    parts: list[np.ndarray] = []
    while sum(len(p) for p in parts) < m:
        kind, n, at = int(rng.integers(3)), int(rng.integers(1, 300)), rng.normal(size=6)
        if kind == 0:
            parts.append(at + rng.normal(0.0, 2e-4, (n, 6)))
        elif kind == 1:
            parts.append(at + np.cumsum(rng.uniform(-4e-4, 6e-4, (n, 6)), axis=0))
        else:
            parts.append(at + np.cumsum(rng.uniform(0.0, 3e-3, (n, 6)), axis=0))
    return np.vstack(parts)[:m]


@pytest.mark.parametrize("chunk", [1 << 18, 64, 7, 1])
def test_poses_are_the_definition_whatever_the_blocks(
    chunk: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The block-at-a-time still poses (only moving stretches looked at sample by sample, the
    open pose carried across blocks) is the sample-by-sample definition, for blocks of every
    size down to one sample."""
    monkeypatch.setattr(leaveout, "POSE_CHUNK", chunk)
    rng = np.random.default_rng(11)
    for m in (1, 2, 5, 400, 3000):
        Q = _session(rng, m)
        assert still_poses(Q).tolist() == _one_by_one(Q).tolist()


def test_a_slow_move_at_1_khz_is_many_poses_and_a_still_pose_one() -> None:
    """A joint at 0.011 rad/s under a 1 kHz tracker (11 µrad a sample: the 1.1 M-sample
    benchmark log's speed) makes poses that each span less than SAME_POSE, about one per
    SAME_POSE travelled; a pose held for 20 000 samples with 0.3 mrad of encoder jitter stays
    one pose."""
    Q = np.zeros((100_000, 6))
    Q[:, 1] = np.arange(100_000) * 1.1e-5
    groups = still_poses(Q)
    count = int(groups[-1]) + 1
    # a pose ends at the first sample SAME_POSE from its first: 91 steps of 11 µrad each
    assert count == math.ceil(100_000 / math.ceil(SAME_POSE / 1.1e-5))
    spans = np.maximum.reduceat(Q[:, 1], np.flatnonzero(np.diff(groups, prepend=-1)))
    starts = Q[np.flatnonzero(np.diff(groups, prepend=-1)), 1]
    assert np.all(spans - starts < SAME_POSE)
    still = np.random.default_rng(2).normal(0.0, 1e-4, (20_000, 6)).clip(-3e-4, 3e-4)
    assert still_poses(still).max() == 0


def test_a_1_khz_sweep_session_is_not_clustered() -> None:
    """The seed method's sweeps recorded at 1 kHz (joint states at 250 Hz, 0.4 rad/s: 0.4 mrad
    a sample): the white noise of the samples is not taken for a pose's shared error (the
    design effect of one pose of 30 000 samples scaled every σ by about 3). Its ``--holdout``:
    tests/test_holdout_stretches.py."""
    samples = 30_000
    speed = 6 * math.radians(90) * 1.34 / (samples / 1000.0)
    cfg = SimulationConfig(
        noise=1e-5, tracker_rate=1000.0, joint_rate=250.0, speed=speed, base_points=12, seed=7
    )
    log = log_data_from_session(simulate_session(load_robot("kr5"), cfg))
    result = process_data(log, ProcessOptions())
    assert result.whole is not None
    assert "pose-clustered" not in {note.code for note in result.notes}


def test_more_folds_than_poses_is_said_before_the_selection_deals_them() -> None:
    """30 still poses and ``--holdout 50``: the run stops with the one-line error naming the
    pose count — not the fast-sampled motion's, also where each pose holds 100 samples. It is
    said before the model selection deals the poses to the same folds (with a fold's training
    poses empty, the selection divided by their zero residuals: the 1 kHz session above)."""
    from dhlog.io.dhfile import DHModel

    robot = load_robot("kr5")
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)
    for rate in (2.0, 200.0):  # one sample a pose, and a hundred: still poses either way
        cfg = SimulationConfig(
            protocol="random-poses", poses=30, noise=1e-5, dwell=0.5, tracker_rate=rate, seed=3
        )
        log = log_data_from_session(simulate_session(robot, cfg))
        with pytest.raises(InputError, match="--holdout 50: the session has 30 distinct poses"):
            process_data(log, ProcessOptions(nominal=nominal, holdout=50))
