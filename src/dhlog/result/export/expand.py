"""A robot description as a template takes it: a URDF read as untrusted input, or a xacro expanded
by the real ``xacro`` package first (:func:`read_description`, :func:`expand_xacro`).

A xacro's ``$(find PKG)`` is resolved as ROS resolves it: through the ament index of a sourced
ROS 2 workspace when ``ament_index_python`` is importable, else in the folders of
``ROS_PACKAGE_PATH`` and the folders above the template, a package being a folder whose
``package.xml`` names it. Every file xacro reads (the template and what it includes) is checked
as a URDF template is: size, no DOCTYPE. Each ``<joint>`` of each file read is marked with the
attribute :data:`SOURCE` (``file:ordinal``) before xacro expands it, so the expanded joints say
where they were written (:class:`Expanded`); the marks are removed from the tree handed on.
"""

from __future__ import annotations

import contextlib
import io
import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dhlog.errors import UsageError
from dhlog.io.safetext import printable
from dhlog.result.export.templatefile import (
    MAX_TEMPLATE_BYTES,
    TemplateError,
    parse_xml,
    read_template,
    read_xml,
)

#: the attribute that marks where an expanded ``<joint>`` was written: ``file:ordinal``
SOURCE = "dhlog-source"
_INSTALL = "pip install 'dhlog[xacro]'"


def is_xacro(path: str | Path) -> bool:
    """Whether a description is a xacro: its name ends in ``.xacro``, or it uses xacro (a
    ``<xacro:…>`` element, a ``${…}`` or ``$(…)``); a URDF that only declares xacro's namespace,
    as xacro's own output does, is a URDF."""
    p = Path(path)
    if p.name.endswith(".xacro"):
        return True
    try:
        with open(p, "rb") as f:
            text = f.read(MAX_TEMPLATE_BYTES + 1)
    except OSError:
        return False
    return b"<xacro:" in text or b"${" in text or b"$(" in text


@dataclass
class Expanded:
    """A xacro expanded: the URDF's ``<robot>`` element (marks removed), the files read in
    order (``files[0]`` the template), each expanded joint's source (name → (file index, ordinal
    among the file's ``<joint>`` elements)), how many expanded joints came from each source, and
    for each included file the ordinal of the template's own include that brought it in."""

    robot: ET.Element
    files: list[str]
    source_of: dict[str, tuple[int, int]]
    copies: dict[tuple[int, int], int]
    top_include: dict[int, int] = field(default_factory=dict)


def _package_folder(name: str, start: Path) -> str:
    """A ROS package's folder: ``ROS_PACKAGE_PATH``'s folders, then those above ``start``."""
    roots = [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    candidates: list[Path] = []
    for root in roots:
        candidates += [root, *(p.parent for p in root.glob("*/package.xml"))]
        candidates += [p.parent for p in root.glob("*/*/package.xml")]
    candidates += [start, *start.parents]
    for folder in candidates:
        manifest = folder / "package.xml"
        if not manifest.is_file():
            continue
        try:
            tag = ET.parse(manifest).getroot().find("name")
        except (ET.ParseError, OSError):
            continue
        if tag is not None and (tag.text or "").strip() == name:
            return str(folder)
    raise LookupError(name)


def _finder(start: Path) -> Any:
    try:
        from ament_index_python.packages import (  # type: ignore[import-not-found]
            PackageNotFoundError,
            get_package_share_directory,
        )
    except ImportError:
        return lambda name: _package_folder(name, start)

    def find(name: str) -> str:
        try:
            return str(get_package_share_directory(name))
        except (PackageNotFoundError, ValueError, LookupError):
            return _package_folder(name, start)

    return find


@contextlib.contextmanager
def _hooked(
    xacro: Any,
    top: Path,
    files: list[str],
    top_include: dict[int, int],
    missing: list[TemplateError],
) -> Iterator[None]:
    """xacro with ``$(find)`` resolved here and every file it parses checked and its joints
    marked; restored after."""
    from xacro import substitution_args  # type: ignore[import-untyped]

    parse, find = xacro.parse, substitution_args._eval_find
    included = [0]

    def marked(inp: Any, filename: str | None = None) -> Any:
        if inp is None and filename is not None:
            read_xml(filename)  # size, DOCTYPE, nesting: before xacro reads it
        doc = parse(inp, filename)
        k = len(files)
        files.append(str(filename) if filename is not None else str(top))
        if k > 0 and len(xacro.filestack or []) == 2:  # included by the template itself
            top_include[k] = included[0]
            included[0] += 1
        elif k > 0:
            stack = list(xacro.filestack or [])
            parent = next((i for i, f in enumerate(files[:k]) if f == stack[1]), None)
            if parent is not None and parent in top_include:
                top_include[k] = top_include[parent]
        for i, joint in enumerate(doc.getElementsByTagName("joint")):
            joint.setAttribute(SOURCE, f"{k}:{i}")
        return doc

    xacro.parse = marked
    finder = _finder(top.resolve().parent)

    def resolving(name: str) -> str:
        try:
            return str(finder(name))
        except LookupError:  # xacro wraps what it catches: kept to be raised whole
            missing.append(
                TemplateError(
                    printable(str(top)),
                    f"needs the ROS package {printable(name)} ($(find {printable(name)})), which "
                    "neither a sourced workspace's ament index nor ROS_PACKAGE_PATH nor a folder "
                    "above the template holds; source its workspace or add the folder it is in "
                    "to ROS_PACKAGE_PATH.",
                )
            )
            raise

    substitution_args._eval_find = resolving
    try:
        yield
    finally:
        xacro.parse, substitution_args._eval_find = parse, find


def expand_xacro(
    path: str | Path, args: Mapping[str, str] | None = None, *, text: str | None = None
) -> Expanded:
    """The xacro at ``path`` expanded by the ``xacro`` package with ``args`` (``name:=value``
    as a mapping), its joints' sources kept (:class:`Expanded`); any failure one line
    (:class:`TemplateError`) naming the file and xacro's message. ``text``: expand this text
    in the file's place (its relative paths resolved from the file's folder)."""
    src = printable(str(path))
    if text is None:
        read_template(path)  # the template itself: size, well-formed, no DOCTYPE, <robot>
    try:
        import xacro
    except ImportError:
        raise TemplateError(
            src,
            f"is a xacro, and expanding it needs the xacro package: {_INSTALL} (or expand it "
            "first: xacro robot.urdf.xacro > robot.urdf).",
        ) from None
    files: list[str] = []
    top_include: dict[int, int] = {}
    missing: list[TemplateError] = []
    said = io.StringIO()
    try:
        hooked = _hooked(xacro, Path(path), files, top_include, missing)
        with hooked, contextlib.redirect_stderr(said):
            if text is None:
                doc = xacro.process_file(str(path), mappings=dict(args or {}))
            else:
                xacro.init_stacks(str(path))
                doc = xacro.parse(text)
                xacro.process_doc(doc, mappings=dict(args or {}))
            expanded = doc.toxml()
    except TemplateError:
        raise
    except Exception as exc:
        if missing:
            raise missing[0] from None  # xacro raises XacroException, NameError, KeyError, … alike
        told = " ".join(str(exc).split()) or type(exc).__name__
        where = printable(Path(files[-1]).name) if len(files) > 1 else ""
        raise TemplateError(
            src,
            f"cannot be expanded by xacro ({printable(told)[:300]}"
            + (f", in {where}" if where else "")
            + "); repair it or give the xacro arguments it needs (--xacro-arg NAME:=VALUE).",
        ) from None
    finally:
        xacro.init_stacks(None)
    robot = parse_xml(expanded, src)
    if robot.tag != "robot":
        raise TemplateError(src, "does not expand to a <robot>; give a robot's description.")
    source_of: dict[str, tuple[int, int]] = {}
    copies: dict[tuple[int, int], int] = {}
    own = {id(j) for j in robot.findall("joint")}  # <robot>'s joints, not a transmission's
    for element in robot.iter():
        mark = element.attrib.pop(SOURCE, None)
        if mark is None or id(element) not in own:
            continue
        k, i = (int(v) for v in mark.split(":"))
        copies[(k, i)] = copies.get((k, i), 0) + 1
        source_of[str(element.get("name"))] = (k, i)
    return Expanded(robot, files, source_of, copies, top_include)


def read_description(
    path: str | Path, args: Mapping[str, str] | None = None
) -> tuple[ET.Element, str]:
    """A template's ``<robot>`` element — a URDF as it is, a xacro expanded — and its name for
    messages."""
    src = printable(str(path))
    if is_xacro(path):
        return expand_xacro(path, args).robot, src
    if args:
        raise TemplateError(src, "is not a xacro, so --xacro-arg has nothing to set; drop it.")
    return read_template(path), src


def files_read(path: str | Path, args: Mapping[str, str] | None = None) -> list[str]:
    """The files a template reads besides itself (a xacro's includes, found by expanding it;
    none for a URDF): an output is never one of them."""
    return expand_xacro(path, args).files[1:] if is_xacro(path) else []


def template_inputs(
    template: str | Path | None, args: Mapping[str, str] | None, *, xacro_out: bool
) -> list[str]:
    """:func:`files_read` of an export's template; xacro arguments without a xacro template, or
    a xacro output asked of a URDF template, refused (:class:`~dhlog.errors.UsageError`)."""
    if template is None or not is_xacro(template):
        if args:
            raise UsageError("export: xacro arguments are for a xacro template; drop them.")
        if xacro_out:
            raise UsageError(
                f"export: {printable(str(template))} is a URDF, not a xacro, so the output is a "
                "URDF: name it .urdf."
                if template is not None
                else "export: a .xacro output is a xacro template's, calibrated; without a "
                "template the URDF is written: name it .urdf."
            )
        return []
    return files_read(template, args)
