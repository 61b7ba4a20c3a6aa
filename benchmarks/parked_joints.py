"""Robots as built: FK against the truth for parked joints and chains of 7 joints.

    .venv/bin/python benchmarks/parked_joints.py [--sessions 4] [--poses 60] [--cases TEXT]

Each case simulates a library robot that is not its nominal (0.5 mm and 0.05° of geometric
error), a tracker of σ = 10 µm, no base points, and identifies it with the library table as the
nominal (``dhlog process --nominal``), in memory. Printed per case and over the seeded sessions:
the RMS FK error against the simulator's truth at 2000 random joint vectors within the limits
(a parked joint at its parked value, 0.3 rad or m), the fit's own predicted FK σ at the same
vectors (its covariance through the Jacobian: the statistical limit of the session) and their
ratio. The cases with ``/6R`` also fit the same samples as the 6-joint chain without the parked
row (the column left out, the row merged into the base: what a user did by hand), with no wander,
so the two are the same robot on the same data.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from dhlog.identify.fit.prediction import predict
from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames, fk_point
from dhlog.model.robots import Robot, load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

PARKED_AT = 0.3
#: name → (robot, protocol, parked joint (1-based) or 0, wander, compare with the 6-joint chain)
CASES: dict[str, tuple[str, str, int, float, bool]] = {
    "torso7 parked torso, random poses /6R": ("torso7", "random-poses", 1, 0.0, True),
    "torso7 parked torso (0.2 mrad wander), random poses": (
        "torso7",
        "random-poses",
        1,
        2e-4,
        False,
    ),
    "torso7 parked torso, sweeps": ("torso7", "sweeps", 1, 2e-4, False),
    "kr5rail parked rail, random poses": ("kr5rail", "random-poses", 1, 2e-4, False),
    "panda joint 3 locked, random poses": ("panda", "random-poses", 3, 2e-4, False),
    "panda (7-DoF), random poses": ("panda", "random-poses", 0, 0.0, False),
    "kr5rail (rail + 6R), random poses": ("kr5rail", "random-poses", 0, 0.0, False),
    "torso7 (torso + 6R), random poses": ("torso7", "random-poses", 0, 0.0, False),
}


def _nominal(robot: Robot) -> DHModel:
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    return DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)


def _rms(got: np.ndarray, want: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1))))


def _split(table: StandardDH, T_base: np.ndarray) -> tuple[StandardDH, np.ndarray]:
    """The chain without row 1, that row at PARKED_AT merged into the base."""

    def rows(sl: slice) -> StandardDH:
        return StandardDH(
            table.joint_types[sl], table.theta_offset[sl], table.d_offset[sl], table.a[sl],
            table.alpha[sl],
        )  # fmt: skip

    return rows(slice(1, None)), fk_frames(rows(slice(0, 1)), np.array([PARKED_AT]), T_base=T_base)[
        -1
    ]


def _six(session: Session, robot: Robot, Q: np.ndarray) -> float:
    table, T_base = _split(session.table, session.T_measurement_base)
    reduced = replace(
        session,
        joint_q=session.joint_q[:, 1:],
        joint_names=session.joint_names[1:],
        joint_types=session.joint_types[1:],
        table=table,
        T_measurement_base=T_base,
        reference_pose=session.reference_pose[1:],
        sweeps=session.sweeps[1:],
        poses=session.poses[:, 1:],
    )
    nt, nb = _split(robot.table, robot.T_base)
    nominal = DHModel(nt, nb, robot.tool_point, tuple(reduced.joint_names), "6R")
    ex = process_data(log_data_from_session(reduced), ProcessOptions(nominal=nominal)).extraction
    assert ex is not None
    got = fk_point(ex.standard, Q[:, 1:], ex.tool_point, T_base=ex.T_measurement_base)
    return _rms(got, fk_point(table, Q[:, 1:], session.tool_point, T_base=T_base))


def _predicted(result: Identification, Q: np.ndarray) -> float:
    w = result.whole
    assert w is not None
    _, J = predict(w.model, Q, w.layout, w.bases)
    assert J is not None
    return math.sqrt(float(np.mean(np.einsum("mij,jk,mik->m", J, w.covariance, J))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sessions", type=int, default=4)
    parser.add_argument("--poses", type=int, default=60)
    parser.add_argument("--cases", default="")
    args = parser.parse_args()
    for name, (robot_name, protocol, joint, wander, six) in CASES.items():
        if args.cases not in name:
            continue
        robot = load_robot(robot_name)
        errors, limits, sixes = [], [], []
        for seed in range(args.sessions):
            cfg = SimulationConfig(
                seed=seed,
                noise=1e-5,
                perturb_length=5e-4,
                perturb_angle=math.radians(0.05),
                base_points=0,
                protocol=protocol,  # type: ignore[arg-type]
                poses=args.poses,
                parked=((joint, PARKED_AT),) if joint else (),
                park_wander=wander,
            )
            session = simulate_session(robot, cfg)
            result = process_data(
                log_data_from_session(session), ProcessOptions(nominal=_nominal(robot))
            )
            ex = result.extraction
            assert ex is not None and result.complete, result.warnings
            Q = np.random.default_rng(99).uniform(
                robot.limits[:, 0], robot.limits[:, 1], (2000, robot.n)
            )
            if joint:
                Q[:, joint - 1] = PARKED_AT
            got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
            want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
            errors.append(_rms(got, want))
            limits.append(_predicted(result, Q))
            if six:
                sixes.append(_six(session, robot, Q))
        e, lim = np.array(errors) * 1e6, np.array(limits) * 1e6
        line = (
            f"{name}: FK RMS vs truth {np.sqrt(np.mean(e**2)):.2f} µm "
            f"(sessions {', '.join(f'{v:.2f}' for v in e)}); predicted σ "
            f"{np.sqrt(np.mean(lim**2)):.2f} µm; ratio "
            f"{np.sqrt(np.mean(e**2) / np.mean(lim**2)):.2f}"
        )
        if sixes:
            s = np.array(sixes) * 1e6
            line += f"; the 6-joint chain without the row {np.sqrt(np.mean(s**2)):.2f} µm"
        print(line, flush=True)


if __name__ == "__main__":
    main()
