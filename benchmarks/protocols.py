"""Issue 17's protocols against the achievable limit, over many seeded sessions.

    .venv/bin/python benchmarks/protocols.py [--sessions 20] [--workers 2] [--points 300]
                                             [--cases SUBSTRING] [--holdout 5]

Every case is a robot **off its nominal** (lengths σ 0.2 mm, angles σ 0.05°: nearly parallel
axes) identified by ``dhlog process`` with the robot's library table as the nominal:

* random: a KR5 at 40 random static poses, one tracker point a pose (σ 10 µm), a 6-DoF probe
  (orientation σ 0.005°) and 60 µm of unmodelled smooth error;
* random × 5: the same without the probe, five tracker samples a pose (they share the pose's
  error: the design effect);
* coupled: a KR5 with 8 stops per joint, joint 2 moved only together with joint 3 (q3 = −q2);
* ur5: a UR5 swept joint by joint, 100 Hz tracker, σ 20 µm.

For each session: the RMS FK error against the simulator's truth at ``--points`` random joint
vectors within the limits, of the default result and of the limit (the whole model fitted to the
same samples — and the same measured orientations — started from the truth, positions weighted
by the tracker's σ and the unmodelled error's together); the predicted σ of
that FK error (``fk_prediction_std``) against the error itself; and with ``--holdout K`` the
K-fold held-out RMS of the nominal and of the calibrated model. Printed per case: default and
limit [µm], their ratio (target ≤ 1.05), the σ ratio (RMS error / RMS predicted σ; target within
15 % of 1), held-out before → after [mm] and the in-sample FK RMS [mm].
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from dhlog.identify.check.validate import fk_prediction_std
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.samples import measured_rotations
from dhlog.identify.fit.whole import fit_whole_model
from dhlog.identify.joints.sweeps import samples_with_encoders
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.noise import NoiseModel
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SIX_DOF_TOOL_ROTATION, SimulationConfig
from dhlog.simulator.session import simulate_session

OFF = {"perturb_length": 2e-4, "perturb_angle": math.radians(0.05)}

CASES: dict[str, tuple[str, dict[str, object]]] = {
    "KR5, 40 random static poses, 6-DoF probe, σ 10 µm + 60 µm unmodelled": (
        "kr5",
        {
            "protocol": "random-poses",
            "poses": 40,
            "noise": 1e-5,
            "model_error": 6e-5,
            "dwell": 0.5,
            "tracker_rate": 2.0,
            "tool_rotation": SIX_DOF_TOOL_ROTATION,
            "orientation_noise": math.radians(0.005),
            **OFF,
        },
    ),
    "KR5, 40 random static poses × 5 samples, σ 10 µm + 60 µm unmodelled": (
        "kr5",
        {
            "protocol": "random-poses",
            "poses": 40,
            "noise": 1e-5,
            "model_error": 6e-5,
            "dwell": 0.5,
            "tracker_rate": 10.0,
            **OFF,
        },
    ),
    "KR5, coupled protocol (joint 2 only with joint 3, q3 = −q2), 8 stops per joint, σ 10 µm": (
        "kr5",
        {
            "protocol": "coupled",
            "steps": 8,
            "noise": 1e-5,
            "dwell": 0.3,
            "tracker_rate": 10.0,
            **OFF,
        },
    ),
    "UR5 off its nominal, 100 Hz tracker, σ 20 µm": (
        "ur5",
        {"noise": 2e-5, "tracker_rate": 100.0, **OFF},
    ),
}


def one(job: tuple[str, int, int, int]) -> dict[str, float]:
    """One seeded session of a case: squared errors' sums and counts, and the held-out RMS."""
    case, seed, points, holdout = job
    robot_name, options = CASES[case]
    robot = load_robot(robot_name)
    cfg = SimulationConfig(seed=seed, **options)  # type: ignore[arg-type]
    session = simulate_session(robot, cfg)
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, robot_name)
    result = process_data(
        log_data_from_session(session), ProcessOptions(nominal=nominal, holdout=holdout)
    )
    rng = np.random.default_rng(seed + 1)
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (points, robot.n))
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    ex = result.extraction
    assert ex is not None and result.complete, result.warnings
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    sd = fk_prediction_std(result, Q)
    ref = result.reference_pose
    T = session.T_measurement_base
    rows, Qs, Ps = samples_with_encoders(result.segmentation)
    rotations = measured_rotations(result.segmentation, rows)
    truth = AxisModel.of_table(
        session.table,
        ref,
        session.tool_point,
        T,
        tool_rotation=session.tool_rotation if rotations is not None else None,
    )
    # the limit weighs positions by what scatters them: the tracker and the unmodelled error
    sigma = math.hypot(cfg.noise, cfg.model_error)
    limit = fit_whole_model(
        truth, FitData(Qs, Ps, rotations=rotations), FitOptions(NoiseModel(), sigma)
    )
    best, _ = predict(limit.model, Q)
    out = {
        "default": float(np.sum((got - want) ** 2)),
        "limit": float(np.sum((best - want) ** 2)),
        "sigma": float(np.sum(sd**2)),
        "n": float(points),
        "in_sample": float(result.validation.rms) if result.validation is not None else math.nan,
    }
    if result.holdout:
        h = result.holdout[0]
        out["before"] = h.nominal.rms if h.nominal is not None else math.nan
        out["after"] = h.calibrated.rms
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sessions", type=int, default=20)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--points", type=int, default=300)
    parser.add_argument("--cases", default="")
    parser.add_argument("--holdout", type=int, default=5)
    args = parser.parse_args()
    context = multiprocessing.get_context("spawn")
    print(
        "| case | sessions | default [µm] | limit [µm] | default / limit | σ ratio | "
        "held-out nominal → calibrated [mm] | in-sample FK RMS [mm] |"
    )
    print("|---|---|---|---|---|---|---|---|")
    with ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        for case in CASES:
            if args.cases not in case:
                continue
            started = time.perf_counter()
            jobs = [(case, 9000 + s, args.points, args.holdout) for s in range(args.sessions)]
            out = list(pool.map(one, jobs))
            n = sum(o["n"] for o in out)
            rms = {k: math.sqrt(sum(o[k] for o in out) / n) for k in ("default", "limit", "sigma")}
            held = ""
            if args.holdout:
                before = math.sqrt(float(np.mean([o["before"] ** 2 for o in out])))
                after = math.sqrt(float(np.mean([o["after"] ** 2 for o in out])))
                held = f"{before * 1e3:.4f} → {after * 1e3:.4f}"
            in_sample = math.sqrt(float(np.mean([o["in_sample"] ** 2 for o in out])))
            print(
                f"| {case} | {args.sessions} | {rms['default'] * 1e6:.1f} | "
                f"{rms['limit'] * 1e6:.1f} | {rms['default'] / rms['limit']:.3f} | "
                f"{rms['default'] / rms['sigma']:.3f} | {held} | {in_sample * 1e3:.4f} |",
                flush=True,
            )
            ratios = [math.sqrt(o["default"] / o["limit"]) for o in out]
            print(
                f"<!-- {time.perf_counter() - started:.0f} s; per-session default / limit "
                f"{min(ratios):.3f}–{max(ratios):.3f} -->",
                flush=True,
            )


if __name__ == "__main__":
    main()
