"""Joint states whose clock is seconds off the tracker's — two computers without a common time,
a bridge that stamps with its own — are moved onto the tracker's clock before the log is
segmented (:func:`dhlog.identify.segment.clocks.coarse_offset`: where each stream moves,
matched from the joints' first move), and the offset estimated finely from there. The fine
estimate alone (a linear model of the lag) lost the offset beyond half a second: on the KR5
session off its nominal, 1 s gave an FK RMS of 2.2 mm, 2 s 169 mm with exit 0."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dhlog.identify.fit.register import nominal_judge
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.identify.segment.clocks import coarse_offset
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
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
    timing = result_document(result)["timing"]  # the part matched, in the JSON
    assert abs(timing["coarse_offset"] - offset) < 0.02 and timing["source"] == "estimated"


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
    found = coarse_offset(log, nominal_judge(log, NOMINAL))
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


def test_an_idle_start_does_not_hide_the_offset() -> None:
    """Five minutes and more of set-up before the joints first move (the tracker started
    early): the match starts where the joints first move, so the offset is found as without
    them; the nominal's judge counts every sample but the worst tenth, so the still ones,
    which no offset changes, do not outvote the misjoined moves."""
    import polars as pl

    log = log_data_from_session(_session(2.0))
    assert log.joints is not None
    idle = 320 * 10**9
    first_p, first_j = log.points.row(0, named=True), log.joints.row(0, named=True)
    t_p = np.arange(log.points["t_ns"][0] - idle, log.points["t_ns"][0], 10**7)
    t_j = np.arange(log.joints["t_ns"][0] - idle, log.joints["t_ns"][0], 4 * 10**6)
    before_p = pl.DataFrame({c: np.full(t_p.size, first_p[c]) for c in log.points.columns})
    before_p = before_p.with_columns(pl.Series("t_ns", t_p))
    before_j = pl.DataFrame({c: np.full(t_j.size, first_j[c]) for c in log.joints.columns})
    before_j = before_j.with_columns(pl.Series("t_ns", t_j))
    points = pl.concat([before_p.cast(log.points.schema), log.points])
    joints = pl.concat([before_j.cast(log.joints.schema), log.joints])
    late = replace(log, points=points, joints=joints)
    found = coarse_offset(late, nominal_judge(late, NOMINAL))
    assert found is not None and abs(found - 2.0) < 0.02


def test_a_clock_nothing_confirms_is_named_when_the_run_goes_wrong(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A UR5's sweeps are alike in time: 2 s off and without a nominal, nothing tells the
    offsets the motion matches apart, the log is left as read and joints fail (exit 3) —
    before with no word of the clock. Now a warning names the offsets the motion lines up
    at, the one written among them, and the ways to settle it. The same robot in time with
    a joint skipped (a partial run for another cause) says nothing of the clock."""
    from dhlog.identify.run import process_log
    from dhlog.io.writer import write_session

    ur5 = load_robot("ur5")
    runs = {}
    for name, more in {"late": {"clock_offset": 2.0}, "skipped": {"skip_joints": (3,)}}.items():
        cfg = SimulationConfig(
            perturb_length=5e-4,
            perturb_angle=math.radians(0.05),
            seed=13,
            **more,  # type: ignore[arg-type]
        )
        write_session(simulate_session(ur5, cfg), tmp_path / f"{name}.mcap")
        runs[name] = process_log(tmp_path / f"{name}.mcap", ProcessOptions())
    late, skipped = runs["late"], runs["skipped"]
    assert not late.complete and not skipped.complete
    hints = [n.text for n in late.notes if n.code == "clock-unconfirmed"]
    assert len(hints) == 1, hints
    assert "+1.99" in hints[0] or "+2.00" in hints[0], hints
    assert "clock-unconfirmed" not in {n.code for n in skipped.notes}
