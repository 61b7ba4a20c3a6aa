"""Joint states whose clock is seconds off the tracker's — two computers without a common time,
a bridge that stamps with its own — are moved onto the tracker's clock before the log is
segmented (:func:`dhlog.identify.segment.timing.coarse_offset`: where each stream moves,
matched over the session), and the offset estimated finely from there. The fine estimate alone
(a linear model of the lag) lost the offset beyond half a second: on the KR5 session off its
nominal, 1 s gave an FK RMS of 2.2 mm, 2 s 169 mm with exit 0."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dhlog.identify.run import ProcessOptions, process_data
from dhlog.identify.segment.clocks import coarse_offset
from dhlog.identify.session import _nominal_miss
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

ROBOT = load_robot("kr5")
NOMINAL = DHModel(
    ROBOT.table,
    ROBOT.T_base,
    ROBOT.tool_point,
    tuple(f"joint_{i + 1}" for i in range(ROBOT.n)),
    "kr5",
)


def _session(offset: float, **more: object):  # type: ignore[no-untyped-def]
    cfg = SimulationConfig(
        noise=1e-5,
        perturb_length=5e-4,
        perturb_angle=math.radians(0.05),
        clock_offset=offset,
        seed=13,
        **more,  # type: ignore[arg-type]
    )
    return simulate_session(ROBOT, cfg)


def _fk_error(result, session) -> float:  # type: ignore[no-untyped-def]
    """RMS FK error (m) against the truth at 300 random joint vectors within the limits."""
    ex = result.extraction
    Q = np.random.default_rng(0).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (300, ROBOT.n))
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    return float(np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1))))


@pytest.fixture(scope="module")
def in_time() -> float:
    """The FK error against the truth of the same session with the clocks 25 ms apart (the
    fine estimate's own range)."""
    session = _session(0.025)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=NOMINAL))
    assert "clock-coarse" not in {n.code for n in result.notes}
    return _fk_error(result, session)


@pytest.mark.parametrize("offset", [-3.0, 1.0, 2.0, 9.0])
def test_joint_states_seconds_off_are_put_on_the_trackers_clock(
    offset: float, in_time: float
) -> None:
    """The offset is found to within 1 ms (the fine estimate's σ is 0.5 µs; 1 ms bounds a
    10 ms grid's start by far), the note says it was moved, and the calibration is that of the
    session in time: its FK error against the truth within 10 % of it (the same samples, joined
    within microseconds of the same instants). 9 s is a third of this 30 s session."""
    session = _session(offset)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=NOMINAL))
    assert result.timing is not None
    assert abs(result.timing.offset - offset) < 1e-3, result.timing
    assert "clock-coarse" in {n.code for n in result.notes}
    assert not result.implausible
    assert _fk_error(result, session) < 1.1 * in_time


def test_a_step_and_measure_tracker_is_matched_by_its_silences() -> None:
    """A tracker triggered at the stops is silent while the robot moves: its silences are the
    moves. With the clocks 2 s apart such a log put its samples on the moves (FK RMS 166 mm,
    exit 0); matched to about 10 ms (a step log carries no finer lag) it calibrates as in time:
    the FK error against the truth within 10 % of the in-time log's. The nominal placed on the
    points confirms the match: without it nothing does, and the log is left as read."""
    step, late = _session(0.0, motion="step"), _session(2.0, motion="step")
    log = log_data_from_session(late)
    # without the nominal nothing confirms the match (the tracker is silent on the sweeps)
    assert coarse_offset(log) is None
    found = coarse_offset(log, _nominal_miss(log, NOMINAL))
    assert found is not None and abs(found - 2.0) < 0.02
    results = [
        process_data(log_data_from_session(s), ProcessOptions(nominal=NOMINAL))
        for s in (step, late)
    ]
    assert "clock-coarse" in {n.code for n in results[1].notes}
    assert results[1].timing is not None and abs(results[1].timing.offset - 2.0) < 0.02
    assert _fk_error(results[1], late) < 1.1 * _fk_error(results[0], step)


def test_a_fixed_offset_is_taken_at_its_word() -> None:
    """A pipeline that fixes the offset: nothing is matched, the offset is the pipeline's."""
    log = log_data_from_session(_session(2.0))
    found = coarse_offset(log)
    assert found is not None and abs(found - 2.0) < 0.02
    seg = replace(log.pipeline.segmentation, clock_offset_fixed=True)
    fixed = replace(log, pipeline=replace(log.pipeline, segmentation=seg))
    result = process_data(fixed, ProcessOptions(nominal=NOMINAL))
    assert "clock-coarse" not in {n.code for n in result.notes}
    assert result.timing is not None and result.timing.offset == 0.0
