"""``--validate`` of task sessions along a path against the truth (issue 39, item 1).

    PYTHONPATH=src .venv/bin/python benchmarks/validate_paths.py [--code SRC] [--noise-um 10]
        [--out DIR]

A KR5 off its nominal (0.2 mm, 0.05°) calibrated from 60 random still poses with a 6-DoF probe
(σ 10 µm, 0.17 mrad; ``dhlog simulate --protocol random-poses --six-dof``), then measured along
a 400 mm line (300 poses) and a planar S-curve (500 poses) at one orientation, and at 60 random
poses, each after the tracker was re-stationed (0.61 m, 125°) and the probe re-mounted (0.955
mm, 1.6°): ``dhlog simulate --protocol line|curve --restation --remount``. The sessions are
written with this checkout's simulator; ``dhlog process cal.mcap --nominal kr5 --validate ...``
runs with the dhlog under ``--code`` (default: this checkout's ``src``; give another tree's
``src`` to measure it). Printed per log: the nominal's and the result's held-out RMS as dhlog
reports it and their error against the noise-free truth, computed here (each model placed by
least squares on every third pose of the truth — base and probe frame, the tool point where the
orientation varies — and scored at the others); the result's with the tracker's noise in a
pose's mean added in quadrature (σ √3 over √ samples a pose: the part of the held-out figure
that is the instrument's, not the model's).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from dhlog.geometry._checks import rotation_from_vector
from dhlog.io.dhfile import parse_dh
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SIX_DOF_TOOL_ROTATION
from dhlog.simulator.session import Session

PIPELINE = (
    'name = "six_dof"\nencoding = "cdr"\n[streams.point]\ntopic = "/tracker/point"\n'
    'orientation = true\n[streams.joints]\ntopic = "/joint_states"\n'
)


def truth_error(
    table: StandardDH, T: np.ndarray, tool: np.ndarray, R_tool: np.ndarray, s: Session
) -> float:
    """RMS (m) of the model's 3-D error against the noise-free truth at the poses not placed on
    (the model placed on every third pose by least squares: base, probe frame with 1 mrad as
    0.1 mm, and the tool point where the flange's orientation varies)."""
    assert s.tool_rotation is not None
    true = fk_frames(s.table, s.poses, T_base=s.T_measurement_base)[:, -1]
    P = np.einsum("kij,j->ki", true[:, :3, :3], s.tool_point) + true[:, :3, 3]
    R = true[:, :3, :3] @ s.tool_rotation
    F = fk_frames(table, s.poses)[:, -1]
    on = np.zeros(len(P), dtype=bool)
    on[::3] = True
    free_tool = s.config.protocol == "random-poses"

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        B = np.eye(4)
        B[:3, :3] = rotation_from_vector(x[:3]) @ T[:3, :3]
        B[:3, 3] = T[:3, 3] + x[3:6]
        return B, tool + (x[9:12] if free_tool else 0.0), R_tool @ rotation_from_vector(x[6:9])

    def position(x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        B, t, _ = unpack(x)
        local = np.einsum("kij,j->ki", F[rows, :3, :3], t) + F[rows, :3, 3]
        return np.asarray(local @ B[:3, :3].T + B[:3, 3])

    def miss(x: np.ndarray) -> np.ndarray:
        B, _, Rt = unpack(x)
        turn = np.einsum(
            "kji,kjl->kil", R[on], np.einsum("ij,kjl,lm->kim", B[:3, :3], F[on, :3, :3], Rt)
        )
        skew = 0.5 * np.stack(
            [
                turn[:, 2, 1] - turn[:, 1, 2],
                turn[:, 0, 2] - turn[:, 2, 0],
                turn[:, 1, 0] - turn[:, 0, 1],
            ],
            axis=1,
        )
        return np.concatenate([(position(x, on) - P[on]).ravel(), 0.1 * skew.ravel()])

    x = least_squares(miss, np.zeros(12 if free_tool else 9), x_scale="jac").x
    return float(np.sqrt(np.mean(np.sum((position(x, ~on) - P[~on]) ** 2, axis=1))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--code", type=Path, default=Path(__file__).parents[1] / "src")
    parser.add_argument("--noise-um", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    import math

    from dhlog.io.writer import write_session
    from dhlog.simulator.config import SimulationConfig
    from dhlog.simulator.session import simulate_session

    folder = args.out or Path(tempfile.mkdtemp())
    folder.mkdir(parents=True, exist_ok=True)
    robot = load_robot("kr5")
    common = {
        "tool_rotation": SIX_DOF_TOOL_ROTATION,
        "orientation_noise": math.radians(0.01),
        "noise": args.noise_um * 1e-6,
        "tracker_rate": 10.0,
        "joint_rate": 100.0,
        "perturb_length": 2e-4,
        "perturb_angle": math.radians(0.05),
        "seed": 5,
    }
    cal = simulate_session(robot, SimulationConfig(protocol="random-poses", poses=60, **common))
    write_session(cal, folder / "cal.mcap", point_type="pose")
    moved = {"restation": True, "remount": True}
    plans = {
        "line": {"protocol": "line", "poses": 300},
        "curve": {"protocol": "curve", "poses": 500},
        "random": {"protocol": "random-poses", "poses": 60, "pose_seed": 6},
    }
    sessions = {}
    for name, plan in plans.items():
        cfg = SimulationConfig(**{**common, **moved, **plan})
        sessions[name] = simulate_session(robot, cfg)
        assert np.array_equal(sessions[name].table.a, cal.table.a)  # the same robot
        write_session(sessions[name], folder / f"{name}.mcap", point_type="pose")
    (folder / "six.toml").write_text(PIPELINE)
    command = [
        sys.executable, "-m", "dhlog", "process", str(folder / "cal.mcap"), "--pipeline",
        str(folder / "six.toml"), "--nominal", "kr5", "--model", "geometric", "--no-rrd",
        "--force", "--out", str(folder / "out"),
        *[a for name in plans for a in ("--validate", str(folder / f"{name}.mcap"))],
    ]  # fmt: skip
    env = dict(os.environ, PYTHONPATH=str(args.code))
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    print(f"dhlog from {args.code}: exit {done.returncode}")
    doc = json.loads((folder / "out" / "cal.dh.json").read_text())
    model = parse_dh(doc, "cal.dh.json")
    R_result = np.array(doc["tool"]["orientation"]["matrix"])
    T_cal = cal.T_measurement_base
    for name, s in sessions.items():
        assert s.tool_rotation is not None
        entry = next(
            (h for h in doc["validation"].get("holdout", []) if h["path"].endswith(f"{name}.mcap")),
            None,
        )
        move = s.T_measurement_base @ np.linalg.inv(T_cal)
        turn = rotation_from_vector(-np.asarray(SIX_DOF_TOOL_ROTATION)) @ s.tool_rotation
        shift = s.tool_point - robot.tool_point
        t_nom = truth_error(robot.table, s.T_measurement_base, s.tool_point, s.tool_rotation, s)
        t_cal = truth_error(
            model.table, move @ model.T_base, model.tool_point + shift, R_result @ turn, s
        )
        if entry is None:
            print(
                f"{name}: not scored; truth nominal {t_nom * 1e3:.4f} mm, result {t_cal * 1e3:.4f}"
            )
            continue
        # the tracker's noise in a pose's mean (3-D): what the held-out figure adds to the truth's
        noise = args.noise_um * 1e-6 * np.sqrt(3.0 * len(s.poses) / len(s.point_xyz))
        t_cal = float(np.hypot(t_cal, noise))
        nom = entry["nominal"]["rms"] if entry["nominal"] else float("nan")
        cal_rms = entry["calibrated"]["rms"]
        print(
            f"{name:7s} dhlog nominal {nom * 1e3:9.4f} mm  result {cal_rms * 1e3:9.4f} mm | "
            f"truth nominal {t_nom * 1e3:.4f} mm  result ⊕ noise {t_cal * 1e3:.4f} mm | "
            f"ratio {nom / t_nom:.3f} {cal_rms / t_cal:.3f}"
        )


if __name__ == "__main__":
    main()
