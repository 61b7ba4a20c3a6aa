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

from dhlog.dh import HayatiDH, JointType, StandardDH
from dhlog.dhfile import DHFileError, parse_dh
from dhlog.geometry._checks import FloatArray, roll_pitch_yaw


def _table_of(data: dict[str, Any], source: str) -> tuple[StandardDH, Any]:
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


def urdf_document(
    result_path: str | Path, *, name: str | None = None, limits: FloatArray | None = None
) -> str:
    """The URDF text of a result (or DH) JSON; ``limits`` (n, 2) the joint limits (rad, m;
    default ±π and ±1 m)."""
    source = str(result_path)
    try:
        data = json.loads(Path(result_path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DHFileError(source, f"cannot be read as JSON ({exc}).") from None
    if not isinstance(data, dict):
        raise DHFileError(source, "must hold an object with a 'standard_dh' array.")
    table, model = _table_of(data, source)
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
