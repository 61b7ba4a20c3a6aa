"""Seeded, structure-aware mutations of what ``dhlog compare`` and ``dhlog export`` read — result
JSONs, batch summaries, URDF templates — and of the names and paths that land in their outputs,
with one run of the command on each, its outcome judged.

Shared by ``tests/test_hostile_results.py`` (about 150 cases in CI) and long runs
(:func:`cases` takes a seed and a count; :func:`run_case` judges one case). The inputs start from
real ones (:func:`make_bases`): the result JSON ``dhlog process`` writes for a small sample log,
the same with a ``hayati_dh`` block (row 2 in the Hayati-Mirmirani form, the same forward
kinematics), a batch summary written by dhlog's own summary writer from rows of that result, and
a URDF template drawn by ``dhlog export`` from it, with meshes and a ``<transmission>`` naming a
joint. The families:

* ``result``: one field, chosen by walking the document (mostly through the fields the commands
  use), deleted, nulled, retyped, nested up to 100 000 deep, given a huge or tiny number
  (±1e308, 1e150, 1e-320, ±inf, NaN, a 5 000-digit integer) or a hostile name, or a list
  shortened or lengthened; or the file's bytes cut short, in UTF-16, nested 100 000 deep, over
  the size limit; then ``compare`` (against the real result) or ``export`` in any format;
* ``summary``: a column dropped or renamed, text in a parameter, numbers or lists in a text
  column, ±inf, 1e308, negative σ, session starts that are no time, 20 000 extra parameter
  columns, robots mixed, a duplicated header, markup in names; or the bytes cut short, flipped,
  in UTF-16, over the size limit; CSV or Parquet; then ``compare SUMMARY`` (sometimes ``--rrd``);
* ``template``: a joint's origin, parent, child or axis dropped or garbled (NaN, 1e400, two
  numbers, text), a zero axis, an unknown type, a joint doubled, renamed, moved into a
  ``<transmission>``, joints forming a loop, a link with two parents, another root element, a
  ``dhlog_target`` link already there, a DOCTYPE with entity expansion or an external entity,
  elements nested 100 to 100 000 deep, a 5 MB comment, an undefined entity, UTF-16, over the
  size limit; then ``export --template``;
* ``names``: file and joint names holding XML characters, ``--``, ``\"\"\"``, newlines, control
  characters, undecodable bytes, console markup; outputs named with markup; every format;
* ``paths``: an output that is one of the inputs (the result, the template, the DH file of
  ``--limits-from``, the summary), by the same name, a symbolic or a hard link.

:func:`run_case` runs the command in this process (Typer's runner) under a time limit, and
judges it: exit 0 or 2 (2 where the case must be refused); no traceback; for 2, exactly one line
on stderr and nothing on stdout; every input unchanged; for 2 no output at all, for 0 exactly the
named output, well-formed for its format (XML, Python, YAML, JSON, CSV), the calibrated origins
only in ``<robot>``'s own joints; never a temporary file left.
"""

from __future__ import annotations

import ast
import csv
import hashlib
import io
import json
import os
import random
import shutil
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fuzzing import Outcome, common_problems, invoke

FAMILIES = ("result", "summary", "template", "names", "paths")
SAMPLE = Path(__file__).parents[1] / "sample_logs" / "kr5_0.01mm.mcap"
EXPORT_CHECKS = {"urdf": "xml", "ur": "yaml", "rtb": "python", "dh-csv": "csv", "dh-json": "json"}
#: Above every size limit of the readers (results and summaries 100 MiB, templates 16 MiB):
#: written sparse, so no test writes that much.
OVERSIZED = 101 * 2**20
#: Names that land in outputs: XML's characters, a comment's end, a docstring's end, line ends,
#: control characters, console markup, non-ASCII.
HOSTILE_NAMES = (
    "a<b>&\"c'",
    "a--b",
    "ends-",
    '"""',
    "x'''y\\",
    "[/]m",
    "[bold]j[/bold]",
    "new\nline",
    "tab\tx",
    "ctrl\x01x",
    "sep\u2028x",
    "ü–ñ✓",
    "%s{0}",
)


@dataclass(frozen=True)
class Case:
    """One run: the input files written into the case's folder (name, bytes), sparse files
    (name, size), links (``symlink``/``hardlink``, name, target), the command (``{d}`` is the
    folder), the output it names (None: none), how to check that output, and whether the case
    must be refused (exit 2)."""

    family: str
    name: str
    files: tuple[tuple[str, bytes], ...]
    args: tuple[str, ...]
    output: str | None
    check: str | None
    refuse: bool
    sparse: tuple[tuple[str, int], ...] = ()
    links: tuple[tuple[str, str, str], ...] = ()


@dataclass(frozen=True)
class Bases:
    """The real inputs the cases start from."""

    result: dict[str, Any]
    hayati: dict[str, Any]
    template: str
    rows: list[dict[str, Any]]


# ---------------------------------------------------------------------------- bases


def make_bases(folder: Path) -> Bases:
    """``dhlog process`` of the small KR5 sample log (geometric model, about 2 s), the same
    result with a Hayati block, a template and summary rows drawn from it."""
    from typer.testing import CliRunner

    from dhlog.cli.app import app
    from dhlog.fleet.batch import summary_row
    from dhlog.result.export import urdf_document

    folder.mkdir(parents=True, exist_ok=True)
    done = CliRunner().invoke(
        app,
        [
            "process",
            str(SAMPLE),
            "--no-rrd",
            "--out",
            str(folder),
            "--model",
            "geometric",
            "--force",
        ],
    )
    assert done.exit_code == 0, done.output
    path = folder / f"{SAMPLE.stem}.dh.json"
    result = json.loads(path.read_text())
    hayati = json.loads(json.dumps(result))
    rows = []
    for i, row in enumerate(result["standard_dh"]):
        # axes 2 and 3 are parallel (α = 0, d = 0 by convention): row 2 in the Hayati form with
        # β = 0 is the same transform
        common = {
            "type": row["type"],
            "theta_offset": row["theta_offset"],
            "a": row["a"],
            "alpha": row["alpha"],
            "std": row["std"],
        }
        if i == 1:
            rows.append({"form": "hayati", **common, "beta": 0.0})
        else:
            rows.append({"form": "dh", **common, "d_offset": row["d_offset"]})
    hayati["hayati_dh"] = {"description": "row 2 in the Hayati-Mirmirani form", "rows": rows}
    robot = ET.fromstring(urdf_document(path))
    link = robot.find("link[@name='link_2']")
    assert link is not None
    visual = ET.SubElement(ET.SubElement(link, "visual"), "geometry")
    ET.SubElement(visual, "mesh", filename="package://kr5/meshes/link_2.dae")
    transmission = ET.SubElement(robot, "transmission", name="trans_2")
    ET.SubElement(transmission, "type").text = "transmission_interface/SimpleTransmission"
    nested = ET.SubElement(transmission, "joint", name="joint_2")
    ET.SubElement(nested, "hardwareInterface").text = "PositionJointInterface"
    ET.SubElement(transmission, "actuator", name="motor_2")
    ET.indent(robot)
    template = '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
    summary = []
    t0 = 1_780_000_000 * 10**9
    for k in range(4):
        doc = json.loads(json.dumps(result))
        doc["standard_dh"][1]["a"] += k * 2e-5
        log = folder / f"session_{k + 1}.mcap"
        summary.append(summary_row(log, doc, "ok", "", 1.0, t0 + k * 86400 * 10**9, None))
    summary.append(
        {
            "log": str(folder / "session_0.mcap"),
            "session_start": None,
            "seconds": 0.0,
            "robot": None,
            "joints": None,
            "status": "failed",
            "reason": "not an MCAP file",
        }
    )
    return Bases(result, hayati, template, summary)


def summary_bytes(rows: list[dict[str, Any]], fmt: str) -> bytes:
    """Rows as dhlog batch writes them (``csv`` or ``parquet``)."""
    from dhlog.fleet.batch import summary_frame

    buf = io.BytesIO()
    frame = summary_frame(rows)
    if fmt == "csv":
        frame.write_csv(buf)
    else:
        frame.write_parquet(buf)
    return buf.getvalue()


# ---------------------------------------------------------------------------- results

#: The fields the commands use, and those of a standard row that must hold a number.
USED = ("standard_dh", "hayati_dh", "joints", "tool", "base", "units", "nongeometric")
ROW_NUMBERS = ("a", "alpha", "theta_offset", "d_offset")
#: Values that cannot be a result's parameter: each is refused wherever a parameter is read.
BAD_NUMBERS = ("1e308", "-1e308", "1e999", "-1e999", "NaN", "9" * 5000, "-" + "7" * 5000)
ODD_VALUES: tuple[object, ...] = ([], {}, "abc", True, False, [1, 2, 3], {"x": 1}, 0, "1e3")


def _walk(doc: dict[str, Any], rng: random.Random) -> list[str | int]:
    """A path into ``doc``: mostly through the fields the commands use."""
    keys = list(doc)
    used = [k for k in USED if k in doc]
    first = rng.choice(used) if used and rng.random() < 0.85 else rng.choice(keys)
    path: list[str | int] = [first]
    node = doc[first]
    while rng.random() < 0.8:
        if isinstance(node, dict) and node:
            key: str | int = rng.choice(list(node))
        elif isinstance(node, list) and node:
            key = rng.randrange(len(node))
        else:
            break
        path.append(key)
        node = node[key]  # type: ignore[index]
    return path


def _parent(doc: Any, path: list[str | int]) -> Any:
    node = doc
    for key in path[:-1]:
        node = node[key]
    return node


def _must_hold_a_number(path: list[str | int]) -> bool:
    """A standard row's a, α, θ offset or d offset (each read, each required to be finite)."""
    return (
        len(path) == 3
        and path[0] == "standard_dh"
        and isinstance(path[1], int)
        and path[2] in ROW_NUMBERS
    )


SENTINEL = "@@dhlog-fuzz@@"


def mutate_result(doc: dict[str, Any], rng: random.Random) -> tuple[str, bytes, bool]:
    """(what was done, the file's bytes, whether it must be refused)."""
    doc = json.loads(json.dumps(doc))
    kind = rng.choice(
        ["delete", "null", "retype", "nest", "number", "number", "name", "length", "bytes"]
    )
    if kind == "bytes":
        return _damaged_bytes(doc, rng)
    if kind == "name":
        name = rng.choice(HOSTILE_NAMES)
        k = rng.randrange(len(doc["joints"]))
        doc["joints"][k]["name"] = name
        control = any(ord(c) < 0x20 for c in name)
        return f"joint_name[{k}]={name!r}", json.dumps(doc).encode(), control
    path = _walk(doc, rng)
    parent, key = _parent(doc, path), path[-1]
    where = ".".join(str(p) for p in path)
    if kind == "delete":
        del parent[key]
        required = path == ["standard_dh"] or (_must_hold_a_number(path) and key in ("a", "alpha"))
        return f"delete {where}", json.dumps(doc).encode(), required
    if kind == "null":
        parent[key] = None
        required = path == ["standard_dh"] or _must_hold_a_number(path)
        return f"null {where}", json.dumps(doc).encode(), required
    if kind == "retype":
        value = rng.choice(ODD_VALUES)
        parent[key] = value
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        refused = path == ["standard_dh"] or (_must_hold_a_number(path) and not number)
        return f"retype {where}={value!r}", json.dumps(doc).encode(), refused
    if kind == "nest":
        depth = rng.choice([2, 10, 500, 5000, 100_000])
        inner = json.dumps(parent[key])
        parent[key] = SENTINEL
        text = json.dumps(doc).replace(f'"{SENTINEL}"', "[" * depth + inner + "]" * depth)
        refused = depth >= 5000 or path == ["standard_dh"] or _must_hold_a_number(path)
        return f"nest{depth} {where}", text.encode(), refused
    if kind == "number":
        token = rng.choice((*BAD_NUMBERS, "1e150", "1e-320", "-0.0", "123456789012345678901234"))
        parent[key] = SENTINEL
        text = json.dumps(doc).replace(f'"{SENTINEL}"', token)
        refused = _must_hold_a_number(path) and token not in ("1e-320", "-0.0")
        return f"number {where}={token[:12]}", text.encode(), refused
    # a list shortened or lengthened
    node = parent[key]
    if isinstance(node, list) and node:
        change = rng.choice(["drop", "double", "many"])
        if change == "drop":
            node.pop()
        elif change == "double":
            node.append(json.loads(json.dumps(node[-1])))
        else:
            node.extend(json.loads(json.dumps(node[-1])) for _ in range(150))
        # 156 joints: beyond the limit; more joint names than rows
        refused = change == "many" and path in (["standard_dh"], ["joints"])
        return f"{change} {where}", json.dumps(doc).encode(), refused
    return f"noop {where}", json.dumps(doc).encode(), False


def _damaged_bytes(doc: dict[str, Any], rng: random.Random) -> tuple[str, bytes, bool]:
    text = json.dumps(doc, indent=2)
    kind = rng.choice(["truncate", "utf16", "deep", "flip", "empty", "binary"])
    if kind == "truncate":
        cut = rng.randrange(1, text.rindex("}"))
        return f"truncate@{cut}", text[:cut].encode(), True
    if kind == "utf16":
        return "utf16", text.encode("utf-16"), True
    if kind == "deep":
        return "deep100000", b"[" * 100_000 + b"]" * 100_000, True
    if kind == "empty":
        return "empty", b"", True
    if kind == "binary":
        return "binary", bytes(rng.randrange(256) for _ in range(4096)), True
    data = bytearray(text.encode())
    for _ in range(rng.choice([1, 4, 32])):
        i = rng.randrange(len(data))
        data[i] ^= 1 << rng.randrange(8)
    return "flip", bytes(data), False


def result_case(bases: Bases, rng: random.Random, k: int) -> Case:
    base = rng.choice([bases.result, bases.hayati])
    what, data, refuse = mutate_result(base, rng)
    files: list[tuple[str, bytes]] = [("r.dh.json", data)]
    sparse: tuple[tuple[str, int], ...] = ()
    if rng.random() < 0.03:
        files, sparse, what, refuse = [], (("r.dh.json", OVERSIZED),), "oversized", True
    command = rng.choice(["compare", "compare", "export", "export", "export", "template"])
    real = ("real.dh.json", json.dumps(bases.result).encode())
    if command == "compare":
        pair = ["{d}/r.dh.json", "{d}/real.dh.json"]
        if rng.random() < 0.5:
            pair.reverse()
        args: tuple[str, ...] = ("compare", *pair)
        return Case(
            "result", f"result/{what}/compare#{k}", (*files, real), args, None, None, refuse, sparse
        )
    if command == "template":
        args = ("export", "{d}/r.dh.json", "-o", "{d}/out.urdf", "--template", "{d}/t.urdf")
        template = ("t.urdf", bases.template.encode())
        return Case(
            "result",
            f"result/{what}/template#{k}",
            (*files, template),
            args,
            "out.urdf",
            "template",
            refuse,
            sparse,
        )
    fmt = rng.choice(list(EXPORT_CHECKS))
    out = f"out.{fmt}"
    args = ("export", "{d}/r.dh.json", "-o", f"{{d}}/{out}", "--format", fmt)
    return Case(
        "result",
        f"result/{what}/{fmt}#{k}",
        tuple(files),
        args,
        out,
        EXPORT_CHECKS[fmt],
        refuse,
        sparse,
    )


# ---------------------------------------------------------------------------- summaries


def mutate_summary(rows: list[dict[str, Any]], rng: random.Random) -> tuple[str, bytes, str, bool]:
    """(what was done, the bytes, the format, whether it must be refused)."""
    import polars as pl

    from dhlog.fleet.batch import summary_frame

    fmt = rng.choice(["csv", "parquet"])
    rows = [dict(r) for r in rows]
    ok = [r for r in rows if r["status"] == "ok"]
    kind = rng.choice(
        [
            "drop_column",
            "rename_column",
            "text_in_parameter",
            "numbers_in_text",
            "bad_value",
            "negative_sigma",
            "bad_start",
            "many_columns",
            "mixed_robots",
            "duplicate_header",
            "markup",
            "bytes",
            "few_rows",
            "ok",
        ]
    )
    frame = summary_frame(rows)
    refused = False
    what = kind
    if kind == "drop_column":
        column = rng.choice(frame.columns)
        frame = frame.drop(column)
        refused = column in ("log", "session_start", "status", "robot", "joints")
        what = f"drop {column}"
    elif kind == "rename_column":
        column = rng.choice(["log", "status", "a_2", "session_start", "joints"])
        frame = frame.rename({column: column + "_x"})
        refused = column != "a_2"
        what = f"rename {column}"
    elif kind == "text_in_parameter":
        column = rng.choice([c for c in frame.columns if c.startswith(("a_", "alpha_", "std_"))])
        values = [str(v) for v in frame[column].to_list()]
        values[rng.randrange(len(values) - 1)] = rng.choice(["abc", "1,5", "0x10", "--", "[/]"])
        frame = frame.with_columns(pl.Series(column, values, dtype=pl.String))
        refused = True
        what = f"text in {column}"
    elif kind == "numbers_in_text":
        column = rng.choice(["status", "log", "robot", "joints", "session_start"])
        frame = frame.with_columns(pl.Series(column, list(range(frame.height))))
        refused = column != "log"  # no session ok, robots differ, starts no times
        what = f"numbers in {column}"
    elif kind == "bad_value":
        column = rng.choice([c for c in frame.columns if c.startswith(("a_", "theta_", "tool_"))])
        value = rng.choice([float("inf"), -float("inf"), 1e308, 1e150, -1e300])
        values = frame[column].to_list()
        values[rng.randrange(len(ok))] = value
        frame = frame.with_columns(pl.Series(column, values, dtype=pl.Float64))
        refused = True
        what = f"{column}={value}"
    elif kind == "negative_sigma":
        column = rng.choice([c for c in frame.columns if c.startswith("std_a_")])
        values = frame[column].to_list()
        values[0] = -1e-6
        frame = frame.with_columns(pl.Series(column, values, dtype=pl.Float64))
        refused = True
    elif kind == "bad_start":
        value = rng.choice(["yesterday", "9999-12-31T00:00:00", "0001-01-01", "", "1e9", "[/]"])
        values = frame["session_start"].to_list()
        values[rng.randrange(len(ok))] = value
        frame = frame.with_columns(pl.Series("session_start", values, dtype=pl.String))
        refused = True
        what = f"session_start={value!r}"
    elif kind == "many_columns":
        extra = {f"a_{k + 100}": [0.1] * frame.height for k in range(20_000)}
        frame = frame.hstack(pl.DataFrame(extra))
        refused = True
    elif kind == "mixed_robots":
        values = frame["robot"].to_list()
        values[0] = "4-joint"
        frame = frame.with_columns(pl.Series("robot", values, dtype=pl.String))
        refused = True
    elif kind == "markup":
        frame = frame.rename({"a_2": "a_[/]2", "log": "log"}).with_columns(
            pl.col("log") + "[bold]\n"
        )
    elif kind == "few_rows":
        frame = frame.head(1)  # one identified session: no trend
        refused = True
    buf = io.BytesIO()
    if fmt == "csv":
        frame.write_csv(buf)
    else:
        frame.write_parquet(buf)
    data = buf.getvalue()
    if kind == "duplicate_header" and fmt == "csv":
        head, _, rest = data.partition(b"\n")
        data = head + b",log\n" + rest.replace(b"\n", b",x\n")
    elif kind == "bytes":
        damage = rng.choice(["truncate", "flip", "utf16", "binary"])
        what = f"bytes {damage}"
        if damage == "truncate":
            data = data[: rng.randrange(1, len(data) // 2)]
        elif damage == "flip":
            buf2 = bytearray(data)
            for _ in range(rng.choice([1, 8, 64])):
                i = rng.randrange(len(buf2))
                buf2[i] ^= 1 << rng.randrange(8)
            data = bytes(buf2)
        elif damage == "utf16" and fmt == "csv":
            data = data.decode().encode("utf-16")
            refused = True
        else:
            data = bytes(rng.randrange(256) for _ in range(2048))
            refused = True
        refused = refused or (damage == "truncate" and fmt == "parquet")
    return what, data, fmt, refused


def summary_case(bases: Bases, rng: random.Random, k: int) -> Case:
    what, data, fmt, refuse = mutate_summary(bases.rows, rng)
    name = f"summary.{fmt}"
    files: tuple[tuple[str, bytes], ...] = ((name, data),)
    sparse: tuple[tuple[str, int], ...] = ()
    if rng.random() < 0.04:
        files, sparse, what, refuse = (), ((name, OVERSIZED),), "oversized", True
    if rng.random() < 0.06:
        args: tuple[str, ...] = ("compare", f"{{d}}/{name}", "--rrd", "{d}/trend.rrd")
        return Case(
            "summary",
            f"summary/{what}/{fmt}/rrd#{k}",
            files,
            args,
            "trend.rrd",
            "rrd",
            refuse,
            sparse,
        )
    return Case(
        "summary",
        f"summary/{what}/{fmt}#{k}",
        files,
        ("compare", f"{{d}}/{name}"),
        None,
        None,
        refuse,
        sparse,
    )


# ---------------------------------------------------------------------------- templates

TEMPLATE_KINDS = (
    "drop_origin",
    "drop_parent",
    "drop_child",
    "bad_xyz",
    "bad_rpy",
    "bad_axis",
    "zero_axis",
    "bad_type",
    "dup_joint",
    "rename_joint",
    "into_transmission",
    "loop",
    "two_parents",
    "root_tag",
    "has_dhlog_link",
    "no_name",
    "doctype_laughs",
    "doctype_external",
    "deep",
    "big_comment",
    "truncate",
    "utf16",
    "undefined_entity",
    "huge_attribute",
    "oversized",
)
LAUGHS = (
    '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa">'
    + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(8))
    + "]>\n"
)
EXTERNAL = '<?xml version="1.0"?>\n<!DOCTYPE robot [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'


def mutate_template(text: str, rng: random.Random) -> tuple[str, bytes, bool]:
    """(what was done, the bytes, whether it must be refused)."""
    kind = rng.choice(TEMPLATE_KINDS)
    body = text.split("\n", 1)[1]  # without the XML declaration
    robot = ET.fromstring(body)
    joints = robot.findall("joint")
    moving = [j for j in joints if j.get("type") in ("revolute", "prismatic")]
    joint = rng.choice(moving)

    def out() -> bytes:
        return ('<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode")).encode()

    if kind == "drop_origin":
        for e in joint.findall("origin"):
            joint.remove(e)
        return f"{kind} {joint.get('name')}", out(), False
    if kind in ("drop_parent", "drop_child"):
        element = joint.find(kind.removeprefix("drop_"))
        assert element is not None
        joint.remove(element)
        return f"{kind} {joint.get('name')}", out(), True
    if kind in ("bad_xyz", "bad_rpy", "bad_axis"):
        value = rng.choice(["nan 0 0", "1e400 0 0", "1 2", "a b c", "", "1 2 3 4", "0 0 1e9"])
        tag, attr = ("axis", "xyz") if kind == "bad_axis" else ("origin", kind[4:])
        element = joint.find(tag)
        assert element is not None
        element.set(attr, value)
        return f"{kind}={value!r} {joint.get('name')}", out(), True
    if kind == "zero_axis":
        element = joint.find("axis")
        assert element is not None
        element.set("xyz", "0 0 0")
        return kind, out(), True
    if kind == "bad_type":
        joint.set("type", rng.choice(["spherical", "", "REVOLUTE", "[/]"]))
        return kind, out(), True
    if kind == "dup_joint":
        robot.append(ET.fromstring(ET.tostring(joint)))
        return kind, out(), True
    if kind == "rename_joint":
        joint.set("name", "renamed_" + str(joint.get("name")))
        return kind, out(), True
    if kind == "into_transmission":  # the joint only inside a transmission: not a joint
        robot.remove(joint)
        transmission = robot.find("transmission")
        assert transmission is not None
        transmission.append(joint)
        return f"{kind} {joint.get('name')}", out(), True
    if kind == "loop":  # link_1's parent joint made a child of link_4: a loop
        first = robot.find("joint[@name='joint_1']")
        assert first is not None
        parent = first.find("parent")
        assert parent is not None
        parent.set("link", "link_4")
        return kind, out(), True
    if kind == "two_parents":
        extra = ET.SubElement(robot, "joint", name="extra", type="fixed")
        ET.SubElement(extra, "parent", link="base_link")
        ET.SubElement(extra, "child", link="link_3")
        return kind, out(), True
    if kind == "root_tag":
        robot.tag = rng.choice(["model", "urdf", "sdf"])
        return kind, out(), True
    if kind == "has_dhlog_link":
        ET.SubElement(robot, "link", name="dhlog_target")
        return kind, out(), True
    if kind == "no_name":
        del joint.attrib["name"]
        return kind, out(), True
    if kind == "doctype_laughs":
        return kind, (LAUGHS + body.replace("<robot ", "<robot note='&i;' ", 1)).encode(), True
    if kind == "doctype_external":
        return kind, (EXTERNAL + body.replace("<robot ", "<robot note='&x;' ", 1)).encode(), True
    if kind == "deep":
        depth = rng.choice([100, 5000, 100_000])
        nest = "<a>" * depth + "</a>" * depth
        return f"deep{depth}", body.replace("</robot>", nest + "</robot>").encode(), True
    if kind == "big_comment":
        comment = "<!-- " + "x" * (5 * 2**20) + " -->"
        return kind, body.replace("</robot>", comment + "</robot>").encode(), False
    if kind == "truncate":
        cut = rng.randrange(10, len(body) - 12)
        return f"truncate@{cut}", body[:cut].encode(), True
    if kind == "utf16":  # well-formed XML in UTF-16 with its byte-order mark
        return kind, body.encode("utf-16"), False
    if kind == "undefined_entity":
        return kind, body.replace("<robot ", "<robot note='&nbsp;' ", 1).encode(), True
    if kind == "huge_attribute":
        link = robot.find("link")
        assert link is not None
        link.set("note", "y" * 2**20)
        return kind, out(), False
    return "oversized", b"", True


def template_case(bases: Bases, rng: random.Random, k: int) -> Case:
    what, data, refuse = mutate_template(bases.template, rng)
    files: tuple[tuple[str, bytes], ...] = (
        ("r.dh.json", json.dumps(bases.result).encode()),
        ("t.urdf", data),
    )
    sparse: tuple[tuple[str, int], ...] = ()
    if what == "oversized":
        files, sparse = files[:1], (("t.urdf", OVERSIZED // 6),)
    args = ("export", "{d}/r.dh.json", "-o", "{d}/out.urdf", "--template", "{d}/t.urdf")
    return Case(
        "template", f"template/{what}#{k}", files, args, "out.urdf", "template", refuse, sparse
    )


# ---------------------------------------------------------------------------- names and paths


def names_case(bases: Bases, rng: random.Random, k: int) -> Case:
    """Hostile names in the result's file name, its joints, and the output's name."""
    name = rng.choice(HOSTILE_NAMES)
    doc = json.loads(json.dumps(rng.choice([bases.result, bases.hayati])))
    where = rng.choice(["file", "joint", "output", "undecodable"])
    result_name, out_stem, refuse = "r.dh.json", "out", False
    if where == "file":
        result_name = name.replace("/", "_") + ".dh.json"
    elif where == "undecodable":
        result_name = os.fsdecode(b"r\xff\xfe.dh.json")
    elif where == "joint":
        for joint in doc["joints"]:
            joint["name"] = f"{joint['name']}{name}"
        refuse = any(ord(c) < 0x20 for c in name)
    else:
        out_stem = name.replace("/", "_").replace("\n", "_")
    template = bases.template
    if where == "joint":  # the template's joints named as the result's
        robot = ET.fromstring(template.split("\n", 1)[1])
        for joint in robot.iter("joint"):
            if str(joint.get("name")).startswith("joint_"):
                joint.set("name", f"{joint.get('name')}{name}")
        template = ET.tostring(robot, encoding="unicode")
    fmt = rng.choice([*EXPORT_CHECKS, "template", "compare"])
    files: tuple[tuple[str, bytes], ...] = ((result_name, json.dumps(doc).encode()),)
    if fmt == "compare":
        files += (("real.dh.json", json.dumps(bases.result).encode()),)
        args: tuple[str, ...] = ("compare", f"{{d}}/{result_name}", "{d}/real.dh.json")
        return Case("names", f"names/{where}:{name!r}/compare#{k}", files, args, None, None, refuse)
    if fmt == "template":
        out = f"{out_stem}.urdf"
        files += (("t.urdf", template.encode()),)
        args = ("export", f"{{d}}/{result_name}", "-o", f"{{d}}/{out}", "--template", "{d}/t.urdf")
        return Case(
            "names", f"names/{where}:{name!r}/template#{k}", files, args, out, "template", refuse
        )
    out = f"{out_stem}.{fmt}"
    args = ("export", f"{{d}}/{result_name}", "-o", f"{{d}}/{out}", "--format", fmt)
    return Case(
        "names", f"names/{where}:{name!r}/{fmt}#{k}", files, args, out, EXPORT_CHECKS[fmt], refuse
    )


def paths_case(bases: Bases, rng: random.Random, k: int) -> Case:
    """An output that is one of the command's inputs: always refused, the input untouched."""
    result = ("r.dh.json", json.dumps(bases.result).encode())
    kind = rng.choice(
        ["same", "same_force", "dotted", "symlink", "hardlink", "template", "limits", "rrd"]
    )
    force = ("--force",) if kind != "same" else ()
    if kind in ("same", "same_force"):
        args: tuple[str, ...] = (
            "export",
            "{d}/r.dh.json",
            "-o",
            "{d}/r.dh.json",
            "--format",
            "dh-json",
            *force,
        )
        return Case("paths", f"paths/{kind}#{k}", (result,), args, None, None, True)
    if kind == "dotted":
        args = (
            "export",
            "{d}/r.dh.json",
            "-o",
            "{d}/./sub/../r.dh.json",
            "--format",
            "dh-json",
            "--force",
        )
        return Case(
            "paths", f"paths/{kind}#{k}", (result, ("sub/.keep", b"")), args, None, None, True
        )
    if kind in ("symlink", "hardlink"):
        args = ("export", "{d}/r.dh.json", "-o", "{d}/link.json", "--format", "dh-json", "--force")
        return Case(
            "paths",
            f"paths/{kind}#{k}",
            (result,),
            args,
            None,
            None,
            True,
            links=((kind, "link.json", "r.dh.json"),),
        )
    if kind == "template":
        args = (
            "export",
            "{d}/r.dh.json",
            "-o",
            "{d}/t.urdf",
            "--template",
            "{d}/t.urdf",
            "--force",
        )
        return Case(
            "paths",
            f"paths/{kind}#{k}",
            (result, ("t.urdf", bases.template.encode())),
            args,
            None,
            None,
            True,
        )
    if kind == "limits":
        args = (
            "export",
            "{d}/r.dh.json",
            "-o",
            "{d}/lim.json",
            "--limits-from",
            "{d}/lim.json",
            "--force",
        )
        lim = ("lim.json", json.dumps(bases.result).encode())
        return Case("paths", f"paths/{kind}#{k}", (result, lim), args, None, None, True)
    fmt = rng.choice(["csv", "parquet"])
    summary = (f"summary.{fmt}", summary_bytes(bases.rows, fmt))
    args = ("compare", f"{{d}}/summary.{fmt}", "--rrd", f"{{d}}/summary.{fmt}")
    return Case("paths", f"paths/rrd-{fmt}#{k}", (summary,), args, None, None, True)


# ---------------------------------------------------------------------------- the cases

_MAKERS = {
    "result": result_case,
    "summary": summary_case,
    "template": template_case,
    "names": names_case,
    "paths": paths_case,
}


def cases(
    seed: int, count: int, bases: Bases, families: tuple[str, ...] = FAMILIES
) -> Iterator[Case]:
    """``count`` seeded cases, the families in turn."""
    rng = random.Random(seed)
    for k in range(count):
        family = families[k % len(families)]
        yield _MAKERS[family](bases, rng, k)


# ---------------------------------------------------------------------------- judging


def _prepare(case: Case, folder: Path) -> None:
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    for name, data in case.files:
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
    for name, size in case.sparse:
        with open(folder / name, "wb") as f:
            f.truncate(size)
    for kind, name, target in case.links:
        if kind == "symlink":
            (folder / name).symlink_to(target)
        else:
            os.link(folder / target, folder / name)


def _state(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` and its fingerprint (SHA-256; size and time of big ones)."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_symlink() or not path.is_file():
            out[str(path.relative_to(folder))] = "link" if path.is_symlink() else "folder"
            continue
        st = path.stat()
        if st.st_size > 2**24:
            out[str(path.relative_to(folder))] = f"{st.st_size}/{st.st_mtime_ns}/{st.st_ino}"
        else:
            out[str(path.relative_to(folder))] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def check_output(kind: str, path: Path) -> list[str]:
    """What is wrong with an output of the kind named (empty: nothing)."""
    data = path.read_bytes()
    try:
        if kind in ("xml", "template"):
            robot = ET.fromstring(data)
            if robot.tag != "robot":
                return [f"root <{robot.tag}>"]
            if kind == "template":
                problems = []
                for transmission in robot.iter("transmission"):
                    for joint in transmission.iter("joint"):
                        if joint.find("origin") is not None:
                            problems.append("an <origin> in a <transmission>'s <joint>")
                for joint in robot.findall("joint"):
                    if len(joint.findall("origin")) > 1:
                        problems.append(f"joint {joint.get('name')!r} has two origins")
                return problems
        elif kind == "python":
            ast.parse(data.decode())
        elif kind == "yaml":
            import yaml

            doc = yaml.safe_load(data.decode())
            if not isinstance(doc, dict) or "kinematics" not in doc:
                return ["YAML without kinematics"]
        elif kind == "json":
            json.loads(data)
        elif kind == "csv":
            rows = list(csv.reader(io.StringIO(data.decode())))
            if len({len(r) for r in rows}) != 1:
                return ["CSV rows of different lengths"]
        elif kind == "rrd" and not data:
            return ["empty recording"]
    except Exception as exc:
        return [f"malformed {kind} output ({type(exc).__name__}: {str(exc)[:80]})"]
    return []


def run_case(case: Case, folder: Path, *, timeout: float = 30.0) -> Outcome:
    """Run ``case`` in this process through Typer's runner and judge it."""
    work = folder / "case"
    _prepare(case, work)
    before = _state(work)
    ran = invoke([a.replace("{d}", str(work)) for a in case.args], timeout)
    if ran is None:
        return Outcome(case.name, case.family, -1, (f"hang (over {timeout:g} s)",), "", timeout)
    problems, new = common_problems(ran, before, _state(work), codes=(0, 2), refuse=case.refuse)
    lines = [line for line in ran.stderr.splitlines() if line.strip()]
    if ran.code == 2 and (len(lines) != 1 or ran.stdout.strip()):
        problems.append(f"{len(lines)} lines on stderr, {len(ran.stdout.splitlines())} on stdout")
    if any(".part" in n or n.startswith(".") for n in new):
        problems.append(f"temporary files left: {new}")
    if ran.code == 0:
        want = [case.output] if case.output else []
        if new != want:
            problems.append(f"outputs {new}, expected {want}")
        elif case.output and case.check:
            problems += check_output(case.check, work / case.output)
    shown = ran.stderr.strip()[-400:]
    return Outcome(case.name, case.family, ran.code, tuple(problems), shown, ran.seconds)
