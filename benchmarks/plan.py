"""``dhlog plan``'s predicted σ against the spread of ``simulate`` + ``process`` over the same plan.

    .venv/bin/python benchmarks/plan.py [--robot kr5] [--protocol random-poses] [--poses 40]
                                        [--sessions 20] [--noise-mm 0.01]

The plan is made once (seed 0); then ``--sessions`` other realisations of the same plan (the same
poses, other noise) are identified with
``--model geometric`` and each free DH parameter's RMS error against the nominal truth is compared
with the plan's σ. Printed: per parameter the ratio σ_plan / RMS error, and their median and range
(the standard error of an RMS over 20 sessions is about 16 %).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from dhlog.dhfile import DHModel
from dhlog.identify.select import ModelRequest
from dhlog.io.memory import log_data_from_session
from dhlog.plan import plan_session
from dhlog.process import process_data
from dhlog.result import display_rows
from dhlog.robots import load_robot
from dhlog.simulate import SimulationConfig, simulate_session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robot", default="kr5")
    parser.add_argument("--protocol", default="random-poses")
    parser.add_argument("--poses", type=int, default=40)
    parser.add_argument("--sessions", type=int, default=20)
    parser.add_argument("--noise-mm", type=float, default=0.01)
    args = parser.parse_args()
    robot = load_robot(args.robot)

    def config(seed: int) -> SimulationConfig:
        return SimulationConfig(
            noise=args.noise_mm * 1e-3,
            motion="step",
            protocol=args.protocol,
            poses=args.poses,
            pose_seed=0,  # the same poses: one plan, other noise
            seed=seed,
        )

    planned = plan_session(robot, config(0))
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)
    truth = None
    errors = []
    for s in range(1, args.sessions + 1):
        session = simulate_session(robot, config(1000 + s))
        result = process_data(
            log_data_from_session(session), nominal=nominal, model=ModelRequest("geometric")
        )
        rows = display_rows(result, "m")
        values = np.array([r.values for r in rows])
        if truth is None:  # the nominal in the shown form: a session without noise
            clean = simulate_session(
                robot, SimulationConfig(**{**config(1000 + s).__dict__, "noise": 0.0})
            )
            truth_result = process_data(
                log_data_from_session(clean), nominal=nominal, model=ModelRequest("geometric")
            )
            truth = np.array([r.values for r in display_rows(truth_result, "m")])
        diff = values - truth
        diff[:, [0, 3]] = (diff[:, [0, 3]] + math.pi) % (2 * math.pi) - math.pi
        errors.append(diff)
    rms = np.sqrt(np.mean(np.array(errors) ** 2, axis=0))
    free = np.isfinite(planned.rows_std) & (rms > 0)
    ratio = planned.rows_std[free] / rms[free]
    print(
        f"{args.robot}, {args.protocol}, {planned.samples} samples at {planned.poses} poses, "
        f"σ {args.noise_mm} mm, {args.sessions} sessions"
    )
    print("σ_plan / RMS error per free parameter (rows θ, d|β, a, α):")
    print(np.where(free, planned.rows_std / np.where(rms > 0, rms, 1.0), np.nan).round(3))
    print(
        f"median {np.median(ratio):.3f}, range {ratio.min():.3f}–{ratio.max():.3f}, "
        f"{free.sum()} parameters"
    )


if __name__ == "__main__":
    main()
