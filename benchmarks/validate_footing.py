"""``--validate`` on one footing: the nominal's and the calibrated model's held-out RMS at a
session measured after the probe was re-mounted (issue 31, item 3), and after the tracker moved.

    .venv/bin/python benchmarks/validate_footing.py [--seeds 3] [--model auto|geometric]
                                                    [--perturb-mm 0.05] [--perturb-deg 0.01]
    PYTHONPATH=/path/to/other/src .venv/bin/python benchmarks/validate_footing.py   # another tree

A KR5 off its nominal (σ ``--perturb-mm`` 0.05 mm, ``--perturb-deg`` 0.01°: a robot close to
its table, whose nominal misses by a few tenths of a millimetre) calibrated from 40 random still
poses (tracker σ 10 µm), position-only and then with a 6-DoF probe (its orientation too, σ 0.2
mrad, read with ``orientation = true``); the same robot measured again at 30 other poses with
the probe re-mounted (its point moved 0.95 mm on the flange, its frame turned 1.6°), and at 30
after the tracker moved (0.5 m). Each session is written as MCAP and calibrated with
``process_log(..., validate=[...])`` as ``dhlog process LOG --nominal kr5 --validate OTHER.mcap``
does. Printed per case and seed: the nominal's and the
calibrated model's held-out RMS (mm), the poses scored, and what was placed again.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import ProcessOptions, process_log
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import parse_pipeline
from dhlog.io.writer import write_session
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session
from dhlog.simulator.tracker import default_measurement_pose

ROTATION = (0.3, -0.2, 0.5)
SIX_DOF = (
    'name = "six_dof"\nencoding = "cdr"\n[streams.point]\ntopic = "/tracker/point"\n'
    'orientation = true\n[streams.joints]\ntopic = "/joint_states"\n'
)
#: the re-mount: the probe's point moved 0.95 mm on the flange, its frame turned 1.6°
SHIFT = np.array([0.6e-3, 0.5e-3, 0.55e-3])
TURN = math.radians(1.6) * np.array([0.0, 0.6, 0.8])


def run(seed: int, six_dof: bool, args: argparse.Namespace, folder: Path) -> None:
    robot = load_robot("kr5")
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, "kr5")
    common: dict[str, object] = {
        "protocol": "random-poses",
        "noise": 1e-5,
        "dwell": 0.5,
        "tracker_rate": 2.0,
    }
    if six_dof:
        common.update(tool_rotation=ROTATION, orientation_noise=2e-4)
    cal = simulate_session(
        robot,
        SimulationConfig(
            seed=seed,
            poses=40,
            perturb_length=args.perturb_mm * 1e-3,
            perturb_angle=math.radians(args.perturb_deg),
            **common,  # type: ignore[arg-type]
        ),
    )
    write_session(cal, folder / "cal.mcap")
    same = dataclasses.replace(robot, table=cal.table)
    turned = Rotation.from_rotvec(ROTATION) * Rotation.from_rotvec(TURN)
    remount = dict(common, tool_rotation=tuple(turned.as_rotvec())) if six_dof else common
    moved = default_measurement_pose()
    moved[:3, 3] += [0.4, 0.3, 0.05]
    cases = {
        "remounted": simulate_session(
            same,
            SimulationConfig(seed=seed + 100, poses=30, **remount),  # type: ignore[arg-type]
            tool_point=robot.tool_point + SHIFT,
        ),
        "tracker moved": simulate_session(
            same,
            SimulationConfig(seed=seed + 200, poses=30, **common),  # type: ignore[arg-type]
            T_measurement_robot=moved,
        ),
    }
    paths = []
    for name, session in cases.items():
        path = folder / f"{name.replace(' ', '_')}.mcap"
        write_session(session, path)
        paths.append(path)
    result = process_log(
        folder / "cal.mcap",
        ProcessOptions(
            pipeline=parse_pipeline(SIX_DOF, "six_dof.toml") if six_dof else None,
            nominal=nominal,
            model=ModelRequest(args.model),
            validate=tuple(paths),
        ),
    )
    for name, check in zip(cases, result.holdout, strict=True):
        assert check.nominal is not None
        placed = [w for w, on in (("base", check.registered),) if on]
        if getattr(check, "tool_replaced", False):
            placed.append("tool")
        print(
            f"{'6-DoF' if six_dof else 'points'} seed {seed} {name:14s} "
            f"nominal {check.nominal.rms * 1e3:.4f} mm  calibrated "
            f"{check.calibrated.rms * 1e3:.4f} mm  poses {check.calibrated.n_poses}  "
            f"placed again: {' and '.join(placed) or 'nothing'}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--model", default="auto")
    parser.add_argument("--perturb-mm", type=float, default=0.05)
    parser.add_argument("--perturb-deg", type=float, default=0.01)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for six_dof in (False, True):
            for seed in range(1, args.seeds + 1):
                run(seed, six_dof, args, Path(tmp))


if __name__ == "__main__":
    main()
