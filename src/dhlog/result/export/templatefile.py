"""A user's URDF template read as untrusted input: its size before it is parsed, no DOCTYPE (no
entity is ever expanded or fetched), bounded nesting (:func:`read_template`); its ``<joint>``
elements checked (:func:`template_joints`) and its link frames composed at joint values zero
(:class:`TemplateFrames`), every fault one line naming the file and the joint or link."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHFileError
from dhlog.io.safetext import printable
from dhlog.result.check import read_limited
from dhlog.result.export.urdf import rpy_matrix
from dhlog.result.fields import MAX_ANGLE_RAD, MAX_LENGTH_M


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


def parse_xml(raw: bytes | str, src: str) -> ET.Element:
    """An untrusted XML text's root (with its comments): no DOCTYPE (no entity is ever expanded
    or fetched), bounded nesting; one line naming ``src`` otherwise."""
    parser = ET.XMLParser(target=_TemplateBuilder())
    try:
        parser.feed(raw)
        return parser.close()
    except _RefusedError as exc:
        raise TemplateError(src, f"cannot be used as a template: {exc}; {_XACRO}.") from None
    except ET.ParseError as exc:
        raise TemplateError(src, f"is not well-formed XML ({exc}); {_XACRO}.") from None
    except (ValueError, LookupError) as exc:  # an encoding the parser does not know
        raise TemplateError(src, f"cannot be read as XML ({exc}).") from None


def read_xml(path: str | Path) -> ET.Element:
    """An untrusted XML file's root: its size before it is parsed, then :func:`parse_xml`."""
    return parse_xml(read_limited(path, MAX_TEMPLATE_BYTES, "URDF template"), printable(str(path)))


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
class TemplateJoint:
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


def template_joints(robot: ET.Element, src: str) -> dict[str, TemplateJoint]:
    """The ``<joint>`` elements of ``<robot>`` itself (not those of a ``<transmission>``), by
    name, each checked: a name, a type, a parent and a child link, origin and axis numbers."""
    joints: dict[str, TemplateJoint] = {}
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
        joints[name] = TemplateJoint(name, kind, parent, child, T, direction)
    return joints


class TemplateFrames:
    """Each link's frame in the tree's root at joint values zero (the origins composed down
    from the root), a loop of joints refused."""

    def __init__(self, joints: dict[str, TemplateJoint], src: str) -> None:
        self.src = src
        self.parent_of: dict[str, TemplateJoint] = {}
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
