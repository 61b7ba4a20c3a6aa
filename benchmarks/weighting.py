"""Weighting by an export's U95 when the robot leaves more than the tracker's noise.

    .venv/bin/python benchmarks/weighting.py [--sessions 10] [--poses 40] [--model-error-mm 0.06]

Seeded KR5 sessions off their nominal (0.2 mm, 0.05°) at ``--poses`` random static poses, one
tracker point a pose (σ 5 µm), with an unmodelled smooth error of the robot's position
(``--model-error-mm`` per coordinate: what gravity and gears leave after a geometric model), and a
per-point covariance such as a tracker export's U95 gives (σ drawn in 1–10 µm per point). Each
session is identified three ways, all from the nominal:

* plain: no per-point covariance (isotropic, σ estimated from the residuals);
* U95 only: weighted by the per-point covariance alone (the model-error component switched off);
* U95 + model error: dhlog's default (a model-error σ estimated and added where χ²/dof > 2).

Printed: the RMS FK error against the simulator's truth at 300 random joint vectors within the
limits, over all sessions, of each, their ratio to plain, and the model-error σ estimated.
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np
import polars as pl

import dhlog.identify.fit.variance as variance
from dhlog.identify import run as process
from dhlog.identify.options import ProcessOptions
from dhlog.io.decode.frames import COVARIANCE_COLUMNS
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sessions", type=int, default=10)
    parser.add_argument("--poses", type=int, default=40)
    parser.add_argument("--model-error-mm", type=float, default=0.06)
    args = parser.parse_args()
    robot = load_robot("kr5")
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, "kr5")
    squared: dict[str, list[np.ndarray]] = {"plain": [], "U95 only": [], "U95 + model error": []}
    estimated = []
    default_threshold = variance.MODEL_ERROR_CHI2
    for seed in range(args.sessions):
        cfg = SimulationConfig(
            seed=3000 + seed,
            protocol="random-poses",
            poses=args.poses,
            noise=5e-6,
            model_error=args.model_error_mm * 1e-3,
            dwell=0.5,
            tracker_rate=2.0,
            perturb_length=2e-4,
            perturb_angle=math.radians(0.05),
        )
        session = simulate_session(robot, cfg)
        log = log_data_from_session(session)
        sd = np.random.default_rng(seed).uniform(1e-6, 1e-5, log.points.height)
        cov = {c: sd**2 if c in ("cxx", "cyy", "czz") else 0.0 * sd for c in COVARIANCE_COLUMNS}
        weighted = dataclasses.replace(
            log, points=log.points.with_columns(pl.Series(k, v) for k, v in cov.items())
        )
        Q = np.random.default_rng(seed + 1).uniform(
            robot.limits[:, 0], robot.limits[:, 1], (300, 6)
        )
        want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
        for label, data, threshold in (
            ("plain", log, default_threshold),
            ("U95 only", weighted, math.inf),
            ("U95 + model error", weighted, default_threshold),
        ):
            variance.MODEL_ERROR_CHI2 = threshold
            result = process.process_data(data, ProcessOptions(nominal=nominal))
            ex = result.extraction
            assert ex is not None
            got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
            squared[label].append(np.sum((got - want) ** 2, axis=1))
            if label == "U95 + model error" and result.noise.model_error is not None:
                estimated.append(result.noise.model_error)
        variance.MODEL_ERROR_CHI2 = default_threshold
    rms = {k: math.sqrt(float(np.mean(np.concatenate(v)))) for k, v in squared.items()}
    print(
        f"KR5, {args.sessions} sessions × {args.poses} random poses, σ 5 µm, U95 1–10 µm, "
        f"unmodelled {args.model_error_mm:g} mm"
    )
    print("| weighting | FK error RMS [µm] | / plain |")
    print("|---|---|---|")
    for k, v in rms.items():
        print(f"| {k} | {v * 1e6:.1f} | {v / rms['plain']:.3f} |")
    if estimated:
        print(
            f"model-error σ estimated: {np.mean(estimated) * 1e3:.4f} mm (mean), "
            f"{min(estimated) * 1e3:.4f}–{max(estimated) * 1e3:.4f} mm"
        )


if __name__ == "__main__":
    main()
