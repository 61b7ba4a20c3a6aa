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

from dhlog.geometry._checks import FloatArray
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.read.analytic import NOMINAL_SIGMA_2D
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.robots import load_robot
from dhlog.result.document import nominal_difference
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def one_session(job: dict[str, object]) -> tuple[FloatArray, FloatArray]:
    """Errors and reported σ (both 4n, rows θ, d, a, α) of one seeded session.

    ``job`` keys: ``robot``, ``seed``, ``noise`` (m; σ, or half-width if ``noise_kind`` is
    ``"uniform"``), ``rate`` (tracker, Hz), ``outliers`` (fraction, 3–9 mm), ``sweep`` (rad),
    ``fit_method`` (``"auto"`` = encoder-aided, ``"algebraic"`` = seed 002), ``analytic_only``
    (bool: the seed method alone instead of the whole-model fit), ``parallel_sigma`` (the σ
    count within which the whole-model fit holds a pair parallel; default 5: the truth is the
    nominal, whose parallel pairs are exactly parallel, so they are held as it says — by
    Akaike's 2σ some sessions leave such a pair free, and a free nearly parallel pair's
    standard d and θ are far from first order).
    The robot's own table is the truth and the nominal; 12 base points.
    """
    name = str(job["robot"])
    robot = load_robot(name)
    nominal = DHModel(
        robot.table,
        robot.T_base,
        robot.tool_point,
        tuple(f"joint_{i + 1}" for i in range(robot.n)),
        name,
    )
    cfg = SimulationConfig(
        seed=int(job["seed"]),  # type: ignore[call-overload]
        noise=float(job.get("noise", 2e-5)),  # type: ignore[arg-type]
        noise_kind=str(job.get("noise_kind", "gaussian")),  # type: ignore[arg-type]
        tracker_rate=float(job.get("rate", 30.0)),  # type: ignore[arg-type]
        sweep=float(job.get("sweep", math.radians(60))),  # type: ignore[arg-type]
        outliers=float(job.get("outliers", 0.0)),  # type: ignore[arg-type]
    )
    result = process_data(
        log_data_from_session(simulate_session(robot, cfg)),
        ProcessOptions(
            nominal=nominal,
            fit_method=str(job.get("fit_method", "auto")),
            analytic_only=bool(job.get("analytic_only", False)),
            parallel_sigma=float(job.get("parallel_sigma", NOMINAL_SIGMA_2D)),
            model=ModelRequest("geometric"),
        ),
    )
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
    **options: object,
) -> tuple[FloatArray, FloatArray]:
    """Errors and reported σ, each (count, 4n), of ``count`` seeded sessions (``options`` are
    further :func:`one_session` keys)."""
    jobs = [
        {
            "robot": name,
            "seed": first_seed + s,
            "noise": noise,
            "rate": rate,
            "outliers": outliers,
            **options,
        }
        for s in range(count)
    ]
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
    held = np.isnan(reported).all(axis=0)  # fixed by a convention (σ null) in every session
    rms = np.sqrt(np.mean(np.nan_to_num(reported) ** 2, axis=0))
    return np.where(held, 0.0, rms), errors.std(axis=0)
