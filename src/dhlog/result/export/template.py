"""A user's URDF template with a result's kinematics (:func:`urdf_from_template`): the calibrated
joint origins written into the template, every other element kept."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable, xml_comment_text
from dhlog.model.dh import JointType
from dhlog.result.export.camera import add_camera_links, camera_link_names, read_hand_eye
from dhlog.result.export.expand import read_description
from dhlog.result.export.source import load_table
from dhlog.result.export.templatefile import (
    MOVING,
    TemplateError,
    TemplateFrames,
    template_joints,
)
from dhlog.result.export.urdf import origin_element


def _align(axis: FloatArray) -> FloatArray:
    """The smallest rotation (3×3) taking the unit vector ``axis`` onto +z."""
    a = axis / np.linalg.norm(axis)
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(a, z), float(a @ z)
    if c < -1.0 + 1e-12:  # opposite: half a turn about x
        return np.diag([1.0, -1.0, -1.0])
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.asarray(np.eye(3) + K + K @ K / (1.0 + c), dtype=np.float64)


def _h(R: FloatArray | None = None, p: FloatArray | None = None) -> FloatArray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def _rz(phi: float) -> FloatArray:
    c, s = math.cos(phi), math.sin(phi)
    return _h(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))


def _tz(t: float) -> FloatArray:
    return _h(p=np.array([0.0, 0.0, t]))


def urdf_from_template(
    result_path: str | Path,
    template_path: str | Path,
    *,
    joint_names: tuple[str, ...] = (),
    xacro_args: Mapping[str, str] | None = None,
) -> str:
    """The template URDF (a xacro expanded first with ``xacro_args``: :mod:`.expand`) with the
    result's kinematics: the template's joints matched by name get calibrated origins; links,
    meshes, inertials, limits and every other element stay.

    Each link keeps the template's frame as closely as the calibration allows: its joint axis
    becomes the measured axis, its origin the nearest point on it, its turn about the axis the
    template's; fixed joints stay as they are (rigid in their link). The measured robot is
    placed by joint 1's link, turned about and moved along axis 1 to fit the other links to the
    template's (the base is a gauge the data does not fix). The measurement frame and the target
    are added as the links ``dhlog_measurement`` and ``dhlog_target``, a camera calibration's
    cameras and board as ``dhlog_<camera>_link``, ``dhlog_<camera>_optical_frame`` and
    ``dhlog_calibration_board`` (:mod:`.camera`) on the template's root (eye-to-hand) or last
    link (eye-in-hand). Joint zero = encoder zero. ``joint_names``: the names to match the
    template's joints by, in the chain's order (the library robot's, as its ROS 2 driver
    publishes them); default the result's.
    Only the ``<joint>`` elements of ``<robot>`` itself are changed (those of a
    ``<transmission>`` name joints, they are not joints).
    """
    robot, src = read_description(template_path, xacro_args)
    calibrate_template(result_path, robot, src, joint_names=joint_names)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def calibrate_template(
    result_path: str | Path,
    robot: ET.Element,
    src: str,
    *,
    joint_names: tuple[str, ...] = (),
) -> list[str]:
    """:func:`urdf_from_template` on a template already read: ``robot`` (its ``<robot>``
    element) edited in place; ``src`` the template's name in messages. Returns the names of the
    joints whose origins were calibrated (all but the first)."""
    from scipy.optimize import least_squares

    data, table, model = load_table(result_path)
    hand_eye = read_hand_eye(data, printable(str(result_path)))
    template = template_joints(robot, src)
    names = list(joint_names or model.joint_names)
    if len(names) != table.n:
        raise TemplateError(
            src, f"{len(names)} joint names were given to match it by, for {table.n} joints."
        )
    if len(set(names)) != len(names):
        raise DHFileError(
            printable(str(result_path)),
            "names two joints alike, so they cannot be matched to a template's by name; "
            "rename them in the result's joints.",
        )
    moving = {name: j for name, j in template.items() if j.kind in MOVING}
    missing = [n for n in names if n not in moving]
    if missing:
        listed = ", ".join(list(moving)[:20]) + (" …" if len(moving) > 20 else "")
        raise TemplateError(
            src,
            f"has no joint {printable(', '.join(missing))[:200]} of the result; its moving "
            f"joints are {printable(listed) or 'none'} (the result's joints are named by the "
            "log's joint states).",
        )
    joints = [moving[n] for n in names]
    for name, j, kind in zip(names, joints, table.joint_types, strict=True):
        if (j.kind == "prismatic") != (kind is JointType.PRISMATIC):
            raise TemplateError(
                src, f"joint {printable(name)} is {j.kind} there but {kind} in the result."
            )
    frames = TemplateFrames(template, src)
    L = [frames.frame(j.child) for j in joints]
    Lp = [frames.frame(j.parent) for j in joints]
    for k in range(1, len(joints)):
        link = joints[k].parent
        while link != joints[k - 1].child:  # no loop: the frames were composed
            up = frames.parent_of.get(link)
            if up is None or up.kind != "fixed":
                raise TemplateError(
                    src,
                    f"joint {printable(names[k])} does not follow joint {printable(names[k - 1])} "
                    "through fixed joints only; give a template whose joints form the result's "
                    "chain.",
                )
            link = up.parent
    root = frames.root(joints[0].parent)
    axes = [j.axis for j in joints]
    align = [_h(_align(a)) for a in axes]
    n = table.n
    rows = table.link_transforms(np.zeros(n))
    F = [model.T_base]
    for i in range(n):
        F.append(F[-1] @ rows[i])  # F[i]: DH frame i+1 at encoder zero, in M

    def placed(x: FloatArray) -> FloatArray:
        """B: M → the template's root, for a turn x[0] about and a shift x[1] along axis 1."""
        return np.asarray(
            L[0]
            @ np.linalg.inv(align[0])
            @ _rz(float(x[0]))
            @ _tz(float(x[1]))
            @ np.linalg.inv(F[0])
        )

    def link_frames(B: FloatArray) -> list[FloatArray]:
        W = [L[0]]
        for i in range(1, n):
            P = B @ F[i]
            local = np.linalg.inv(P) @ L[i]
            D = P[:3, :3].T @ L[i][:3, :3] @ align[i][:3, :3].T
            phi = math.atan2(D[1, 0] - D[0, 1], D[0, 0] + D[1, 1])
            W.append(P @ _tz(float(local[2, 3])) @ _rz(phi) @ align[i])
        return W

    def misfit(x: FloatArray) -> FloatArray:
        B = placed(x)
        out: list[float] = []
        for i in range(1, n):
            P = B @ F[i]
            local = np.linalg.inv(P) @ L[i]
            out.extend(local[:2, 3])  # the template's link origin off the measured axis
            out.extend(P[:3, 2] - L[i][:3, :3] @ axes[i] / np.linalg.norm(axes[i]))
        return np.asarray(out if out else [0.0])

    x = least_squares(misfit, np.zeros(2), x_scale=[0.1, 0.1]).x if n > 1 else np.zeros(2)
    B = placed(x)
    W = link_frames(B)
    by_name = {j.get("name"): j for j in robot.findall("joint")}  # <robot>'s own joints
    for i in range(1, n):
        parent = W[i - 1] @ np.linalg.inv(L[i - 1]) @ Lp[i]  # rigid in link i-1
        element = by_name[names[i]]
        olds = element.findall("origin")
        at = list(element).index(olds[0]) if olds else 0  # where the template has it
        for old in olds:
            element.remove(old)
        origin_at = origin_element(np.linalg.inv(parent) @ W[i])
        if olds:
            origin_at.tail = olds[0].tail
        element.insert(at, origin_at)
    target = B @ F[n] @ np.r_[model.tool_point, 1.0]
    last = np.linalg.inv(W[n - 1]) @ target
    if len(robot):
        robot[-1].tail = "\n  "
    links = {e.get("name") for e in robot.findall("link")}
    for link, parent_link, T in (
        ("dhlog_measurement", root, B),
        ("dhlog_target", joints[-1].child, _h(p=last[:3])),
    ):
        if link in links or f"{link}_fixed" in template:
            raise TemplateError(src, f"already has a link {link} (or its joint); remove it first.")
        ET.SubElement(robot, "link", name=link).tail = "\n  "
        joint = ET.SubElement(robot, "joint", name=f"{link}_fixed", type="fixed")
        ET.SubElement(joint, "parent", link=parent_link)
        ET.SubElement(joint, "child", link=link)
        joint.append(origin_element(T))
        ET.indent(joint, level=1)
        joint.tail = "\n  "
    if hand_eye is not None:  # on the template's root (the base) and last link (the flange)
        taken = links | set(template) | {e.get("name") for e in robot.iter("joint")}
        clash = [x for x in camera_link_names(hand_eye, "dhlog_") if x in taken]
        if clash:
            raise TemplateError(
                src, f"already has a link {clash[0]} (or its joint); remove it first."
            )
        flange = np.linalg.inv(W[n - 1]) @ B @ F[n]
        parents = {"base": (root, B @ F[0]), "flange": (joints[-1].child, flange)}
        for element in add_camera_links(
            robot,
            hand_eye,
            lambda j, T: j.append(origin_element(T)),
            parents=parents,
            prefix="dhlog_",
        ):
            ET.indent(element, level=1)
            element.tail = "\n  "
            joint = element
    joint.tail = "\n"
    note = ET.Comment(
        xml_comment_text(
            f" joint origins of {', '.join(names[1:])} calibrated by dhlog export from "
            f"{Path(str(result_path)).name}: joint zero = encoder zero; dhlog_measurement = the "
            "tracker's frame, dhlog_target = the measured target "
            + (
                "; dhlog_<camera>_optical_frame = the calibrated camera frame (OpenCV's: x right, "
                "y down, z forward), dhlog_<camera>_link the same origin in body axes (x forward, "
                "y left, z up), dhlog_calibration_board the board's corner frame "
                if hand_eye is not None
                else ""
            )
        )
    )
    note.tail = "\n  "
    robot.insert(0, note)
    return names[1:]
