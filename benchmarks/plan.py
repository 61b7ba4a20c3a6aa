"""``dhlog plan``'s predictions against ``simulate`` + ``process`` of the same plan.

    .venv/bin/python benchmarks/plan.py [--robot kr5] [--poses 40] [--sessions 50]
                                        [--noise-mm 0.01] [--workers 2] [--select-sessions 20]

Part 1, σ: the plan (``--poses`` random static poses, seed 0) is made once on the nominal;
then ``--sessions`` realisations of the same poses on robots **off their nominal** (0.2 mm /
0.05° per DH parameter, a new robot each) are simulated, identified with ``--model geometric``
and the nominal, and compared with their own truth: each free DH parameter (in the shown form)
against the truth's (the same session without noise, identified the same way), and the FK at the
plan's 300 random joint vectors within the limits. Printed: σ_plan / RMS error per parameter
(median, range, how many within 15 %: the RMS over S sessions has a standard error of about
1/√(2S), 10 % at 50), and the FK: RMS predicted σ against the RMS error over all sessions.

Part 2, ``--select``: 40 of 500 random candidates chosen (D-optimal) and 40 drawn at random,
each replayed as a pose list (``simulate --poses``) over ``--select-sessions`` robots off their
nominal: the FK error measured against the one the plan predicts for each list.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from dhlog.cell.plan import WORKSPACE_POINTS, plan_session, select_poses
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.result.document import display_rows
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

OFF = {"perturb_length": 2e-4, "perturb_angle": math.radians(0.05)}
Poses = tuple[tuple[float, ...], ...]


def config(noise: float, poses: int, pose_list: Poses, seed: int, off: bool) -> SimulationConfig:
    return SimulationConfig(
        noise=noise,
        motion="step",
        protocol="random-poses",
        poses=poses,
        pose_list=pose_list,
        pose_seed=0,  # the same poses: one plan, other robots and noise
        seed=seed,
        **(OFF if off else {}),  # type: ignore[arg-type]
    )


def workspace(robot_name: str) -> np.ndarray:
    """The plan's joint vectors (:data:`dhlog.cell.plan.WORKSPACE_POINTS`, seeded as the plan)."""
    robot = load_robot(robot_name)
    return np.random.default_rng(0).uniform(
        robot.limits[:, 0], robot.limits[:, 1], (WORKSPACE_POINTS, robot.n)
    )


def one(job: tuple[str, float, int, Poses, int]) -> tuple[np.ndarray, np.ndarray]:
    """One realisation: the shown DH rows' errors against the truth's (4 columns a row) and the
    FK position errors (m, 3-D) at the plan's workspace vectors."""
    robot_name, noise, poses, pose_list, seed = job
    robot = load_robot(robot_name)
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)
    geometric = ModelRequest("geometric")
    cfg = config(noise, poses, pose_list, seed, off=True)
    session = simulate_session(robot, cfg)
    result = process_data(
        log_data_from_session(session), ProcessOptions(nominal=nominal, model=geometric)
    )
    clean = simulate_session(robot, SimulationConfig(**{**cfg.__dict__, "noise": 0.0}))
    truth = process_data(
        log_data_from_session(clean), ProcessOptions(nominal=nominal, model=geometric)
    )
    values = np.array([r.values for r in display_rows(result, "m")])
    diff = values - np.array([r.values for r in display_rows(truth, "m")])
    diff[:, [0, 3]] = (diff[:, [0, 3]] + math.pi) % (2 * math.pi) - math.pi
    Q = workspace(robot_name)
    ex = result.extraction
    assert ex is not None
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    return diff, np.linalg.norm(got - want, axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robot", default="kr5")
    parser.add_argument("--poses", type=int, default=40)
    parser.add_argument("--sessions", type=int, default=50)
    parser.add_argument("--select-sessions", type=int, default=20)
    parser.add_argument("--noise-mm", type=float, default=0.01)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    robot = load_robot(args.robot)
    noise = args.noise_mm * 1e-3
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        planned = plan_session(robot, config(noise, args.poses, (), 0, off=False))
        jobs = [(args.robot, noise, args.poses, (), 1000 + s) for s in range(args.sessions)]
        runs = list(pool.map(one, jobs))
        errors = np.array([d for d, _ in runs])
        rms = np.sqrt(np.mean(errors**2, axis=0))
        free = np.isfinite(planned.rows_std) & (rms > 0)
        ratio = planned.rows_std[free] / rms[free]
        fk_err = np.array([e for _, e in runs])
        fk_measured = math.sqrt(float(np.mean(fk_err**2)))
        fk_predicted = math.sqrt(float(np.mean(planned.fk_sd**2)))
        print(
            f"{args.robot} off its nominal (0.2 mm / 0.05°), {args.poses} random static poses, "
            f"{planned.samples} samples, σ {args.noise_mm} mm, {args.sessions} sessions"
        )
        print("σ_plan / RMS error per free parameter (rows θ, d|β, a, α):")
        print(np.where(free, planned.rows_std / np.where(rms > 0, rms, 1.0), np.nan).round(3))
        within = int(np.sum(np.abs(ratio - 1) <= 0.15))
        print(
            f"median {np.median(ratio):.3f}, range {ratio.min():.3f}–{ratio.max():.3f}, "
            f"{within} of {free.sum()} within 15 % (standard error of one ratio "
            f"{1 / math.sqrt(2 * args.sessions):.0%})"
        )
        print(
            f"FK at {WORKSPACE_POINTS} random joint vectors: predicted σ RMS "
            f"{fk_predicted * 1e6:.3f} µm, measured RMS error {fk_measured * 1e6:.3f} µm, "
            f"ratio {fk_predicted / fk_measured:.3f}"
        )

        C = np.random.default_rng(3).uniform(robot.limits[:, 0], robot.limits[:, 1], (500, robot.n))
        found = select_poses(robot, C, 40, noise)
        drawn = np.random.default_rng(11).choice(500, 40, replace=False)
        print(
            f"\n--select 40 of 500 random candidates ({found.singular} near a singularity), "
            f"{args.select_sessions} sessions each:"
        )
        print(
            f"  the selection's own figure (one sample a pose): {found.fk_sd_chosen * 1e6:.3f} "
            f"µm chosen, {found.fk_sd_random * 1e6:.3f} µm for 40 drawn at random"
        )
        for label, rows in (("D-optimal", found.chosen), ("random", list(drawn))):
            listed = tuple(tuple(float(v) for v in C[r]) for r in rows)
            plan = plan_session(robot, config(noise, 40, listed, 0, off=False))
            jobs = [(args.robot, noise, 40, listed, 2000 + s) for s in range(args.select_sessions)]
            err = np.array([e for _, e in pool.map(one, jobs)])
            measured = math.sqrt(float(np.mean(err**2)))
            predicted = math.sqrt(float(np.mean(plan.fk_sd**2)))
            print(
                f"  {label:9s}: predicted FK σ RMS {predicted * 1e6:.3f} µm, measured RMS "
                f"error {measured * 1e6:.3f} µm (ratio {predicted / measured:.3f})"
            )


if __name__ == "__main__":
    main()
