"""Does the coarse clock match (``dhlog.identify.segment.clocks``) find joint states seconds off
the tracker's, and leave sessions in time alone? Simulated sessions of four robots (KR5, PUMA 560,
UR5, SCARA) at 30 and 100 Hz, three protocols (sweeps, coupled, random poses), with and without
5 % gross outliers, three seeds each: 132 sessions, each off its nominal (0.2 mm, 0.02°).

    .venv/bin/python benchmarks/clock_match.py [--offset 2.0] [--without-nominal]

Prints the sessions, how many the match moved, and every one it moved to a wrong offset (more
than 50 ms from the simulated one; with ``--offset 0``, any move of 0.1 s or more).

2026-12-04, this machine: with the nominal, ``--offset 2``: 132 of 132 found, none wrong;
``--offset 0``: none moved. Without it: ``--offset 2`` 28 found (the KR5's and the SCARA's
sweeps, mostly), none wrong; ``--offset 0`` none moved.
"""

from __future__ import annotations

import argparse
import itertools
import math

from dhlog.identify.fit.register import nominal_judge
from dhlog.identify.segment.clocks import COARSE_BELOW, coarse_offset
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--offset", type=float, default=2.0)
    parser.add_argument("--without-nominal", action="store_true")
    args = parser.parse_args()
    total = moved = wrong = 0
    cases = itertools.product(
        ["kr5", "puma560", "ur5", "scara"],
        [30.0, 100.0],
        [0.0, 0.05],
        ["sweeps", "coupled", "random-poses"],
        range(3),
    )
    for name, rate, outliers, protocol, seed in cases:
        if protocol == "coupled" and name == "scara":
            continue
        robot = load_robot(name)
        names = tuple(f"joint_{i + 1}" for i in range(robot.n))
        nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, name)
        cfg = SimulationConfig(
            seed=500 + seed,
            noise=2e-5,
            tracker_rate=rate,
            outliers=outliers,
            protocol=protocol,  # type: ignore[arg-type]
            clock_offset=args.offset,
            perturb_length=2e-4,
            perturb_angle=math.radians(0.02),
            **({"poses": 30} if protocol == "random-poses" else {}),  # type: ignore[arg-type]
        )
        log = log_data_from_session(simulate_session(robot, cfg))
        found = coarse_offset(log, None if args.without_nominal else nominal_judge(log, nominal))
        total += 1
        if found is None or abs(found) < COARSE_BELOW:
            continue
        moved += 1
        if abs(found - args.offset) > 0.05:
            wrong += 1
            print(
                f"wrong: {name} {rate:g} Hz {protocol}, outliers {outliers}, seed {seed}: {found}"
            )
    print(f"offset {args.offset:g} s: {total} sessions, {moved} moved, {wrong} wrongly")


if __name__ == "__main__":
    main()
