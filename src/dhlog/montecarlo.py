"""Monte Carlo checks on seeded simulated sessions.

Each session simulates a library robot (its own table as truth and as nominal), identifies it in
memory (no MCAP file) and records, for every standard-DH parameter, the error and the σ dhlog
reported. Over many sessions the RMS of the reported σ should equal the empirical spread.
"""

from __future__ import annotations

import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from dhlog.dhfile import DHModel
from dhlog.geometry._checks import FloatArray
from dhlog.io.memory import log_data_from_session
from dhlog.process import nominal_difference, process_data
from dhlog.robots import load_robot
from dhlog.simulate import SimulationConfig, simulate_session


def one_session(args: tuple[str, int, float, float, float]) -> tuple[FloatArray, FloatArray]:
    """Errors and reported σ (both 4n, rows θ, d, a, α) of one seeded session.

    ``args``: robot name, seed, Gaussian noise σ (m), tracker rate (Hz), fraction of gross
    outliers (3–9 mm); sweeps of 60°, 12 base points.
    """
    name, seed, noise, rate, outliers = args
    robot = load_robot(name)
    nominal = DHModel(
        robot.table,
        robot.T_base,
        robot.tool_point,
        tuple(f"joint_{i + 1}" for i in range(robot.n)),
        name,
    )
    cfg = SimulationConfig(
        seed=seed, noise=noise, tracker_rate=rate, sweep=math.radians(60), outliers=outliers
    )
    result = process_data(log_data_from_session(simulate_session(robot, cfg)), nominal=nominal)
    diff = nominal_difference(result)
    assert diff is not None and result.std is not None
    return diff.ravel(), result.std[: diff.size]


def sessions(
    name: str,
    count: int,
    *,
    workers: int = 2,
    noise: float = 2e-5,
    rate: float = 30.0,
    outliers: float = 0.0,
    first_seed: int = 1000,
) -> tuple[FloatArray, FloatArray]:
    """Errors and reported σ, each (count, 4n), of ``count`` seeded sessions."""
    jobs = [(name, first_seed + s, noise, rate, outliers) for s in range(count)]
    if workers > 1:
        # spawn, not fork: forking a process whose polars/zstd thread pools are running can hang
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context) as pool:
            out = list(pool.map(one_session, jobs, chunksize=8))
    else:
        out = [one_session(j) for j in jobs]
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


def calibration(
    name: str, count: int, *, workers: int = 2, noise: float = 2e-5, rate: float = 30.0
) -> tuple[FloatArray, FloatArray]:
    """(RMS of the reported σ, empirical σ of the error) per parameter over ``count`` sessions."""
    errors, reported = sessions(name, count, workers=workers, noise=noise, rate=rate)
    return np.sqrt(np.mean(reported**2, axis=0)), errors.std(axis=0)
