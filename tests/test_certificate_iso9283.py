"""``dhlog report RESULT --iso9283 FILE`` (issue 34, item 4): the certificate's section
"Acceptance test (ISO 9283)" shows the report's figures as the JSON has them (each cell's SI value
to the bit, its text in mm or s to the digits shown), the test cube found from the commanded
P1 … P5, the notes; a damaged field of the report is one line naming it; without the option the
page has no such section."""

from __future__ import annotations

import copy
import dataclasses
import html
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.present.certificate.iso9283 import cube_from_poses, load_iso9283

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
SCHEMA = ROOT / "src" / "dhlog" / "schemas" / "iso9283.schema.json"
#: The KR5's test cube (docs/iso9283.md): edge and centre, m.
EDGE, CENTRE = 0.241, np.array([1.303, 0.0, 0.286])


@pytest.fixture(scope="module")
def result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A calibration result: the bundled KR5 sweeps session processed (1 s)."""
    folder = tmp_path_factory.mktemp("result")
    done = runner.invoke(
        app,
        [
            "process",
            str(ROOT / "sample_logs" / "kr5_0.01mm.mcap"),
            "--out",
            str(folder),
            "--no-rrd",
        ],
    )
    assert done.exit_code == 0, done.output
    return folder / "kr5_0.01mm.dh.json"


def _commanded() -> dict[str, np.ndarray]:
    """P1 … P5 of the plane C1-C2-C7-C8 (clause 6.3): the centre and 10 % of each diagonal from
    C1, C2, C7, C8."""
    h = EDGE / 2
    corners = {
        "P2": CENTRE + np.array([-h, -h, -h]),  # C1
        "P3": CENTRE + np.array([h, -h, -h]),  # C2
        "P4": CENTRE + np.array([h, h, h]),  # C7
        "P5": CENTRE + np.array([-h, h, h]),  # C8
    }
    out = {"P1": CENTRE.copy()}
    for name, c in corners.items():
        out[name] = CENTRE + 0.8 * (c - CENTRE)
    return out


def _document(*, points: bool = False) -> dict[str, Any]:
    """An ISO 9283 report as dhlog iso9283 writes it (checked against its schema), with figures
    that differ from pose to pose so that a swapped cell shows."""
    rng = np.random.default_rng(7)
    poses = []
    for k, (name, c) in enumerate(_commanded().items()):
        off_before = rng.normal(0, 3e-4, 3)
        off_after = rng.normal(0, 3e-5, 3)
        pose: dict[str, Any] = {
            "pose": name,
            "visits": 5,
            "barycentre": (c + off_before).tolist(),
            "commanded": c.tolist(),
            "before": {
                "AP": float(np.linalg.norm(off_before)),
                "AP_x": float(off_before[0]),
                "AP_y": float(off_before[1]),
                "AP_z": float(off_before[2]),
                "AP_sigma": 1e-5 + 1e-6 * k,
            },
            "after": {
                "AP": float(np.linalg.norm(off_after)),
                "AP_x": float(off_after[0]),
                "AP_y": float(off_after[1]),
                "AP_z": float(off_after[2]),
            },
            "RP": 6e-5 + 1e-6 * k + float(rng.uniform(0, 1e-7)),
            "l_mean": 4e-5,
            "S_l": 1e-5,
            "RP_abc": None,
            "stabilisation_time": 0.08 + 0.01 * k,
            "stabilisation_time_max": 0.1 + 0.02 * k,
            "overshoot": 1e-4 + 1e-6 * k,
            "overshoot_max": 1.2e-4 + 1e-6 * k,
            "unsettled": 0,
            "vAP": None if k else 2.5e-5,
            "directions": 2 if k == 0 else 1,
        }
        poses.append(pose)
    doc: dict[str, Any] = {
        "format": "dhlog.iso9283/1",
        "dhlog_version": "0.2.0",
        "source": {
            "logs": ["test.mcap"],
            "nominal": "kr5",
            "result": "calib.dh.json",
            "commanded": None,
            "pipeline": None,
        },
        "iso9283": {
            "units": {"length": "m", "angle": "rad", "time": "s"},
            "frame": "base",
            "registration": "the result's T_measurement_base (calib.dh.json)",
            "commanded_from": "the commanded joint stream /joint_command",
            "after": "computed: not measured",
            "tracker_rate_hz": 100.0,
            "visits": 25,
            "cycles": 5,
            "orientation": False,
            "poses": poses,
            "distance": {
                "poses": ["P2", "P4"],
                "cycles": 5,
                "D_mean": 0.3339258098969555,
                "D_commanded": 0.3339393956992795,
                "AD": -1.3585802323967666e-05,
                "AD_after": -6.986206269599116e-06,
                "RD": 3.707216636905002e-05,
            },
            "drift": {
                "pose": "P1",
                "group": 2,
                "hours": 0.01059166666666667,
                "dAP": 3.0356745284626702e-05,
                "dRP": 5.100763110148211e-06,
                "shift": 6.087251517865475e-05,
                "rate_per_hour": 0.006021284796483782,
            },
            "paths": [
                {
                    "path": name,
                    "cycles": 3,
                    "points": n,
                    "first_point": 0,
                    "AT": at,
                    "AT_after": after,
                    "RT": rt,
                    "AT_at_point": 0,
                    "RT_at_point": 67,
                }
                for name, n, at, after, rt in (
                    ("line", 100, 4.8326208333656615e-4, 1.3273192885847782e-4, 6.43e-5),
                    ("circle_large", 121, 5.747e-4, None, 8.25e-5),
                    ("circle_small", 121, 7.137e-4, 2.599e-4, 1.116e-4),
                )
            ],
            "notes": [
                "5 cycle(s) per pose: the standard asks 30; the figures are from these.",
                'a hostile <script>alert("x")</script> note',
            ],
        },
    }
    jsonschema.validate(doc, json.loads(SCHEMA.read_text()))
    if points:  # the optional per-pose positions (the schema's block does not carry them)
        for p in doc["iso9283"]["poses"]:
            bary = np.array(p["barycentre"])
            p["attained"] = (bary + rng.normal(0, 2e-5, (5, 3))).tolist()
    return doc


@dataclass
class Cells(HTMLParser):
    """Every ``data-key`` cell (its ``data-si`` and text), the text of elements by id, the
    sections' ids and the plots' labels."""

    cells: dict[str, tuple[str | None, str]] = field(default_factory=dict)
    stds: dict[str, str] = field(default_factory=dict)
    ids: dict[str, str] = field(default_factory=dict)
    sections: list[str] = field(default_factory=list)
    plots: list[str] = field(default_factory=list)
    _key: str | None = None
    _open: list[tuple[str, str | None]] = field(default_factory=list)

    def __post_init__(self) -> None:
        super().__init__()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "td" and a.get("data-key"):
            self._key = str(a["data-key"])
            self.cells[self._key] = (a.get("data-si"), "")
            if a.get("data-std"):
                self.stds[self._key] = str(a["data-std"])
        if tag == "section" and a.get("id"):
            self.sections.append(str(a["id"]))
        if tag == "svg":
            self.plots.append(str(a.get("aria-label")))
        if tag not in ("br", "meta", "img", "input", "link"):
            self._open.append((tag, a.get("id")))

    def handle_endtag(self, tag: str) -> None:
        if tag == "td":
            self._key = None
        while self._open:
            if self._open.pop()[0] == tag:
                break

    def handle_data(self, data: str) -> None:
        if self._key is not None:
            si, text = self.cells[self._key]
            self.cells[self._key] = (si, text + data)
        for _, ident in self._open:
            if ident:
                self.ids[ident] = self.ids.get(ident, "") + data


def _report(result: Path, folder: Path, doc: Any | None, *extra: str) -> tuple[Any, str]:
    out = folder / "cert.html"
    args = ["report", str(result), "-o", str(out), "--force", *extra]
    if doc is not None:
        iso = folder / "test.iso9283.json"
        iso.write_text(doc if isinstance(doc, str) else json.dumps(doc))
        args += ["--iso9283", str(iso)]
    done = runner.invoke(app, args)
    return done, out.read_text(encoding="utf-8") if done.exit_code == 0 else ""


def _parse(text: str) -> Cells:
    page = Cells()
    page.feed(text)
    return page


def test_the_section_shows_the_reports_figures(result: Path, tmp_path: Path) -> None:
    doc = _document()
    done, text = _report(result, tmp_path, doc, "--robot", "KR5 sixx #4711")
    assert done.exit_code == 0, done.output
    page = _parse(text)
    assert "s-iso9283" in page.sections
    block = doc["iso9283"]
    want: dict[str, tuple[float | None, float, int]] = {}  # key: (SI value, scale, places)
    for p in block["poses"]:
        n = p["pose"]
        want[f"{n}.AP_before"] = (p["before"]["AP"], 1e3, 4)
        want[f"{n}.AP_after"] = (p["after"]["AP"], 1e3, 4)
        for key in ("RP", "overshoot", "overshoot_max", "vAP"):
            want[f"{n}.{key}"] = (p[key], 1e3, 4)
        for key in ("stabilisation_time", "stabilisation_time_max"):
            want[f"{n}.{key}"] = (p[key], 1.0, 3)
    for p in block["paths"]:
        for key in ("AT", "AT_after", "RT"):
            want[f"{p['path']}.{key}"] = (p[key], 1e3, 4)
    for key in ("D_mean", "D_commanded", "AD", "AD_after", "RD"):
        want[f"distance.{key}"] = (block["distance"][key], 1e3, 4)
    for key in ("dAP", "dRP", "shift", "rate_per_hour"):
        want[f"drift.{key}"] = (block["drift"][key], 1e3, 4)
    want["drift.hours"] = (block["drift"]["hours"], 1.0, 3)
    assert set(page.cells) == set(want)
    for key, (value, scale, places) in want.items():
        si, shown = page.cells[key]
        if value is None:
            assert si is None and shown.strip() == "—", key
            continue
        assert si is not None and float(si) == value, key  # to the bit
        shown, _, under = shown.partition("±")
        assert float(shown) == round(value * scale, places), key  # to the digits shown
        if key.endswith("AP_before"):  # its standard uncertainty under it
            sigma = block["poses"][int(key[1]) - 1]["before"]["AP_sigma"]
            assert float(page.stds[key]) == sigma and float(under) == round(sigma * 1e3, 4)
        else:
            assert key not in page.stds and not under
    test = html.unescape(page.ids["iso9283-test"])
    assert "KR5 sixx #4711" in test and "test.mcap" in test
    assert "edge 241.0 mm, centre (1303.0, 0.0, 286.0) mm" in test
    assert "5 per pose, 25 visits found, tracker at 100 Hz" in test
    iso = tmp_path / "test.iso9283.json"
    import hashlib

    assert page.ids["iso9283-sha256"] == hashlib.sha256(iso.read_bytes()).hexdigest()
    notes = page.ids["iso9283-notes"]
    assert block["notes"][0] in notes and block["notes"][1] in notes  # unescaped by the parser
    assert "<script" not in text
    assert "AP before and after calibration and RP per test pose" in page.plots


def test_the_plot_shows_the_attained_positions_when_the_file_has_them(
    result: Path, tmp_path: Path
) -> None:
    done, text = _report(result, tmp_path, _document(points=True))
    assert done.exit_code == 0, done.output
    page = _parse(text)
    assert "attained positions of each test pose about their barycentre" in page.plots
    assert "with the circle of radius RP" in page.ids["iso9283-plot"]


def test_the_cube_from_the_commanded_poses() -> None:
    """The cube of P1 … P5 (any plane of clause 6.3: the corners' bounding box); poses that are
    not the standard's give none."""
    shown = load_iso9283_doc(_document())
    assert shown.cube is not None
    assert shown.cube.edge == pytest.approx(EDGE, abs=1e-12)
    assert np.allclose(shown.cube.centre, CENTRE, atol=1e-12)
    moved = copy.deepcopy(shown.poses)
    moved[2] = dataclasses.replace(moved[2], commanded=[1.3, 0.01, 0.3])
    assert cube_from_poses(moved) is None
    assert cube_from_poses(shown.poses[:4]) is None


def load_iso9283_doc(doc: dict[str, Any], folder: Path | None = None) -> Any:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "t.iso9283.json"
        path.write_text(json.dumps(doc))
        return load_iso9283(path)


def _set(path: str, value: Any) -> Callable[[Any], None]:
    def change(doc: Any) -> None:
        *parents, last = path.split(".")
        node = doc
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        node[int(last) if isinstance(node, list) else last] = value

    return change


def _delete(path: str) -> Callable[[Any], None]:
    def change(doc: Any) -> None:
        *parents, last = path.split(".")
        node = doc
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        del node[last]

    return change


DAMAGED = [
    (_set("format", "dhlog.result/1"), "format must be dhlog.iso9283/1"),
    (_delete("iso9283"), "iso9283 is missing"),
    (_set("iso9283.poses.1.RP", "0.1"), "iso9283.poses[1].RP must be a number, not a string"),
    (_set("iso9283.poses.2.RP", -1e-5), "iso9283.poses[2].RP is -1e-05; a standard deviation"),
    (_set("iso9283.poses.0.before.AP_x", 1e9), "iso9283.poses[0].before.AP_x is 1e+09, beyond"),
    (
        _delete("iso9283.poses.3.stabilisation_time"),
        "iso9283.poses[3].stabilisation_time is missing",
    ),
    (_set("iso9283.poses.4.barycentre", [1, 2]), "iso9283.poses[4].barycentre must hold 3 numbers"),
    (_set("iso9283.paths.0.AT", None), "iso9283.paths[0].AT is null"),
    (_set("iso9283.distance.poses", ["P2"]), "iso9283.distance.poses must name 2 poses"),
    (_set("iso9283.drift", []), "iso9283.drift must be an object, not an array"),
    (_set("iso9283.notes", "none"), "iso9283.notes must be an array, not a string"),
    (_set("iso9283.frame", "world"), "iso9283.frame must be one of base, measurement"),
    (_set("iso9283.poses.0.attained", [[1, 2, "x"]]), "iso9283.poses[0].attained[0][2] must be"),
    (_set("iso9283.poses.1.before.AP_sigma", -1e-6), "iso9283.poses[1].before.AP_sigma is -1e-06"),
]


@pytest.mark.parametrize(("change", "message"), DAMAGED)
def test_a_damaged_field_is_one_line_naming_it(
    result: Path, tmp_path: Path, change: Callable[[Any], None], message: str
) -> None:
    doc = _document()
    change(doc)
    done, _ = _report(result, tmp_path, doc)
    assert done.exit_code == 2, done.output
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "test.iso9283.json" in lines[0], lines
    assert "write it again with dhlog iso9283" in lines[0]
    assert not (tmp_path / "cert.html").exists()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{", "is not valid JSON"),
        (b"\xff\xfe{}", "is not UTF-8 text"),
        ("[]", "the file must be an object"),
    ],
)
def test_a_file_that_is_not_a_report_is_one_line(
    result: Path, tmp_path: Path, content: str | bytes, message: str
) -> None:
    iso = tmp_path / "x.iso9283.json"
    iso.write_bytes(content if isinstance(content, bytes) else content.encode())
    out = tmp_path / "cert.html"
    done = runner.invoke(app, ["report", str(result), "-o", str(out), "--iso9283", str(iso)])
    assert done.exit_code == 2, done.output
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert not out.exists()


def test_without_the_file_no_section(result: Path, tmp_path: Path) -> None:
    done, text = _report(result, tmp_path, None)
    assert done.exit_code == 0, done.output
    page = _parse(text)
    assert "s-iso9283" not in page.sections and "ISO 9283" not in text
    assert page.sections == [
        "s-identification",
        "s-accuracy",
        "s-parameters",
        "s-measurement",
        "s-joints",
        "s-terms",
        "s-warnings",
    ]


def test_a_test_without_a_model_shows_what_was_computed(result: Path, tmp_path: Path) -> None:
    """dhlog iso9283 without --nominal: the tracker's frame, no commanded positions, no AP, AD,
    dAP or paths: dashes, the cube not known, RP and the stabilisation as the file has them."""
    doc = _document()
    block = doc["iso9283"]
    block["frame"] = "measurement"
    for p in block["poses"]:
        p["commanded"] = p["before"] = p["after"] = None
    block["distance"].update(D_commanded=None, AD=None, AD_after=None)
    block["drift"]["dAP"] = None
    block["paths"] = []
    block["after"] = None
    jsonschema.validate(doc, json.loads(SCHEMA.read_text()))
    done, text = _report(result, tmp_path, doc)
    assert done.exit_code == 0, done.output
    page = _parse(text)
    for p in block["poses"]:
        assert page.cells[f"{p['pose']}.AP_before"] == (None, "—")
        assert float(str(page.cells[f"{p['pose']}.RP"][0])) == p["RP"]
    assert page.cells["distance.AD"] == (None, "—") and page.cells["drift.dAP"] == (None, "—")
    assert "not known" in page.ids["iso9283-test"]
    assert "not computed" in page.ids["iso9283-paths"]
    assert "RP per test pose" in " ".join(page.plots)
    assert "no model given to dhlog iso9283, so no AP" in page.ids["iso9283-plot"]
