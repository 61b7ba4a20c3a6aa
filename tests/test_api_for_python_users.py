"""The Python API as a user's script takes it: dhlog's warnings through :mod:`warnings`
(:class:`dhlog.DhlogWarning`) and the ``dhlog`` logger, the command line printing each once;
``Calibration.changes()`` equal to the console's measured − nominal table to the digits shown,
with σ; ``Calibration.nominal`` a public :class:`dhlog.DHModel`; ``dhlog fk --json`` equal to
``Calibration.fk``; ``dhlog compare --json`` and ``--fail-beyond``."""

from __future__ import annotations

import json
import logging
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import dhlog
from dhlog.cli.app import app
from dhlog.cli.common import EXIT_CHANGED, EXIT_USAGE

ROOT = Path(__file__).parents[1]
SAMPLE = ROOT / "sample_logs" / "kr5_0.01mm.mcap"
runner = CliRunner()
FLAGS = ("--nominal", "kr5", "--no-rrd", "--out")
DEGREES = ("--angle-unit", "deg", "--json")

#: joint 3 never moves: parked, held at the nominal, and said in a warning
PARKED = {"seed": 11, "noise": 2e-5, "skip_joints": (3,), "perturb_length": 5e-4}


@pytest.fixture(scope="module")
def parked_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("parked") / "parked.mcap"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return dhlog.simulate("kr5", out, **PARKED).log  # type: ignore[arg-type]


def test_a_scripts_warnings_and_logging_handler_get_dhlogs_warnings(parked_log: Path) -> None:
    """Each warning the run gives (``Calibration.warnings``) arrives once through
    ``warnings.catch_warnings(record=True)`` as a DhlogWarning naming the log, and once through
    a handler on the ``dhlog`` logger at WARNING; the logger is silent by default."""
    assert any(isinstance(h, logging.NullHandler) for h in logging.getLogger("dhlog").handlers)
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    handler = Keep(logging.WARNING)
    logging.getLogger("dhlog").addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            found = dhlog.process(parked_log, nominal="kr5")
    finally:
        logging.getLogger("dhlog").removeHandler(handler)
    parked = [w for w in found.warnings if "parked" in w]
    assert len(parked) == 1, found.warnings
    given = [w for w in caught if issubclass(w.category, dhlog.DhlogWarning)]
    assert [str(w.message) for w in given] == [f"parked.mcap: {w}" for w in found.warnings]
    assert all(w.filename == __file__ for w in given)  # pointed at the user's call
    assert [r.getMessage() for r in records] == [str(w.message) for w in given]
    assert all(r.levelno == logging.WARNING and r.name == "dhlog" for r in records)
    # an error filter on the category stops a script at the first warning
    with warnings.catch_warnings():
        warnings.simplefilter("error", dhlog.DhlogWarning)
        with pytest.raises(dhlog.DhlogWarning, match="parked"):
            dhlog.process(parked_log, nominal="kr5")


def test_implausible_warning_is_a_dhlog_warning() -> None:
    assert issubclass(dhlog.ImplausibleWarning, dhlog.DhlogWarning)
    assert issubclass(dhlog.DhlogWarning, UserWarning)
    assert {"DhlogWarning", "DHModel"} <= set(dhlog.__all__)


def test_the_command_line_prints_each_warning_once(parked_log: Path, tmp_path: Path) -> None:
    """``dhlog process`` prints its warnings itself: not again through warnings or logging,
    even with every warning shown (-W always) and the root logger printing."""
    import subprocess
    import sys

    code = (
        "import logging, sys; logging.basicConfig(level=logging.WARNING); "
        "from dhlog.entry import run; sys.argv = ['dhlog'] + sys.argv[1:]; run()"
    )
    args = [str(parked_log), *FLAGS, str(tmp_path)]
    done = subprocess.run(
        [sys.executable, "-W", "always", "-c", code, "process", *args],
        capture_output=True,
        text=True,
        env={**__import__("os").environ, "COLUMNS": "200"},
    )
    assert done.returncode == 0, done.stderr
    said = (done.stdout + done.stderr).count("its encoder spans 0 mrad): parked in the session")
    assert said == 1, done.stdout + done.stderr


def _console_changes(text: str) -> list[list[str]]:
    """The cells of the console's "Measured − nominal" table (Δθ, Δd or Δβ, Δa, Δα per joint)."""
    lines = text.splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith("Measured − nominal"))
    rows = []
    for line in lines[start + 4 :]:
        if not line.strip():
            break
        cells = re.findall(r"(Δβ [+-]\d+\.\d+|[+-]\d+\.\d+|–)", line)
        rows.append(cells)
    return rows


def _shown(changes: dict[tuple[int, str], float | None], joint: int, key: str) -> str:
    """A change as the console shows it in mm and degrees, 4 decimals."""
    value = changes[(joint, key)]
    if value is None:
        return "–"
    scaled = value * (1e3 if key in ("d", "a") else 180 / math.pi)
    return ("Δβ " if key == "beta" else "") + f"{scaled:+.4f}"


def _check_against_console(found: dhlog.Calibration, console: str) -> None:
    table = found.changes()
    by = {
        (r["joint"], r["parameter"]): (r["change_m"] if r["unit"] == "m" else r["change_rad"])
        for r in table.iter_rows(named=True)
    }
    rows = _console_changes(console)
    assert len(rows) == found.n
    for j, cells in enumerate(rows, start=1):
        second = "beta" if (j, "beta") in by else "d"
        expect = [_shown(by, j, k) for k in ("theta", second, "a", "alpha")]
        assert cells == expect, (j, cells, expect)
    # σ as the parameters table has it, null where fixed; the unit in the column's name
    params = found.parameters
    assert table["sigma_m"].to_list() == params["sigma_m"].to_list()
    assert table["sigma_rad"].to_list() == params["sigma_rad"].to_list()
    assert table["fixed"].to_list() == params["fixed"].to_list()
    assert table.filter(fixed=True)["sigma_m"].null_count() == table.filter(fixed=True).height
    free = table.filter(fixed=False)
    assert (free["sigma_m"].fill_null(0) + free["sigma_rad"].fill_null(0) > 0).all()


def test_changes_equal_the_console_table_of_the_bundled_sample() -> None:
    found = dhlog.process(SAMPLE, nominal="kr5")
    assert isinstance(found.nominal, dhlog.DHModel)
    _check_against_console(found, found.report(width=200))
    # the change is measured − nominal: the identified table minus the library's
    kr5 = dhlog.robot("kr5")
    a2 = found.changes().filter(joint=2, parameter="a")["change_m"][0]
    assert a2 == pytest.approx(found.table.a[1] - kr5.table.a[1], abs=1e-12)


def test_changes_equal_the_console_table_of_a_simulated_ur5(tmp_path: Path) -> None:
    """A UR5 off its nominal processed with --nominal ur5 (Hayati rows 2 and 3: Δβ): the
    console's table, read back as ``dhlog.load(result, nominal="ur5").changes()``."""
    log = tmp_path / "u5.mcap"
    made = runner.invoke(
        app, ["simulate", "ur5", "-o", str(log), "--perturb-mm", "0.3", "--perturb-deg", "0.02"]
    )
    assert made.exit_code == 0, made.output
    done = runner.invoke(
        app,
        ["process", str(log), "--nominal", "ur5", "--no-rrd", "--out", str(tmp_path)],
        env={"COLUMNS": "200"},
    )
    assert done.exit_code == 0, done.output
    found = dhlog.load(tmp_path / "u5.dh.json", nominal="ur5")
    assert "beta" in found.changes()["parameter"].to_list()
    _check_against_console(found, done.output)


def test_changes_without_a_nominal_say_what_to_pass() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found = dhlog.load(ROOT / "sample_logs" / "kr5_0.01mm.truth.json")
    with pytest.raises(dhlog.UsageError, match="nominal="):
        found.changes()


def test_fk_json_equals_calibration_fk(tmp_path: Path) -> None:
    found = dhlog.process(SAMPLE)
    result = tmp_path / "kr5.dh.json"
    found.save(result)
    q = np.array([0.3, -0.4, 0.5, 0.2, -0.7, 1.1])
    done = runner.invoke(app, ["fk", str(result), "--q", ",".join(map(str, q)), "--json"])
    assert done.exit_code == 0, done.output
    doc = json.loads(done.stdout)
    assert doc["schema"] == "dhlog.fk/1" and doc["units"] == {"length": "m", "angle": "rad"}
    assert np.allclose(doc["tool_point"], found.fk(q), atol=1e-12, rtol=0)
    assert np.allclose(doc["T_base_last"], found.fk_frames(q)[-1], atol=1e-12, rtol=0)
    assert np.asarray(doc["jacobian"]).shape == (6, 6)
    # degrees in, radians out
    deg = runner.invoke(
        app,
        ["fk", "kr5", "--q", ",".join(f"{v:.12f}" for v in np.degrees(q)), *DEGREES],
    )
    assert np.allclose(json.loads(deg.stdout)["q"], q, atol=1e-12)


def _result(tmp_path: Path, source: str | Path, name: str, seed: int) -> Path:
    log = tmp_path / f"{name}.mcap"
    made = runner.invoke(app, ["simulate", str(source), "-o", str(log), "--seed", str(seed)])
    assert made.exit_code == 0, made.output
    done = runner.invoke(app, ["process", str(log), "--no-rrd", "--out", str(tmp_path)])
    assert done.exit_code == 0, done.output
    return tmp_path / f"{name}.dh.json"


def test_compare_json_and_fail_beyond(tmp_path: Path) -> None:
    """Two sessions of a KR5, the second with a2 0.5 mm longer: --json names a_2 significant
    with its change and σ (SI); --fail-beyond 10 exits 5 naming it; the same session twice
    exits 0."""
    truth = json.loads((ROOT / "sample_logs" / "kr5_0.01mm.truth.json").read_text())
    robot = tmp_path / "robot.json"
    robot.write_text(json.dumps(truth))
    truth["standard_dh"][1]["a"] += 5e-4
    longer = tmp_path / "longer.json"
    longer.write_text(json.dumps(truth))
    a, b = _result(tmp_path, robot, "a", 1), _result(tmp_path, longer, "b", 2)
    done = runner.invoke(app, ["compare", str(a), str(b), "--json"])
    assert done.exit_code == 0, done.output
    doc = json.loads(done.stdout)
    assert doc["schema"] == "dhlog.compare/1"
    a2 = next(c for c in doc["changes"] if c["name"] == "a_2")
    assert a2["unit"] == "m" and a2["change"] == pytest.approx(5e-4, abs=3e-5)
    assert a2["significant"] and a2["significance"] == pytest.approx(a2["change"] / a2["sigma"])
    assert "a_2" in doc["significant"]
    assert doc["fk"]["rms"] > 1e-4 and len(doc["fk"]["max_at"]) == 6
    failed = runner.invoke(app, ["compare", str(a), str(b), "--fail-beyond", "10"])
    assert failed.exit_code == EXIT_CHANGED == 5
    assert "a_2" in failed.stderr and "exit 5" in failed.stderr
    same = runner.invoke(app, ["compare", str(a), str(a), "--fail-beyond", "3", "--json"])
    assert same.exit_code == 0 and json.loads(same.stdout)["significant"] == []
    bad = runner.invoke(app, ["compare", str(a), str(b), "--fail-beyond", "-1"])
    assert bad.exit_code == EXIT_USAGE and "positive" in bad.stderr


def test_si_columns_name_their_units() -> None:
    """parameters and holdout keep their names and carry the same values with the unit in the
    column's name (one unit per column)."""
    found = dhlog.process(SAMPLE, holdout=3)
    params = found.parameters
    metres = params.filter(unit="m")
    assert metres["value_m"].to_list() == metres["value"].to_list()
    assert metres["value_rad"].null_count() == metres.height
    radians = params.filter(unit="rad")
    assert radians["sigma_rad"].to_list() == radians["sigma"].to_list()
    held = found.holdout
    assert held.height and held["rms_m"].to_list() == held["rms"].to_list()
    assert 5e-6 < held.filter(model="calibrated")["rms_m"][0] < 5e-5  # the sample's 10 µm noise
