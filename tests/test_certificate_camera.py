"""``dhlog report`` of a camera calibration (issue 32, item 6): the certificate's camera section
and its held-out check in pixels and mm, from real results (``dhlog simulate --instrument
camera`` rendered with OpenCV, then ``dhlog process``), checked against the result JSON; a
damaged ``camera`` block is one line naming the field; a tracker's certificate has no camera
section."""

from __future__ import annotations

import html
import json
import math
import re
import shutil
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dhlog.cli.app import app

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]


@dataclass
class Made:
    """A result written by ``dhlog process`` (its folder, JSON and document)."""

    folder: Path
    result: Path
    doc: dict[str, Any]


def _camera_result(folder: Path, setup: str, *extra: str) -> Made:
    """A 20-pose random-poses log of the small camera preset (its board: 60 mm squares, 45 mm
    markers), rendered as PNG, processed with the board's pipeline and 5-fold held-out."""
    log = folder / "cam.mcap"
    done = runner.invoke(
        app,
        [
            "simulate", "kr5", "-o", str(log), "--instrument", "camera",
            "--protocol", "random-poses", "--poses", "20", "--camera", "small",
            "--image-format", "png", "--camera-setup", setup,
        ],
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    text = (ROOT / "pipelines" / "ros2_camera.toml").read_text()
    text = re.sub(r"(?m)^square_m = .*$", "square_m = 0.06", text)
    text = re.sub(r"(?m)^marker_m = .*$", "marker_m = 0.045", text)
    assert "square_m = 0.06" in text and "marker_m = 0.045" in text
    pipeline = folder / "board.toml"
    pipeline.write_text(text)
    done = runner.invoke(
        app,
        [
            "process", str(log), "--nominal", "kr5", "--pipeline", str(pipeline),
            "--holdout", "5", "--no-rrd", *extra,
        ],
    )  # fmt: skip
    assert done.exit_code == 0, done.output
    result = folder / "cam.dh.json"
    return Made(folder, result, json.loads(result.read_text()))


@pytest.fixture(scope="module")
def to_hand(tmp_path_factory: pytest.TempPathFactory) -> Made:
    return _camera_result(tmp_path_factory.mktemp("eye_to_hand"), "eye-to-hand")


@pytest.fixture(scope="module")
def in_hand(tmp_path_factory: pytest.TempPathFactory) -> Made:
    folder = tmp_path_factory.mktemp("eye_in_hand")
    return _camera_result(folder, "eye-in-hand", "--refine-intrinsics")


@pytest.fixture(scope="module")
def tracker(tmp_path_factory: pytest.TempPathFactory) -> Made:
    """The bundled KR5 sweeps session (a laser tracker's)."""
    folder = tmp_path_factory.mktemp("tracker")
    log = ROOT / "sample_logs" / "kr5_0.01mm.mcap"
    done = runner.invoke(app, ["process", str(log), "--out", str(folder), "--no-rrd"])
    assert done.exit_code == 0, done.output
    result = folder / "kr5_0.01mm.dh.json"
    return Made(folder, result, json.loads(result.read_text()))


def report(result: Path, out: Path, *extra: str) -> str:
    done = runner.invoke(app, ["report", str(result), "-o", str(out), "--force", *extra])
    assert done.exit_code == 0, done.output
    return out.read_text(encoding="utf-8")


class Page(HTMLParser):
    """The text of every element with an id, the attributes and text of every ``td`` by the
    id of the table holding it, and the sections' headings."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: dict[str, str] = {}
        self.cells: dict[str, list[tuple[dict[str, str | None], str]]] = {}
        self.headings: list[str] = []
        self._open: list[tuple[str, str | None]] = []
        self._cell: tuple[dict[str, str | None], list[str]] | None = None
        self._table: list[str | None] = []
        self._h2: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "table":
            self._table.append(a.get("id"))
        if tag == "td":
            self._cell = (a, [])
        if tag == "h2":
            self._h2 = []
        if tag not in ("br", "meta"):
            self._open.append((tag, a.get("id")))

    def handle_endtag(self, tag: str) -> None:
        if tag == "td" and self._cell is not None and self._table and self._table[-1]:
            self.cells.setdefault(str(self._table[-1]), []).append(
                (self._cell[0], "".join(self._cell[1]))
            )
            self._cell = None
        if tag == "table" and self._table:
            self._table.pop()
        if tag == "h2" and self._h2 is not None:
            self.headings.append("".join(self._h2))
            self._h2 = None
        while self._open:
            if self._open.pop()[0] == tag:
                break

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell[1].append(data)
        if self._h2 is not None:
            self._h2.append(data)
        for _, ident in self._open:
            if ident:
                self.ids[ident] = self.ids.get(ident, "") + data


def parse(text: str) -> Page:
    page = Page()
    page.feed(text)
    return page


def _pose_expected(T: list[list[float]]) -> list[float]:
    """x, y, z (m) and roll, pitch, yaw (rad) of a 4×4, by SciPy (fixed axes x, y, z)."""
    M = np.array(T)
    rpy = Rotation.from_matrix(M[:3, :3]).as_euler("xyz")
    return [*M[:3, 3].tolist(), *rpy.tolist()]


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
def test_the_camera_section_shows_the_json(
    setup: str, to_hand: Made, in_hand: Made, tmp_path: Path
) -> None:
    """The set-up and its reason, the topic, the tally, both poses (value and σ to the bit in
    the cells' data, the shown text to its last digit), the intrinsics (held, or refined with
    σ), the corners' σ and RMS, and the held-out check (px, mm, in sample, PnP noise) with its
    notes, each as the JSON has it."""
    made = to_hand if setup == "eye-to-hand" else in_hand
    cam = made.doc["camera"]
    assert cam["setup"] == setup
    text = report(made.result, tmp_path / "c.html", "--nominal", "kr5")
    page = parse(text)
    assert "Camera and board" in " ".join(page.headings)
    assert "from a camera log" in text and "laser-tracker" not in text
    head = page.ids["camera-setup"]
    for said in (cam["topic"], cam["setup_reason"], cam["detections"], f"{cam['frames']} frames"):
        assert said in head
    assert f"σ {cam['corner_sigma_px']:.3f} px" in head
    assert f"RMS {cam['reprojection_rms_px']:.3f} px" in head
    assert f"{cam['inlier_corners']} of {cam['corners']} corners" in head

    # the poses: the fixed part's in the base frame, the mounted part's on the flange
    names = ("T_base_camera", "T_flange_board")
    if setup == "eye-in-hand":
        names = ("T_base_board", "T_flange_camera")
    assert re.search(rf'data-pose="{names[0]}".*data-pose="{names[1]}"', text)
    assert "in the DH table's base frame, with its conventions" in text
    cells = page.cells["camera-poses"]
    assert len(cells) == 12  # 6 rows, 2 poses
    for col, name in enumerate(names):
        values = _pose_expected(cam[name])
        std = cam[f"{name}_std"]
        sds = [*std["translation_m"], *std["rotation_rad"]]
        for k in range(6):
            attrs, shown = cells[2 * k + col]
            assert float(str(attrs["data-si"])) == pytest.approx(values[k], abs=1e-12)
            assert float(str(attrs["data-std"])) == sds[k]  # to the bit
            factor = 1e3 if k < 3 else 180 / math.pi
            value_text, sd_text = shown.split("± ")
            places = len(value_text.split(".")[1])
            assert abs(float(value_text) - values[k] * factor) <= 0.5 * 10**-places + 1e-9
            assert abs(float(sd_text) - sds[k] * factor) <= 0.5 * 10**-places + 1e-9
            assert 4 <= places <= 7

    # the intrinsics: held as given, or refined with σ
    intr = cam["intrinsics"]
    shown_intr = page.ids["camera-intrinsics"]
    assert f"{intr['width']} × {intr['height']} px" in shown_intr
    assert intr["distortion_model"] in shown_intr
    if intr["refined"]:
        assert "refined" in shown_intr and intr["std"] is not None
        fx, sd = intr["K"][0][0], intr["std"][0]
        m = re.search(r"fx ([0-9.]+) ± ([0-9.]+) px", shown_intr)
        assert m is not None, shown_intr
        places = len(m.group(2).split(".")[1])
        assert abs(float(m.group(1)) - fx) <= 0.5 * 10**-places
        assert abs(float(m.group(2)) - sd) <= 0.5 * 10**-places
        assert sd > 0 and "±" in shown_intr.split("Lens")[1]
    else:
        assert "held" in shown_intr and "±" not in shown_intr
        assert f"fx {intr['K'][0][0]:.6g} px" in shown_intr

    # the held-out check in pixels and mm, in section 2, the nominal placed on training frames
    h = cam["holdout"]
    assert "Accuracy at held-out frames" in " ".join(page.headings)
    assert 'id="no-holdout"' not in text
    got = [
        float(str(a["data-value"])) if a.get("data-value") else None
        for a, _ in page.cells["camera-holdout"]
        if a.get("class") == "num"
    ]
    want = [
        h["reprojection_rms_px"]["nominal"],
        h["target_rms_mm"]["nominal"],
        h["reprojection_rms_px"]["calibrated"],
        h["target_rms_mm"]["calibrated"],
        h["in_sample_rms_px"],
        h["target_rms_mm"]["in_sample"],
        None,
        h["target_rms_mm"]["pnp_noise"],
    ]
    assert got == want  # to the bit
    assert f"{h['folds']}-fold cross-validation, {h['frames']} frames" in page.ids["camera-holdout"]
    assert "before (the nominal placed on the frames the calibration was fitted on" in text
    beyond = h["target_rms_mm"]["calibrated_beyond_noise"]
    assert f"{beyond:.4f} mm" in page.ids["camera-beyond-noise"]
    plain = html.unescape(text)
    for note in h["notes"]:
        assert f"Held out: {note}" in plain
    # the cards at the top: the camera's held-out figures, not "none: run --holdout 5"
    assert f"{h['reprojection_rms_px']['calibrated']:.4f} px" in plain
    assert "none: run --holdout 5" not in plain


def test_a_camera_without_holdout_or_nominal_says_so(to_hand: Made, tmp_path: Path) -> None:
    doc = json.loads(to_hand.result.read_text())
    doc["camera"]["holdout"]["reprojection_rms_px"]["nominal"] = None
    doc["camera"]["holdout"]["target_rms_mm"]["nominal"] = None
    (tmp_path / "a.dh.json").write_text(json.dumps(doc))
    text = report(tmp_path / "a.dh.json", tmp_path / "a.html")
    assert "no nominal given to dhlog process" in parse(text).ids["camera-holdout"]
    doc["camera"]["holdout"] = None
    (tmp_path / "b.dh.json").write_text(json.dumps(doc))
    text = report(tmp_path / "b.dh.json", tmp_path / "b.html")
    page = parse(text)
    assert "camera-holdout" not in page.ids and "no-holdout" in page.ids
    assert "none: run --holdout 5" in text and "camera-poses" in page.ids


def test_hostile_text_in_the_camera_block_is_escaped(to_hand: Made, tmp_path: Path) -> None:
    doc = json.loads(to_hand.result.read_text())
    evil = '<script>alert("x")</script>'
    doc["camera"]["topic"] = evil
    doc["camera"]["setup_reason"] = evil
    doc["camera"]["detections"] = evil
    doc["camera"]["holdout"]["notes"] = [evil]
    (tmp_path / "r.dh.json").write_text(json.dumps(doc))
    text = report(tmp_path / "r.dh.json", tmp_path / "r.html")
    assert "<script" not in text and text.count("&lt;script&gt;") == 4


def _set(path: str, value: Any) -> Any:
    def change(doc: Any) -> None:
        *parents, last = path.split(".")
        node = doc
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        node[int(last) if isinstance(node, list) else last] = value

    return change


def _delete(path: str) -> Any:
    def change(doc: Any) -> None:
        *parents, last = path.split(".")
        node = doc
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        del node[last]

    return change


def _skew(doc: Any) -> None:
    doc["camera"]["T_base_camera"][0][1] += 0.01


DAMAGED = [
    (
        "sigma-text",
        _set("camera.corner_sigma_px", "0.05"),
        "camera.corner_sigma_px must be a number",
    ),
    ("no-pose", _delete("camera.T_base_camera"), "camera.T_base_camera is missing"),
    ("no-mount", _delete("camera.T_flange_board"), "camera.T_flange_board is missing"),
    ("no-std", _delete("camera.T_flange_board_std"), "camera.T_flange_board_std is missing"),
    ("pose-row", _set("camera.T_base_camera.2", [1, 2]), "camera.T_base_camera[2] must hold 4"),
    ("pose-text", _set("camera.T_base_camera.0.3", "0.1"), "camera.T_base_camera[0][3] must be"),
    ("not-rigid", _skew, "camera.T_base_camera must be a rigid transform"),
    ("std-text", _set("camera.T_base_camera_std.rotation_rad.1", "x"), "rotation_rad[1] must be"),
    ("std-negative", _set("camera.T_base_camera_std.translation_m.0", -1e-4), "translation_m[0]"),
    ("setup", _set("camera.setup", "stereo"), "camera.setup must be eye-to-hand or eye-in-hand"),
    ("refined", _set("camera.intrinsics.refined", "yes"), "camera.intrinsics.refined must be"),
    ("K", _set("camera.intrinsics.K", [[1, 0, 0]]), "camera.intrinsics.K must be a 3×3"),
    ("lens", _set("camera.intrinsics.distortion_model", "pinhole"), "distortion_model must be"),
    ("istd", _set("camera.intrinsics.std", [1.0]), "camera.intrinsics.std must hold 9 numbers"),
    ("width", _set("camera.intrinsics.width", 0), "camera.intrinsics.width must be at least 1"),
    ("inliers", _set("camera.inlier_corners", 10**6), "camera.inlier_corners is 1000000"),
    ("holdout", _set("camera.holdout", [1]), "camera.holdout must be an object"),
    ("held-mm", _set("camera.holdout.target_rms_mm.calibrated", "1"), "target_rms_mm.calibrated"),
    ("held-px", _delete("camera.holdout.reprojection_rms_px"), "reprojection_rms_px is missing"),
    ("notes", _set("camera.holdout.notes", [3]), "camera.holdout.notes[0] must be a string"),
    ("block", _set("camera", "eye-to-hand"), "camera must be an object, not a string"),
]


@pytest.mark.parametrize(("name", "change", "says"), DAMAGED, ids=[d[0] for d in DAMAGED])
def test_a_damaged_camera_block_is_one_line_exit_2(
    tmp_path: Path, to_hand: Made, name: str, change: Any, says: str
) -> None:
    doc = json.loads(to_hand.result.read_text())
    change(doc)
    result = tmp_path / "run.dh.json"
    result.write_text(json.dumps(doc))
    out = tmp_path / "certificate.html"
    done = runner.invoke(app, ["report", str(result), "-o", str(out)])
    assert done.exit_code == 2, done.output
    lines = [line for line in done.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in done.output, done.output
    assert lines[0].startswith("error: ") and str(result) in lines[0] and says in lines[0]
    assert "dhlog process" in lines[0]  # what to do
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.dh.json"]


def test_a_tracker_result_has_no_camera_section(tracker: Made, tmp_path: Path) -> None:
    assert "camera" not in tracker.doc
    text = report(tracker.result, tmp_path / "t.html")
    page = parse(text)
    assert not any(k.startswith("camera") for k in page.ids)
    assert "s-camera" not in text and "Camera and board" not in text
    assert [re.sub(r"^\d+", "", h) for h in page.headings] == [
        "Identification",
        "Accuracy at held-out poses",
        "DH parameters",
        "Tracker and noise model",
        "Per-joint residuals",
        "Beyond the geometry",
        "Warnings and notes",
    ]
    assert "from a laser-tracker log" in text
    assert "M: the tracker's measurement frame." in text


CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run"]


def test_the_camera_page_renders_in_chromium(to_hand: Made, tmp_path: Path) -> None:
    """Without console or page errors or requests beyond its file; the poses table drawn."""
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium not installed: apt-get install chromium")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright not installed: pip install -e '.[test]'")
    path = tmp_path / "camera.html"
    report(to_hand.result, path, "--nominal", "kr5")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            errors: list[str] = []
            requests: list[str] = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("request", lambda r: requests.append(r.url))
            page.goto(path.as_uri())
            page.wait_for_load_state("load")
            assert errors == [] and requests == [path.as_uri()]
            assert page.locator("table#camera-poses tbody tr").count() == 6
            box = page.locator("table#camera-poses").bounding_box()
            assert box is not None and box["width"] > 300 and box["height"] > 100
        finally:
            browser.close()
