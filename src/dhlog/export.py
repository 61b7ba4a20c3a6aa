"""Results in the forms robot stacks load: a URDF whose joints reproduce the identified model.

The URDF chain is ``measurement`` (the tracker's frame M) → ``base_link`` (DH frame 1, placed by
``T_measurement_base``) → ``link_1`` … ``link_n`` → ``flange`` (frame n+1) → ``tool0`` (the
target). Joint i turns (slides) about z of its frame; its origin is the previous row's transform
at encoder zero, ``A_{i−1}(0) = Rz(θ_offset) Tz(d_offset) Tx(a) Rx(α)`` (a Hayati–Mirmirani row
``… Rx(α) Ry(β)``, when the result has one: the well-conditioned form), so that

    link_i = frame_i · Rz(q_i)   and   frame_{i+1} = link_i · A_i(0) = frame_i · A_i(q_i),

which is the result's forward kinematics exactly: the URDF's joint zero is the encoder zero (the
zero offsets are in the joint origins). An encoder scale (``--fit-encoder-scales``) has no place
in a URDF and is refused.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.dh import HayatiDH, JointType, StandardDH, standard_to_modified
from dhlog.dhfile import DHFileError, DHModel, parse_dh
from dhlog.geometry._checks import FloatArray, roll_pitch_yaw


def _table_of(data: dict[str, Any], source: str) -> tuple[StandardDH, DHModel]:
    """The result's table (the Hayati form where it has one) and the DH model."""
    model = parse_dh(data, source)
    rows = data.get("standard_dh", [])
    if any(abs(float(r.get("encoder_scale", 1.0)) - 1.0) > 0 for r in rows):
        raise DHFileError(
            source,
            "the result has fitted encoder scales, which a URDF cannot hold; export a result "
            "made without --fit-encoder-scales.",
        )
    hayati = (data.get("hayati_dh") or {}).get("rows")
    if not hayati:
        return model.table, model
    try:
        table = HayatiDH(
            [r["type"] for r in hayati],
            [float(r["theta_offset"]) for r in hayati],
            [float(r.get("d_offset", 0.0)) for r in hayati],
            [float(r["a"]) for r in hayati],
            [float(r["alpha"]) for r in hayati],
            [float(r.get("beta", 0.0)) for r in hayati],
            [r["form"] == "hayati" for r in hayati],
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise DHFileError(source, f"malformed hayati_dh ({exc}).") from None
    return table, model


def _origin(parent: ET.Element, T: FloatArray) -> None:
    xyz = " ".join(f"{v:.17g}" for v in T[:3, 3])
    rpy = " ".join(f"{v:.17g}" for v in roll_pitch_yaw(T[:3, :3]))
    ET.SubElement(parent, "origin", xyz=xyz, rpy=rpy)


def _load(result_path: str | Path) -> tuple[dict[str, Any], StandardDH, DHModel]:
    """The result (or DH) JSON, its well-conditioned table and its DH model."""
    source = str(result_path)
    try:
        data = json.loads(Path(result_path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DHFileError(source, f"cannot be read as JSON ({exc}).") from None
    if not isinstance(data, dict):
        raise DHFileError(source, "must hold an object with a 'standard_dh' array.")
    table, model = _table_of(data, source)
    return data, table, model


def urdf_document(
    result_path: str | Path, *, name: str | None = None, limits: FloatArray | None = None
) -> str:
    """The URDF text of a result (or DH) JSON; ``limits`` (n, 2) the joint limits (rad, m;
    default ±π and ±1 m)."""
    source = str(result_path)
    _, table, model = _load(result_path)
    n = table.n
    if limits is None:
        limits = np.array(
            [
                [-math.pi, math.pi] if t is JointType.REVOLUTE else [-1.0, 1.0]
                for t in table.joint_types
            ]
        )
    names = list(model.joint_names)
    if len(set(names)) != len(names):
        names = [f"joint_{i + 1}" for i in range(n)]
    robot = ET.Element("robot", name=name or Path(source).name.split(".")[0])
    ET.SubElement(robot, "link", name="measurement")
    ET.SubElement(robot, "link", name="base_link")
    fixed = ET.SubElement(robot, "joint", name="base_in_measurement", type="fixed")
    ET.SubElement(fixed, "parent", link="measurement")
    ET.SubElement(fixed, "child", link="base_link")
    _origin(fixed, model.T_base)
    rows = table.link_transforms(np.zeros(n))
    parent = "base_link"
    for i in range(n):
        child = f"link_{i + 1}"
        ET.SubElement(robot, "link", name=child)
        kind = "revolute" if table.joint_types[i] is JointType.REVOLUTE else "prismatic"
        joint = ET.SubElement(robot, "joint", name=names[i], type=kind)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=child)
        _origin(joint, np.eye(4) if i == 0 else rows[i - 1])
        ET.SubElement(joint, "axis", xyz="0 0 1")
        lo, hi = limits[i]
        ET.SubElement(
            joint, "limit", lower=f"{lo:.17g}", upper=f"{hi:.17g}", effort="0", velocity="0"
        )
        parent = child
    for link, origin in (("flange", rows[n - 1]), ("tool0", None)):
        ET.SubElement(robot, "link", name=link)
        joint = ET.SubElement(robot, "joint", name=f"{link}_fixed", type="fixed")
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=link)
        if origin is None:
            origin = np.eye(4)
            origin[:3, 3] = model.tool_point
        _origin(joint, origin)
        parent = link
    comment = ET.Comment(
        " written by dhlog export from "
        + Path(source).name
        + ": joint zero = encoder zero (the zero offsets are in the joint origins); "
        "frame base_link = DH frame 1, flange = frame n+1, tool0 = the measured target "
    )
    robot.insert(0, comment)
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


# ---------------------------------------------------------------------------------------------
# Universal Robots calibration file

#: The UR description's joints, in chain order, and their entries in ``kinematics:``.
UR_ENTRIES = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: base_link → base_link_inertia, wrist_3_link → flange → tool0 in the UR description (rpy).
UR_BASE_INERTIA = (0.0, 0.0, math.pi)
UR_FLANGE = (0.0, -math.pi / 2, -math.pi / 2)
UR_TOOL0 = (math.pi / 2, 0.0, math.pi / 2)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """URDF's fixed-axis roll-pitch-yaw: ``Rz(yaw) Ry(pitch) Rx(roll)``, as a 4×4 transform."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    T = np.eye(4)
    T[:3, :3] = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return T


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
    data, table, model = _load(result_path)
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
    digest = hashlib.sha256(Path(result_path).read_bytes()).hexdigest()[:16]
    lines = [
        f"# written by dhlog export from {Path(source).name}: the kinematics of the measured",
        "# robot in the Universal Robots ROS 2 description's layout (default_kinematics.yaml).",
        "# base_link = DH frame 1; joint zero = encoder zero. The target (TCP) in tool0, in m:",
        f"#   tcp: [{tcp[0]:.9f}, {tcp[1]:.9f}, {tcp[2]:.9f}]",
        "kinematics:",
    ]
    for entry, T in zip(UR_ENTRIES, origins, strict=True):
        r, p, y = roll_pitch_yaw(T[:3, :3])
        lines.append(f"  {entry}:")
        for key, value in zip(
            ("x", "y", "z", "roll", "pitch", "yaw"), (*T[:3, 3], r, p, y), strict=True
        ):
            lines.append(f"    {key}: {float(value):.17g}")
    lines.append(f"  hash: dhlog_{digest}")
    del data
    return "\n".join(lines) + "\n", tcp[:3]


# ---------------------------------------------------------------------------------------------
# robotics-toolbox snippet and plain DH tables


def rtb_document(result_path: str | Path) -> str:
    """A Python file defining ``robot``, a roboticstoolbox ``DHRobot`` of the result's standard
    table, with its base (DH frame 1 in the measurement frame) and the target as its tool:
    ``robot.fkine(q).t`` is the target in the measurement frame."""
    source = str(result_path)
    _, _, model = _load(result_path)
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
    return f"""\"\"\"{Path(source).name} as a robotics-toolbox robot (written by dhlog export).

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


def dh_table_document(result_path: str | Path, fmt: str) -> str:
    """The standard and modified DH tables as CSV (``dh-csv``: one row per joint and
    convention) or JSON (``dh-json``), SI units, with σ where the result has it."""
    source = str(result_path)
    data, _, model = _load(result_path)
    table = model.table
    modified, post = standard_to_modified(table)
    std_rows = data.get("standard_dh", [])
    names = list(model.joint_names)
    out: list[dict[str, Any]] = []
    for i in range(table.n):
        sigma = std_rows[i].get("std", {}) if i < len(std_rows) else {}
        common = {"joint": names[i], "type": str(table.joint_types[i])}
        out.append(
            {
                "convention": "standard",
                **common,
                "theta_offset": float(table.theta_offset[i]),
                "d": float(table.d_offset[i]),
                "a": float(table.a[i]),
                "alpha": float(table.alpha[i]),
                **{
                    f"std_{k}": sigma.get(key)
                    for k, key in (
                        ("theta_offset", "theta"),
                        ("d", "d"),
                        ("a", "a"),
                        ("alpha", "alpha"),
                    )
                },
            }
        )
    for i in range(table.n):
        out.append(
            {
                "convention": "modified",
                "joint": names[i],
                "type": str(table.joint_types[i]),
                "alpha_prev": float(modified.alpha[i]),
                "a_prev": float(modified.a[i]),
                "theta_offset": float(modified.theta_offset[i]),
                "d": float(modified.d_offset[i]),
            }
        )
    if fmt == "dh-json":
        doc = {
            "source": Path(source).name,
            "units": {"length": "m", "angle": "rad"},
            "T_base": model.T_base.tolist(),
            "tool_point": model.tool_point.tolist(),
            "standard": [r for r in out if r["convention"] == "standard"],
            "modified": [r for r in out if r["convention"] == "modified"],
            "modified_T_tool_end": post.tolist(),
        }
        return json.dumps(doc, indent=2) + "\n"
    import csv
    import io

    columns = [
        "convention",
        "joint",
        "type",
        "theta_offset",
        "d",
        "a",
        "alpha",
        "alpha_prev",
        "a_prev",
        "std_theta_offset",
        "std_d",
        "std_a",
        "std_alpha",
    ]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, columns, lineterminator="\n")
    writer.writeheader()
    for row in out:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in columns})
    return buf.getvalue()
