"""A result for two robot stacks that take their kinematics as numbers rather than as a URDF: the
Universal Robots ROS 2 description's calibration file (``default_kinematics.yaml``,
:func:`ur_calibration`) and a roboticstoolbox-python ``DHRobot`` (:func:`rtb_document`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dhlog.geometry._checks import FloatArray, roll_pitch_yaw
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable
from dhlog.model.dh import JointType
from dhlog.result.check import MAX_RESULT_BYTES, read_limited
from dhlog.result.export.source import load_table
from dhlog.result.export.urdf import rpy_matrix

#: The UR description's joints, in chain order, and their entries in ``kinematics:``.
UR_ENTRIES = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: base_link → base_link_inertia, wrist_3_link → flange → tool0 in the UR description (rpy).
UR_BASE_INERTIA = (0.0, 0.0, math.pi)
UR_FLANGE = (0.0, -math.pi / 2, -math.pi / 2)
UR_TOOL0 = (math.pi / 2, 0.0, math.pi / 2)


def ur_calibration(result_path: str | Path) -> tuple[str, FloatArray]:
    """The UR description's calibration file (``default_kinematics.yaml`` layout) of a 6R result,
    and the target in ``tool0`` (m) — the TCP to set on the controller.

    ``base_link`` is DH frame 1 (on the base plane when the log has probed base points); the
    description turns base_link by π about z into ``base_link_inertia``, so ``shoulder`` holds
    that turn back, and each following entry is the previous joint's row at encoder zero, as in
    the URDF export. The last row (and the target) is what lies past wrist_3: it becomes the TCP.
    ``hash`` names this calibration (``dhlog_`` + the result's SHA-256 prefix): the UR driver
    compares it with the controller's own calibration checksum and reports a mismatch, which is
    expected — this file describes the measured robot, not the controller's model.
    """
    import hashlib

    source = str(result_path)
    _, table, model = load_table(result_path)
    if table.n != 6 or any(t is not JointType.REVOLUTE for t in table.joint_types):
        raise DHFileError(
            source, f"a UR calibration needs six revolute joints; this result has {table.n}."
        )
    rows = table.link_transforms(np.zeros(6))
    origins = [np.linalg.inv(rpy_matrix(*UR_BASE_INERTIA))] + [rows[i] for i in range(5)]
    tail = rows[5].copy()
    tail[:3, 3] += tail[:3, :3] @ model.tool_point  # the target in wrist_3_link
    to_tool0 = rpy_matrix(*UR_FLANGE) @ rpy_matrix(*UR_TOOL0)
    tcp = np.linalg.inv(to_tool0) @ np.r_[tail[:3, 3], 1.0]
    digest = hashlib.sha256(read_limited(result_path, MAX_RESULT_BYTES, "result JSON"))
    lines = [
        f"# written by dhlog export from {printable(Path(source).name)}: the kinematics of the "
        "measured",
        "# robot in the Universal Robots ROS 2 description's layout (default_kinematics.yaml).",
        "# base_link = DH frame 1; joint zero = encoder zero. The target (TCP) in tool0, in m:",
        f"#   tcp: [{tcp[0]:.17g}, {tcp[1]:.17g}, {tcp[2]:.17g}]",
        "kinematics:",
    ]
    for entry, T in zip(UR_ENTRIES, origins, strict=True):
        r, p, y = roll_pitch_yaw(T[:3, :3])
        lines.append(f"  {entry}:")
        for key, value in zip(
            ("x", "y", "z", "roll", "pitch", "yaw"), (*T[:3, 3], r, p, y), strict=True
        ):
            lines.append(f"    {key}: {float(value):.17g}")
    lines.append(f"  hash: dhlog_{digest.hexdigest()[:16]}")
    return "\n".join(lines) + "\n", tcp[:3]


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
