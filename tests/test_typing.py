"""A user's script against the installed package (issue 33, items 1 and 5): the script of the docs
(docs/examples/user_script.py, nothing but ``import dhlog``) runs on the bundled sample — the
held-out table, a URDF, ten compensated targets — and type-checks under ``mypy --strict`` from the
user's side: dhlog found as an installed package, which mypy reads only with its ``py.typed``
marker (without it: ``import-untyped``). A wrong variant of the script must fail the check.

mypy runs with an empty configuration (not the project's) and the repository's own cache
(``.mypy_cache`` beside pyproject.toml, which CI's ``mypy`` step warms): about 1 s warm, 10-15 s
cold on this 2-core machine."""

import os
import re
import runpy
import subprocess
import sys
import warnings
from pathlib import Path
from xml.etree import ElementTree

import pytest

import dhlog

ROOT = Path(__file__).parents[1]
SCRIPT = ROOT / "docs" / "examples" / "user_script.py"


def mypy_strict(script: Path, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    """``mypy --strict script`` as a user runs it: an empty configuration, dhlog from the
    interpreter's site-packages (an editable install's .pth as well as a wheel's files)."""
    pytest.importorskip("mypy")
    config = tmp_path / "mypy.ini"
    config.write_text("[mypy]\n")
    env = {k: v for k, v in os.environ.items() if k not in ("MYPYPATH", "PYTHONPATH")}
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "mypy",
            "--config-file",
            str(config),
            "--strict",
            "--cache-dir",
            str(ROOT / ".mypy_cache"),
            "--no-error-summary",
            "--hide-error-context",
            str(script),
        ],
        cwd=tmp_path,  # no dhlog beside it: found as installed, or not at all
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_the_users_script_type_checks_strictly_against_the_installed_package(
    tmp_path: Path,
) -> None:
    assert (Path(dhlog.__file__).parent / "py.typed").is_file()
    run = mypy_strict(SCRIPT, tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr


def test_a_wrong_script_fails_the_type_check(tmp_path: Path) -> None:
    """The check can fail: a fold count given as text and an export format dhlog does not write
    are each an error at their line (a package mypy could not read would pass both as Any)."""
    text = SCRIPT.read_text()
    wrong = text.replace("holdout=5", 'holdout="5"').replace('export("urdf"', 'export("pdf"')
    assert wrong.count('"5"') == 1 and wrong.count('"pdf"') == 1
    script = tmp_path / "wrong_script.py"
    script.write_text(wrong)
    run = mypy_strict(script, tmp_path)
    errors = re.findall(r"^.*wrong_script\.py:(\d+): error: (.*)$", run.stdout, flags=re.MULTILINE)
    lines = wrong.splitlines()
    assert run.returncode == 1, run.stdout + run.stderr
    assert len(errors) == 2, run.stdout
    (l1, e1), (l2, e2) = errors
    assert 'holdout="5"' in lines[int(l1) - 1] and '"holdout" to "process"' in e1, errors
    assert 'export("pdf"' in lines[int(l2) - 1] and '"export" of "Calibration"' in e2, errors


def test_the_users_script_runs_on_the_bundled_sample(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The script as the docs show it, from the repository's root: 5-fold held-out rows for the
    nominal and the calibrated model, a URDF of the six joints, ten targets compensated; the
    result's dhlog_version is the package's; no DeprecationWarning of dhlog's on the way."""
    monkeypatch.chdir(ROOT)
    monkeypatch.setattr(sys, "argv", [str(SCRIPT), str(tmp_path / "out")])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        names = runpy.run_path(str(SCRIPT), run_name="__main__")
    said = capsys.readouterr().out
    ours = [
        w
        for w in caught
        if issubclass(w.category, DeprecationWarning)
        and (str(w.message).startswith("dhlog.") or "/dhlog/" in w.filename)
    ]
    assert not ours, [str(w.message) for w in ours]

    calibration = names["calibration"]
    assert isinstance(calibration, dhlog.Calibration)
    assert calibration.version == dhlog.__version__  # the result's dhlog_version
    table = calibration.holdout
    assert table["model"].to_list() == ["nominal", "calibrated"]
    assert set(table["check"]) == {"5-fold"}
    # the sample's tracker noise is 10 um (its name): the held-out RMS is that noise, not 10x it
    assert 5e-6 < table["rms"][1] < 30e-6
    rows = [line for line in said.splitlines() if line.startswith("5-fold")]
    assert len(rows) == 2 and rows[1].split()[1] == "calibrated"
    assert f"{1e3 * table['rms'][1]:8.4f}" in rows[1]

    urdf = ElementTree.parse(tmp_path / "out" / "kr5_calibrated.urdf").getroot()
    revolute = [j for j in urdf.iter("joint") if j.get("type") == "revolute"]
    assert len(revolute) == 6

    compensated = names["compensated"]
    assert compensated.targets.shape == (10, 6)
    assert "10 of 10 targets compensated" in said
