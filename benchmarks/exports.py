"""FK agreement of every export with dhlog's own FK, read back by the real consumers.

    .venv/bin/python benchmarks/exports.py [--vectors 1000]

For a UR5 off its nominal (0.2 mm, 0.02°, simulated and processed by the command line) and the
``kr5_real`` sample log (a Hayati row): each export format written by ``dhlog export``, loaded by
its consumer (yourdfpy for the URDFs, the UR description's composition for the UR file,
roboticstoolbox-python for the rtb snippet, the DH transforms for the plain tables), and the
largest distance between its target position and dhlog's at random joint vectors within the
robot's limits. Prints one line per export.
"""

from __future__ import annotations

import argparse
import json
import runpy
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml
import yourdfpy

from dhlog.io.dhfile import load_dh
from dhlog.model.dh import modified_dh_transform
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot

DHLOG = str(Path(sys.executable).with_name("dhlog"))
ROOT = Path(__file__).resolve().parents[1]


def run(*args: str) -> None:
    subprocess.run([DHLOG, *args], check=True, capture_output=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vectors", type=int, default=1000)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="dhlog-exports-"))
    run(
        "simulate",
        "ur5",
        "-o",
        str(work / "ur5.mcap"),
        "--perturb-mm",
        "0.2",
        "--perturb-deg",
        "0.02",
        "--seed",
        "3",
    )
    run("process", str(work / "ur5.mcap"), "--no-rrd", "--out", str(work))
    run("process", str(ROOT / "sample_logs" / "kr5_real.mcap"), "--no-rrd", "--out", str(work))
    sys.path.insert(0, str(ROOT / "tests"))
    from test_export import ur5_template, ur_target  # the tests' UR5 template, UR composition

    ur5_template(work / "template.urdf")
    for stem, robot in (("ur5", "ur5"), ("kr5_real", "kr5")):
        result = work / f"{stem}.dh.json"
        dh = load_dh(result)
        rob = load_robot(robot)
        Q = np.random.default_rng(0).uniform(
            rob.limits[:, 0], rob.limits[:, 1], (args.vectors, rob.n)
        )
        want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
        errors: dict[str, float] = {}

        run("export", str(result), "-o", str(work / "a.urdf"), "--force")
        model = yourdfpy.URDF.load(str(work / "a.urdf"), load_meshes=False)
        err = 0.0
        for q, p in zip(Q, want, strict=True):
            model.update_cfg(q)
            err = max(err, np.abs(model.get_transform("tool0", "measurement")[:3, 3] - p).max())
        errors["urdf (yourdfpy)"] = err

        run(
            "export",
            str(result),
            "-o",
            str(work / "c.urdf"),
            "--zero-offsets",
            "calibration",
            "--force",
        )
        model = yourdfpy.URDF.load(str(work / "c.urdf"), load_meshes=False)
        rising = np.array(
            [model.joint_map[n].calibration.rising for n in model.actuated_joint_names]
        )
        err = 0.0
        for q, p in zip(Q, want, strict=True):
            model.update_cfg(q + rising)
            err = max(err, np.abs(model.get_transform("tool0", "measurement")[:3, 3] - p).max())
        errors["urdf --zero-offsets calibration (yourdfpy)"] = err

        run("export", str(result), "-o", str(work / "r.py"), "--format", "rtb", "--force")
        robot_rtb = runpy.run_path(str(work / "r.py"))["robot"]
        errors["rtb (roboticstoolbox-python)"] = max(
            np.abs(robot_rtb.fkine(q).t - p).max() for q, p in zip(Q, want, strict=True)
        )

        run("export", str(result), "-o", str(work / "d.json"), "--format", "dh-json", "--force")
        doc = json.loads((work / "d.json").read_text())
        err = 0.0
        for q, p in zip(Q, want, strict=True):
            T = np.asarray(doc["T_base"])
            for k, m in enumerate(doc["modified"]):
                T = T @ modified_dh_transform(
                    m["alpha_prev"], m["a_prev"], m["theta_offset"] + q[k], m["d"]
                )
            T = T @ np.asarray(doc["modified_T_tool_end"])
            err = max(err, np.abs((T @ np.r_[doc["tool_point"], 1.0])[:3] - p).max())
        errors["dh-json modified rows"] = err

        if stem == "ur5":
            run(
                "export",
                str(result),
                "-o",
                str(work / "t.urdf"),
                "--template",
                str(work / "template.urdf"),
                "--force",
            )
            model = yourdfpy.URDF.load(str(work / "t.urdf"), load_meshes=False)
            err = 0.0
            for q, p in zip(Q, want, strict=True):
                model.update_cfg(q)
                T = model.get_transform("dhlog_target", "dhlog_measurement")
                err = max(err, np.abs(T[:3, 3] - p).max())
            errors["urdf --template (yourdfpy)"] = err

            run("export", str(result), "-o", str(work / "u.yaml"), "--format", "ur", "--force")
            text = (work / "u.yaml").read_text()
            kin = yaml.safe_load(text)["kinematics"]
            tcp = np.array([float(v) for v in text.split("tcp: [")[1].split("]")[0].split(",")])
            local = fk_point(dh.table, Q, dh.tool_point, T_base=np.eye(4))
            err = max(
                np.abs(ur_target(kin, tcp, q) - p).max() for q, p in zip(Q, local, strict=True)
            )
            errors["ur (as ur_macro.xacro composes it)"] = err
        for name, value in errors.items():
            print(f"{stem:9s} {name:45s} max |Δ| {value:.2e} m over {args.vectors} joint vectors")


if __name__ == "__main__":
    main()
