"""A step of the joint states' clock in the middle of a sweeps session: a time daemon setting
the clock of the computer that stamps them (ntpd beyond 128 ms, chrony's ``makestep``, Windows'
time service), every stamp after it that much off those before. One offset cannot join both
halves: on a KR5 off its nominal (seed 5, 100 Hz tracker, σ 10 µm) a clock set 20 ms back or
on mid-session gave an FK check of 0.45-0.83 mm and an error against the truth of 2.0-2.2 mm
(0.0058 mm in time), exit 0 with no word of the clock. The sweeps' lags either side of the
stream's odd interval tell the step (``identify.segment.steps``): the stamps from there on are
moved by it, and the fit is as in time.

The sessions stepped and in time are the same motion and noise (one seed), only the joint
states' stamps after mid-session moved, so what differs is the join alone: the tolerance on
the error against the truth is 1.2x that in time (the step is read from the lags to their σ,
10-30 µs, and the fit's one clock offset cannot take up what is left on one side)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

ROBOT = load_robot("kr5")
OFF = {"noise": 1e-5, "perturb_length": 5e-4, "perturb_angle": math.radians(0.05)}


def _session(seed: int = 5, **faults: float) -> Session:
    return simulate_session(ROBOT, SimulationConfig(seed=seed, **OFF, **faults))  # type: ignore[arg-type]


def _stepped(session: Session, seconds: float, at: float = 0.5) -> Session:
    """``session`` with its joint states' clock set ``seconds`` on at the fraction ``at`` of
    the session (their stamps from there on later by it; back where negative)."""
    t = session.joint_t_ns.copy()
    t[t > t[0] + int((t[-1] - t[0]) * at)] += round(seconds * 1e9)
    return replace(session, joint_t_ns=t)


def _run(session: Session) -> Identification:
    return process_data(log_data_from_session(session), ProcessOptions())


def _fk_error(result: Identification, session: Session) -> float:
    """RMS FK error (m) against the truth at 300 random joint vectors within the limits."""
    ex = result.extraction
    assert ex is not None
    Q = np.random.default_rng(0).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (300, 6))
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    return float(np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1))))


@pytest.fixture(scope="module")
def in_time() -> tuple[Session, Identification]:
    session = _session()
    return session, _run(session)


@pytest.mark.parametrize("seconds", [0.03, -0.02, -0.2])
def test_a_clock_set_mid_session_is_taken_out(
    seconds: float, in_time: tuple[Session, Identification]
) -> None:
    """Set on 30 ms (a gap in the stamps), back 20 ms and 200 ms (stamps before the last
    ones): found to a fraction of a ms, the stamps moved back by it, the fit as in time."""
    truth_session, truth = in_time
    assert truth.timing is not None and truth.timing.step == 0.0
    assert not any(n.code == "clock-step" for n in truth.notes)
    session = _stepped(truth_session, seconds)
    result = _run(session)
    t = result.timing
    assert t is not None and abs(t.step + seconds) < 1e-4  # the step taken out: −seconds
    assert t.document()["clock_step"] == t.step
    assert any(n.code == "clock-step" for n in result.notes)
    assert result.validation is not None and truth.validation is not None
    assert result.validation.rms < 1.05 * truth.validation.rms
    assert _fk_error(result, session) < 1.2 * _fk_error(truth, truth_session)


def test_dropouts_are_no_step() -> None:
    """A stream with gaps where messages were lost (2 % dropped) and a clock that runs on: the
    odd intervals are tried, the lags either side agree, and no step is taken."""
    result = _run(_session(seed=4, dropouts=0.02))
    assert result.timing is not None and result.timing.step == 0.0
    assert "clock_step" not in result.timing.document()
