"""Does a sweeps session whose joint-state clock is set mid-session (a time daemon stepping
it) calibrate as one in time? Simulated sessions of three robots (KR5, UR5, PUMA 560), each
off its nominal (lengths σ 0.5 mm, angles σ 0.05°, σ 10 µm), the joint states' clock set
``--ms`` on (negative: back) at a share of the motion drawn in [0.3, 0.8] per seed, written to
a real MCAP file as a recorder writes it (each stream in the order sent) and read back, then
processed as ``dhlog process --nominal`` does; the FK error against the truth at 300 random
joint vectors within the limits, beside the same session in time (the same motion and
noise), and the step found against the one written.

    .venv/bin/python benchmarks/clock_step.py [--ms -200 -20 5 20 50] [--seeds 3] [--robots kr5 …]
        [--outliers 0.05]

2026-12-05, this machine, the defaults (the figures in docs/accuracy.md): see the printed
table.
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
from pathlib import Path

import numpy as np

from dhlog.identify.check.plausible import judge
from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.reader import read_log
from dhlog.io.writer import write_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session


def _error(result: Identification, session: Session, Q: np.ndarray) -> float:
    ex = result.extraction
    if ex is None:
        return math.inf
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    return float(np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ms", type=float, nargs="+", default=[-200.0, -20.0, 5.0, 20.0, 50.0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--robots", nargs="+", default=["kr5", "ur5", "puma560"])
    parser.add_argument("--outliers", type=float, default=0.0, help="share of gross outliers")
    args = parser.parse_args()
    print("robot      ms   error / in time, median [max]   step found − written (ms, max)   found")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.robots:
            robot = load_robot(name)
            names = tuple(f"joint_{i + 1}" for i in range(robot.n))
            nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, name)
            options = ProcessOptions(nominal=nominal)
            Q = np.random.default_rng(0).uniform(
                robot.limits[:, 0], robot.limits[:, 1], (300, robot.n)
            )
            in_time: dict[int, float] = {}
            for ms in args.ms:
                ratios, misses, found, implausible = [], [], 0, 0
                for seed in range(args.seeds):
                    at = float(np.random.default_rng(seed).uniform(0.3, 0.8))
                    base = {
                        "noise": 1e-5,
                        "perturb_length": 5e-4,
                        "perturb_angle": math.radians(0.05),
                        "seed": seed,
                        "outliers": args.outliers,
                    }
                    runs = [] if seed in in_time else [(0.0, True)]
                    for step, reference in [*runs, (ms * 1e-3, False)]:
                        cfg = SimulationConfig(**base, clock_step=step, clock_step_at=at)  # type: ignore[arg-type]
                        session = simulate_session(robot, cfg)
                        path = Path(tmp) / f"{name}_{seed}.mcap"
                        write_session(session, path)
                        result = judge(process_data(read_log(path), options))
                        error = _error(result, session, Q)
                        if reference:
                            in_time[seed] = error
                            continue
                        assert result.timing is not None
                        ratios.append(error / in_time[seed])
                        misses.append(abs(result.timing.step + step) * 1e3)
                        found += result.timing.step != 0.0
                        implausible += bool(result.implausible)
                print(
                    f"{name:8} {ms:6.0f}   {statistics.median(ratios):.3f} [{max(ratios):.3f}]"
                    f"                     {max(misses):8.3f}                     "
                    f"{found}/{args.seeds}"
                    + (f" ({implausible} implausible)" if implausible else "")
                )


if __name__ == "__main__":
    main()
