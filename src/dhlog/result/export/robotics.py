"""A result as a roboticstoolbox-python ``DHRobot`` (:func:`rtb_document`), for a robot stack
that takes its kinematics as numbers rather than as a URDF (the UR calibration file: :mod:`.ur`)."""

from __future__ import annotations

from pathlib import Path

from dhlog.model.dh import JointType
from dhlog.result.export.source import load_table


def rtb_document(result_path: str | Path) -> str:
    """A Python file defining ``robot``, a roboticstoolbox ``DHRobot`` of the result's standard
    table, with its base (DH frame 1 in the measurement frame) and the target as its tool:
    ``robot.fkine(q).t`` is the target in the measurement frame."""
    source = str(result_path)
    _, _, model = load_table(result_path)
    table = model.table
    links = []
    for i in range(table.n):
        if table.joint_types[i] is JointType.REVOLUTE:
            links.append(
                f"        RevoluteDH(d={table.d_offset[i]!r}, a={table.a[i]!r}, "
                f"alpha={table.alpha[i]!r}, offset={table.theta_offset[i]!r}),"
            )
        else:
            links.append(
                f"        PrismaticDH(theta={table.theta_offset[i]!r}, a={table.a[i]!r}, "
                f"alpha={table.alpha[i]!r}, offset={table.d_offset[i]!r}),"
            )
    base = ",\n".join(
        "        [" + ", ".join(repr(float(v)) for v in row) + "]" for row in model.T_base
    )
    tool = ", ".join(repr(float(v)) for v in model.tool_point)
    # the file name as a Python literal (its repr), written so that the docstring holds exactly
    # that: backslashes doubled, double quotes escaped (no \"\"\" can end it early)
    shown = repr(Path(source).name).replace("\\", "\\\\").replace('"', '\\"')
    return f"""\"\"\"{shown} as a robotics-toolbox robot (written by dhlog export).

Standard DH, SI units; q is the encoder value (the zero offsets are the links' offsets);
robot.fkine(q).t is the measured target in the measurement frame.
\"\"\"

import numpy as np
from roboticstoolbox import DHRobot, PrismaticDH, RevoluteDH
from spatialmath import SE3

robot = DHRobot(
    [
{chr(10).join(links)}
    ],
    name={Path(source).name.split(".")[0]!r},
    base=SE3(np.array([
{base},
    ]), check=False),
    tool=SE3({tool}),
)
"""
