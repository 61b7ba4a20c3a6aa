"""Hostile inputs beside the log (issue 20, "the new inputs"): nominal DH files and result JSONs
read as models, pipeline files, tracker exports and joints files for ``dhlog import``. Each is
refused the way the log reader refuses a damaged log: exit 2, one line on stderr naming the file
(and the line, field or column) and what to do, no traceback, nothing written, the input
unchanged. Also the few inputs now read rather than refused (a header's unit without brackets,
joint columns out of order, decimal commas in a ``;`` table, UTF-16 exports), the degenerate
data behind ``fit_line``'s and ``whiten``'s divisions, and an import of many stops (the seconds
it takes are in docs/robustness.md)."""

from __future__ import annotations

import codecs
import hashlib
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.errors import DhlogError, GeometryError, InputError

ROOT = Path(__file__).parents[1]
SAMPLE = ROOT / "sample_logs" / "kr5_0.01mm.mcap"
TRUTH = ROOT / "sample_logs" / "kr5_0.01mm.truth.json"
PIPELINE = ROOT / "pipelines" / "ros2_tracker.toml"
runner = CliRunner()


def _digest(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def refused(args: list[str], folder: Path, names: str, says: str, code: int = 2) -> str:
    """Run ``dhlog args`` and check the refusal: exit ``code``, one line on stderr holding
    ``names`` (the file) and ``says``, no traceback, the folder's files unchanged and nothing
    new in it. The line, for more checks."""
    before = _digest(folder)
    result = runner.invoke(app, args)
    crashed = result.exception is not None and not isinstance(result.exception, SystemExit)
    assert not crashed, repr(result.exception)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.exit_code == code, (result.exit_code, result.stderr, result.stdout)
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    assert names in lines[0] and says in lines[0], lines[0]
    assert _digest(folder) == before, "an input changed or an output was written"
    return lines[0]


# ---------------------------------------------------------------------------- DH files


def _truth() -> dict[str, Any]:
    return dict(json.loads(TRUTH.read_text()))


def _dh(change: Callable[[dict[str, Any]], None]) -> bytes:
    doc = _truth()
    change(doc)
    return json.dumps(doc).encode()


def _set(path: str, value: object) -> Callable[[dict[str, Any]], None]:
    """A change setting the field at ``path`` (``standard_dh.0.a``) to ``value``."""

    def change(doc: dict[str, Any]) -> None:
        *head, last = path.split(".")
        node: Any = doc
        for part in head:
            node = node[int(part)] if isinstance(node, list) else node[part]
        if isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value

    return change


def _huge_integer(digits: int) -> bytes:
    text = TRUTH.read_text()
    doc = json.loads(text)
    a = json.dumps(doc["standard_dh"][1]["a"])
    return text.replace(f'"a": {a}', '"a": ' + "9" * digits, 1).encode()


DH_CASES: list[tuple[str, str, bytes, str]] = [
    (
        "boolean",
        "dh.json",
        _dh(_set("standard_dh.0.a", True)),
        "standard_dh[0] (joint 1).a is true",
    ),
    ("1e308", "dh.json", _dh(_set("standard_dh.2.a", 1e308)), "beyond ±100 m"),
    ("5000 digits", "dh.json", _huge_integer(5000), "more than 4300 digits"),
    ("400 digits", "dh.json", _huge_integer(400), "not a finite number"),
    ("nan", "dh.json", _dh(_set("standard_dh.1.alpha", math.nan)), ".alpha is nan"),
    ("string", "dh.json", _dh(_set("standard_dh.1.alpha", "90")), 'is "90", not a number'),
    ("null", "dh.json", _dh(_set("standard_dh.3.theta_offset", None)), "is null, not a number"),
    ("angle", "dh.json", _dh(_set("standard_dh.3.alpha", 100.0)), "beyond ±12.5664 rad"),
    ("row", "dh.json", _dh(_set("standard_dh.2", [1, 2, 3])), "each row must be an object"),
    ("no a", "dh.json", _dh(_set("standard_dh.2", {"alpha": 0.0})), "has no 'a'"),
    ("type", "dh.json", _dh(_set("standard_dh.0.type", 5)), "type is 5; it must be a string"),
    ("kind", "dh.json", _dh(_set("standard_dh.0.type", "helical")), "use revolute or prismatic"),
    ("units", "dh.json", _dh(_set("units", [1])), "units is [1]"),
    ("unit", "dh.json", _dh(_set("units.length", "km")), 'units.length is "km"'),
    ("joints", "dh.json", _dh(_set("joints", {"a": 1})), "joints must be an array"),
    ("name", "dh.json", _dh(_set("joints.0.name", 7)), "joints[0].name is 7"),
    ("base 1-D", "dh.json", _dh(_set("base.T_measurement_base", [1, 2, 3])), "4 rows of 4"),
    ("base scaled", "dh.json", _dh(_set("base.T_measurement_base.0.0", 1.5)), "rigid transform"),
    ("tool", "dh.json", _dh(_set("tool", {"point": [0, 0]})), "tool.point"),
    ("rows", "dh.json", _dh(_set("standard_dh", [{"a": 0, "alpha": 0}] * 65)), "at most 64"),
    (
        "deep JSON",
        "dh.json",
        b'{"standard_dh": ' + b"[" * 100_000 + b"]" * 100_000 + b"}",
        "nested",
    ),
    ("deep TOML", "dh.toml", b"x = " + b"[" * 50_000 + b"]" * 50_000 + b"\n", "nested"),
    (
        "TOML digits",
        "dh.toml",
        b"standard_dh = [{a = " + b"9" * 5000 + b", alpha = 0}]\n",
        "digits",
    ),
    ("UTF-16", "dh.json", codecs.BOM_UTF16_LE + TRUTH.read_text().encode("utf-16-le"), "UTF-16"),
    ("not UTF-8", "dh.json", b'{"standard_dh": [{"a": 0, "alpha": 0, "x": "\xff"}]}', "not UTF-8"),
    ("NUL", "dh.json", b'{"standard_dh": \x00}', "NUL byte"),
    ("too large", "dh.json", b"{" + b" " * (10 * 2**20) + b"}", "larger than any DH file"),
    ("not JSON", "dh.json", b"standard_dh = []", "not valid JSON"),
    ("a list", "dh.json", b"[1, 2]", "must hold an object"),
    (
        "nongeometric",
        "dh.json",
        _dh(_set("nongeometric", {"terms": [1], "gravity": [0, 0, 1e400]})),
        "nongeometric",
    ),
]


@pytest.mark.parametrize(
    ("name", "data", "says"), [(c[1], c[2], c[3]) for c in DH_CASES], ids=[c[0] for c in DH_CASES]
)
def test_a_hostile_dh_file_is_one_line(tmp_path: Path, name: str, data: bytes, says: str) -> None:
    dh = tmp_path / name
    dh.write_bytes(data)
    refused(["fk", str(dh), "--q", "0,0,0,0,0,0"], tmp_path, name, says)


def test_a_dh_file_that_is_no_regular_file_is_refused_before_reading(tmp_path: Path) -> None:
    """``/dev/zero`` would be read until memory runs out; a folder named like a DH file."""
    refused(["fk", "/dev/zero", "--q", "0"], tmp_path, "/dev/zero", "not a regular file")
    (tmp_path / "robot.json").mkdir()
    refused(["fk", str(tmp_path / "robot.json"), "--q", "0"], tmp_path, "robot.json", "folder")


def test_the_nominal_of_process_is_refused_before_any_work(tmp_path: Path) -> None:
    nominal = tmp_path / "nominal.json"
    nominal.write_bytes(_dh(_set("standard_dh.4.a", False)))
    out = tmp_path / "out"
    args = ["process", str(SAMPLE), "--nominal", str(nominal), "--no-rrd", "--out", str(out)]
    refused(args, tmp_path, "nominal.json", "standard_dh[4] (joint 5).a is false")
    assert not out.exists()


def test_a_project_written_dh_file_still_reads() -> None:
    from dhlog.io.dhfile import load_dh

    model = load_dh(TRUTH)
    assert model.table.n == 6 and model.joint_names[0] == "joint_1"


# ---------------------------------------------------------------------------- pipelines


def _pipeline(*changes: tuple[str, str]) -> bytes:
    """The shipped ros2_tracker pipeline with lines replaced (``old`` → ``new``); ``old`` empty:
    ``new`` appended."""
    text = PIPELINE.read_text()
    for old, new in changes:
        if old:
            assert old in text, old
            text = text.replace(old, new, 1)
        else:
            text += new
    return text.encode()


SEG = "min_samples = 3"
PIPELINE_CASES: list[tuple[str, bytes, str]] = [
    ("encoding int", _pipeline(('encoding = "cdr"', "encoding = 5")), "encoding must be a list"),
    ("encoding nested", _pipeline(('encoding = "cdr"', "encoding = [[1]]")), "encoding[0]"),
    ("length_unit", _pipeline(('length_unit = "m"', "length_unit = 1")), "length_unit must be"),
    ("required", _pipeline(("required = true", 'required = "no"')), "required must be true"),
    ("topic", _pipeline(('topic = "/tracker/point"', "topic = 5")), "topic must be a string"),
    (
        "names",
        _pipeline(("[joints]", '[joints]\nnames = "joint_1"')),
        "names must be a list",
    ),
    ("names twice", _pipeline(("[joints]", '[joints]\nnames = ["a", "a"]')), "holds 'a' twice"),
    ("window", _pipeline(("motion_window = 0.05", "motion_window = -1")), "motion_window"),
    ("window 1e300", _pipeline(("motion_window = 0.05", "motion_window = 1e300")), "3600 s"),
    ("join inf", _pipeline(("join_tolerance = 0.05", "join_tolerance = inf")), "join_tolerance"),
    ("min_samples 0", _pipeline((SEG, "min_samples = 0")), "min_samples must be"),
    ("min_samples 2.5", _pipeline((SEG, "min_samples = 2.5")), "a whole one"),
    ("min_samples huge", _pipeline((SEG, "min_samples = " + "9" * 400)), "30 digits"),
    ("digits", _pipeline((SEG, "min_samples = " + "9" * 5000)), "more than 4300 digits"),
    ("clock", _pipeline((SEG, f"{SEG}\nclock_offset = 1e300")), "clock_offset"),
    ("boolean", _pipeline((SEG, f"{SEG}\nmin_sweep = true")), "not true"),
    ("fixed", _pipeline((SEG, f"{SEG}\nclock_offset_fixed = 1")), "must be true or false"),
    ("sigma 0", _pipeline(("", "\n[noise]\nsigma = 0\n")), "[noise] sigma must be"),
    ("sigma bool", _pipeline(("", "\n[noise]\nsigma = true\n")), "[noise] sigma"),
    ("radial", _pipeline(("", '\n[noise]\nmodel = "tracker"\nradial = 1e-320\n')), "radial"),
    ("station", _pipeline(("", "\n[noise]\nstation = [1e308, 0, 0]\n")), "station[0]"),
    ("model", _pipeline(("", "\n[noise]\nmodel = 3\n")), "[noise] model must be a string"),
    ("pose_index", _pipeline(("", "\n[streams.point]\npose_index = 100000000000\n")), "not valid"),
    ("deep", b"x = " + b"[" * 50_000 + b"]" * 50_000 + b"\n", "nested too deeply"),
    ("UTF-16", codecs.BOM_UTF16_LE + PIPELINE.read_text().encode("utf-16-le"), "UTF-16"),
    ("not UTF-8", PIPELINE.read_bytes().replace(b"ROS 2", b"ROS \xe9", 1), "not UTF-8"),
    ("too large", b"#" * (2**20 + 1), "larger than any pipeline"),
]


@pytest.mark.parametrize(
    ("data", "says"), [c[1:] for c in PIPELINE_CASES], ids=[c[0] for c in PIPELINE_CASES]
)
def test_a_hostile_pipeline_is_one_line(tmp_path: Path, data: bytes, says: str) -> None:
    pipe = tmp_path / "pipe.toml"
    pipe.write_bytes(data)
    out = tmp_path / "out"
    args = ["process", str(SAMPLE), "--pipeline", str(pipe), "--no-rrd", "--out", str(out)]
    refused(args, tmp_path, "pipe.toml", says)
    assert not out.exists()


def test_a_pipeline_that_is_no_regular_file_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["process", str(SAMPLE), "--pipeline", "/dev/zero", "--no-rrd", "--out", str(out)]
    refused(args, tmp_path, "/dev/zero", "not a regular file")


def test_segmentation_out_of_range_is_refused_by_the_segmentation_too() -> None:
    """Settings made in code (not from a pipeline file) are checked before they become an
    index (a negative window) or a count of nanoseconds (1e300 s)."""
    import dataclasses

    from dhlog.identify.segment.segment import check_settings
    from dhlog.io.pipeline import SegmentationSettings

    check_settings(SegmentationSettings(), "here")
    for key, value in (("motion_window", -1.0), ("join_tolerance", 1e300), ("min_samples", 0)):
        bad = dataclasses.replace(SegmentationSettings(), **{key: value})
        with pytest.raises(InputError, match=rf"here: \[segmentation\] {key} is"):
            check_settings(bad, "here")


# ---------------------------------------------------------------------------- degenerate data


def test_whiten_refuses_a_zero_sigma() -> None:
    from dhlog.model.noise import NoiseModel

    points = np.zeros((3, 3))
    assert NoiseModel().whiten(points, 2e-5) == pytest.approx(5e4)
    for sigma in (0.0, -1.0, math.nan):
        with pytest.raises(InputError, match="isotropic noise σ"):
            NoiseModel().whiten(points, sigma)


def test_fit_line_on_denormal_travel_is_a_geometry_error() -> None:
    """A SCARA with its joint 2 skipped and DH offsets of 1e-320 m: the timing's line fit
    (``min_travel=0``) met a travel whose square is 0 — ZeroDivisionError before."""
    from dhlog.geometry.fitting import fit_line

    points = np.array([[k * 1e-320, 0.0, 0.0] for k in range(6)])
    with pytest.raises(GeometryError, match="joint 2: the sweep covers only"):
        fit_line(points, min_travel=0.0, what="joint 2")
    with pytest.raises(DhlogError):
        fit_line(np.zeros((6, 3)) + 1.0, min_travel=0.0, what="joint 2")


# ---------------------------------------------------------------------------- imports

HEAD = "x,y,z,j1,j2,j3"
ROWS = "1000,200,300,0,10,20\n1100,200,300,5,10,20\n1200,200,300,10,10,20\n"
LEICA = "Point Name;X [mm];Y [mm];Z [mm];U95 [mm];j1;j2;j3"


def _leica_row(k: int, u95: str = "0.020", x: str = "1000") -> str:
    return f"P{k};{x};200;300;{u95};{k};10;20"


IMPORT_CASES: list[tuple[str, str, list[str], str]] = [
    ("x 1e308", f"{HEAD}\n{ROWS}1e308,200,300,0,10,20\n", [], "line 5: x '1e308' is out of range"),
    ("joint 1e308", f"{HEAD}\n{ROWS}1,2,3,0,1e308,20\n", [], "line 5: joint j2 '1e308'"),
    ("joint 1e999", f"{HEAD}\n1,2,3,0,1e999,20\n", [], "line 2: joint j2 '1e999' is not finite"),
    (
        "U95 1e-320",
        f"{LEICA}\n{_leica_row(1)}\n{_leica_row(2, '1e-320')}\n",
        ["--format", "leica"],
        "line 3: U95 [mm] '1e-320' is out of range",
    ),
    (
        "U95 1e150",
        f"{LEICA}\n{_leica_row(1, '1e150')}\n",
        ["--format", "leica"],
        "line 2: U95 [mm] '1e150' is out of range",
    ),
    ("mixed units", f"x [m],y,z,j1,j2,j3\n{ROWS}", [], "states the unit of 'x [m]' but not of"),
    ("joint units", "x,y,z,j1 [rad],j2\n1,2,3,0,0\n", [], "'j1 [rad]' but not of 'j2'"),
    ("two joint 1", "x,y,z,j1,q1\n1,2,3,0,0\n", [], "two columns for joint 1"),
    ("joint 2 missing", "x,y,z,j1,j3\n1,2,3,0,0\n", [], "none for joint 2"),
    ("--y X", f"{HEAD}\n{ROWS}", ["--y", "x"], "--x and --y both name the column 'x'"),
    ("--time z", f"{HEAD}\n{ROWS}", ["--time", "z"], "--z and --time both name"),
    ("--joint-columns", f"{HEAD}\n{ROWS}", ["--joint-columns", "j1,j1,j2"], "'j1' twice"),
    ("--joint-names", f"{HEAD}\n{ROWS}", ["--joint-names", "a,a,b"], "named 'a'"),
    (
        "--orientation-columns",
        "x,y,z,rx,ry,j1\n1,2,3,0,0,0\n",
        ["--orientation-columns", "rx,ry,x"],
        "--x and --orientation-columns both name",
    ),
    ("extra field", f"{HEAD}\n{ROWS}1,2,3,0,0,0,7\n", [], "line 5: has 7 fields, the header 6"),
    ("decimal commas", f"{HEAD}\n1,5,2,5,3,5,0,0,0\n", [], "decimal commas in a comma-separated"),
    ("quoted comma", f'{HEAD}\n"1,5",2,3,0,0,0\n', [], "line 2: x '1,5' is not a number (a deci"),
    ("mixed marks", "x;y;z;j1\n1,5;2;3;0\n2.5;2;3;0\n", [], "line 3: x mixes decimal commas"),
    ("thousands", "x;y;z;j1\n1.000,5;2;3;0\n", [], "line 2: x '1.000,5' holds a thousands"),
    ("units row", f"{HEAD}\nm,m,m,deg,deg,deg\n{ROWS}", [], "line 2: x 'm' is not a number"),
    ("NUL", f"{HEAD}\n1,2,3,0,0\x00,0\n", [], "line 2: holds a NUL byte"),
    ("csv error", f"{HEAD}\n{'1' * 200_000},2,3,0,0,0\n", [], "line 2: cannot be read as a table"),
    ("huge time", "t,x,y,z,j1\n0,1,2,3,0\n1e300,1,2,3,0\n", ["--time", "t"], "check --time-unit"),
    ("digits", f"{HEAD}\n{'9' * 5000},2,3,0,0,0\n", [], "line 2: x '9999"),
]


@pytest.mark.parametrize(
    ("text", "args", "says"), [c[1:] for c in IMPORT_CASES], ids=[c[0] for c in IMPORT_CASES]
)
def test_a_hostile_export_is_one_line_naming_the_line(
    tmp_path: Path, text: str, args: list[str], says: str
) -> None:
    src = tmp_path / "export.csv"
    src.write_bytes(text.encode())
    out = tmp_path / "export.mcap"
    refused(["import", str(src), "-o", str(out), *args], tmp_path, "export.csv", says)


def test_a_hostile_point_list_is_one_line(tmp_path: Path) -> None:
    src, joints = tmp_path / "points.txt", tmp_path / "joints.csv"
    src.write_text("P1 1 2 3\nP2 1e999 2 3\n")
    joints.write_text("Point,j1\nP1,0\nP2,1\n")
    args = ["import", str(src), "--format", "spatialanalyzer", "--joints-file", str(joints)]
    refused([*args, "-o", str(tmp_path / "o.mcap")], tmp_path, "points.txt", "line 2: the point")


def test_the_output_is_never_an_input(tmp_path: Path) -> None:
    """``import … --joints-file joints.csv -o joints.csv`` replaced the joints file (exit 1:
    a usage error, as for the source itself)."""
    src, joints = tmp_path / "points.csv", tmp_path / "joints.csv"
    src.write_text("Point,x,y,z\nP1,1,2,3\nP2,4,5,6\nP3,7,8,9\n")
    joints.write_text("Point,j1\nP1,0\nP2,1\nP3,2\n")
    base = ["import", str(src), "--joints-file", str(joints), "--force"]
    refused(
        [*base, "-o", str(joints)], tmp_path, "joints.csv", "would replace the --joints-file", 1
    )
    refused([*base, "-o", str(src)], tmp_path, "points.csv", "would replace the source", 1)
    link = tmp_path / "link.csv"
    link.symlink_to(joints)
    refused([*base, "-o", str(link)], tmp_path, "link.csv", "would replace the --joints-file", 1)
    loop = tmp_path / "loop.csv"
    loop.symlink_to(loop)  # resolving it raised RuntimeError
    refused(["import", str(loop)], tmp_path, "loop.csv", "cannot be read")


def test_an_import_source_that_is_no_regular_file_is_refused(tmp_path: Path) -> None:
    """``dhlog import /dev/zero`` read until 3.7 GB."""
    out = tmp_path / "zero.mcap"
    refused(["import", "/dev/zero", "-o", str(out)], tmp_path, "/dev/zero", "not a regular file")
    src = tmp_path / "a.csv"
    src.write_text(f"{HEAD}\n{ROWS}")
    args = ["import", str(src), "--joints-file", "/dev/zero", "-o", str(out)]
    refused(args, tmp_path, "/dev/zero", "not a regular file")


def test_an_export_larger_than_the_cap_is_refused_before_reading(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import dhlog.io.exports.table as table

    monkeypatch.setattr(table, "MAX_TABLE_BYTES", 1000)
    src = tmp_path / "big.csv"
    src.write_text(HEAD + "\n" + "1,2,3,0,0,0\n" * 200)
    refused(
        ["import", str(src), "-o", str(tmp_path / "o.mcap")], tmp_path, "big.csv", "(1 kB at most)"
    )


# ---------------------------------------------------------------------------- read, not refused


def _imported(tmp_path: Path, text: str | bytes, *args: str) -> tuple[Any, str]:
    from dhlog.io.reader import read_log

    src = tmp_path / "in.csv"
    src.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "in.mcap"
    result = runner.invoke(app, ["import", str(src), "-o", str(out), *args])
    assert result.exit_code == 0, result.stderr
    return read_log(out), result.stdout


def test_a_unit_after_an_underscore_or_a_slash_is_the_header_unit(tmp_path: Path) -> None:
    """``X_m`` said metres and was read as millimetres."""
    log, _ = _imported(tmp_path, "X_m,Y/m,Z in m,A1_deg,A2 rad\n1.5,0.2,0.3,0,10\n")
    np.testing.assert_allclose(log.points.select(["x", "y", "z"]).to_numpy()[0], [1.5, 0.2, 0.3])
    assert log.joints is not None
    np.testing.assert_allclose(log.joints["q_2"].to_numpy()[0], 10.0)  # rad as the header says


def test_joint_columns_out_of_order_are_taken_by_their_number(tmp_path: Path) -> None:
    log, printed = _imported(tmp_path, "x,y,z,j2,j1,j3\n1,2,3,20,10,30\n")
    assert log.joint_names == ["j1", "j2", "j3"]
    assert log.joints is not None
    np.testing.assert_allclose(log.joints.row(0)[1:4], np.radians([10, 20, 30]))
    assert "in the order of their numbers (j1, j2, j3), not the header's" in printed


def test_decimal_commas_in_a_semicolon_table_are_read(tmp_path: Path) -> None:
    log, _ = _imported(tmp_path, "x;y;z;j1\n1,5;2,25;3;0,5\n")
    np.testing.assert_allclose(
        log.points.select(["x", "y", "z"]).to_numpy()[0] * 1e3, [1.5, 2.25, 3]
    )


def test_a_utf16_export_with_its_byte_order_mark_is_read(tmp_path: Path) -> None:
    """Spreadsheets' "Unicode text": UTF-16 with a byte-order mark, tab-separated."""
    text = "x\ty\tz\tj1\n1\t2\t3\t0\n"
    log, _ = _imported(tmp_path, codecs.BOM_UTF16_LE + text.encode("utf-16-le"))
    np.testing.assert_allclose(log.points.select(["x", "y", "z"]).to_numpy()[0] * 1e3, [1, 2, 3])


def test_many_stops_import_in_linear_time(tmp_path: Path) -> None:
    """40 joint states a stop made 200 000 stops 8 million messages (over 60 s); three a stop
    (its start, the measurement, its end) carry what the segmentation reads. The 200 000-stop
    timing is in docs/robustness.md; here 20 000 stops, imported and read back."""
    from dhlog.io.importer import STOP_JOINT_TIMES
    from dhlog.io.reader import read_log

    n = 20_000
    rng = np.random.default_rng(20)
    table = np.column_stack([rng.uniform(-1500, 1500, (n, 3)), rng.uniform(-90, 90, (n, 6))])
    src = tmp_path / "stops.csv"
    np.savetxt(src, table, fmt="%.4f", delimiter=",", header="x,y,z,j1,j2,j3,j4,j5,j6", comments="")
    out = tmp_path / "stops.mcap"
    result = runner.invoke(app, ["import", str(src), "-o", str(out)])
    assert result.exit_code == 0, result.stderr
    log = read_log(out)
    assert log.points.height == n
    assert log.joints is not None and log.joints.height == len(STOP_JOINT_TIMES) * n
    np.testing.assert_allclose(
        log.joints["q_6"].to_numpy()[1::3], np.radians(np.round(table[:, 8], 4))
    )


# ---------------------------------------------------------------------------- fuzz


@pytest.fixture(scope="module")
def bases(tmp_path_factory: pytest.TempPathFactory) -> Any:
    from fuzz_inputs import make_bases

    return make_bases(tmp_path_factory.mktemp("fuzz-bases"))


FUZZ_CASES_PER_FAMILY = 50


@pytest.mark.parametrize("family", ["dh", "pipeline", "export"])
def test_mutated_inputs_never_end_in_a_traceback(bases: Any, family: str, tmp_path: Path) -> None:
    """Seeded mutations (``tests/fuzz_inputs.py``) of real DH files, pipelines and exports:
    exit 0, 2 or 3, no traceback, one line for 2 and 3, the input unchanged, no partial output,
    and the inputs that must be refused refused."""
    from fuzz_inputs import FAMILIES, cases, run_case

    failures = []
    seed = 2000 + FAMILIES.index(family)
    for case in cases(seed, FUZZ_CASES_PER_FAMILY, bases, families=(family,)):
        outcome = run_case(case, tmp_path)
        if outcome.problems:
            failures.append(f"{outcome.case}: {', '.join(outcome.problems)}: {outcome.stderr}")
    assert not failures, "\n".join(failures[:10])
