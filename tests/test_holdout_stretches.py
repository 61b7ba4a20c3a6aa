"""``--holdout K`` on a motion sampled in steps below ``SAME_POSE`` (a tracker at 1 kHz along the
seed method's sweeps): no pose stands apart from its neighbours, so the folds hold out
stretches of the session (:meth:`dhlog.identify.fit.leaveout.PoseFolds.of_stretches`), scored at
the still poses within them. Poses chained sample to sample made each whole sweep one "pose"
(held out in one fold beside single samples of the faster moves), and a session slower than
``SAME_POSE`` a sample throughout was refused in one line."""

from __future__ import annotations

import json
import math
from importlib import resources

import jsonschema
import numpy as np
import pytest

import dhlog.identify.check.holdout as holdout
import dhlog.identify.fit.leaveout as leaveout
from dhlog.errors import InputError
from dhlog.identify.fit.leaveout import (
    MOTION_SHARE,
    STRETCHES_PER_FOLD,
    PoseFolds,
    motion_share,
    pose_groups,
    still_poses,
)
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.memory import log_data_from_session
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def _sweeps(rng: np.random.Generator) -> np.ndarray:
    """Three joints swept one after the other at 20 µrad a sample, each sweep between dwells of
    4 000 samples with 0.2 mrad of encoder jitter."""
    parts = []
    at = np.zeros(3)
    for j in range(3):
        dwell = at + rng.uniform(-2e-4, 2e-4, (4_000, 3))
        ramp = np.repeat(at[None], 40_000, axis=0)
        ramp[:, j] += np.arange(1, 40_001) * 2e-5
        at = ramp[-1].copy()
        parts += [dwell, ramp]
    return np.vstack([*parts, at + rng.uniform(-2e-4, 2e-4, (4_000, 3))])


def _runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    """The runs of equal ``labels`` in order: (label, first, end)."""
    cuts = np.flatnonzero(np.diff(labels)) + 1
    starts, ends = np.r_[0, cuts], np.r_[cuts, labels.size]
    return [(int(labels[s]), int(s), int(e)) for s, e in zip(starts, ends, strict=True)]


def test_stretches_hold_out_whole_still_poses_and_a_fifth_of_them_each() -> None:
    """Five folds of ten stretches each: every still pose lies in one fold (no held-out pose has
    a fitted sample), each fold is at most ten runs of consecutive samples and holds out a fifth
    of the still poses (a stretch's count rounded), the dwells with their encoder jitter one
    still pose each; the deal is seeded."""
    Q = _sweeps(np.random.default_rng(4))
    still = still_poses(Q)
    poses = int(still.max()) + 1
    dealt = PoseFolds.of_stretches(still, 5)
    assert dealt.stretches == 5 * STRETCHES_PER_FOLD
    assert dealt.stretch_poses == poses / dealt.stretches
    assert np.array_equal(dealt.groups, still)
    pairs = np.unique(np.column_stack([still, dealt.fold]), axis=0)
    assert pairs.shape[0] == poses  # one fold per still pose
    runs = _runs(dealt.fold)
    assert len(runs) <= dealt.stretches
    fold_of_pose = pairs[:, 1]
    for k in range(5):
        assert 1 <= sum(1 for f, _, _ in runs if f == k) <= STRETCHES_PER_FOLD
        share = float(np.count_nonzero(fold_of_pose == k)) / poses
        assert abs(share - 0.2) <= STRETCHES_PER_FOLD / poses
    again = PoseFolds.of_stretches(still, 5)
    assert np.array_equal(again.fold, dealt.fold)
    assert not np.array_equal(PoseFolds.of_stretches(still, 5, seed=1).fold, dealt.fold)


def test_a_gap_in_the_samples_empties_no_fold() -> None:
    """The tracker's beam broken while a joint swept on (4 rad of motion between two samples):
    the stretches count still poses, so the gap is one step and every fold holds a fifth of
    them; counted by joint travel, the gap took eight stretches' share and left a fold empty."""
    a = np.arange(1_000)[:, None] * np.array([[5e-4, 0.0]])
    Q = np.vstack([a, a[-1] + np.array([4.0, 0.0]) + a])
    still = still_poses(Q)
    dealt = PoseFolds.of_stretches(still, 5)
    per_fold = np.bincount(np.asarray(dealt.fold), minlength=5)
    assert per_fold.min() > 0.15 * Q.shape[0], per_fold


def test_more_still_poses_than_scored_are_scored_in_runs_within_a_stretch(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Above MAX_SCORED_POSES still poses the scored poses are runs of consecutive ones, as
    many as that about, none across two stretches (the poses of a long 1 kHz session: the
    check's per-pose arrays stay bounded)."""
    monkeypatch.setattr(leaveout, "MAX_SCORED_POSES", 120)
    Q = _sweeps(np.random.default_rng(6))
    still = still_poses(Q)
    dealt = PoseFolds.of_stretches(still, 5)
    groups = np.asarray(dealt.groups)
    assert 120 <= int(groups.max()) + 1 <= 120 + dealt.stretches
    pairs = np.unique(np.column_stack([groups, dealt.fold]), axis=0)
    assert pairs.shape[0] == int(groups.max()) + 1  # one fold per scored pose
    firsts = np.flatnonzero(np.diff(still, prepend=-1))
    runs = np.unique(np.column_stack([still[firsts], groups[firsts]]), axis=0)
    assert np.array_equal(runs[:, 0], np.arange(int(still.max()) + 1))  # a still pose whole


def test_too_few_still_poses_for_the_stretches_is_one_line() -> None:
    """A slow motion of 39 still poses (0.1 mrad a sample over 40 mrad; rounding puts a few
    poses at 11 samples): five folds need fifty stretches, two twenty; the line says so and what
    to do, not that the session has one pose."""
    from dhlog.identify.wholefit import _dealt

    Q = np.arange(400)[:, None] * np.array([[1e-4, 0.0, 0.0]])
    assert int(still_poses(Q).max()) + 1 == 39
    with pytest.raises(InputError, match="its 39 still poses are fewer than the 50 stretches"):
        _dealt(Q, None, 5)  # type: ignore[arg-type]
    assert _dealt(Q, None, 2).stretches == 20  # type: ignore[arg-type]


def test_a_1_khz_sweep_session_is_held_out_in_stretches(monkeypatch: pytest.MonkeyPatch) -> None:
    """The seed method's sweeps of a KR5 that is not its nominal, recorded at 1 kHz (0.4 mrad a
    sample): ``--holdout 5`` gives the error at the still poses of the stretches each fold held
    out, and says so. No fold was fitted to a sample of a pose it scores (the masks handed to
    the fits). At 2.7 samples a still pose the figure is the noise a pose's mean keeps,
    σ √3 √(mean 1/n) (11.4 µm), as the note says; the model's own error on the arcs (0.5–0.6
    µm, against the truth over four seeds) adds 0.1 % in quadrature, and the RMS of 11 000
    poses spreads by about 0.6 %: 5 % is far outside both (a figure that scored the stretches'
    means, 1 µm, would miss it; one from the fitted samples would not: hence the masks)."""
    samples = 30_000
    speed = 6 * math.radians(90) * 1.34 / (samples / 1000.0)
    cfg = SimulationConfig(
        noise=1e-5,
        tracker_rate=1000.0,
        joint_rate=250.0,
        speed=speed,
        base_points=12,
        seed=7,
        perturb_length=2e-4,
        perturb_angle=math.radians(0.05),
    )
    session = simulate_session(load_robot("kr5"), cfg)
    dealt: list[PoseFolds] = []
    trained: list[np.ndarray] = []
    deal, fit = PoseFolds.of_stretches, holdout.fit_whole_model

    def dealing(still: np.ndarray, folds: int, seed: int = 0) -> PoseFolds:
        dealt.append(deal(still, folds, seed))
        return dealt[-1]

    def fitting(start, data, options, **kw):  # type: ignore[no-untyped-def]
        trained.append(np.asarray(data.keep, dtype=bool).copy())
        return fit(start, data, options, **kw)

    monkeypatch.setattr(PoseFolds, "of_stretches", staticmethod(dealing))
    monkeypatch.setattr(holdout, "fit_whole_model", fitting)
    result = process_data(log_data_from_session(session), ProcessOptions(holdout=5))
    (check,) = result.checks.holdout
    assert check.folds == 5
    assert any("stretches of the session" in note for note in check.notes)
    assert check.stretches == 5 * STRETCHES_PER_FOLD
    (folds,) = dealt
    groups, fold = np.asarray(folds.groups), np.asarray(folds.fold)
    assert len(trained) == 5
    for k, train in enumerate(trained):
        assert not np.any(train & (fold == k))
        assert np.intersect1d(groups[train], groups[fold == k]).size == 0
    document = check.document()
    assert document["stretches"] == check.stretches
    assert document["stretch_poses"] == check.stretch_poses > 1
    schema = json.loads(resources.files("dhlog").joinpath("schemas/result.schema.json").read_text())
    jsonschema.validate(json.loads(json.dumps(result_document(result))), schema)
    n = session.joint_q.shape[1]
    Q = np.column_stack(
        [np.interp(session.point_t_ns, session.joint_t_ns, session.joint_q[:, j]) for j in range(n)]
    )
    per_pose = np.bincount(still_poses(Q))
    assert check.calibrated.n_poses > 0.95 * per_pose.size
    noise = 1e-5 * math.sqrt(3.0 * float(np.mean(1.0 / per_pose)))
    assert abs(check.calibrated.rms / noise - 1.0) < 0.05
    said = next(note for note in check.notes if "stretches of the session" in note)
    floor = float(said.split("the noise a pose's mean keeps is about ")[1].split(" mm")[0])
    assert abs(floor * 1e-3 / noise - 1.0) < 0.05  # the note's floor, with the fit's σ


def test_the_motion_share_is_that_of_the_sweeps_chained_below_same_pose() -> None:
    """Sweeps at 0.5 mrad a sample between moves at 1.2 mrad a sample (the simulator's 1 kHz
    session): the sweeps' samples are motion, the moves' single samples are not; the same
    sweeps at 5 mrad a sample (a 100 Hz tracker) and dwells with 0.3 mrad of jitter have
    none."""
    rng = np.random.default_rng(5)
    sweep = np.arange(4_000)[:, None] * np.array([[5e-4, 0.0]])
    move = sweep[-1] + np.arange(1, 1_001)[:, None] * np.array([[0.0, 1.2e-3]])
    Q = np.vstack([sweep, move, move[-1] + sweep])
    share = motion_share(pose_groups(Q), still_poses(Q))
    assert share == 8_001 / 9_000  # the sweeps, and the move's last sample that starts one
    fast = np.arange(4_000)[:, None] * np.array([[5e-3, 0.0]])
    assert motion_share(pose_groups(fast), still_poses(fast)) == 0.0
    dwells = np.vstack([k * 0.1 + rng.uniform(-1.5e-4, 1.5e-4, (500, 2)) for k in range(8)])
    assert motion_share(pose_groups(dwells), still_poses(dwells)) == 0.0
    assert share >= MOTION_SHARE


def test_a_1_khz_session_with_faster_moves_between_its_sweeps_is_held_out_in_stretches() -> None:
    """The simulator's default sweep speed under a 1 kHz tracker: the moves between the sweeps
    step up to 1.1 mrad a sample, so the chained poses are many (2 439 here, 2 431 of them single
    samples) but eight span a sweep or most of one (over 90 % of the samples); the folds hold
    out stretches, scored at its 11 000 still poses, not those eight and the moves' samples."""
    cfg = SimulationConfig(noise=1e-5, tracker_rate=1000.0, seed=3)
    session = simulate_session(load_robot("kr5"), cfg)
    result = process_data(log_data_from_session(session), ProcessOptions(holdout=5))
    (check,) = result.checks.holdout
    assert check.stretches == 5 * STRETCHES_PER_FOLD
    assert check.calibrated.n_poses > 10_000
