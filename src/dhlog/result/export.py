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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.geometry._checks import FloatArray, roll_pitch_yaw
from dhlog.io.dhfile import DHFileError, DHModel, parse_dh
from dhlog.model.dh import HayatiDH, JointType, StandardDH, standard_to_modified
from dhlog.result.check import (
    MAX_ANGLE_RAD,
    MAX_LENGTH_M,
    MAX_RESULT_BYTES,
    load_result,
    printable,
    read_limited,
    xml_comment_text,
)


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
    """The result (or DH) JSON, its well-conditioned table and its DH model; the file's size,
    nesting and every field used checked first (:func:`dhlog.result.check.load_result`)."""
    data = load_result(result_path)
    table, model = _table_of(data, printable(str(result_path)))
    return data, table, model


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


def urdf_document(
    result_path: str | Path,
    *,
    name: str | None = None,
    limits: FloatArray | None = None,
    zero_offsets: str = "origins",
) -> str:
    """The URDF text of a result (or DH) JSON; ``limits`` (n, 2) the joint limits (rad, m;
    default ±π and ±1 m). ``zero_offsets``: ``origins`` (joint zero = encoder zero, the
    offsets in the joint origins) or ``calibration`` (the origins without them; each joint's
    ``<calibration rising="…"/>`` holds its offset: joint position = encoder value + rising)."""
    source = str(result_path)
    _, table, model = _load(result_path)
    if zero_offsets not in ("origins", "calibration"):
        raise ValueError(f"zero_offsets must be origins or calibration, not {zero_offsets!r}")
    offsets = np.where(
        [t is JointType.REVOLUTE for t in table.joint_types], table.theta_offset, table.d_offset
    )
    if zero_offsets == "calibration":
        table = _without_offsets(table)
    n = table.n
    if limits is None:
        limits = np.array(
            [
                [-math.pi, math.pi] if t is JointType.REVOLUTE else [-1.0, 1.0]
                for t in table.joint_types
            ]
        )
    limits = _limits(limits, n, printable(source))
    names = list(model.joint_names)
    if len(set(names)) != len(names):
        names = [f"joint_{i + 1}" for i in range(n)]
    robot_name = printable(name or Path(source).name.split(".")[0]) or "robot"
    robot = ET.Element("robot", name=robot_name)
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
        if zero_offsets == "calibration":
            ET.SubElement(joint, "calibration", rising=f"{offsets[i]:.17g}")
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
        xml_comment_text(
            " written by dhlog export from "
            + Path(source).name
            + (
                ": joint zero = encoder zero (the zero offsets are in the joint origins); "
                if zero_offsets == "origins"
                else ": the zero offsets are in each joint's <calibration rising>: joint "
                "position = encoder value + rising; "
            )
            + "frame base_link = DH frame 1, flange = frame n+1, tool0 = the measured target "
        )
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
    _, table, model = _load(result_path)
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
        sigma = (std_rows[i].get("std") or {}) if i < len(std_rows) else {}
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


# ---------------------------------------------------------------------------------------------
# a URDF template with calibrated joint origins


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


class TemplateError(DHFileError):
    """A URDF template that cannot take the result (unreadable, joints missing or not a chain)."""


#: The largest URDF template read (a robot's URDF is tens of kB; its meshes are other files).
MAX_TEMPLATE_BYTES = 16 * 2**20
#: The deepest nesting of a template's elements (a URDF's is four or five).
MAX_TEMPLATE_DEPTH = 64
#: URDF's joint types; the moving ones (one degree of freedom) take a result's joint.
URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
MOVING = ("revolute", "continuous", "prismatic")
_XACRO = "a xacro file must be expanded first (xacro robot.urdf.xacro > robot.urdf)"


class _RefusedError(Exception):
    """What stops the template's parser: a DOCTYPE, or elements nested too deep."""


class _TemplateBuilder(ET.TreeBuilder):
    """The template's tree with its comments; a DOCTYPE (the door to entity expansion and
    external entities: a URDF needs none) and nesting beyond ``MAX_TEMPLATE_DEPTH`` stop the
    parser before anything is built from them."""

    def __init__(self) -> None:
        super().__init__(insert_comments=True)
        self.depth = 0

    def start(self, tag: str, attrs: dict[str, str]) -> ET.Element:
        self.depth += 1
        if self.depth > MAX_TEMPLATE_DEPTH:
            raise _RefusedError(f"its elements are nested more than {MAX_TEMPLATE_DEPTH} deep")
        return super().start(tag, attrs)

    def end(self, tag: str) -> ET.Element:
        self.depth -= 1
        return super().end(tag)

    def doctype(self, name: str, pubid: str | None, system: str | None) -> None:
        raise _RefusedError(
            "it has a DOCTYPE (a URDF needs none, and its entities are not expanded)"
        )


def read_template(template_path: str | Path) -> ET.Element:
    """A URDF template's ``<robot>`` element (with its comments), read as untrusted input: its
    size before it is parsed, no DOCTYPE (no entity is ever expanded or fetched), bounded
    nesting."""
    src = printable(str(template_path))
    raw = read_limited(template_path, MAX_TEMPLATE_BYTES, "URDF template")
    parser = ET.XMLParser(target=_TemplateBuilder())
    try:
        parser.feed(raw)
        robot = parser.close()
    except _RefusedError as exc:
        raise TemplateError(src, f"cannot be used as a template: {exc}; {_XACRO}.") from None
    except ET.ParseError as exc:
        raise TemplateError(src, f"is not well-formed XML ({exc}); {_XACRO}.") from None
    except (ValueError, LookupError) as exc:  # an encoding the parser does not know
        raise TemplateError(src, f"cannot be read as XML ({exc}).") from None
    if robot.tag != "robot":
        raise TemplateError(
            src, f"has <{printable(str(robot.tag))[:40]}> at its root, not <robot>; {_XACRO}."
        )
    return robot


@dataclass(frozen=True)
class _TemplateJoint:
    """A ``<joint>`` of a template: its links, its origin (4×4) and its axis (unit vector)."""

    name: str
    kind: str
    parent: str
    child: str
    origin: FloatArray
    axis: FloatArray


def _triple(element: ET.Element | None, attr: str, default: float, bound: float) -> list[float]:
    """Three finite numbers of an attribute (``xyz``, ``rpy``), each within ±``bound``."""
    text = None if element is None else element.get(attr)
    if text is None:
        return [default] * 3
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= bound for v in values):
        raise ValueError(f"{attr}='{printable(text)[:60]}' is not three numbers within ±{bound:g}")
    return values


def _template_joints(robot: ET.Element, src: str) -> dict[str, _TemplateJoint]:
    """The ``<joint>`` elements of ``<robot>`` itself (not those of a ``<transmission>``), by
    name, each checked: a name, a type, a parent and a child link, origin and axis numbers."""
    joints: dict[str, _TemplateJoint] = {}
    for k, element in enumerate(robot.findall("joint")):
        name = element.get("name")
        if not name:
            raise TemplateError(src, f"joint {k + 1} of <robot> has no name; repair the template.")
        shown = printable(name)[:80]
        if name in joints:
            raise TemplateError(src, f"has two joints named {shown}; repair the template.")
        kind = element.get("type")
        if kind not in URDF_JOINT_TYPES:
            raise TemplateError(
                src,
                f"joint {shown} has type '{printable(str(kind))[:20]}', not one of "
                f"{', '.join(URDF_JOINT_TYPES)}; repair the template.",
            )
        links = [element.find(tag) for tag in ("parent", "child")]
        parent, child = (e.get("link") if e is not None else None for e in links)
        if not parent or not child:
            raise TemplateError(
                src, f"joint {shown} needs <parent link=…> and <child link=…>; repair the template."
            )
        origin, axis = element.find("origin"), element.find("axis")
        try:
            xyz = _triple(origin, "xyz", 0.0, MAX_LENGTH_M)
            rpy = _triple(origin, "rpy", 0.0, MAX_ANGLE_RAD)
            direction = np.array([1.0, 0.0, 0.0])  # URDF's default axis
            if axis is not None and axis.get("xyz") is not None:
                direction = np.array(_triple(axis, "xyz", 0.0, MAX_LENGTH_M))
        except ValueError as exc:
            raise TemplateError(src, f"joint {shown}: {exc}; repair the template.") from None
        if kind in MOVING and not np.linalg.norm(direction) > 1e-9:
            raise TemplateError(src, f"joint {shown} has a zero axis; repair the template.")
        T = rpy_matrix(*rpy)
        T[:3, 3] = xyz
        joints[name] = _TemplateJoint(name, kind, parent, child, T, direction)
    return joints


class _Frames:
    """Each link's frame in the tree's root at joint values zero (the origins composed down
    from the root), a loop of joints refused."""

    def __init__(self, joints: dict[str, _TemplateJoint], src: str) -> None:
        self.src = src
        self.parent_of: dict[str, _TemplateJoint] = {}
        for j in joints.values():
            other = self.parent_of.setdefault(j.child, j)
            if other is not j:
                raise TemplateError(
                    src,
                    f"link {printable(j.child)[:80]} is the child of two joints "
                    f"({printable(other.name)[:80]}, {printable(j.name)[:80]}); a URDF is a "
                    "tree: repair the template.",
                )
        self.cache: dict[str, FloatArray] = {}

    def root(self, link: str) -> str:
        self.frame(link)  # refuses a loop on the way up
        while link in self.parent_of:
            link = self.parent_of[link].parent
        return link

    def frame(self, link: str) -> FloatArray:
        chain: list[str] = []
        at = link
        while at not in self.cache:
            joint = self.parent_of.get(at)
            if joint is None:  # the root
                self.cache[at] = np.eye(4)
                break
            if at in chain:
                raise TemplateError(
                    self.src,
                    f"its joints form a loop through link {printable(at)[:80]}; a URDF is a "
                    "tree: repair the template.",
                )
            chain.append(at)
            at = joint.parent
        T = self.cache[at]
        for name in reversed(chain):
            T = T @ self.parent_of[name].origin
            self.cache[name] = T
        return self.cache[link]


def urdf_from_template(result_path: str | Path, template_path: str | Path) -> str:
    """The template URDF with the result's kinematics: the template's joints matched by name get
    calibrated origins; links, meshes, inertials, limits and every other element stay.

    Each link keeps the template's frame as closely as the calibration allows: its joint axis
    becomes the measured axis, its origin the nearest point on it, its turn about the axis the
    template's; fixed joints stay as they are (rigid in their link). The measured robot is
    placed by joint 1's link, turned about and moved along axis 1 to fit the other links to the
    template's (the base is a gauge the data does not fix). The measurement frame and the target
    are added as the links ``dhlog_measurement`` and ``dhlog_target``. Joint zero = encoder zero.
    Only the ``<joint>`` elements of ``<robot>`` itself are changed (those of a
    ``<transmission>`` name joints, they are not joints).
    """
    from scipy.optimize import least_squares

    src = printable(str(template_path))
    _, table, model = _load(result_path)
    robot = read_template(template_path)
    template = _template_joints(robot, src)
    names = list(model.joint_names)
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
    frames = _Frames(template, src)
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
        for old in element.findall("origin"):
            element.remove(old)
        origin_at = _origin_element(np.linalg.inv(parent) @ W[i])
        element.insert(0, origin_at)
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
        joint.append(_origin_element(T))
        ET.indent(joint, level=1)
        joint.tail = "\n  "
    joint.tail = "\n"
    note = ET.Comment(
        xml_comment_text(
            f" joint origins of {', '.join(names[1:])} calibrated by dhlog export from "
            f"{Path(str(result_path)).name}: joint zero = encoder zero; dhlog_measurement = the "
            "tracker's frame, dhlog_target = the measured target "
        )
    )
    note.tail = "\n  "
    robot.insert(0, note)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def _origin_element(T: FloatArray) -> ET.Element:
    element = ET.Element("origin")
    element.set("xyz", " ".join(f"{v:.17g}" for v in T[:3, 3]))
    element.set("rpy", " ".join(f"{v:.17g}" for v in roll_pitch_yaw(T[:3, :3])))
    return element
