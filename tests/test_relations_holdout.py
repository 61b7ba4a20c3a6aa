"""The decision to hold a nearly parallel pair parallel, made by held-out poses
(:mod:`dhlog.identify.model.pairs`): a seeded UR5 session swept as the seed protocol records it
(100 Hz, σ 30 µm), off its nominal and at it, judged by the FK error against the simulator's
truth at random joint vectors within the robot's limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.whole import fit_whole_model
from dhlog.identify.joints.sweeps import samples_with_encoders
from dhlog.identify.model.pairs import (
    Folds,
    candidate_pairs,
    decide_pairs,
    held_out_squares,
    linearised,
)
from dhlog.identify.model.relations import constrain_pairs, pair_constraints
from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.noise import NoiseModel
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

NOISE = 3e-5


def _session(seed: int, off: bool) -> tuple[Session, DHModel]:
    robot = load_robot("ur5")
    cfg = SimulationConfig(
        seed=seed,
        noise=NOISE,
        tracker_rate=100.0,
        perturb_length=5e-4 if off else 0.0,
        perturb_angle=math.radians(0.05) if off else 0.0,
    )
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    return simulate_session(robot, cfg), DHModel(
        robot.table, robot.T_base, robot.tool_point, names, "ur5"
    )


def _fk_rms(session: Session, result: Identification) -> tuple[float, float]:
    """The RMS FK error (m) of ``result``'s DH table and of the limit (the whole model fitted to
    the same samples from the truth) at 300 random joint vectors within the UR5's limits."""
    robot = load_robot("ur5")
    Q = np.random.default_rng(1).uniform(robot.limits[:, 0], robot.limits[:, 1], (300, 6))
    T, tool = session.T_measurement_base, session.tool_point
    want = fk_point(session.table, Q, tool, T_base=T)
    ex = result.extraction
    assert ex is not None
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    truth = AxisModel.of_table(session.table, result.reference_pose, tool, T)
    _, Qs, Ps = samples_with_encoders(result.segmentation)
    limit = fit_whole_model(truth, FitData(Qs, Ps), FitOptions(NoiseModel(), NOISE))
    best, _ = predict(limit.model, Q)
    rms = [math.sqrt(float(np.mean(np.sum((x - want) ** 2, axis=1)))) for x in (got, best)]
    return rms[0], rms[1]


@pytest.fixture(scope="module")
def tilted() -> tuple[Session, DHModel]:
    """Seed 7004 of ``benchmarks/accuracy.py``'s case: axes 3–4 of the truth 11 mdeg apart,
    fitted 7 mdeg apart, 3.3σ with the relation's covariance (1.9σ by the mean of its two
    components' variances, which the 2σ rule read)."""
    return _session(7004, off=True)


def test_a_tilted_pair_the_2_sigma_rule_held_is_left_free_at_the_limit(
    tilted: tuple[Session, DHModel],
) -> None:
    """The held-out poses leave axes 3–4 free (said in a note) where the 2σ rule held them;
    the FK error stays at the limit. Bounds: free fits of this case span 0.93–1.07× the limit
    over 40 sessions (1.009× here), so 1.1× fails only on a hold; the 2σ rule's hold cost 1.54×
    here, and 1.3× keeps it apart from the free fits' spread."""
    session, nominal = tilted
    log = log_data_from_session(session)
    result = process_data(log, ProcessOptions(nominal=nominal))
    before = process_data(log, ProcessOptions(nominal=nominal, parallel_sigma=2.0))
    assert result.whole is not None and before.whole is not None
    assert 2 in before.whole.constrained and 2 not in result.whole.constrained
    assert any("axes 3–4" in s and "left free" in s for s in result.info), result.info
    assert any(n.code in ("pair-free", "pairs-free") and "axes 3–4" in n.text for n in result.notes)
    error, limit = _fk_rms(session, result)
    held, _ = _fk_rms(session, before)
    assert error < 1.1 * limit, (error, limit)
    assert held > 1.3 * limit, (held, limit)


def test_pairs_parallel_in_truth_are_held() -> None:
    """The UR5 at its nominal (axes 2, 3, 4 exactly parallel): the held-out poses hold both
    pairs, and the FK error falls below the free limit (the two pairs' four parameters' noise
    removed: 0.61× here, as under the 2σ rule; 1.01× left free). Bound: free fits of the UR5 at
    its nominal span 0.98–1.02× the limit over six sessions, so 0.9× fails unless a pair is
    held."""
    session, nominal = _session(7000, off=False)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal))
    assert result.whole is not None
    assert result.whole.constrained == {1: "parallel", 2: "parallel"}
    assert sum("held parallel" in s for s in result.info) == 2, result.info
    held = [n for n in result.notes if n.code == "held-parallel"]
    assert [n.text.split(":")[0] for n in held] == ["axes 2–3", "axes 3–4"], held
    assert all(n.level == "info" and "held parallel" in n.text for n in held)
    error, limit = _fk_rms(session, result)
    assert error < 0.9 * limit, (error, limit)


def test_the_linearised_hold_is_the_first_order_of_constrain_pairs(
    tilted: tuple[Session, DHModel],
) -> None:
    """On every sample, the linearised fit held by ``pair_constraints`` mapped into its
    coordinates (``(A B) z = −c₀``) moves the predictions from the free one as
    ``constrain_pairs`` moves the fitted model (first order, then snapped exactly parallel: a
    change of second order, L θ² ≈ 1 m × (1.2e-4)² = 15 nm): within 0.1 µm of a move of
    several µm (a wrong sign or basis would be off by the move itself)."""
    session, nominal = tilted
    free = process_data(
        log_data_from_session(session), ProcessOptions(nominal=nominal, parallel_sigma=0.0)
    )
    whole = free.whole
    assert whole is not None and not whole.constrained
    _, Q, P = samples_with_encoders(free.segmentation)
    d = linearised(whole, FitData(Q, P), FitOptions(free.noise, NOISE))
    assert d.pick.size == Q.shape[0]  # 3 000 samples: no stride
    A, c0 = pair_constraints(whole, [2], [])
    every = np.ones(Q.shape[0], dtype=bool)
    A_all, g_all, _ = d.lin.normal(every)
    # the free step is not quite 0: the fit stops within a µm of the linearisation's optimum
    z_free, _ = d.lin.step(A_all, g_all)
    z_held, _ = d.lin.step(A_all, g_all, (A @ d.lin.B, -c0))
    linear = d.lin.residuals(z_held, every) - d.lin.residuals(z_free, every)
    every_q = Q[d.pick]
    exact, _ = predict(constrain_pairs(whole, [2], []).model, every_q)
    unheld, _ = predict(whole.model, every_q)
    move = exact - unheld
    assert np.abs(move).max() > 3e-6
    assert np.abs(linear - move).max() < 1e-7


def test_the_decision_inside_a_fold_reads_its_training_poses_alone(
    tilted: tuple[Session, DHModel],
) -> None:
    """``decide_pairs`` with a training mask (a fold of ``--holdout K``): the samples outside
    it replaced by nonsense (residuals of a metre) change nothing; on the full samples the
    same poses' decision is the run's (axes 3–4 left free)."""
    import dataclasses

    session, nominal = tilted
    free = process_data(
        log_data_from_session(session), ProcessOptions(nominal=nominal, parallel_sigma=0.0)
    )
    whole = free.whole
    assert whole is not None
    _, Q, P = samples_with_encoders(free.segmentation)
    d = linearised(whole, FitData(Q, P), FitOptions(free.noise, NOISE))
    candidates = {2: "parallel"}
    everything = decide_pairs(d, candidates)
    assert [(t.pair, t.held) for t in everything] == [(2, False)]
    outer = Folds.of(d, np.ones(Q.shape[0], dtype=bool), 5, 0).fold
    train = outer != 0
    inside = decide_pairs(d, candidates, train)
    rng = np.random.default_rng(0)
    lin = d.lin
    rw, e = lin.rw.copy(), lin.e.copy()
    rw[~train] = rng.normal(size=rw[~train].shape) * 1e4
    e[~train] = rng.normal(size=e[~train].shape)
    spoilt = dataclasses.replace(d, lin=dataclasses.replace(lin, rw=rw, e=e))
    again = decide_pairs(spoilt, candidates, train)
    assert [(t.held, t.gain, t.spread) for t in again] == [
        (t.held, t.gain, t.spread) for t in inside
    ]
    assert candidate_pairs(whole, None) == {}
    squares = held_out_squares(d, {}, Folds.of(d, train, 5, 1))
    assert squares.size == np.unique(d.groups[train & d.lin.use]).size
