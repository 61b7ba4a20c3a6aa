"""Hostile inputs of ``compare``, ``export`` and ``batch`` (issue 20): damaged result JSONs, batch
summaries and URDF templates, names that land in outputs, outputs that are inputs.

Each damaged input ends in exit 2 with one line naming the file and the field (or column, line)
and what to do, no traceback, nothing written, the input's bytes unchanged; outputs stay
well-formed whatever the names hold. Then seeded cases of ``tests/fuzz_results.py``, judged by
the same rules.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

import polars as pl
import pytest
import yaml
from typer.testing import CliRunner

from dhlog.cli.app import app
from fuzz_results import (
    FAMILIES,
    LAUGHS,
    Bases,
    cases,
    check_output,
    make_bases,
    run_case,
    summary_bytes,
)

runner = CliRunner()


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> Bases:
    """One ``dhlog process`` of a small sample log (about 2 s), and what is drawn from it."""
    return make_bases(tmp_path_factory.mktemp("bases"))


def _digests(folder: Path) -> dict[str, str]:
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not path.is_symlink():
            st = path.stat()
            big = st.st_size > 2**24
            out[str(path.relative_to(folder))] = (
                f"{st.st_size}/{st.st_mtime_ns}"
                if big
                else hashlib.sha256(path.read_bytes()).hexdigest()
            )
    return out


def _refused(folder: Path, args: list[str], *mentions: str) -> str:
    """Run ``args``; exit 2, one line on stderr (naming ``mentions``), nothing on stdout, no file
    added or changed under ``folder``. Returns the line."""
    before = _digests(folder)
    done = runner.invoke(app, args)
    assert done.exception is None or isinstance(done.exception, SystemExit), done.exception
    assert done.exit_code == 2, done.output
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and not done.stdout.strip(), done.output
    assert "Traceback" not in done.output
    for text in mentions:
        assert text in lines[0], (text, lines[0])
    assert _digests(folder) == before
    return lines[0]


def _result(bases: Bases, change: Callable[[dict[str, Any]], Any]) -> bytes:
    doc = json.loads(json.dumps(bases.hayati))
    out = change(doc)
    return out if isinstance(out, bytes) else json.dumps(doc).encode()


def _deep(doc: dict[str, Any]) -> bytes:
    doc["standard_dh"][0]["a"] = "@@"
    return json.dumps(doc).replace('"@@"', "[" * 100_000 + "]" * 100_000).encode()


def _digits(doc: dict[str, Any]) -> bytes:
    doc["standard_dh"][2]["d_offset"] = "@@"
    return json.dumps(doc).replace('"@@"', "9" * 5000).encode()


def _token(path: str, token: str) -> Callable[[dict[str, Any]], bytes]:
    def change(doc: dict[str, Any]) -> bytes:
        row, key = path.split(".")
        doc["standard_dh"][int(row)][key] = "@@"
        return json.dumps(doc).replace('"@@"', token).encode()

    return change


def _set(path: str, value: object) -> Callable[[dict[str, Any]], None]:
    def change(doc: dict[str, Any]) -> None:
        node: Any = doc
        keys = [int(k) if k.isdigit() else k for k in path.split(".")]
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value

    return change


def _delete(path: str) -> Callable[[dict[str, Any]], None]:
    def change(doc: dict[str, Any]) -> None:
        node: Any = doc
        keys = [int(k) if k.isdigit() else k for k in path.split(".")]
        for key in keys[:-1]:
            node = node[key]
        del node[keys[-1]]

    return change


DAMAGED_RESULTS: list[tuple[str, Callable[[dict[str, Any]], Any], str]] = [
    ("missing a", _delete("standard_dh.1.a"), "standard_dh[1].a is missing"),
    ("null alpha", _set("standard_dh.2.alpha", None), "standard_dh[2].alpha is null"),
    ("list θ", _set("standard_dh.0.theta_offset", [1.0]), "standard_dh[0].theta_offset is a list"),
    ("boolean a", _set("standard_dh.3.a", True), "standard_dh[3].a is true/false"),
    ("text tool", _set("tool.point", "0 0 0.1"), "tool.point is text"),
    ("short tool", _set("tool.point", [0.0, 0.1]), "tool.point has 2 entries"),
    ("1e308", _token("0.a", "1e308"), "standard_dh[0].a is 1e+308, beyond ±1000 m"),
    ("inf", _token("4.alpha", "-1e999"), "standard_dh[4].alpha is not a finite number"),
    ("NaN", _token("5.theta_offset", "NaN"), "standard_dh[5].theta_offset is not a finite"),
    ("5000 digits", _digits, "standard_dh[2].d_offset is not a finite number"),
    ("deep field", _deep, "nested too deeply"),
    ("deep file", lambda doc: b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    ("no table", _delete("standard_dh"), "standard_dh is missing"),
    ("table of text", _set("standard_dh", ["a", "b"]), "standard_dh[0] is text"),
    ("Hayati list", _set("hayati_dh", [1, 2]), "hayati_dh is a list, not an object"),
    ("Hayati β", _delete("hayati_dh.rows.1.beta"), "hayati_dh.rows[1].beta is missing"),
    ("Hayati rows", _set("hayati_dh.rows", [{}]), "hayati_dh.rows has 1 rows, standard_dh 6"),
    ("Hayati form", _set("hayati_dh.rows.0.form", "mdh"), "hayati_dh.rows[0].form must be dh"),
    ("σ list", _set("standard_dh.0.std", [1e-6]), "standard_dh[0].std is a list"),
    ("σ negative", _set("standard_dh.1.std.a", -1e-6), "standard_dh[1].std.a is -1e-06"),
    ("fixed number", _set("standard_dh.0.fixed", 3), "standard_dh[0].fixed is a number"),
    ("base not rigid", _set("base.T_measurement_base.0.0", 2.0), "is not a rigid transform"),
    ("base 3x3", _set("base.T_measurement_base", [[1, 0, 0]] * 3), "must be a 4×4 list"),
    ("joint name", _set("joints.2.name", "j\n3"), "joints[2].name holds the character U+000A"),
    ("joint type", _set("joints.1.type", "ball"), "joints[1].type must be one of"),
    ("units", _set("units", {"length": "inch"}), "units.length must be m or mm"),
    ("terms", _set("nongeometric", {"terms": 5}), "nongeometric.gravity"),
    ("object", lambda doc: b"[1, 2, 3]", "holds a list, not an object"),
    ("UTF-16", lambda doc: json.dumps(doc).encode("utf-16"), "is not UTF-8 text"),
    ("cut short", lambda doc: json.dumps(doc).encode()[:5000], "is not valid JSON"),
    ("binary", lambda doc: bytes(range(256)) * 8, "is not UTF-8 text"),
]


@pytest.mark.parametrize("command", ["compare", "urdf", "rtb", "template"])
@pytest.mark.parametrize(
    ("label", "change", "said"), DAMAGED_RESULTS, ids=[c[0] for c in DAMAGED_RESULTS]
)
def test_a_damaged_result_is_one_line_naming_the_field(
    label: str,
    change: Callable[[dict[str, Any]], Any],
    said: str,
    command: str,
    bases: Bases,
    tmp_path: Path,
) -> None:
    bad = tmp_path / "bad.dh.json"
    bad.write_bytes(_result(bases, change))
    real = tmp_path / "real.dh.json"
    real.write_text(json.dumps(bases.result))
    (tmp_path / "t.urdf").write_text(bases.template)
    args = {
        "compare": ["compare", str(real), str(bad)],
        "urdf": ["export", str(bad), "-o", str(tmp_path / "o.urdf")],
        "rtb": ["export", str(bad), "-o", str(tmp_path / "o.py"), "--format", "rtb"],
        "template": ["export", str(bad), "-o", str(tmp_path / "o.urdf"), "--template"],
    }[command]
    if command == "template":
        args.append(str(tmp_path / "t.urdf"))
    line = _refused(tmp_path, args, str(bad), said)
    assert "; " in line or "give" in line  # and what to do


def test_results_over_the_size_limit_folders_and_devices_are_refused_before_reading(
    bases: Bases, tmp_path: Path
) -> None:
    real = tmp_path / "real.dh.json"
    real.write_text(json.dumps(bases.result))
    big = tmp_path / "big.dh.json"
    with open(big, "wb") as f:  # sparse: 101 MiB on paper
        f.write(b'{"standard_dh": [')
        f.truncate(101 * 2**20)
    start = time.monotonic()
    _refused(tmp_path, ["compare", str(real), str(big)], "over 100 MiB")
    _refused(tmp_path, ["export", str(big), "-o", str(tmp_path / "o.urdf")], "over 100 MiB")
    assert time.monotonic() - start < 5
    _refused(tmp_path, ["compare", str(real), str(tmp_path)], "is a folder")
    _refused(tmp_path, ["export", "/dev/zero", "-o", str(tmp_path / "o.urdf")], "regular file")


# ---------------------------------------------------------------------------- summaries


def _summary_frame(bases: Bases) -> pl.DataFrame:
    from dhlog.fleet.batch import summary_frame

    return summary_frame(bases.rows)


def _column(frame: pl.DataFrame, name: str, values: list[Any], dtype: Any) -> pl.DataFrame:
    return frame.with_columns(pl.Series(name, values, dtype=dtype))


DAMAGED_SUMMARIES: list[tuple[str, str, Callable[[pl.DataFrame], pl.DataFrame], str]] = [
    ("no robot", "csv", lambda f: f.drop("robot"), "no column robot"),
    ("no status", "parquet", lambda f: f.drop("status"), "no column status"),
    (
        "text in a_2",
        "csv",
        lambda f: _column(f, "a_2", ["0.6", "0.6", "abc", "0.6", None], pl.String),
        "column a_2, line 4: 'abc' is not a number",
    ),
    (
        "text in a_2",
        "parquet",
        lambda f: _column(f, "a_2", ["0.6", "x", "0.6", "0.6", None], pl.String),
        "column a_2, row 2: 'x' is not a number",
    ),
    (
        "list in a_2",
        "parquet",
        lambda f: _column(f, "a_2", [[1.0]] * 5, pl.List(pl.Float64)),
        "column a_2 holds List(Float64), not numbers",
    ),
    (
        "inf",
        "parquet",
        lambda f: _column(f, "theta_3", [0.0, float("inf"), 0.0, 0.0, None], pl.Float64),
        "column theta_3, row 2: inf is not a value within ±100 rad",
    ),
    (
        "1e308",
        "csv",
        lambda f: _column(f, "tool_z", [0.1, 0.1, 1e308, 0.1, None], pl.Float64),
        "column tool_z, line 4: 1e+308 is not a value within ±1000 m",
    ),
    (
        "negative σ",
        "csv",
        lambda f: _column(f, "std_a_2", [1e-6, -1e-6, 1e-6, 1e-6, None], pl.Float64),
        "column std_a_2, line 3: -1e-06 is not a σ",
    ),
    (
        "not a time",
        "csv",
        lambda f: _column(
            f, "session_start", ["yesterday", *f["session_start"].to_list()[1:]], pl.String
        ),
        "column session_start of",
    ),
    (
        "year 9999",
        "parquet",
        lambda f: _column(
            f,
            "session_start",
            ["9999-12-31T00:00:00+00:00", *f["session_start"].to_list()[1:]],
            pl.String,
        ),
        "not a time from 1970 to 2262",
    ),
    (
        "status numbers",
        "parquet",
        lambda f: _column(f, "status", [1, 2, 3, 4, 5], pl.Int64),
        "needs two identified sessions",
    ),
    (
        "robots mixed",
        "csv",
        lambda f: _column(f, "robot", ["a", "b", "[/]c\n", "a", None], pl.String),
        "holds sessions of different robots",
    ),
    (
        "20 000 columns",
        "csv",
        lambda f: f.hstack(pl.DataFrame({f"a_{k + 9}": [0.1] * f.height for k in range(20_000)})),
        "columns, more than a batch summary has (at most 1024)",
    ),
    (
        "20 000 columns",
        "parquet",
        lambda f: f.hstack(pl.DataFrame({f"d_{k + 9}": [0.1] * f.height for k in range(20_000)})),
        "columns, more than a batch summary has",
    ),
]


@pytest.mark.parametrize(
    ("label", "fmt", "change", "said"),
    DAMAGED_SUMMARIES,
    ids=[f"{c[0]}-{c[1]}" for c in DAMAGED_SUMMARIES],
)
def test_a_damaged_summary_is_one_line_naming_the_column(
    label: str,
    fmt: str,
    change: Callable[[pl.DataFrame], pl.DataFrame],
    said: str,
    bases: Bases,
    tmp_path: Path,
) -> None:
    frame = change(_summary_frame(bases))
    path = tmp_path / f"summary.{fmt}"
    if fmt == "csv":
        frame.write_csv(path)
    else:
        frame.write_parquet(path)
    start = time.monotonic()
    _refused(tmp_path, ["compare", str(path), "--rrd", str(tmp_path / "t.rrd")], str(path), said)
    assert time.monotonic() - start < 10  # 20 000 columns hung for minutes


def test_summaries_cut_short_or_garbled_or_too_big_are_one_line(
    bases: Bases, tmp_path: Path
) -> None:
    parquet = summary_bytes(bases.rows, "parquet")
    csv = summary_bytes(bases.rows, "csv")
    cut = tmp_path / "cut.parquet"
    cut.write_bytes(parquet[: len(parquet) // 2])
    _refused(tmp_path, ["compare", str(cut)], "cannot be read as a batch summary")
    wide = tmp_path / "utf16.csv"
    wide.write_bytes(csv.decode().encode("utf-16"))
    _refused(tmp_path, ["compare", str(wide)], str(wide))
    big = tmp_path / "big.csv"
    with open(big, "wb") as f:
        f.write(csv)
        f.truncate(101 * 2**20)
    _refused(tmp_path, ["compare", str(big)], "over 100 MiB")


def test_an_intact_summary_and_result_still_compare(bases: Bases, tmp_path: Path) -> None:
    """The control: what the hostile cases start from passes (markup in names included)."""
    frame = _summary_frame(bases).rename({"a_2": "a_[/]2"})
    frame = frame.with_columns(pl.col("log") + "[bold]")
    path = tmp_path / "s.csv"
    frame.write_csv(path)
    done = runner.invoke(app, ["compare", str(path)])
    assert done.exit_code == 0, done.output
    assert "a_[/]2" in done.stdout
    real = tmp_path / "r.dh.json"
    real.write_text(json.dumps(bases.result))
    hayati = tmp_path / "h.dh.json"
    hayati.write_text(json.dumps(bases.hayati))
    done = runner.invoke(app, ["compare", str(real), str(hayati)])
    assert done.exit_code == 0, done.output
    assert "no parameter changed" in done.stdout


# ---------------------------------------------------------------------------- templates


def _template(bases: Bases, tmp_path: Path, change: Callable[[str], str] | None = None) -> Path:
    path = tmp_path / "t.urdf"
    path.write_text(change(bases.template) if change else bases.template)
    return path


DAMAGED_TEMPLATES: list[tuple[str, Callable[[str], str], str]] = [
    (
        "entities",
        lambda t: LAUGHS + t.split("\n", 1)[1].replace("<robot ", "<robot n='&i;' ", 1),
        "DOCTYPE",
    ),
    (
        "external entity",
        lambda t: (
            '<?xml version="1.0"?>\n<!DOCTYPE r [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
            + t.split("\n", 1)[1].replace("<robot ", "<robot n='&x;' ", 1)
        ),
        "DOCTYPE",
    ),
    (
        "deep",
        lambda t: t.replace("</robot>", "<a>" * 100_000 + "</a>" * 100_000 + "</robot>"),
        "nested more than 64 deep",
    ),
    ("cut short", lambda t: t[: len(t) // 2], "is not well-formed XML"),
    ("undefined entity", lambda t: t.replace("<robot ", "<robot n='&nbsp;' ", 1), "undefined"),
    ("root", lambda t: t.replace("<robot ", "<model ").replace("</robot>", "</model>"), "<model>"),
    (
        "only in a transmission",
        lambda t: t.replace('<joint name="joint_3"', '<joint name="elbow"'),
        "has no joint joint_3 of the result",
    ),
    (
        "xyz",
        lambda t: t.replace('<axis xyz="0 0 1"', '<axis xyz="nan 0 1"', 1),
        "xyz='nan 0 1' is not three numbers",
    ),
    ("zero axis", lambda t: t.replace('<axis xyz="0 0 1"', '<axis xyz="0 0 0"', 1), "zero axis"),
    (
        "loop",
        lambda t: t.replace('<parent link="base_link" />', '<parent link="link_4" />'),
        "form a loop",
    ),
    (
        "two joints alike",
        lambda t: t.replace('name="joint_4"', 'name="joint_5"', 1),
        "has two joints named joint_5",
    ),
    ("type", lambda t: t.replace('type="revolute"', 'type="ball"', 1), "has type 'ball'"),
    ("no parent", lambda t: t.replace('<parent link="link_2" />', "", 1), "needs <parent"),
]


@pytest.mark.parametrize(
    ("label", "change", "said"), DAMAGED_TEMPLATES, ids=[c[0] for c in DAMAGED_TEMPLATES]
)
def test_a_damaged_template_is_one_line(
    label: str, change: Callable[[str], str], said: str, bases: Bases, tmp_path: Path
) -> None:
    result = tmp_path / "r.dh.json"
    result.write_text(json.dumps(bases.result))
    template = _template(bases, tmp_path, change)
    args = ["export", str(result), "-o", str(tmp_path / "o.urdf"), "--template", str(template)]
    start = time.monotonic()
    _refused(tmp_path, args, str(template), said)
    assert time.monotonic() - start < 5


def test_a_template_with_a_100_mb_comment_is_refused_before_parsing(
    bases: Bases, tmp_path: Path
) -> None:
    result = tmp_path / "r.dh.json"
    result.write_text(json.dumps(bases.result))
    template = tmp_path / "t.urdf"
    with open(template, "wb") as f:
        f.write(bases.template.encode().replace(b"</robot>", b"<!-- "))
        f.truncate(100 * 2**20)  # sparse: the comment runs on for 100 MB
    start = time.monotonic()
    args = ["export", str(result), "-o", str(tmp_path / "o.urdf"), "--template", str(template)]
    _refused(tmp_path, args, "over 16 MiB")
    assert time.monotonic() - start < 5


def test_origins_go_only_into_the_robots_own_joints(bases: Bases, tmp_path: Path) -> None:
    """A ``<transmission>`` names joint_2 with a ``<joint>`` of its own: it gets no origin; the
    robot's joint_2 gets the calibrated one, and the output reproduces the result's FK."""
    import numpy as np
    import yourdfpy

    from dhlog.io.dhfile import load_dh
    from dhlog.model.fk import fk_point

    result = tmp_path / "r.dh.json"
    result.write_text(json.dumps(bases.result))
    template = _template(bases, tmp_path)
    out = tmp_path / "o.urdf"
    done = runner.invoke(app, ["export", str(result), "-o", str(out), "--template", str(template)])
    assert done.exit_code == 0, done.output
    assert check_output("template", out) == []
    robot = ET.parse(out).getroot()
    nested = robot.find("transmission/joint")
    assert nested is not None and nested.find("origin") is None
    own = robot.find("joint[@name='joint_2']")
    assert own is not None and len(own.findall("origin")) == 1
    model = yourdfpy.URDF.load(str(out), load_meshes=False)
    dh = load_dh(result)
    q = np.random.default_rng(1).uniform(-2, 2, (30, 6))
    want = fk_point(dh.table, q, dh.tool_point, T_base=dh.T_base)
    for qi, p in zip(q, want, strict=True):
        model.update_cfg(qi)
        got = model.get_transform("dhlog_target", "dhlog_measurement")[:3, 3]
        assert np.abs(got - p).max() < 1e-9


# ---------------------------------------------------------------------------- names in outputs


@pytest.mark.parametrize(
    "name", ["r--x-", 'x"""y', "new\nline", "a<b>&\"c'", "[bold red]m", "back\\", "\u2028", "ü✓"]
)
def test_outputs_stay_well_formed_whatever_the_file_name_holds(
    name: str, bases: Bases, tmp_path: Path
) -> None:
    result = tmp_path / f"{name}.dh.json"
    result.write_text(json.dumps(bases.hayati))
    template = _template(bases, tmp_path)
    for fmt, check in (
        ("urdf", "xml"),
        ("ur", "yaml"),
        ("rtb", "python"),
        ("dh-json", "json"),
        ("dh-csv", "csv"),
        ("template", "template"),
    ):
        out = tmp_path / f"out.{fmt}"
        extra = ["--template", str(template)] if fmt == "template" else ["--format", fmt]
        done = runner.invoke(app, ["export", str(result), "-o", str(out), *extra])
        assert done.exit_code == 0, done.output
        assert check_output(check, out) == [], (fmt, out.read_text()[:300])
    tree = ast.parse((tmp_path / "out.rtb").read_text())
    docstring = ast.get_docstring(tree)
    assert docstring is not None and docstring.startswith(repr(result.name))
    kinematics = yaml.safe_load((tmp_path / "out.ur").read_text())["kinematics"]
    assert set(kinematics) >= {"shoulder", "wrist_3", "hash"}


def test_undecodable_file_names_and_xml_characters_in_joint_names(
    bases: Bases, tmp_path: Path
) -> None:
    doc = json.loads(json.dumps(bases.result))
    hostile = ['a<b>&"c', "d--e", "f-", '"""', "[/]g", "ü✓", "j'", "k&amp;"]
    for joint, name in zip(doc["joints"], hostile, strict=False):
        joint["name"] = name
    result = tmp_path / os.fsdecode(b"r\xff\xfe--.dh.json")
    result.write_text(json.dumps(doc))
    out = tmp_path / "o.urdf"
    done = runner.invoke(app, ["export", str(result), "-o", str(out)])
    assert done.exit_code == 0, done.output
    robot = ET.parse(out).getroot()
    assert [j.get("name") for j in robot.findall("joint")][1:7] == hostile[:6]
    for fmt, check in (("dh-csv", "csv"), ("dh-json", "json"), ("rtb", "python")):
        other = tmp_path / f"o.{fmt}"
        done = runner.invoke(app, ["export", str(result), "-o", str(other), "--format", fmt])
        assert done.exit_code == 0, done.output
        assert check_output(check, other) == []


def test_markup_in_paths_and_values_is_never_read_as_markup(bases: Bases, tmp_path: Path) -> None:
    result = tmp_path / "r.dh.json"
    result.write_text(json.dumps(bases.result))
    (tmp_path / "[").mkdir()
    out = tmp_path / "[/]o.urdf"
    done = runner.invoke(app, ["export", str(result), "-o", str(out)])
    assert done.exit_code == 0 and out.exists() and "[/]o.urdf" in done.stdout, done.output
    summary = tmp_path / "[/]s.parquet"
    summary.write_bytes(summary_bytes(bases.rows, "parquet"))
    done = runner.invoke(app, ["compare", str(summary), "--rrd", str(tmp_path / "[/]t.rrd")])
    assert done.exit_code == 0 and (tmp_path / "[/]t.rrd").stat().st_size > 0, done.output
    for args in (
        ["export", str(result), "-o", str(tmp_path / "x.urdf"), "--format", "[/]"],
        ["batch", str(result), "--out", str(tmp_path / "b"), "--units", "[/]"],
        ["batch", str(result), "--out", str(tmp_path / "b"), "--model", "[/]"],
    ):
        done = runner.invoke(app, args)
        assert done.exit_code == 1 and "[/]" in done.stderr, done.output
        assert len(done.stderr.strip().splitlines()) == 1 and done.exception is not None
        assert isinstance(done.exception, SystemExit)


def test_batch_into_a_folder_named_with_markup(tmp_path: Path) -> None:
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    out = tmp_path / "[/]o"
    done = runner.invoke(app, ["batch", str(broken), "--out", str(out), "--no-rrd"])
    assert done.exit_code == 3, done.output  # the one log failed; the summary is written
    assert (out / "summary.csv").exists() and (out / "summary.parquet").exists()


# ---------------------------------------------------------------------------- outputs = inputs


def test_an_export_never_writes_over_its_inputs(bases: Bases, tmp_path: Path) -> None:
    result = tmp_path / "r.dh.json"
    result.write_text(json.dumps(bases.result))
    template = _template(bases, tmp_path)
    (tmp_path / "sym.json").symlink_to("r.dh.json")
    os.link(result, tmp_path / "hard.json")
    for args in (
        ["export", str(result), "-o", str(result), "--format", "dh-json"],
        ["export", str(result), "-o", str(result), "--format", "dh-json", "--force"],
        ["export", str(result), "-o", str(tmp_path / "sub" / ".." / "r.dh.json"), "--force"],
        ["export", str(result), "-o", str(tmp_path / "sym.json"), "--force"],
        ["export", str(result), "-o", str(tmp_path / "hard.json"), "--force"],
        ["export", str(result), "-o", str(template), "--template", str(template), "--force"],
        ["export", str(result), "-o", str(result), "--limits-from", str(result), "--force"],
    ):
        (tmp_path / "sub").mkdir(exist_ok=True)
        _refused(tmp_path, args, "would be overwritten")


def test_compare_never_writes_its_recording_over_the_summary(bases: Bases, tmp_path: Path) -> None:
    for fmt in ("csv", "parquet"):
        summary = tmp_path / f"summary.{fmt}"
        summary.write_bytes(summary_bytes(bases.rows, fmt))
        _refused(tmp_path, ["compare", str(summary), "--rrd", str(summary)], "would be overwritten")


def test_batch_never_writes_over_its_inputs(bases: Bases, tmp_path: Path) -> None:
    """``batch out/summary.parquet … --out out``, a log named as another's recording, the nominal
    DH file as the summary: exit 2 before any work, with or without --force."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.parquet").write_bytes(summary_bytes(bases.rows, "parquet"))
    (out / "summary.csv").write_bytes(summary_bytes(bases.rows, "csv"))
    broken = tmp_path / "a.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    (out / "a.rrd").write_bytes(b"not a recording")
    for args in (
        ["batch", str(out / "summary.parquet"), str(broken), "--out", str(out)],
        ["batch", str(broken), str(out / "summary.parquet"), "--out", str(out), "--force"],
        ["batch", str(broken), str(out / "a.rrd"), "--out", str(out), "--force"],
        ["batch", str(broken), "--nominal", str(out / "summary.csv"), "--out", str(out)],
    ):
        _refused(tmp_path, args, "would be overwritten")


def test_batch_leaves_no_summary_csv_without_its_parquet(
    bases: Bases, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A summary.parquet that is a folder: exit 2 before any log is processed. And when the
    parquet cannot be moved into place after the CSV was, the CSV is taken back."""
    from dhlog.fleet import batch
    from dhlog.io import writer

    out = tmp_path / "out"
    (out / "summary.parquet").mkdir(parents=True)
    broken = tmp_path / "a.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)
    _refused(tmp_path, ["batch", str(broken), "--out", str(out), "--force"], "is a folder")
    assert sorted(p.name for p in out.iterdir()) == ["summary.parquet"]

    folder = tmp_path / "direct"
    folder.mkdir()
    publish = writer.publish

    def refuse_parquet(tmp: str | Path, target: str | Path) -> None:
        if str(target).endswith(".parquet"):
            raise OSError(28, "No space left on device")
        publish(tmp, target)

    monkeypatch.setattr(writer, "publish", refuse_parquet)
    with pytest.raises(OSError):
        batch.write_summary(batch.summary_frame(bases.rows), folder)
    assert list(folder.iterdir()) == []


# ---------------------------------------------------------------------------- seeded cases

CASES_PER_FAMILY = 30


@pytest.mark.parametrize("family", FAMILIES)
def test_hostile_inputs_never_end_in_a_traceback(family: str, bases: Bases, tmp_path: Path) -> None:
    """30 seeded cases a family (``tests/fuzz_results.py``): exit 0 or 2 (2 where the case must
    be refused), no traceback, one line on 2, inputs unchanged, no partial or malformed output."""
    failures, codes = [], []
    seed = 200 + FAMILIES.index(family)
    for case in cases(seed, CASES_PER_FAMILY, bases, (family,)):
        outcome = run_case(case, tmp_path, timeout=20.0)
        codes.append(outcome.exit_code)
        if outcome.problems:
            failures.append(f"{outcome.case!a}: {', '.join(outcome.problems)}: {outcome.stderr!a}")
    assert not failures, "\n".join(failures[:10])
    if family in ("result", "summary", "template"):  # cases that pass, and cases refused
        assert 0 in codes and 2 in codes
