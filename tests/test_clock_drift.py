"""Joint states whose clock runs at another rate than the tracker's: two computers without a common
time drift by 10-50 ppm, 12 ms over a 10-minute session at 20 ppm. One constant offset cannot
join such a session: on the KR5 session off its nominal (30 s of sweeps) a drift of 50 ppm (1.5
ms across it, as 20 ppm over 70 s) gave an FK error against the truth of 0.37 mm, 1 000 ppm
(29 ms, as 50 ppm over ten minutes) 4.5 mm, each with exit 0 (in time: 0.02 mm). The sweeps'
lags against when each was swept show the drift (``timing.phase_drift``); the joint states'
stamps are mapped by it and the session is read again."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import polars as pl
import pytest

from dhlog.identify.run import ProcessOptions, process_data
from dhlog.identify.segment.segment import segment_log
from dhlog.identify.segment.timing import phase_drift, sweep_phases
from dhlog.io.dhfile import DHModel
from dhlog.io.logdata import LogData
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

ROBOT = load_robot("kr5")
NOMINAL = DHModel(
    ROBOT.table, ROBOT.T_base, ROBOT.tool_point, tuple(f"joint_{i + 1}" for i in range(6)), "kr5"
)
OFF = {"noise": 1e-5, "perturb_length": 5e-4, "perturb_angle": math.radians(0.05)}


def _drifting(session: Session, ppm: float) -> LogData:
    """The session's log with its joint states' stamps running ``ppm`` fast from the first."""
    log = log_data_from_session(session)
    assert log.joints is not None
    t = log.joints["t_ns"].to_numpy()
    late = t + np.round(ppm * 1e-6 * (t - t[0]).astype(np.float64)).astype(np.int64)
    return replace(log, joints=log.joints.with_columns(pl.Series("t_ns", late)))


def _fk_error(result, session: Session) -> float:  # type: ignore[no-untyped-def]
    """RMS FK error (m) against the truth at 300 random joint vectors within the limits."""
    ex = result.extraction
    Q = np.random.default_rng(0).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (300, 6))
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    return float(np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1))))


@pytest.fixture(scope="module")
def session() -> Session:
    return simulate_session(ROBOT, SimulationConfig(seed=13, **OFF))  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def in_time(session: Session) -> float:
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=NOMINAL))
    assert result.timing is not None and result.timing.drift == 0.0
    assert "clock-drift" not in {n.code for n in result.notes}
    return _fk_error(result, session)


@pytest.mark.parametrize("ppm", [50.0, 1000.0])
def test_a_drifting_clock_is_mapped_onto_the_trackers(
    session: Session, in_time: float, ppm: float
) -> None:
    """The drift found within 4 ppm (the stamps are mapped back: -ppm / (1 + ppm); the sweeps'
    lags in time scatter by 0.02-0.05 ms, one joint's from another's, which over the 24 s they
    span reads as 2-3 ppm: `benchmarks/clock_drift.py`), said in a warning and the JSON, and the
    calibration near that of the session in time: its FK error against the truth within 1.3×
    of it (the 2-3 ppm left misjoin the fastest samples by some 20 µm; before, 0.37 mm and
    4.5 mm)."""
    result = process_data(_drifting(session, ppm), ProcessOptions(nominal=NOMINAL))
    assert result.timing is not None
    want = -ppm * 1e-6 / (1 + ppm * 1e-6)
    assert abs(result.timing.drift - want) < 4e-6, result.timing
    assert "clock-drift" in {n.code for n in result.notes}
    assert _fk_error(result, session) < 1.3 * in_time
    timing = result_document(result)["timing"]
    assert timing["clock_drift"] == result.timing.drift
    assert isinstance(timing["drift_reference_ns"], int)


@pytest.mark.parametrize("robot", ["kr5", "ur5", "puma560", "scara"])
@pytest.mark.parametrize("more", [{}, {"outliers": 0.05}, {"clock_offset": 0.03}])
def test_a_clock_in_step_shows_no_drift(robot: str, more: dict[str, float]) -> None:
    """Sessions in time (a constant offset, gross outliers) show no drift: the sweeps' lags
    agree within their σ (96 such sessions over six seeds and 1 kHz trackers: none)."""
    sim = simulate_session(load_robot(robot), SimulationConfig(seed=2, **OFF, **more))  # type: ignore[arg-type]
    log = log_data_from_session(sim)
    assert phase_drift(sweep_phases(segment_log(log), log)) is None


def test_a_fixed_clock_is_not_mapped(session: Session) -> None:
    """A pipeline that fixes the offset: the stamps are taken at their word, drift or not."""
    log = _drifting(session, 1000.0)
    seg = replace(log.pipeline.segmentation, clock_offset_fixed=True)
    fixed = replace(log, pipeline=replace(log.pipeline, segmentation=seg))
    result = process_data(fixed, ProcessOptions(nominal=NOMINAL))
    assert result.timing is not None and result.timing.drift == 0.0
    assert "clock-drift" not in {n.code for n in result.notes}


@pytest.mark.parametrize("offset", [0.05, 0.07])
def test_an_offset_of_tens_of_ms_is_no_drift(offset: float) -> None:
    """Each sweep's lag is read by a model linear in it, which misreads a misjoin of 50 ms by a
    different amount for each joint; swept in turn, that was read as a drift of 11-22 ppm (the
    FK check 0.0188 → 0.0268 mm). Read with the encoders joined near the sweeps' mean lag,
    none is found (a review's case: 200 Hz, seeds 13 and 2)."""
    for seed in (13, 2):
        cfg = SimulationConfig(seed=seed, tracker_rate=200.0, clock_offset=offset, **OFF)  # type: ignore[arg-type]
        result = process_data(
            log_data_from_session(simulate_session(ROBOT, cfg)), ProcessOptions(nominal=NOMINAL)
        )
        assert result.timing is not None and result.timing.drift == 0.0, (seed, result.timing)
        assert abs(result.timing.offset - offset) < 1e-5
