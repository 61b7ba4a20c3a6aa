"""Write a simulated random-pose session as a laser tracker program's CSV export with a 6-DoF
probe (the sample for the README's "Random poses" walkthrough) and its truth:

    python sample_logs/make_random_poses_csv.py sample_logs/kr5_random_poses.csv

A KUKA KR5 off its nominal (lengths σ 0.2 mm, angles σ 0.05°) leaving 0.03 mm of unmodelled
error (what gravity and gears leave a geometric model), measured at 40 random static poses
within its joint limits by a tracker of σ 0.01 mm with a 6-DoF probe (orientation σ 0.005°), one
point a pose. The export as Tracker-Pilot-style software writes it: `;`-separated, a header with
units in brackets, the 3-D U95 to 1 µm (the probe's stated uncertainty, 1–10 µm, far below what
the robot leaves; at least 0.001: an export writing 0.000 is refused by ``dhlog import``), the
probe's orientation as a unit quaternion
`Q0 Q1 Q2 Q3` (scalar first), and the controller's joint values `j1 … j6` in degrees beside it.
The truth goes to `<stem>.truth.json` (the result contract's shape).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dhlog import __version__
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SIX_DOF_TOOL_ROTATION, SimulationConfig
from dhlog.simulator.session import simulate_session
from dhlog.simulator.truth import truth_document

CONFIG = SimulationConfig(
    seed=31,
    protocol="random-poses",
    poses=40,
    noise=1e-5,
    model_error=3e-5,
    dwell=0.5,
    tracker_rate=2.0,  # one point a pose, as the export has
    perturb_length=2e-4,
    perturb_angle=math.radians(0.05),
    tool_rotation=SIX_DOF_TOOL_ROTATION,
    orientation_noise=math.radians(0.005),
    base_points=0,
)


def main(csv_path: str) -> None:
    robot = load_robot("kr5")
    session = simulate_session(robot, CONFIG)
    assert session.point_rotation is not None and session.poses.shape[0] == CONFIG.poses
    xyz = session.point_xyz * 1e3
    # the joint values at each point: the still pose it was measured at
    t = (session.point_t_ns - session.point_t_ns[0]).astype(float)
    jt = (session.joint_t_ns - session.point_t_ns[0]).astype(float)
    q = np.column_stack([np.interp(t, jt, session.joint_q[:, k]) for k in range(robot.n)])
    quat = Rotation.from_matrix(session.point_rotation).as_quat(canonical=True)  # x, y, z, w
    rng = np.random.default_rng(CONFIG.seed)
    u95 = rng.uniform(0.0003, 0.010, xyz.shape[0])  # mm, rounded to 1 µm below
    head = ["Point Name", "X [mm]", "Y [mm]", "Z [mm]", "U(95)  [mm]", "Q0", "Q1", "Q2", "Q3"]
    head += [f"j{k + 1}" for k in range(robot.n)]
    lines = [";".join(head)]
    for k in range(xyz.shape[0]):
        w, x, y, z = quat[k, 3], quat[k, 0], quat[k, 1], quat[k, 2]
        u = max(round(float(np.asarray(u95)[k]), 3), 0.001)
        cells = [f"P{k + 1:03d}", *(f"{v:.4f}" for v in xyz[k]), f"{u:.3f}"]
        cells += [f"{v:.8f}" for v in (w, x, y, z)]
        cells += [f"{v:.4f}" for v in np.degrees(q[k])]
        lines.append(";".join(cells))
    out = Path(csv_path)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    truth = truth_document(
        session, source_path=out.name, sha256="", pipeline="import", version=__version__
    )
    truth_path = out.with_name(out.name.removesuffix(".csv") + ".truth.json")
    truth_path.write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main(sys.argv[1])
