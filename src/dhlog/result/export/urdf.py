"""A result as a URDF whose joints reproduce the identified model (:func:`urdf_document`).

The URDF chain is ``measurement`` (the tracker's frame M) → ``base_link`` (DH frame 1, placed by
``T_measurement_base``) → ``link_1`` … ``link_n`` → ``flange`` (frame n+1) → ``tool0`` (the
target). Joint i turns (slides) about z of its frame; its origin is the previous row's transform
at encoder zero, ``A_{i−1}(0) = Rz(θ_offset) Tz(d_offset) Tx(a) Rx(α)`` (a Hayati–Mirmirani row
``… Rx(α) Ry(β)``, when the result has one: the well-conditioned form), so that

    link_i = frame_i · Rz(q_i)   and   frame_{i+1} = link_i · A_i(0) = frame_i · A_i(q_i),

which is the result's forward kinematics exactly: the URDF's joint zero is the encoder zero (the
zero offsets are in the joint origins). An encoder scale (``--fit-encoder-scales``) has no place
in a URDF and is refused. A camera calibration's result adds each camera's ``<name>_link`` and
``<name>_optical_frame`` and the board's ``calibration_board`` as fixed links on ``base_link`` or
``flange`` (:mod:`.camera`).

Given the library robot (``--nominal`` or ``--limits-from``), the URDF is that robot's: its name,
the joint names its ROS 2 driver publishes, its position limits and, where the library has them,
its velocity and effort limits. URDF's ``<limit>`` must carry ``effort`` and ``velocity``
(urdfdom refuses a joint limit without them); where they are not known they are written 0 with a
comment that says so on the joint, because consumers read 0 differently: ros2_control's joint
limits from the URDF hold a joint of velocity limit 0 still, MoveIt reads it as no velocity bound.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from dhlog.geometry._checks import FloatArray, roll_pitch_yaw
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable, xml_comment_text
from dhlog.model.dh import HayatiDH, JointType, StandardDH
from dhlog.model.robots import Robot
from dhlog.result.export.camera import add_camera_links, read_hand_eye
from dhlog.result.export.source import load_table


def _origin(parent: ET.Element, T: FloatArray) -> None:
    xyz = " ".join(f"{v:.17g}" for v in T[:3, 3])
    rpy = " ".join(f"{v:.17g}" for v in roll_pitch_yaw(T[:3, :3]))
    ET.SubElement(parent, "origin", xyz=xyz, rpy=rpy)


def origin_element(T: FloatArray) -> ET.Element:
    """An ``<origin>`` element of the transform ``T`` (4×4): its ``xyz`` and URDF's ``rpy``."""
    element = ET.Element("origin")
    element.set("xyz", " ".join(f"{v:.17g}" for v in T[:3, 3]))
    element.set("rpy", " ".join(f"{v:.17g}" for v in roll_pitch_yaw(T[:3, :3])))
    return element


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


def _limits(limits: FloatArray, n: int, source: str) -> FloatArray:
    """Joint limits (n, 2), finite, lower below upper."""
    limits = np.asarray(limits, dtype=np.float64)
    if limits.shape != (n, 2) or not np.all(np.isfinite(limits)):
        raise DHFileError(
            source,
            f"has {n} joints, but the limits given are for {len(limits)}; give the limits of "
            "the same robot (--limits-from).",
        )
    return limits


def _without_offsets(table: StandardDH) -> StandardDH:
    """The table with its zero offsets (θ of revolute, d of prismatic rows) set to zero."""
    revolute = np.array([t is JointType.REVOLUTE for t in table.joint_types])
    theta = np.where(revolute, 0.0, table.theta_offset)
    d = np.where(revolute, table.d_offset, 0.0)
    if isinstance(table, HayatiDH):
        return HayatiDH(table.joint_types, theta, d, table.a, table.alpha, table.beta, table.hayati)
    return StandardDH(table.joint_types, theta, d, table.a, table.alpha)


def unknown_dynamics(robot: Robot | None, which: str = "velocity and effort limits") -> str:
    """A joint's comment where its velocity or effort limit (``which``) is not known."""
    why = (
        f"the library has none for {printable(robot.name)}"
        if robot is not None
        else "no library robot given to export as its nominal or limits-from"
    )
    return (
        f" {which} not known to dhlog ({why}): written 0; ros2_control's joint limits hold a "
        "joint of velocity 0 still, MoveIt reads 0 as no velocity bound: set the robot's values "
    )


def _robot_of(robot: Robot | None, n: int, source: str) -> Robot | None:
    """The library robot, refused when its joint count is not the result's."""
    if robot is not None and robot.n != n:
        raise DHFileError(
            source,
            f"has {n} joints, but {printable(robot.name)} has {robot.n}; give the library robot "
            "this result is of (--nominal, --limits-from).",
        )
    return robot


def urdf_document(
    result_path: str | Path,
    *,
    name: str | None = None,
    limits: FloatArray | None = None,
    zero_offsets: str = "origins",
    robot: Robot | None = None,
) -> str:
    """The URDF text of a result (or DH) JSON; ``limits`` (n, 2) the joint limits (rad, m;
    default the ``robot``'s, else ±π and ±1 m). ``zero_offsets``: ``origins`` (joint zero =
    encoder zero, the offsets in the joint origins) or ``calibration`` (the origins without them;
    each joint's ``<calibration rising="…"/>`` holds its offset: joint position = encoder value +
    rising). ``robot``: the library robot the result is of — the URDF takes its name, its joint
    names (as its ROS 2 driver publishes them) and its position, velocity and effort limits."""
    source = str(result_path)
    data, table, model = load_table(result_path)
    robot = _robot_of(robot, table.n, printable(source))
    hand_eye = read_hand_eye(data, printable(source))
    if zero_offsets not in ("origins", "calibration"):
        raise ValueError(f"zero_offsets must be origins or calibration, not {zero_offsets!r}")
    offsets = np.where(
        [t is JointType.REVOLUTE for t in table.joint_types], table.theta_offset, table.d_offset
    )
    if zero_offsets == "calibration":
        table = _without_offsets(table)
    n = table.n
    if limits is None and robot is not None:
        limits = robot.limits
    if limits is None:
        limits = np.array(
            [
                [-math.pi, math.pi] if t is JointType.REVOLUTE else [-1.0, 1.0]
                for t in table.joint_types
            ]
        )
    limits = _limits(limits, n, printable(source))
    names = list(
        robot.joint_names if robot is not None and robot.joint_names else model.joint_names
    )
    if len(set(names)) != len(names):
        names = [f"joint_{i + 1}" for i in range(n)]
    fallback = robot.name if robot is not None else Path(source).name.split(".")[0]
    robot_name = printable(name or fallback) or "robot"
    velocity = robot.velocity_limits if robot is not None else np.zeros(0)
    effort = robot.effort_limits if robot is not None else np.zeros(0)
    known_velocity, known_effort = len(velocity) == n, len(effort) == n
    given = " and ".join(
        what for what, known in (("velocity", known_velocity), ("effort", known_effort)) if known
    )
    unknown = " and ".join(
        what
        for what, known in (("velocity", known_velocity), ("effort", known_effort))
        if not known
    )
    urdf = ET.Element("robot", name=robot_name)
    ET.SubElement(urdf, "link", name="measurement")
    ET.SubElement(urdf, "link", name="base_link")
    fixed = ET.SubElement(urdf, "joint", name="base_in_measurement", type="fixed")
    ET.SubElement(fixed, "parent", link="measurement")
    ET.SubElement(fixed, "child", link="base_link")
    _origin(fixed, model.T_base)
    rows = table.link_transforms(np.zeros(n))
    parent = "base_link"
    for i in range(n):
        child = f"link_{i + 1}"
        ET.SubElement(urdf, "link", name=child)
        kind = "revolute" if table.joint_types[i] is JointType.REVOLUTE else "prismatic"
        joint = ET.SubElement(urdf, "joint", name=names[i], type=kind)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=child)
        _origin(joint, np.eye(4) if i == 0 else rows[i - 1])
        ET.SubElement(joint, "axis", xyz="0 0 1")
        lo, hi = limits[i]
        ET.SubElement(
            joint,
            "limit",
            lower=f"{lo:.17g}",
            upper=f"{hi:.17g}",
            effort=f"{effort[i]:.17g}" if known_effort else "0",
            velocity=f"{velocity[i]:.17g}" if known_velocity else "0",
        )
        if unknown:
            told = unknown_dynamics(robot, f"{unknown} limit" + ("s" if " and " in unknown else ""))
            joint.append(ET.Comment(xml_comment_text(told)))
        if zero_offsets == "calibration":
            ET.SubElement(joint, "calibration", rising=f"{offsets[i]:.17g}")
        parent = child
    for link, origin in (("flange", rows[n - 1]), ("tool0", None)):
        ET.SubElement(urdf, "link", name=link)
        joint = ET.SubElement(urdf, "joint", name=f"{link}_fixed", type="fixed")
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=link)
        if origin is None:
            origin = np.eye(4)
            origin[:3, 3] = model.tool_point
        _origin(joint, origin)
        parent = link
    if hand_eye is not None:
        add_camera_links(urdf, hand_eye, _origin)
    comment = ET.Comment(
        xml_comment_text(
            " written by dhlog export from "
            + Path(source).name
            + (
                ": joint zero = encoder zero (the zero offsets are in the joint origins); "
                if zero_offsets == "origins"
                else ": the zero offsets are in each joint's <calibration rising>: joint "
                "position = encoder value + rising; "
            )
            + "frame base_link = DH frame 1, flange = frame n+1, tool0 = the measured target"
            + (
                f"; joint names and position limits of the library robot {robot.name} "
                f"({robot.title})" + (f", {given} limits its description's" if given else "")
                if robot is not None
                else ""
            )
            + (
                "; <camera>_optical_frame = the calibrated camera frame (OpenCV's: x right, y "
                "down, z forward; REP 103's optical frame), <camera>_link the same origin in "
                "body axes (x forward, y left, z up), calibration_board the board's corner frame "
                if hand_eye is not None
                else " "
            )
        )
    )
    urdf.insert(0, comment)
    ET.indent(urdf)
    return '<?xml version="1.0"?>\n' + ET.tostring(urdf, encoding="unicode") + "\n"
