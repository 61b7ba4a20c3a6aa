"""The program filter on a simulated pick-and-place cell: how close, how continuous.

    .venv/bin/python benchmarks/program_filter.py [--seeds 5] [--robot ur5e]

Per seed: a UR-style robot 0.5 mm / 0.05° off its nominal is simulated (sweeps, 10 µm tracker
noise) and identified with ``--nominal``; a URScript program of 22 ``movel`` poses (a gripper
100 mm along the flange's z, above / 46 mm above / at a pick and a place spot, a transfer,
twice) is filtered by ``dhlog compensate --program``. The corrected program is then run as the
controller would: each commanded pose (as computed; the program's text carries 1e-10 m and rad)
through the nominal's inverse kinematics from the previous joints. Printed: the largest distance
(µm) and rotation (µrad) of the calibrated TCP from the original targets there (before: the
uncorrected program's), the flips (changes of the sign of the Jacobian's determinant between
neighbours), the largest joint step between neighbours and at the 46 mm pairs; and, solved each
pose alone (the earlier ``--poses``), the flips and the largest step.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dhlog.cell.compensate import compensate_poses
from dhlog.cell.programs import filtered, read
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel, parse_dh
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_frames
from dhlog.model.ik import solve, tool_jacobian
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

TCP = np.eye(4)
TCP[2, 3] = 0.1
START = [0.35, -1.3, 1.6, 1.3, 1.5708, -1.2]


def poses() -> list[np.ndarray]:
    down = Rotation.from_rotvec([math.pi, 0, 0])
    spots = [(-0.40, -0.30, 0.05, 0.0), (-0.45, 0.25, 0.05, 30.0)]
    out = []
    for _ in range(2):
        for x, y, z, yaw in spots:
            for dz in (0.2, 0.046, 0.0, 0.046, 0.2):
                out.append((x, y, z + dz, yaw))
        out.append((-0.55, -0.02, 0.3, 15.0))
    Ts = []
    for x, y, z, yaw in out:
        T = np.eye(4)
        T[:3, :3] = (Rotation.from_euler("z", yaw, degrees=True) * down).as_matrix()
        T[:3, 3] = x, y, z
        Ts.append(T)
    return Ts


def script(targets: list[np.ndarray]) -> str:
    lines = ["def cell():", "  set_tcp(p[0, 0, 0.1, 0, 0, 0])"]
    lines.append(f"  movej([{', '.join(str(v) for v in START)}])")
    for T in targets:
        r = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        lines.append(f"  movel(p[{', '.join(f'{v:.12f}' for v in (*T[:3, 3], *r))}])")
    return "\n".join([*lines, "end", ""])


def controller(nominal: DHModel, commanded: list[np.ndarray], q0: np.ndarray) -> np.ndarray:
    q, out = q0, []
    for T in commanded:
        found = solve(nominal.table, (T @ np.linalg.inv(TCP))[None], q[None], np.zeros(3))
        q = found.q[0]
        out.append(q)
    return np.array(out)


def miss(model: DHModel, q: np.ndarray, goal: list[np.ndarray]) -> tuple[float, float]:
    T = fk_frames(model.table, model.joint_values(q))[:, -1] @ TCP
    G = np.array(goal)
    dp = np.linalg.norm(T[:, :3, 3] - G[:, :3, 3], axis=1).max()
    dr = Rotation.from_matrix(np.einsum("mij,mkj->mik", T[:, :3, :3], G[:, :3, :3])).magnitude()
    return float(dp), float(dr.max())


def flips(nominal: DHModel, q: np.ndarray) -> int:
    J = tool_jacobian(nominal.table, q, np.zeros(3), T_base=nominal.T_base)
    s = np.sign(np.linalg.det(J))
    return int(np.sum(s[1:] != s[:-1]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--robot", default="ur5e")
    args = parser.parse_args()
    rob = load_robot(args.robot)
    nominal = DHModel(rob.table, rob.T_base, rob.tool_point, rob.joint_names, args.robot)
    goal = poses()
    print("seed  before µm  after µm  after µrad  flips  step°  46mm step°  alone: flips  step°")
    for seed in range(args.seeds):
        cfg = SimulationConfig(
            perturb_length=5e-4, perturb_angle=math.radians(0.05), seed=seed, noise=1e-5
        )
        session = simulate_session(rob, cfg)
        doc = json.loads(
            json.dumps(
                result_document(
                    process_data(log_data_from_session(session), ProcessOptions(nominal=nominal))
                )
            )
        )
        model = parse_dh(doc, f"seed {seed}")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "cell.script"
            path.write_text(script(goal))
            done = filtered(read(path, "urscript", 6, None), model, nominal, limits=rob.limits)
        assert not done.problems, done.problems
        q0 = done.filtered.joints[0]
        commanded = list(done.filtered.commanded[1:])
        q = controller(nominal, commanded, q0)
        raw = controller(nominal, goal, np.array(START))
        before = miss(model, raw, goal)[0]
        dp, dr = miss(model, q, goal)
        steps = np.degrees(np.abs(np.diff(np.vstack([q0, q]), axis=0)).max(axis=1))
        flanges = np.array([T @ np.linalg.inv(TCP) for T in goal])
        alone = compensate_poses(model, nominal, flanges, limits=rob.limits)[0].targets
        alone_steps = np.degrees(np.abs(np.diff(alone, axis=0)).max(axis=1))
        print(
            f"{seed:4d}  {before * 1e6:9.1f}  {dp * 1e6:8.2g}  {dr * 1e6:10.2g}  "
            f"{flips(nominal, np.vstack([q0, q])):5d}  {steps.max():5.1f}  "
            f"{steps[[2, 3, 7, 8]].max():10.2f}  {flips(nominal, alone):12d}  "
            f"{alone_steps.max():5.1f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
