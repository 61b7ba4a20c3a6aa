"""A user's xacro description with a result's kinematics, as a xacro (:func:`xacro_from_template`):
the template's own text with only the calibrated joints' ``<origin>`` changed, so that the launch
files that run xacro on it (with the same arguments) still do.

The template is expanded by the real xacro (:mod:`.expand`) and calibrated as a URDF template is
(:func:`dhlog.result.export.template.calibrate_template`); each calibrated joint's ``<origin>``
is then written where the joint is written: in the template itself, or — for a joint written in
a macro of a file the template includes (a vendor's ``*_macro.xacro``, read-only in its package)
— in a copy of that macro put in the template right after the include that brings it in, which
redefines it (xacro takes a macro's last definition). The measurement frame and the target are
added as fixed links at the end, as in the URDF. The xacro written is expanded again and must
give the calibrated URDF, element for element; a joint whose origin cannot be written so (an
``<origin>`` from ``xacro:insert_block``, a macro called for several joints, a namespaced
include) is one line naming it and the file it is written in.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
import xml.parsers.expat
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

from dhlog.io.safetext import printable
from dhlog.result.export.expand import Expanded, expand_xacro
from dhlog.result.export.template import calibrate_template
from dhlog.result.export.templatefile import TemplateError

_URDF = "write the calibrated URDF instead (-o robot.urdf)"


@dataclass
class _Span:
    """An element of a file: its tag, its bytes ``start:end`` and its parent's index (-1)."""

    tag: str
    start: int
    end: int
    parent: int


def _tag_end(raw: bytes, at: int) -> int:
    """The index after the ``>`` that closes the tag starting at ``at`` (quotes skipped)."""
    quote = 0
    for k in range(at, len(raw)):
        c = raw[k]
        if quote:
            quote = 0 if c == quote else quote
        elif c in (0x22, 0x27):
            quote = c
        elif c == 0x3E:
            return k + 1
    return len(raw)


def _spans(raw: bytes) -> list[_Span]:
    """Every element of an XML file, in document order, with where its text is."""
    parser = xml.parsers.expat.ParserCreate()
    spans: list[_Span] = []
    open_: list[int] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        spans.append(_Span(tag, parser.CurrentByteIndex, -1, open_[-1] if open_ else -1))
        open_.append(len(spans) - 1)

    def end(tag: str) -> None:
        span = spans[open_.pop()]
        at = parser.CurrentByteIndex
        span.end = _tag_end(raw, at if raw[at : at + 2] == b"</" else span.start)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.Parse(raw, True)
    return spans


def _spliced(raw: bytes, edits: list[tuple[int, int, bytes]], offset: int = 0) -> bytes:
    """``raw`` with each ``(start, end, text)`` (indices less ``offset``) put in place."""
    out, at = [], 0
    for start, end, text in sorted(edits):
        out += [raw[at : start - offset], text]
        at = end - offset
    return b"".join([*out, raw[at:]])


def _numbers(text: str) -> list[float] | None:
    try:
        return [float(v) for v in text.split()]
    except ValueError:
        return None


def _difference(a: ET.Element, b: ET.Element, at: str) -> str | None:
    """Where two URDF trees differ (comments and whitespace aside; numbers to 1e-12), or None."""
    if a.tag != b.tag:
        return f"{at}: <{a.tag}> against <{b.tag}>"
    here = f"{at}/{a.tag}" + (f"[{a.get('name')}]" if a.get("name") else "")
    if set(a.attrib) != set(b.attrib):
        return f"{here}: attributes {sorted(a.attrib)} against {sorted(b.attrib)}"
    for key, value in a.attrib.items():
        other = b.attrib[key]
        x, y = _numbers(value), _numbers(other)
        same = (
            x is not None
            and y is not None
            and len(x) == len(y)
            and all(math.isclose(u, v, rel_tol=0, abs_tol=1e-12) for u, v in zip(x, y, strict=True))
        )
        if value != other and not same:
            return f"{here}: {key}={value!r} against {other!r}"
    ca = [c for c in a if c.tag is not ET.Comment]  # type: ignore[comparison-overlap]
    cb = [c for c in b if c.tag is not ET.Comment]  # type: ignore[comparison-overlap]
    if len(ca) != len(cb):
        return f"{here}: {len(ca)} elements against {len(cb)}"
    for x_, y_ in zip(ca, cb, strict=True):
        found = _difference(x_, y_, here)
        if found:
            return found
    return None


def xacro_from_template(
    result_path: str | Path,
    template_path: str | Path,
    *,
    args: Mapping[str, str] | None = None,
    joint_names: tuple[str, ...] = (),
) -> str:
    """The xacro template's text with the result's calibrated joint origins (module docstring);
    ``args`` the xacro arguments to expand it with, ``joint_names`` the names to match its
    joints by (default the result's)."""
    src = printable(str(template_path))
    expanded = expand_xacro(template_path, args)
    changed = calibrate_template(result_path, expanded.robot, src, joint_names=joint_names)
    calibrated = {str(j.get("name")): j for j in expanded.robot.findall("joint")}
    raws: dict[int, bytes] = {}
    spans: dict[int, list[_Span]] = {}
    for k in {0, *(_source(expanded, name, src)[0] for name in changed)}:
        # each file was checked (size, DOCTYPE) when xacro read it
        raws[k] = Path(expanded.files[k]).read_bytes()
        spans[k] = _spans(raws[k])
    edits: dict[int, list[tuple[int, int, bytes]]] = {k: [] for k in raws}
    macros: dict[tuple[int, int], int] = {}  # (file, macro span) → the template's include
    for name in changed:
        k, i = _source(expanded, name, src)
        where = printable(Path(expanded.files[k]).name)
        joint = [n for n, e in enumerate(spans[k]) if e.tag == "joint"][i]
        origins = [e for e in spans[k] if e.parent == joint and e.tag == "origin"]
        if len(origins) != 1:
            raise TemplateError(
                src,
                f"joint {printable(name)} is written in {where} without an <origin> of its own "
                f"(from xacro:insert_block or a macro), so its calibrated origin has no place "
                f"there; {_URDF}.",
            )
        new = calibrated[name].find("origin")
        assert new is not None  # calibrate_template wrote it
        text = (
            f"<origin xyz={quoteattr(str(new.get('xyz')))} rpy={quoteattr(str(new.get('rpy')))}/>"
        )
        edits[k].append((origins[0].start, origins[0].end, text.encode()))
        if k == 0:
            continue
        macro = spans[k][joint].parent
        while macro >= 0 and spans[k][macro].tag != "xacro:macro":
            macro = spans[k][macro].parent
        include = expanded.top_include.get(k)
        if macro < 0 or include is None:
            raise TemplateError(
                src,
                f"joint {printable(name)} is written in {where} outside a macro (or in a file "
                f"not included by {Path(src).name} itself), so a copy cannot redefine it; "
                f"{_URDF}.",
            )
        macros[(k, macro)] = include
    top = spans[0]
    includes = [e for e in top if e.tag == "xacro:include" and e.parent == 0]
    for (k, m), ordinal in sorted(macros.items()):
        if (
            ordinal >= len(includes)
            or b" ns=" in raws[0][includes[ordinal].start : includes[ordinal].end]
        ):
            raise TemplateError(
                src,
                "includes the macro of a calibrated joint inside a namespace or a condition, "
                f"where a copy cannot redefine it; {_URDF}.",
            )
        span = spans[k][m]
        inside = [e for e in edits[k] if span.start <= e[0] and e[1] <= span.end]
        copy = _spliced(raws[k][span.start : span.end], inside, span.start)
        opening = raws[k][span.start : _tag_end(raws[k], span.start)].decode("utf-8")
        called = re.search(r"""\bname\s*=\s*["']([^"']*)["']""", opening)
        macro_name = called.group(1) if called else "?"
        note = (
            f"\n\n  <!-- macro {macro_name} of {Path(expanded.files[k]).name} with the calibrated "
            "joint origins (dhlog export): it redefines the included one; only the joints' "
            "<origin> differ -->\n  "
        )
        at = includes[ordinal].end
        edits[0].append((at, at, note.encode() + copy))
    root = top[0]
    told = next(c.text for c in expanded.robot if c.tag is ET.Comment)  # type: ignore[comparison-overlap]
    head = _tag_end(raws[0], root.start)
    edits[0].append((head, head, f"\n  <!--{told}-->".encode()))
    closing = raws[0].rindex(b"</", 0, root.end)
    added = [e for e in expanded.robot if str(e.get("name", "")).startswith("dhlog_")]
    tail = "".join(f"  {ET.tostring(e, encoding='unicode').strip()}\n" for e in added)
    edits[0].append((closing, closing, tail.encode()))
    text = _spliced(raws[0], edits[0]).decode("utf-8")
    again = expand_xacro(template_path, args, text=text)
    found_at = _difference(expanded.robot, again.robot, "")
    if found_at:
        raise TemplateError(
            src,
            "the calibrated xacro does not expand to the calibrated URDF "
            f"({printable(found_at)[:200]}); {_URDF}.",
        )
    return text if text.endswith("\n") else text + "\n"


def _source(expanded: Expanded, name: str, src: str) -> tuple[int, int]:
    """Where a calibrated joint is written; one that stands for several expanded joints refused."""
    source = expanded.source_of.get(name)
    if source is None:
        raise TemplateError(
            src, f"joint {printable(name)} is not written as a <joint> in any file; {_URDF}."
        )
    if expanded.copies[source] > 1:
        raise TemplateError(
            src,
            f"joint {printable(name)} is written once in "
            f"{printable(Path(expanded.files[source[0]]).name)} but expanded "
            f"{expanded.copies[source]} times (a macro called for several joints), so its "
            f"calibrated origin has no one place; {_URDF}.",
        )
    return source
