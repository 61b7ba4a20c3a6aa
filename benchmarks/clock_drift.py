"""Does a joint-state clock drifting against the tracker's calibrate as one in time? Simulated
sweep sessions of three robots (KR5, UR5, PUMA 560), each off its nominal (lengths σ 0.5 mm,
angles σ 0.05°, σ 10 µm), its joint states' clock running ``--ppm`` fast (0 for the sessions
in time), several seeds (noise realisations and robots) each, processed as ``dhlog process
--nominal`` does in memory; the FK error against the truth at 300 random joint vectors within
the limits, and the drift found against the one written (the stamps mapped back: −ppm / (1 +
ppm)).

    .venv/bin/python benchmarks/clock_drift.py [--ppm 0 50 200 1000] [--seeds 5] [--outliers 0.05]

The simulator's sessions last 30 s: 1 000 ppm there misjoins as 50 ppm does over ten minutes.
2026-12-04, this machine, ``--seeds 5`` (the figures in docs/method.md): see the printed table.
"""

from __future__ import annotations

import argparse
import math
import statistics

import numpy as np

from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ppm", type=float, nargs="+", default=[0.0, 50.0, 200.0, 1000.0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--outliers", type=float, default=0.0, help="share of gross outliers")
    args = parser.parse_args()
    print("robot    ppm   FK error median [max] (mm)   drift found − written (ppm, max)   warned")
    for name in ("kr5", "ur5", "puma560"):
        robot = load_robot(name)
        names = tuple(f"joint_{i + 1}" for i in range(robot.n))
        nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, name)
        Q = np.random.default_rng(0).uniform(robot.limits[:, 0], robot.limits[:, 1], (300, robot.n))
        for ppm in args.ppm:
            errors, misses, warned = [], [], 0
            for seed in range(args.seeds):
                cfg = SimulationConfig(
                    noise=1e-5,
                    perturb_length=5e-4,
                    perturb_angle=math.radians(0.05),
                    clock_drift=ppm * 1e-6,
                    outliers=args.outliers,
                    seed=seed,
                )
                session = simulate_session(robot, cfg)
                result = process_data(
                    log_data_from_session(session), ProcessOptions(nominal=nominal)
                )
                ex = result.extraction
                assert ex is not None and result.timing is not None
                got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
                want = fk_point(
                    session.table, Q, session.tool_point, T_base=session.T_measurement_base
                )
                errors.append(float(np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1)))))
                want_rate = -ppm * 1e-6 / (1 + ppm * 1e-6)
                misses.append(abs(result.timing.drift - want_rate) * 1e6)
                warned += "clock-drift" in {n.code for n in result.notes}
            print(
                f"{name:8} {ppm:5.0f}   {statistics.median(errors) * 1e3:.4f} "
                f"[{max(errors) * 1e3:.4f}]              {max(misses):8.2f}"
                f"                        {warned}/{args.seeds}"
            )


if __name__ == "__main__":
    main()
