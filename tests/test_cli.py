"""The command line, through typer's CliRunner."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from dhlog import __version__
from dhlog.cli import app

runner = CliRunner()


def test_version_and_help() -> None:
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and __version__ in result.stdout
    assert runner.invoke(app, ["simulate", "--help"]).exit_code == 0


def test_simulate_writes_the_log_and_its_truth(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    result = runner.invoke(
        app,
        [
            "simulate",
            "scara",
            "-o",
            str(out),
            "--sweep-deg",
            "30",
            "--encoding",
            "json",
            "--seed",
            "3",
        ],
    )
    assert result.exit_code == 0, result.output
    truth = json.loads((tmp_path / "run.truth.json").read_text())
    assert truth["source"]["pipeline"] == "foxglove_json"
    assert [row["a"] for row in truth["standard_dh"]] == [0.05, 0.10, 0.0, 0.0]
    again = runner.invoke(app, ["simulate", "scara", "-o", str(out)])
    assert again.exit_code == 1 and "--force" in again.output  # outputs are kept


def test_simulate_from_a_dh_file(tmp_path: Path) -> None:
    dh = tmp_path / "arm.json"
    dh.write_text(
        json.dumps(
            {
                "standard_dh": [
                    {"type": "revolute", "theta_offset": 0, "d": 0.3, "a": 0.2, "alpha": 1.5707963},
                    {"type": "revolute", "theta_offset": 0, "d": 0, "a": 0.25, "alpha": 0},
                ]
            }
        )
    )
    out = tmp_path / "arm.mcap"
    result = runner.invoke(app, ["simulate", str(dh), "-o", str(out), "--seed", "1"])
    assert result.exit_code == 0, result.output
    assert out.exists()


def test_bad_input_gives_one_line_and_exit_2(tmp_path: Path) -> None:
    result = runner.invoke(app, ["simulate", "r2d2", "-o", str(tmp_path / "x.mcap")])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert "Unknown robot 'r2d2'" in result.output and "Traceback" not in result.output
    assert len(lines) <= 2  # one message (wrapped at most once by the console)
    bad = runner.invoke(
        app, ["simulate", "kr5", "-o", str(tmp_path / "y.mcap"), "--encoding", "ros1"]
    )
    assert bad.exit_code == 1 and "--encoding must be one of" in bad.output
