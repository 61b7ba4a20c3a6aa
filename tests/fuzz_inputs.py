"""Seeded, structure-aware mutations of the inputs beside the log — DH files (and results read
as models), pipeline files, tracker exports and joints files — with one ``dhlog`` run on each,
its outcome judged.

Shared by ``tests/test_hostile_inputs.py`` (about 150 cases in CI) and long runs
(``benchmarks/fuzz.py`` can drive :func:`cases`, which takes a seed and a count, and
:func:`run_case`, which judges one case). The inputs start from real ones (:func:`make_bases`):
the truth JSONs dhlog's simulator wrote for the sample logs (a KR5, a SCARA with a prismatic
joint), the result JSON ``dhlog process`` writes for the small KR5 log, a DH TOML in mm and
degrees; the shipped pipelines, each with the sample log it reads; the sample stop CSV, the
Leica-style CSV with U95 and a quaternion, and the stop CSV split into points and a joints file.
The families:

* ``dh``: a value (mostly the DH values, units, base and tool) retyped (a string, a boolean,
  null, a list, an object), given a huge or tiny number (±1e308, 1e150, 1e-320, 5e-324, NaN,
  ±Infinity, a 5 000-digit or a 400-digit integer), nested 10 000 to 100 000 deep; a key
  dropped; rows dropped, doubled, emptied; or the bytes cut short, in UTF-16 with or without a
  byte-order mark, with a NUL or a byte that is not UTF-8; then ``fk`` or ``process --nominal``;
* ``pipeline``: a ``key = value`` line's value retyped (string, boolean, array, table, date),
  made huge, tiny, negative, ``nan`` or ``inf``, a 5 000-digit integer, nested deep; a line
  dropped or doubled, an unknown key, a section doubled; the bytes cut short or re-encoded;
  then ``process`` of the log the pipeline reads;
* ``export``: a cell made 1e308, 1e999, ``nan``, text, empty, a decimal comma, 1e-320 (in a U95),
  a 5 000-digit number; a column dropped, doubled, or two swapped; a header renamed to another's,
  given a unit (``[m]``, ``[ft]``, ``_m``); a row given an extra field or cut short; a line in
  another separator, a quote left open, a 200 000-character field; the bytes cut short, in
  UTF-16 with or without a byte-order mark, with a NUL; then ``import`` (generic, Leica, or with
  a joints file, either of the two mutated).

A case is marked ``refuse`` when its input must be refused (a DH value that is no finite number
in range, a typed pipeline value of the wrong type or out of range, a bad cell in a column the
import reads): exit 0 there is a problem too. :func:`run_case` runs the command in this process
(Typer's runner) under a time limit and judges it: exit 0, 2 or 3; no traceback; for 2 and 3
exactly one line on stderr; every input unchanged; for 2 no output at all; for 0 and 3 every
named output written whole, and no temporary file left.
"""

from __future__ import annotations

import codecs
import hashlib
import json
import math
import random
import re
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fuzzing import Outcome, common_problems, invoke

FAMILIES = ("dh", "pipeline", "export")
ROOT = Path(__file__).parents[1]
SAMPLES = ROOT / "sample_logs"
#: Each shipped pipeline and the sample log it reads.
PIPELINE_LOGS = {
    "ros2_tracker": "kr5_0.01mm.mcap",
    "foxglove_json": "puma560_step.mcap",
    "foxglove_protobuf": "scara.mcap",
    "phase_markers": "kr5_phase.mcap",
}
#: Values no DH field or typed pipeline key may hold (as JSON/TOML text), and the harmless ones.
HUGE = ("1e308", "-1e308", "1e150", "9" * 400, "9" * 5000, "-" + "7" * 5000)
TINY = ("1e-320", "5e-324", "-0.0", "0")


@dataclass(frozen=True)
class Case:
    """One run: the input files written into the case's folder (name, bytes), the command
    (``{d}`` is the folder), the outputs it names on success (relative to the folder), and
    whether the case must be refused (exit 2)."""

    family: str
    name: str
    files: tuple[tuple[str, bytes], ...]
    args: tuple[str, ...]
    outputs: tuple[str, ...]
    refuse: bool


@dataclass(frozen=True)
class Bases:
    """The real inputs the cases start from: DH documents (name, parsed JSON), the DH TOML
    text, pipelines (name, text), and exports (name, text, the import's options)."""

    dh: tuple[tuple[str, dict[str, Any]], ...]
    dh_toml: str
    pipelines: tuple[tuple[str, str], ...]
    exports: tuple[tuple[str, str, tuple[str, ...]], ...]
    joints: str  # the joints file beside the "points" export


def make_bases(folder: Path) -> Bases:
    """The inputs above; the result JSON from ``dhlog process`` of the small KR5 sample log
    (geometric model, about a second)."""
    from typer.testing import CliRunner

    from dhlog.cli.app import app

    folder.mkdir(parents=True, exist_ok=True)
    log = SAMPLES / "kr5_0.01mm.mcap"
    args = ["process", str(log), "--no-rrd", "--out", str(folder), "--model", "geometric"]
    done = CliRunner().invoke(app, [*args, "--force"])
    assert done.exit_code == 0, done.output
    result = json.loads((folder / f"{log.stem}.dh.json").read_text())
    truth = json.loads((SAMPLES / "kr5_0.01mm.truth.json").read_text())
    scara = json.loads((SAMPLES / "scara.truth.json").read_text())
    rows = []
    for row in truth["standard_dh"]:
        rows.append(
            f'{{type = "{row["type"]}", theta_offset = {math.degrees(row["theta_offset"])!r}, '
            f"d_offset = {row['d_offset'] * 1e3!r}, a = {row['a'] * 1e3!r}, "
            f"alpha = {math.degrees(row['alpha'])!r}}}"
        )
    toml = (
        '# KR5 nominal in mm and degrees\nunits = {length = "mm", angle = "deg"}\n'
        "standard_dh = [\n  " + ",\n  ".join(rows) + ",\n]\n\n[tool]\npoint = [0.0, 0.0, 100.0]\n"
    )
    pipelines = tuple(
        (name, (ROOT / "pipelines" / f"{name}.toml").read_text()) for name in PIPELINE_LOGS
    )
    stops = (SAMPLES / "kr5_stops.csv").read_text()
    lines = stops.splitlines()
    points = "\n".join(",".join(line.split(",")[:4]) for line in lines) + "\n"
    joints = "\n".join(",".join([line.split(",")[0], *line.split(",")[4:]]) for line in lines)
    exports = (
        ("stops", stops, ()),
        ("leica", (SAMPLES / "kr5_random_poses.csv").read_text(), ("--format", "leica")),
        ("points", points, ("--joints-file", "{d}/joints.csv")),
    )
    return Bases(
        (("kr5_truth", truth), ("scara_truth", scara), ("kr5_result", result)),
        toml,
        pipelines,
        exports,
        joints + "\n",
    )


# ---------------------------------------------------------------------------- DH files


#: The fields of a DH document dhlog reads: a bad value there must be refused.
DH_VALUES = ("theta_offset", "d_offset", "a", "alpha")


def _leaves(doc: Any, path: tuple[str | int, ...] = ()) -> Iterator[tuple[str | int, ...]]:
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(doc, list) and doc:
        for k, v in enumerate(doc):
            yield from _leaves(v, (*path, k))
    else:
        yield path


def _read_field(path: tuple[str | int, ...]) -> bool:
    """True for a field dhlog reads as a number (a DH value, the base, the tool point)."""
    if len(path) == 3 and path[0] == "standard_dh" and path[2] in DH_VALUES:
        return True
    if path[:2] == ("base", "T_measurement_base") or path[:2] == ("tool", "point"):
        return True
    return False


def _bad_value(rng: random.Random) -> tuple[str, str, bool]:
    """A replacement as JSON text, its name, and whether no number field may hold it."""
    kind = rng.choice(["huge", "tiny", "nan", "type", "deep"])
    if kind == "huge":
        text = rng.choice(HUGE)
        return text, f"huge {text[:8]}", True
    if kind == "tiny":
        text = rng.choice(TINY)
        return text, f"tiny {text}", False
    if kind == "nan":
        text = rng.choice(["NaN", "Infinity", "-Infinity"])
        return text, text, True
    if kind == "type":
        text = rng.choice(['"1.5"', "true", "false", "null", "[1.0]", '{"x": 1}', '""'])
        return text, f"type {text}", True
    depth = rng.choice([10_000, 100_000])
    return "[" * depth + "1" + "]" * depth, f"nested {depth}", True


def _set_text(doc: dict[str, Any], path: tuple[str | int, ...], text: str) -> bytes:
    """``doc`` as JSON with the value at ``path`` replaced by the raw JSON ``text``."""
    sentinel = "@@dhlog-fuzz@@"
    node: Any = doc
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = sentinel
    return json.dumps(doc).replace(f'"{sentinel}"', text, 1).encode()


def _encoded(data: bytes, rng: random.Random) -> tuple[str, bytes, bool]:
    """``data`` damaged as bytes: cut short, UTF-16, a NUL, a byte that is not UTF-8."""
    kind = rng.choice(["truncate", "utf-16", "utf-16 bom", "nul", "latin"])
    if kind == "truncate":
        return kind, data[: rng.randrange(len(data))], False
    if kind == "utf-16":
        return kind, data.decode().encode("utf-16-le"), True
    if kind == "utf-16 bom":
        return kind, codecs.BOM_UTF16_LE + data.decode().encode("utf-16-le"), True
    at = rng.randrange(len(data))
    return kind, data[:at] + (b"\x00" if kind == "nul" else b"\xe9\xff") + data[at:], True


def mutate_dh(doc: dict[str, Any], rng: random.Random) -> tuple[str, bytes, bool]:
    """One mutation of a DH document: (what was done, the bytes, whether it must be refused)."""
    doc = json.loads(json.dumps(doc))
    kind = rng.choice(["value", "value", "value", "drop", "rows", "bytes"])
    leaves = [p for p in _leaves(doc) if p]
    read = [p for p in leaves if _read_field(p)]
    if kind == "value":
        path = rng.choice(read if read and rng.random() < 0.8 else leaves)
        text, what, bad = _bad_value(rng)
        must = bad and _read_field(path)
        return f"{'.'.join(map(str, path))} = {what}", _set_text(doc, path, text), must
    if kind == "drop":
        path = rng.choice(read or leaves)
        node: Any = doc
        for part in path[:-1]:
            node = node[part]
        del node[path[-1]]
        must = len(path) == 3 and path[0] == "standard_dh" and path[2] in ("a", "alpha")
        return f"drop {'.'.join(map(str, path))}", json.dumps(doc).encode(), must
    if kind == "rows":
        rows = doc["standard_dh"]
        how = rng.choice(["empty", "drop", "double", "many", "scalar"])
        if how == "empty":
            doc["standard_dh"] = []
        elif how == "drop":
            rows.pop(rng.randrange(len(rows)))
        elif how == "double":
            rows.insert(0, rows[0])
        elif how == "many":
            doc["standard_dh"] = rows * 20
        else:
            doc["standard_dh"] = 5
        return f"rows {how}", json.dumps(doc).encode(), how in ("empty", "many", "scalar")
    what, data, must = _encoded(json.dumps(doc).encode(), rng)
    return what, data, must


def _joint_count(data: bytes, toml: bool, fallback: int) -> int:
    """The rows of a (mutated) DH file, to give ``fk`` as many joint values; ``fallback``
    when it cannot be told."""
    try:
        import tomllib

        text = data.decode()
        doc = tomllib.loads(text) if toml else json.loads(text)
        rows = doc.get("standard_dh")
        return len(rows) if isinstance(rows, list) and 0 < len(rows) <= 64 else fallback
    except Exception:  # the harness only guesses: dhlog itself judges the file
        return fallback


def dh_case(bases: Bases, rng: random.Random, k: int) -> Case:
    if rng.random() < 0.2:
        name, data, must = _mutated_toml(bases.dh_toml, rng)
        name, file, toml, n = f"kr5_toml: {name}", "nominal.toml", True, 6
    else:
        base, doc = rng.choice(bases.dh)
        n = len(doc["standard_dh"])
        name, data, must = mutate_dh(doc, rng)
        name, file, toml = f"{base}: {name}", "nominal.json", False
    if rng.random() < 0.25:
        log = str(SAMPLES / "kr5_0.01mm.mcap")
        args = ("process", log, "--nominal", "{d}/" + file, "--no-rrd", "--out", "{d}/out")
        args += ("--model", "geometric")
        outputs: tuple[str, ...] = ("out/kr5_0.01mm.dh.json", "out/kr5_0.01mm.dh.csv")
    else:
        q = ",".join(["0"] * _joint_count(data, toml, n))
        args, outputs = ("fk", "{d}/" + file, "--q", q), ()
    return Case("dh", f"dh#{k} {name}"[:200], ((file, data),), args, outputs, must)


# ---------------------------------------------------------------------------- TOML


_KEY_LINE = re.compile(r"^(?P<key>[A-Za-z_][A-Za-z0-9_]*)\s*=\s*(?P<value>.*?)\s*(#.*)?$")
#: Keys of a pipeline whose value is a string, a boolean or a number (checked for its range).
TEXT_KEYS = ("name", "description", "length_unit", "angle_unit", "topic", "model", "child_frame")
BOOL_KEYS = ("required", "orientation", "clock_offset_fixed")
NUMBER_KEYS = (
    "lock_tolerance",
    "motion_window",
    "join_tolerance",
    "min_samples",
    "min_sweep",
    "min_travel",
    "clock_offset",
    "sigma",
    "radial",
    "transverse",
)


def _toml_value(rng: random.Random) -> tuple[str, str]:
    """A replacement value as TOML text, and its kind (``huge``, ``nan``, ``tiny``,
    ``negative``, ``string``, ``bool``, ``array``, ``table``, ``date``, ``deep``)."""
    kind = rng.choice(
        ["huge", "nan", "tiny", "negative", "string", "bool", "array", "table", "date", "deep"]
    )
    text = {
        "huge": rng.choice(["1e308", "1e300", "9" * 400, "9" * 5000, "-" + "9" * 30]),
        "nan": rng.choice(["nan", "inf", "-inf"]),
        "tiny": rng.choice(["1e-320", "5e-324", "0", "0.0"]),
        "negative": rng.choice(["-1", "-0.05", "-1e10"]),
        "string": rng.choice(['"0.05"', '""', '"' + "x" * 5000 + '"']),
        "bool": rng.choice(["true", "false"]),
        "array": rng.choice(["[1, 2]", "[]", '["a", 1]']),
        "table": "{a = 1}",
        "date": "1979-05-27T07:32:00Z",
        "deep": "[" * 50_000 + "]" * 50_000,
    }[kind]
    return text, kind


def _refused_toml(key: str, kind: str) -> bool:
    """Whether a pipeline whose ``key`` holds a value of ``kind`` must be refused."""
    wrong = kind in ("array", "table", "date", "deep")
    if key in TEXT_KEYS:
        return wrong or kind in ("huge", "nan", "tiny", "negative", "bool")
    if key in BOOL_KEYS:
        return kind != "bool"
    if key in NUMBER_KEYS:
        positive = key in ("min_samples", "sigma", "radial", "transverse")
        return (
            wrong
            or kind in ("huge", "nan", "string", "bool")
            or (kind == "negative" and key != "clock_offset")
            or (kind == "tiny" and positive)
        )
    return kind == "deep"


def _mutated_toml(text: str, rng: random.Random) -> tuple[str, bytes, bool]:
    """One mutation of a TOML file (a pipeline or a DH TOML): (what, bytes, must refuse)."""
    lines = text.splitlines()
    keyed = [i for i, line in enumerate(lines) if _KEY_LINE.match(line)]
    kind = rng.choice(["value", "value", "value", "drop", "double", "unknown", "bytes"])
    if kind == "value" and keyed:
        i = rng.choice(keyed)
        m = _KEY_LINE.match(lines[i])
        assert m is not None
        value, what = _toml_value(rng)
        lines[i] = f"{m['key']} = {value}"
        must = _refused_toml(m["key"], what)
        return f"{m['key']} = {what}", ("\n".join(lines) + "\n").encode(), must
    if kind == "drop" and keyed:
        i = rng.choice(keyed)
        gone = lines.pop(i)
        return f"drop {gone[:40]}", ("\n".join(lines) + "\n").encode(), False
    if kind == "double" and keyed:
        i = rng.choice(keyed)
        lines.insert(i, lines[i])
        return f"double {lines[i][:40]}", ("\n".join(lines) + "\n").encode(), True
    if kind == "unknown":
        lines.insert(rng.randrange(len(lines) + 1), "zzz_unknown = 1")
        return "unknown key", ("\n".join(lines) + "\n").encode(), False
    what, data, must = _encoded(text.encode(), rng)
    return what, data, must


def pipeline_case(bases: Bases, rng: random.Random, k: int) -> Case:
    name, text = rng.choice(bases.pipelines)
    what, data, must = _mutated_toml(text, rng)
    log = SAMPLES / PIPELINE_LOGS[name]
    args = ("process", str(log), "--pipeline", "{d}/pipe.toml", "--no-rrd", "--out", "{d}/out")
    outputs = (f"out/{log.stem}.dh.json", f"out/{log.stem}.dh.csv")
    return Case(
        "pipeline",
        f"pipeline#{k} {name}: {what}"[:200],
        (("pipe.toml", data),),
        (*args, "--model", "geometric"),
        outputs,
        must,
    )


# ---------------------------------------------------------------------------- exports


#: Columns whose cells the import reads as numbers (by header, before any unit).
READ_COLUMNS = re.compile(r"^(x|y|z|u\(?95\)?|q[0-3]|a[1-6]|j[1-6])\b", re.IGNORECASE)


def mutate_export(text: str, rng: random.Random) -> tuple[str, bytes, bool]:
    """One mutation of a CSV export: (what, bytes, must refuse)."""
    lines = text.splitlines()
    sep = ";" if lines[0].count(";") > lines[0].count(",") else ","
    header = lines[0].split(sep)
    rows = [line.split(sep) for line in lines[1:]]
    kind = rng.choice(["cell", "cell", "cell", "column", "header", "row", "line", "bytes"])

    def joined() -> bytes:
        return ("\n".join(sep.join(r) for r in [header, *rows]) + "\n").encode()

    if kind == "cell":
        c = rng.randrange(len(header))
        r = rng.randrange(len(rows))
        value = rng.choice(
            ["1e308", "-1e308", "1e999", "nan", "inf", "oops", "", "9" * 5000, "1e-320", "1,5"]
        )
        if value == "1,5" and sep == ";":
            value = "1.000,5"  # a thousands separator: refused in a ';' table
        rows[r][c] = value
        read = bool(READ_COLUMNS.match(header[c].strip()))
        u95 = "95" in header[c]
        must = read and (value not in ("1e-320",) or u95)
        must = must or value == "1,5"  # an extra field in a ',' table
        return f"cell {header[c]!r} line {r + 2} = {value[:8]}", joined(), must
    if kind == "column":
        c = rng.randrange(len(header))
        how = rng.choice(["drop", "double", "swap"])
        if how == "drop":
            for row in [header, *rows]:
                row.pop(c)
            return f"drop column {c}", joined(), False
        if how == "double":
            for row in [header, *rows]:
                row.insert(c, row[c])
            must = bool(READ_COLUMNS.match(header[c].strip()))
            return f"double column {header[c]!r}", joined(), must
        d = rng.randrange(len(header))
        for row in [header, *rows]:
            row[c], row[d] = row[d], row[c]
        return f"swap columns {c}, {d}", joined(), False
    if kind == "header":
        c = rng.randrange(len(header))
        how = rng.choice(["rename", "unit", "suffix"])
        if how == "rename":
            header[c] = header[rng.randrange(len(header))]
        elif how == "unit":
            header[c] = header[c].split(" [")[0] + rng.choice([" [m]", " [ft]", " [rad]", " []"])
        else:
            header[c] = header[c].split(" [")[0] + rng.choice(["_m", "/mm", " in m", "_deg"])
        return f"header {how} {c}: {header[c]!r}", joined(), False
    if kind == "row":
        r = rng.randrange(len(rows))
        how = rng.choice(["extra", "short", "long field", "quote"])
        if how == "extra":
            rows[r].append("7")
        elif how == "short":
            rows[r] = rows[r][: rng.randrange(1, len(rows[r]))]
        elif how == "long field":
            rows[r][rng.randrange(len(rows[r]))] = "1" * 200_000
        else:
            rows[r][rng.randrange(len(rows[r]))] = '"1'
        return f"row {r + 2} {how}", joined(), how in ("extra", "short", "long field")
    if kind == "line":
        r = rng.randrange(len(rows))
        other = "\t" if sep == "," else ","
        rows[r] = [other.join(rows[r])]
        return f"line {r + 2} separated by {other!r}", joined(), True
    what, data, _ = _encoded(text.encode(), rng)
    return what, data, what in ("nul", "utf-16")


def export_case(bases: Bases, rng: random.Random, k: int) -> Case:
    name, text, options = rng.choice(bases.exports)
    joints = bases.joints
    if name == "points" and rng.random() < 0.5:
        what, data, must = mutate_export(joints, rng)
        files = (("export.csv", text.encode()), ("joints.csv", data))
        what = f"joints file: {what}"
    else:
        what, data, must = mutate_export(text, rng)
        files = (("export.csv", data),) + (
            (("joints.csv", joints.encode()),) if name == "points" else ()
        )
    args = ("import", "{d}/export.csv", *options, "-o", "{d}/export.mcap")
    return Case("export", f"export#{k} {name}: {what}"[:200], files, args, ("export.mcap",), must)


# ---------------------------------------------------------------------------- cases


_MAKERS: dict[str, Callable[[Bases, random.Random, int], Case]] = {
    "dh": dh_case,
    "pipeline": pipeline_case,
    "export": export_case,
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


def _state(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` and its SHA-256."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def run_case(case: Case, folder: Path, *, timeout: float = 30.0) -> Outcome:
    """Run ``case`` in this process through Typer's runner and judge it."""
    work = folder / "case"
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for name, data in case.files:
        (work / name).write_bytes(data)
    before = _state(work)
    ran = invoke([a.replace("{d}", str(work)) for a in case.args], timeout)
    if ran is None:
        return Outcome(case.name, case.family, -1, (f"hang (over {timeout:g} s)",), "", timeout)
    problems, new = common_problems(ran, before, _state(work), codes=(0, 2, 3), refuse=case.refuse)
    lines = [line for line in ran.stderr.splitlines() if line.strip()]
    if ran.code in (2, 3) and len(lines) != 1:
        problems.append(f"{len(lines)} lines on stderr")
    if any(n.startswith(".") or "/." in n or ".part" in n or "tmp" in n for n in new):
        problems.append(f"temporary files left: {new}")
    if ran.code in (0, 3) and not set(case.outputs) <= set(new):
        problems.append(f"outputs {new}, expected {list(case.outputs)}")
    shown = ran.stderr.strip()[-400:]
    return Outcome(case.name, case.family, ran.code, tuple(problems), shown, ran.seconds)
