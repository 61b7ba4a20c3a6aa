"""``dhlog report``: the calibration certificate of a real result (docs/random-poses.md's
walkthrough, and a sweeps session), checked against the result JSON; damaged inputs; and the
page in a headless Chromium."""

from __future__ import annotations

import hashlib
import html
import json
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.model.robots import load_robot

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
ROBOT = 'KR5 sixx <script>alert("x")</script> #4711'


@dataclass
class Made:
    """A result written by ``dhlog process`` and its console output."""

    folder: Path
    result: Path
    log: Path
    console: str


@pytest.fixture(scope="module")
def poses(tmp_path_factory: pytest.TempPathFactory) -> Made:
    """docs/random-poses.md's commands: the export imported, then processed with the
    nominal and 5-fold held-out validation (results beside the log)."""
    folder = tmp_path_factory.mktemp("poses")
    log = folder / "poses.mcap"
    done = runner.invoke(app, ["import", str(SAMPLES / "kr5_random_poses.csv"), "-o", str(log)])
    assert done.exit_code == 0, done.output
    done = runner.invoke(
        app, ["process", str(log), "--nominal", "kr5", "--holdout", "5", "--no-rrd"]
    )
    assert done.exit_code == 0, done.output
    return Made(folder, folder / "poses.dh.json", log, done.output)


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory: pytest.TempPathFactory) -> Made:
    """The bundled KR5 sweeps session, results in another folder than the log, no holdout."""
    folder = tmp_path_factory.mktemp("sweeps")
    log = SAMPLES / "kr5_0.01mm.mcap"
    done = runner.invoke(app, ["process", str(log), "--out", str(folder), "--no-rrd"])
    assert done.exit_code == 0, done.output
    return Made(folder, folder / "kr5_0.01mm.dh.json", log, done.output)


def report(made: Made, name: str, *extra: str) -> tuple[Path, str]:
    out = made.folder / name
    done = runner.invoke(app, ["report", str(made.result), "-o", str(out), "--force", *extra])
    assert done.exit_code == 0, done.output
    return out, out.read_text(encoding="utf-8")


@dataclass
class Page(HTMLParser):
    """The parts of a certificate the tests read: every ``data-parameter`` cell of the
    parameter table (its attributes and text lines) by joint, the text of elements by id,
    the held-out table's text."""

    cells: dict[int, dict[str, dict[str, Any]]] = field(default_factory=dict)
    ids: dict[str, str] = field(default_factory=dict)
    _joint: int | None = None
    _cell: dict[str, Any] | None = None
    _open: list[tuple[str, str | None]] = field(default_factory=list)

    def __post_init__(self) -> None:
        super().__init__()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "tr" and a.get("data-joint"):
            self._joint = int(str(a["data-joint"]))
            self.cells[self._joint] = {}
        if tag == "td" and a.get("data-parameter") and self._joint is not None:
            self._cell = {"attrs": a, "lines": []}
            self.cells[self._joint][str(a["data-parameter"])] = self._cell
        if tag == "span" and self._cell is not None:
            self._cell["lines"].append("")
        if tag not in ("br", "meta", "img", "input", "link"):
            self._open.append((tag, a.get("id")))

    def handle_endtag(self, tag: str) -> None:
        if tag == "td":
            self._cell = None
        if tag == "tr":
            self._joint = None
        while self._open:
            if self._open.pop()[0] == tag:
                break

    def handle_data(self, data: str) -> None:
        if self._cell is not None and self._cell["lines"]:
            self._cell["lines"][-1] += data
        for _, ident in self._open:
            if ident:
                self.ids[ident] = self.ids.get(ident, "") + data


def parse(text: str) -> Page:
    page = Page()
    page.feed(text)
    return page


def shown_rows(doc: dict[str, Any]) -> list[dict[str, Any]]:
    if "hayati_dh" in doc:
        return list(doc["hayati_dh"]["rows"])
    return [dict(r, form="dh") for r in doc["standard_dh"]]


KEYS = {"theta": "theta_offset", "d": "d_offset", "beta": "beta", "a": "a", "alpha": "alpha"}


def shown_number(line: str) -> float:
    return float(re.sub(r"[^0-9.+-]", "", line.replace("β", "")))


def test_the_certificate_shows_the_result_as_the_json_has_it(poses: Made) -> None:
    """Every parameter's value and σ equal the JSON's (to the bit in the cell's data, to the
    printed decimals in its text), fixed ones say fixed with their reason and carry no σ or
    measured − nominal; measured − nominal equals the console's; both hashes are right; the
    held-out figures are there; the plots are well-formed SVG; nothing is fetched; the robot's
    name is escaped."""
    out, text = report(poses, "certificate.html", "--nominal", "kr5", "--robot", ROBOT)
    doc = json.loads(poses.result.read_text())
    page = parse(text)
    rows = shown_rows(doc)
    assert sorted(page.cells) == list(range(1, len(rows) + 1))
    hayati = [i + 1 for i, r in enumerate(rows) if r["form"] == "hayati"]
    assert hayati == [2]  # the sample's nearly parallel pair, shown in its form
    assert "beta" in page.cells[2] and "d" not in page.cells[2]
    ol = re.search(r'<ol class="footnotes" id="fixed-reasons">(.*?)</ol>', text, re.DOTALL)
    assert ol is not None
    footnotes = re.findall(r"<li>(.*?)</li>", ol.group(1))
    n_fixed = 0
    for i, row in enumerate(rows):
        cells = page.cells[i + 1]
        held = set(row.get("fixed", []))
        for name, cell in cells.items():
            attrs, lines = cell["attrs"], cell["lines"]
            value = row[KEYS[name]]
            assert float(attrs["data-si"]) == value
            factor = 1e3 if name in ("d", "a") else 180 / 3.141592653589793
            places = len(lines[0].split(".")[1].rstrip("°"))
            assert abs(shown_number(lines[0]) - value * factor) <= 0.51 * 10**-places
            if name in held:
                n_fixed += 1
                assert attrs.get("data-fixed") == "true" and lines[1].startswith("fixed")
                assert "data-std" not in attrs and "data-delta" not in attrs
                mark = int(lines[1].split()[-1])
                symbol = {"theta": "θ", "d": "d", "a": "a", "alpha": "α"}[name]
                held_by = footnotes[mark - 1].split(" fixed: ")[0].split(", ")
                assert f"{symbol}{i + 1}" in held_by
            else:
                sd = row["std"]["d" if name == "d" else name]
                assert float(attrs["data-std"]) == sd
                assert abs(shown_number(lines[1]) - sd * factor) <= 0.51 * 10**-places
                assert "data-delta" in attrs
    assert n_fixed == sum(len(r.get("fixed", [])) for r in rows) >= 6
    for reason in {r["fixed_reason"] for r in rows if "fixed_reason" in r}:
        for part in re.split(r"(?:^|; )(?:theta|d|beta|a|alpha): ", reason):
            assert part.strip() in page.ids["fixed-reasons"]

    # measured − nominal: the DH rows against the library's table, and every row against the
    # console's "Measured − nominal" table (4 decimals), the Hayati row's Δβ included
    nominal = load_robot("kr5").table
    for i in (0, 3, 4):
        for name, key in (("a", "a"), ("alpha", "alpha"), ("d", "d_offset")):
            attrs = page.cells[i + 1][name]["attrs"]
            if name in rows[i].get("fixed", []):
                continue
            expected = rows[i][key] - float(getattr(nominal, key)[i])
            assert float(attrs["data-delta"]) == pytest.approx(expected, abs=1e-12)
    console = {
        int(m.group(1)): [float(v) for v in re.findall(r"[+-]\d+\.\d+", m.group(2))]
        for m in re.finditer(
            r"^ (\d)\s+j\d\s+(\S+\s+(?:Δβ )?\S+\s+\S+\s+\S+)\s*$", poses.console, re.M
        )
    }
    assert sorted(console) == [1, 2, 3, 4, 5, 6]
    for joint, deltas in console.items():
        for k, name in enumerate(("theta", "beta" if joint in hayati else "d", "a", "alpha")):
            attrs = page.cells[joint][name]["attrs"]
            if "data-delta" in attrs:
                factor = 1e3 if name in ("d", "a") else 180 / 3.141592653589793
                assert float(attrs["data-delta"]) * factor == pytest.approx(deltas[k], abs=6e-5)

    # hashes: the result file's own, the log's recorded and recomputed
    assert page.ids["result-sha256"] == hashlib.sha256(poses.result.read_bytes()).hexdigest()
    log_sha = hashlib.sha256(poses.log.read_bytes()).hexdigest()
    assert doc["source"]["sha256"] == log_sha
    assert page.ids["log-sha256-recorded"] == log_sha and page.ids["log-sha256"] == log_sha
    assert "matches the recorded hash" in text

    # held-out figures, before and after, beside the in-sample fit
    check = doc["validation"]["holdout"][0]
    table = page.ids["holdout"]
    for model in ("nominal", "calibrated"):
        for stat in ("mean", "rms", "p95", "max"):
            assert f"{check[model][stat] * 1e3:.4f}" in table
    assert f"{doc['validation']['fk_rms'] * 1e3:.4f}" in table and "5-fold" in table
    assert "No held-out validation" not in text

    # plots: well-formed SVG, the histogram among them; nothing external, nothing executable
    svgs = re.findall(r"<svg\b.*?</svg>", text, flags=re.DOTALL)
    assert len(svgs) == 1  # the held-out histogram (random poses have no per-joint fits)
    for svg in svgs:
        ET.fromstring(svg)
    ids = re.findall(r'\bid="([^"]+)"', text)
    assert len(ids) == len(set(ids))
    for bad in ('src="http', "src='http", 'href="http', "href='http", "url(http", "@import"):
        assert bad not in text
    assert "<script" not in text and "<link" not in text and "<iframe" not in text
    assert "KR5 sixx &lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; #4711" in text
    assert page.ids["robot"].startswith(ROBOT)  # as text, not as an element
    assert 'id="no-joint-residuals"' in text
    assert out.stat().st_size < 400_000


def test_a_sweeps_result_without_holdout_says_so_and_plots_per_joint_residuals(
    sweeps: Made,
) -> None:
    """No held-out validation is said prominently; the per-joint fits' residuals are drawn and
    listed as the JSON has them; the log, not beside the result, is not hashed (said), and is
    with --log."""
    _, text = report(sweeps, "sweeps.html")
    doc = json.loads(sweeps.result.read_text())
    page = parse(text)
    assert "No held-out validation" in page.ids["no-holdout"]
    assert "--holdout 5" in page.ids["no-holdout"]
    assert page.ids["log-sha256"] == "log not found, hash not computed"
    assert "not recorded in the result JSON" in text  # the nominal
    svgs = re.findall(r"<svg\b.*?</svg>", text, flags=re.DOTALL)
    assert len(svgs) == 1  # per-joint residual bars
    ET.fromstring(svgs[0])
    residuals = page.ids["joint-residuals"]
    for j in doc["joints"]:
        assert f"{j['fit']['rms'] * 1e3:.4f}" in residuals
        assert f"{j['validation']['fk_max'] * 1e3:.4f}" in residuals
    _, text = report(sweeps, "sweeps_log.html", "--log", str(sweeps.log))
    assert parse(text).ids["log-sha256"] == hashlib.sha256(sweeps.log.read_bytes()).hexdigest()
    assert "matches the recorded hash" in text


def test_terms_beyond_the_geometry_and_hostile_text(tmp_path: Path, poses: Made) -> None:
    """The terms of the nongeometric block with their σ and lumps; HTML in a joint name, a
    warning or a note is text, never markup."""
    hostile = '<img src="http://example.invalid/x" onerror="alert(1)">'

    def change(doc: Any) -> None:
        block = doc["nongeometric"]
        block["lumps"] = [{"on": "axis 3", "point": [0.0, 0.0, 0.0]}]
        block["lumps"].append({"on": "target", "point": [0.0, 0.0, 0.1]})
        block["terms"] = [
            {"name": "c2", "kind": "compliance", "joint": 2, "lump": 1, "value": 2.5e-4}
            | {"std": 3e-6, "unit": "rad/m"},
            {"name": "h3s", "kind": "harmonic_sin", "joint": 3, "value": -1e-5}
            | {"std": None, "unit": "rad"},
        ]
        block["max_target_displacement"] = 2.1e-4
        doc["joints"][0]["name"] = hostile
        doc["warnings"].append(hostile)
        doc["notes"].append(hostile)

    result = _damaged(tmp_path, poses, change)
    out = tmp_path / "terms.html"
    done = runner.invoke(app, ["report", str(result), "-o", str(out)])
    assert done.exit_code == 0, done.output
    text = out.read_text()
    terms = parse(text).ids["terms"]
    assert "c2" in terms and "0.00025" in terms and "± 3e-06" in terms and "target" in terms
    assert "h3s" in terms and "-1e-05" in terms and "harmonic_sin" in terms
    assert "0.2100 mm" in text
    assert "<img" not in text and 'src="http' not in text
    assert text.count(html.escape(hostile)) >= 4  # joints, parameter table, warning, note


@pytest.mark.parametrize("name", ["/dev/zero", "../../../../etc/passwd", "", "."])
def test_the_log_named_by_the_json_is_only_looked_for_beside_it(
    tmp_path: Path, poses: Made, name: str
) -> None:
    """The JSON's log name is untrusted: only its last part is looked for, and never a
    device (which would never end)."""
    result = _damaged(tmp_path, poses, _set("source.path", name))
    out = tmp_path / "certificate.html"
    done = runner.invoke(app, ["report", str(result), "-o", str(out)])
    assert done.exit_code == 0, done.output
    assert parse(out.read_text()).ids["log-sha256"] == "log not found, hash not computed"


def _damaged(tmp_path: Path, poses: Made, change: Any, *, csv: bool = False) -> Path:
    """A copy of the result (and its held-out CSV when ``csv``) with ``change`` applied: a
    function of the document, or bytes replacing the file."""
    target = tmp_path / "run.dh.json"
    if isinstance(change, bytes):
        target.write_bytes(change)
    else:
        doc = json.loads(poses.result.read_text())
        change(doc)
        target.write_text(json.dumps(doc))
    if csv:
        shutil.copy(poses.folder / "poses.holdout.csv", tmp_path / "run.holdout.csv")
    return target


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


DAMAGED = [
    ("missing-a", _delete("hayati_dh.rows.2.a"), "hayati_dh.rows[2].a is missing"),
    ("a-as-text", _set("hayati_dh.rows.0.a", "0.18"), "hayati_dh.rows[0].a must be a number"),
    ("std-negative", _set("hayati_dh.rows.3.std.d", -1.0), "hayati_dh.rows[3].std.d must be"),
    ("nested-rows", _set("standard_dh", [[[[]]]]), "hayati_dh.rows has 6 rows, standard_dh 1"),
    ("nested-row", _set("hayati_dh.rows.1", [[{"a": []}]]), "rows[1] must be an object"),
    ("nested-std", _set("hayati_dh.rows.4.std", {"a": {"b": [1]}}), "rows[4].std.theta is"),
    ("joints-object", _set("joints", {"a": [1, {"b": None}]}), "joints must be an array"),
    ("no-validation", _delete("validation"), "validation is missing"),
    ("holdout-list", _set("validation.holdout.0.calibrated", [1, 2]), "calibrated must be"),
    ("holdout-nan", _set("validation.holdout.0.nominal.rms", float("nan")), "finite"),
    ("warnings", _set("warnings", [1]), "warnings[0] must be a string"),
    ("format", _set("format", "something/2"), "format is 'something/2'"),
    ("form", _set("hayati_dh.rows.1.form", "<b>x</b>"), "hayati_dh.rows[1].form must be"),
    ("fixed", _set("hayati_dh.rows.0.fixed", ["gamma"]), "hayati_dh.rows[0].fixed[0]"),
    ("terms", _set("nongeometric.terms", [{"name": 1}]), "nongeometric.terms[0].name"),
    ("top-list", _set("source", None), "source must be an object"),
    ("not-json", b'{"format": "dhlog.result/1", ', "is not valid JSON"),
    ("not-utf8", b"\xff\xfe{}", "is not UTF-8"),
    ("deep", b"[" * 200_000, "the file"),
    ("digits", b'{"format": ' + b"7" * 5000 + b"}", "is not valid JSON"),
    ("huge", _set("hayati_dh.rows.0.a", 10**400), "hayati_dh.rows[0].a is out of range"),
    ("infinite", _set("hayati_dh.rows.0.alpha", float("inf")), "must be a finite number"),
    ("array", b"[1, 2, 3]", "the document must be an object"),
]


@pytest.mark.parametrize(("name", "change", "says"), DAMAGED, ids=[d[0] for d in DAMAGED])
def test_a_damaged_result_is_one_line_exit_2_and_nothing_written(
    tmp_path: Path, poses: Made, name: str, change: Any, says: str
) -> None:
    result = _damaged(tmp_path, poses, change)
    out = tmp_path / "certificate.html"
    done = runner.invoke(app, ["report", str(result), "-o", str(out)])
    assert done.exit_code == 2, done.output
    lines = [line for line in done.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in done.output, done.output
    assert lines[0].startswith("error: ") and str(result) in lines[0] and says in lines[0]
    assert "dhlog process" in lines[0]  # what to do
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.dh.json"]  # no output, no .part


def _line(k: int, change: Any) -> Any:
    """Line ``k`` (1-based) of a CSV text replaced by ``change(line)``."""

    def damage(text: str) -> str:
        lines = text.splitlines()
        lines[k - 1] = change(lines[k - 1])
        return "\n".join(lines) + "\n"

    return damage


HOLDOUT_DAMAGE = [
    # the calibrated error: the cell before the last (point_id)
    ("cell", _line(4, lambda line: "{0},abc,{2}".format(*line.rsplit(",", 2))), "line 4"),
    ("negative", _line(5, lambda line: "{0},-1,{2}".format(*line.rsplit(",", 2))), "line 5"),
    ("stale", lambda t: "\n".join(t.splitlines()[:-3]) + "\n", "from another run"),
    ("header", _line(1, lambda line: "a,b,c"), "the header"),
    ("ragged", _line(3, lambda line: line + ",1"), "line 3"),
]


@pytest.mark.parametrize(
    ("name", "damage", "says"), HOLDOUT_DAMAGE, ids=[d[0] for d in HOLDOUT_DAMAGE]
)
def test_a_damaged_holdout_csv_is_one_line_exit_2(
    tmp_path: Path, poses: Made, name: str, damage: Any, says: str
) -> None:
    result = _damaged(tmp_path, poses, lambda doc: None, csv=True)
    csv_path = tmp_path / "run.holdout.csv"
    csv_path.write_text(damage(csv_path.read_text()))
    out = tmp_path / "certificate.html"
    done = runner.invoke(app, ["report", str(result), "-o", str(out)])
    assert done.exit_code == 2, done.output
    lines = [line for line in done.output.splitlines() if line.strip()]
    assert len(lines) == 1 and str(csv_path) in lines[0] and says in lines[0], done.output
    assert not out.exists()


def test_the_output_never_replaces_an_input_or_an_existing_file(poses: Made) -> None:
    for target in (poses.result, poses.folder / "poses.holdout.csv", poses.log):
        done = runner.invoke(app, ["report", str(poses.result), "-o", str(target), "--force"])
        assert done.exit_code == 1 and "is an input" in done.output
    out = poses.folder / "kept.html"
    out.write_text("mine")
    done = runner.invoke(app, ["report", str(poses.result), "-o", str(out)])
    assert done.exit_code == 1 and "--force" in done.output and out.read_text() == "mine"
    done = runner.invoke(app, ["report", str(poses.result), "-o", str(out), "--force"])
    assert done.exit_code == 0 and out.read_text().startswith("<!DOCTYPE html>")
    out.write_text("mine")
    for nominal, says in (("ur5x", "ur5x"), ("scara", "has 4 joints")):
        bad = runner.invoke(
            app, ["report", str(poses.result), "-o", str(out), "--force", "--nominal", nominal]
        )
        assert bad.exit_code == 2 and says in bad.output and out.read_text() == "mine"


def test_other_commands_do_not_import_matplotlib() -> None:
    code = "import sys, dhlog.cli.app; print('matplotlib' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def test_the_page_renders_in_chromium_without_errors(poses: Made, sweeps: Made) -> None:
    """Each certificate loads in a headless Chromium without console or page errors and
    without a request beyond its own file; it has the parameter table and every plot drawn
    at a size."""
    chromium = shutil.which("chromium")
    if chromium is None:
        pytest.skip("chromium not installed: apt-get install chromium")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("playwright not installed: pip install -e '.[test]'")
    pages = [
        report(poses, "browser.html", "--nominal", "kr5", "--robot", ROBOT),
        report(sweeps, "browser.html"),
    ]
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        try:
            for path, text in pages:
                page = browser.new_page(viewport={"width": 1200, "height": 900})
                errors: list[str] = []
                requests: list[str] = []
                page.on(
                    "console",
                    lambda m, errors=errors: errors.append(m.text) if m.type == "error" else None,
                )
                page.on("pageerror", lambda e, errors=errors: errors.append(str(e)))
                page.on("request", lambda r, requests=requests: requests.append(r.url))
                page.goto(path.as_uri())
                page.wait_for_load_state("load")
                assert errors == []
                assert requests == [path.as_uri()]
                rows = page.locator("table#parameters tbody tr")
                assert rows.count() == 6
                svgs = page.locator("svg")
                assert svgs.count() == text.count("<svg") >= 1
                for k in range(svgs.count()):
                    box = svgs.nth(k).bounding_box()
                    assert box is not None and box["width"] > 300 and box["height"] > 80
                assert page.evaluate("document.scripts.length") == 0
                shot = path.with_suffix(".png")
                page.screenshot(path=str(shot), full_page=True)
                assert shot.stat().st_size > 10_000
                page.close()
        finally:
            browser.close()


def test_a_result_that_is_a_pipe_is_refused_without_waiting(tmp_path: Path) -> None:
    """A FIFO named as the result: the read waited for a writer forever; now one line, exit 2."""
    fifo = tmp_path / "r.dh.json"
    os.mkfifo(fifo)
    done = runner.invoke(app, ["report", str(fifo), "-o", str(tmp_path / "c.html")])
    assert done.exit_code == 2, done.output
    assert "is not a regular file" in done.stderr and len(done.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.dh.json"]
