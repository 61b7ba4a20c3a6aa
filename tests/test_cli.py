"""The command line, through typer's CliRunner."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from dhlog import __version__
from dhlog.cli.app import app

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


DHLOG = str(Path(sys.executable).with_name("dhlog"))


def _dhlog(*args: str, **kw: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([DHLOG, *args], capture_output=True, text=True, **kw)  # type: ignore[call-overload,no-any-return]


def test_no_arguments_print_the_help_and_succeed() -> None:
    result = _dhlog()
    assert result.returncode == 0 and "Usage" in result.stdout and not result.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--noise-mm", "-1"], "noise must be ≥ 0"),
        (["--outliers", "2"], "outlier fraction"),
        (["--tracker-rate", "0"], "tracker rate"),
        (["--skip-joints", "9"], "kr5 has joints 1-6"),
        (["--sweep-deg", "400"], "sweep must be in (0, 360]"),
        (["--encoding", "xml"], "--encoding must be one of"),
    ],
)
def test_simulate_arguments_are_checked_with_one_line_and_exit_1(
    args: list[str], message: str, tmp_path: Path
) -> None:
    result = _dhlog("simulate", "kr5", "-o", str(tmp_path / "x.mcap"), *args)
    assert result.returncode == 1, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.stderr
    assert not list(tmp_path.iterdir())


def test_a_clipped_travel_is_said_and_recorded_in_the_truth(tmp_path: Path) -> None:
    result = _dhlog("simulate", "scara", "-o", str(tmp_path / "x.mcap"), "--travel-mm", "100")
    assert result.returncode == 0 and "travel 50.0 mm (asked 100 mm)" in result.stdout
    truth = json.loads((tmp_path / "x.truth.json").read_text())
    assert truth["simulation"]["joint_sweeps"][3] == pytest.approx(0.05)


def test_outputs_go_only_to_folders_that_exist_and_can_be_written(tmp_path: Path) -> None:
    missing = _dhlog("simulate", "kr5", "-o", str(tmp_path / "no" / "such" / "x.mcap"))
    assert missing.returncode == 1 and "does not exist" in missing.stderr
    assert not (tmp_path / "no").exists()
    log = tmp_path / "run.mcap"
    assert _dhlog("simulate", "scara", "-o", str(log), "--sweep-deg", "30").returncode == 0
    a_file = tmp_path / "a_file"
    a_file.write_text("not a folder")
    blocked = _dhlog("process", str(log), "--out", str(a_file / "sub"), "--no-rrd")
    assert blocked.returncode == 2 and f"{a_file} is a file, not a folder" in blocked.stderr
    assert len([line for line in blocked.stderr.splitlines() if line.strip()]) == 1
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    if os.access(locked, os.W_OK):  # root ignores permissions: nothing to check here
        return
    result = _dhlog("process", str(log), "--out", str(locked), "--no-rrd")
    assert result.returncode == 2 and "cannot write the results" in result.stderr


def test_outputs_follow_the_umask(tmp_path: Path) -> None:
    log = tmp_path / "run.mcap"
    assert _dhlog("simulate", "scara", "-o", str(log), "--sweep-deg", "30").returncode == 0
    out = tmp_path / "out"
    result = subprocess.run(
        ["sh", "-c", f"umask 027 && exec {DHLOG} process {log} --out {out}"],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    modes = {p.name: p.stat().st_mode & 0o777 for p in out.iterdir()}
    assert set(modes.values()) == {0o640}, modes


@pytest.mark.parametrize(("signum", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_at_any_point_leaves_no_partial_output(
    signum: int, code: int, tmp_path: Path
) -> None:
    """SIGINT / SIGTERM sent at several moments of a run (start-up, reading, fitting,
    writing): exit 130 / 143 with one line and no output file at all (no temporary files
    either), or a finished run with every output; the log untouched."""
    log = tmp_path / "run.mcap"
    made = _dhlog("simulate", "kr5", "-o", str(log), "--tracker-rate", "400", "--seed", "2")
    assert made.returncode == 0
    before = log.read_bytes()
    interrupted = 0
    for k, delay in enumerate((0.05, 0.4, 0.8, 1.2, 1.8, 2.5)):
        out = tmp_path / f"out{k}"
        proc = subprocess.Popen(
            [DHLOG, "process", str(log), "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        time.sleep(delay)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=120)
        written = sorted(p.name for p in out.iterdir()) if out.exists() else []
        if proc.returncode == 0:
            assert written == ["run.dh.csv", "run.dh.json", "run.rrd", "run.terms.csv"], written
        else:
            interrupted += 1
            # before Python runs any code (its own start-up) the signal ends it the default way:
            # status -n here, 128 + n in a shell, with nothing written and nothing said
            assert proc.returncode in (code, -signum), err
            lines = [line for line in err.splitlines() if line.strip()]
            assert len(lines) <= 1 and "Traceback" not in err, err
            assert len(lines) == 1 or proc.returncode == -signum or delay < 0.3, err
            assert written == [], written
        assert log.read_bytes() == before
    assert interrupted >= 1


def test_a_shipped_pipeline_by_name_and_the_list_of_them(tmp_path: Path) -> None:
    """``--pipeline ros2_tracker`` (the name dhlog prints) works; ``dhlog pipelines`` lists
    every shipped one; the viewer hint is a command that exists here."""
    listed = _dhlog("pipelines")
    assert listed.returncode == 0
    for name in ("ros2_tracker", "foxglove_json", "foxglove_protobuf", "phase_markers"):
        assert name in listed.stdout
    log = Path(__file__).parents[1] / "sample_logs" / "kr5_0.01mm.mcap"
    result = _dhlog("process", str(log), "--pipeline", "ros2_tracker", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    hint = next(line for line in result.stdout.splitlines() if "open the recording" in line)
    viewer = hint.split(": ", 1)[1].rsplit(" ", 1)[0]
    assert viewer == "rerun" or Path(viewer.split()[0]).exists()
