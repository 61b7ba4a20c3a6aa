"""A result dhlog itself judges implausible never exits 0 (issue 39, item 5): it is written,
marked ``"plausible": false`` with the reasons, the console's last line says so and ``dhlog
process`` exits 4; ``dhlog batch``, ``export``, ``report`` and the API (``Calibration.plausible``,
``ImplausibleWarning``) say it too. A plausible run says ``"plausible": true`` and exits 0.

The unit slip: the bundled random-pose export (a KR5 off its nominal, 40 poses, a 6-DoF probe)
rewritten with its coordinates in inches under its ``X [mm]`` header — nothing in the file can
tell, the points span a tenth of a metre as a small robot's would — so every length comes out
1/25.4 of the nominal's. The nominal's own miss: a robot far from its nominal (lengths 0.8 mm,
and 1.4 mm of smooth error a geometric model cannot take) calibrated geometrically leaves 2.2
mm FK RMS while its nominal misses the same points by 3.3 mm: a poor but real calibration, not
inputs read wrong."""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import polars as pl
import pytest
from typer.testing import CliRunner

import dhlog
from dhlog.cli.app import app
from dhlog.cli.common import EXIT_IMPLAUSIBLE, EXIT_INPUT

runner = CliRunner()
SAMPLE = Path(__file__).parents[1] / "sample_logs" / "kr5_random_poses.csv"


def inches_export(path: Path) -> Path:
    """The sample export with X, Y, Z written in inches, the header still saying mm."""
    lines = SAMPLE.read_text().splitlines()
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(";")
        for k in (1, 2, 3):
            cells[k] = f"{float(cells[k]) / 25.4:.7f}"
        out.append(";".join(cells))
    path.write_text("\n".join(out) + "\n")
    return path


def imported(csv: Path, log: Path) -> Path:
    done = runner.invoke(app, ["import", str(csv), "-o", str(log)])
    assert done.exit_code == 0, done.output
    return log


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(the export read right, the export in inches read as mm), imported as a user would."""
    tmp = tmp_path_factory.mktemp("plausible")
    right = imported(SAMPLE, tmp / "right.mcap")
    inches = imported(inches_export(tmp / "inches.csv"), tmp / "inches.mcap")
    return right, inches


def test_a_unit_slip_is_written_marked_and_exits_4(logs: tuple[Path, Path], tmp_path: Path) -> None:
    """The inches log: every output written, the JSON ``plausible: false`` with the reason
    naming inches read as mm and the fix, the last line saying so, exit 4. The same export read
    right: ``plausible: true``, no reasons, exit 0."""
    right, inches = logs
    args = ["--nominal", "kr5", "--model", "geometric", "--no-rrd", "--out", str(tmp_path)]
    done = runner.invoke(app, ["process", str(inches), *args])
    assert done.exit_code == EXIT_IMPLAUSIBLE, done.output
    last = done.output.strip().splitlines()[-1]
    assert last.startswith("implausible result: the calibrated lengths are all 0.039"), last
    assert "inches read as mm" in last and "length_unit" in last and "exit 4" in last
    doc = json.loads((tmp_path / "inches.dh.json").read_text())
    assert doc["plausible"] is False and len(doc["implausible"]) == 1
    assert "inches read as mm" in doc["implausible"][0]
    assert (tmp_path / "inches.dh.csv").exists()
    # the result is right for what it was given: its lengths are 1/25.4 of the KR5's
    assert abs(doc["standard_dh"][1]["a"] - 0.6 / 25.4) < 1e-3
    ok = runner.invoke(app, ["process", str(right), *args])
    assert ok.exit_code == 0, ok.output
    assert "implausible" not in ok.output and "likely read wrong" not in ok.output
    doc = json.loads((tmp_path / "right.dh.json").read_text())
    assert doc["plausible"] is True and doc["implausible"] == []


def test_readers_of_an_implausible_result_see_it(logs: tuple[Path, Path], tmp_path: Path) -> None:
    """``dhlog.process`` and ``dhlog.load`` warn (``ImplausibleWarning``) and give
    ``Calibration.plausible`` False with the reasons; ``dhlog export`` and ``compare`` do what
    is asked and warn; ``dhlog report`` shows the reasons on the certificate; a plausible
    result gives none of these."""
    right, inches = logs
    with pytest.warns(dhlog.ImplausibleWarning, match="inches read as mm"):
        cal = dhlog.process(inches, nominal="kr5", model="geometric")
    assert cal.plausible is False and len(cal.implausible) == 1
    assert "inches read as mm" in cal.implausible[0]
    saved = tmp_path / "inches.dh.json"
    cal.save(saved)
    with pytest.warns(dhlog.ImplausibleWarning):
        back = dhlog.load(saved)
    assert back.plausible is False and back.implausible == cal.implausible
    done = runner.invoke(app, ["export", str(saved), "-o", str(tmp_path / "r.urdf")])
    assert done.exit_code == 0, done.output
    assert (tmp_path / "r.urdf").exists()
    said = " ".join(done.output.split())
    assert "judged implausible" in said and "inches read as mm" in said, said
    kept = tmp_path / "good.dh.json"
    dhlog.process(right, nominal="kr5", model="geometric").save(kept)
    done = runner.invoke(app, ["compare", str(kept), str(saved)])
    assert done.exit_code == 0, done.output
    said = " ".join(done.output.split())
    assert "inches.dh.json is a result dhlog judged implausible" in said, said
    assert "good.dh.json is a result" not in said
    done = runner.invoke(app, ["report", str(saved), "-o", str(tmp_path / "r.html")])
    assert done.exit_code == 0, done.output
    page = (tmp_path / "r.html").read_text()
    assert 'id="implausible"' in page and "inches read as mm" in page
    with warnings.catch_warnings():
        warnings.simplefilter("error", dhlog.ImplausibleWarning)
        good = dhlog.process(right, nominal="kr5", model="geometric")
        good.save(tmp_path / "right.dh.json")
        assert dhlog.load(tmp_path / "right.dh.json").plausible
    assert good.plausible and good.implausible == ()
    # a DH file (no judgement in it) is plausible
    assert dhlog.load(Path(__file__).parents[1] / "sample_logs" / "kr5_real.truth.json").plausible


def test_a_batch_reports_its_implausible_logs(logs: tuple[Path, Path], tmp_path: Path) -> None:
    """One log of two implausible: its row's status ``implausible`` with the reason, the
    closing line counts it, exit 4 (nothing failed); its results are written."""
    right, inches = logs
    out = tmp_path / "batch"
    done = runner.invoke(
        app,
        [
            *("batch", str(right), str(inches), "--out", str(out), "--nominal", "kr5"),
            *("--model", "geometric", "--no-rrd", "--jobs", "1"),
        ],
    )
    assert done.exit_code == EXIT_IMPLAUSIBLE, done.output
    assert "1 ok, 0 partial, 1 implausible, 0 failed" in " ".join(done.output.split())
    summary = pl.read_csv(out / "summary.csv")
    assert summary["status"].to_list() == ["ok", "implausible"]
    assert "inches read as mm" in summary["reason"][1]
    assert json.loads((out / "inches.dh.json").read_text())["plausible"] is False


def test_the_nominals_own_miss_is_the_measure(tmp_path: Path) -> None:
    """A robot far from its nominal, calibrated geometrically: 2.2 mm FK RMS where its nominal
    misses the same points by 3.3 mm. No "inputs likely read wrong" (a fixed 2 mm called it a
    slip), plausible, exit 0."""
    log = tmp_path / "far.mcap"
    done = runner.invoke(
        app,
        [
            *("simulate", "kr5", "-o", str(log), "--protocol", "random-poses", "--poses", "60"),
            *("--perturb-mm", "0.8", "--model-error-mm", "1.4", "--noise-mm", "0.02"),
            *("--seed", "3"),
        ],
    )
    assert done.exit_code == 0, done.output
    args = ["--nominal", "kr5", "--model", "geometric", "--no-rrd", "--out", str(tmp_path)]
    done = runner.invoke(app, ["process", str(log), *args])
    assert done.exit_code == 0, done.output
    doc = json.loads((tmp_path / "far.dh.json").read_text())
    miss = [re.search(r"RMS there ([0-9.]+) mm", n) for n in doc["notes"]]
    nominal_mm = next(float(m.group(1)) for m in miss if m)
    fk_mm = doc["validation"]["fk_rms"] * 1e3
    assert 2.0 < fk_mm < nominal_mm < 2 * fk_mm, (fk_mm, nominal_mm)
    assert doc["plausible"] is True
    assert not any("likely read wrong" in w for w in doc["warnings"]), doc["warnings"]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"plausible": "no"}, "plausible"),
        ({"implausible": [1]}, "implausible[0]"),
        ({"plausible": True, "implausible": ["a reason"]}, "implausible"),
    ],
)
def test_a_damaged_judgement_is_one_line(
    logs: tuple[Path, Path], tmp_path: Path, change: dict[str, object], field: str
) -> None:
    """``plausible`` not true/false, a reason not a sentence, a plausible result listing
    reasons: ``dhlog export`` refuses the file in one line naming the field, exit 2."""
    right, _ = logs
    cal = dhlog.process(right, nominal="kr5", model="geometric")
    doc = {**cal.document, **change}
    bad = tmp_path / "bad.dh.json"
    bad.write_text(json.dumps(doc))
    done = runner.invoke(app, ["export", str(bad), "-o", str(tmp_path / "x.urdf")])
    assert done.exit_code == EXIT_INPUT, done.output
    said = " ".join(done.output.split())
    assert f"{field} " in said and "Traceback" not in said, said
