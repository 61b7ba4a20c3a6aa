"""``dhlog batch`` and the trend of ``dhlog compare SUMMARY``: three sessions of one KR5 (off
its nominal; the third after a 0.5 mm change of a_2), a damaged log among them, processed by a
pool of two workers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app

SAMPLES = Path(__file__).parents[1] / "sample_logs"
runner = CliRunner()


@pytest.fixture(scope="module")
def batch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("batch")
    truth = json.loads((SAMPLES / "kr5_0.01mm.truth.json").read_text())
    robot = folder / "kr5_cell.json"
    robot.write_text(json.dumps(truth))
    changed = json.loads(json.dumps(truth))
    changed["standard_dh"][1]["a"] += 0.5e-3
    moved = folder / "kr5_cell_after.json"
    moved.write_text(json.dumps(changed))
    logs = []
    for k, dh in enumerate((robot, robot, moved)):
        log = folder / f"session_{k + 1}.mcap"
        made = runner.invoke(
            app,
            [
                "simulate",
                str(dh),
                "-o",
                str(log),
                "--noise-mm",
                "0.01",
                "--seed",
                str(k),
                "--start-day",
                str(30 * k),
            ],  # a session a month
        )
        assert made.exit_code == 0, made.output
        logs.append(log)
    broken = folder / "session_0.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 40)  # the magic, then nothing usable
    out = folder / "out"
    done = runner.invoke(
        app, ["batch", *map(str, [broken, *logs]), "--out", str(out), "--jobs", "2", "--no-rrd"]
    )
    assert done.exit_code == 3, done.output  # one log failed: the others are done
    assert "4 log(s)" in done.output and "3 ok, 0 partial, 1 failed" in done.output
    return out


def test_the_summary_has_a_row_per_log_in_order_with_every_parameter(batch: Path) -> None:
    csv = pl.read_csv(batch / "summary.csv")
    parquet = pl.read_parquet(batch / "summary.parquet")
    assert csv.height == parquet.height == 4
    assert parquet["log"].str.contains("session_0").to_list() == [True, False, False, False]
    assert parquet["status"].to_list() == ["failed", "ok", "ok", "ok"]
    assert "session_0.mcap" in parquet["reason"][0]
    for column in ("session_start", "fk_rms_m", "clock_offset_s", "a_2", "std_a_2", "tool_z"):
        assert column in parquet.columns
    for column in ("fk_max_m", "std_clock_offset_s"):
        assert column in parquet.columns
    assert not {"fk_rms", "fk_max", "clock_offset", "std_clock_offset"} & set(parquet.columns)
    ok = parquet.filter(pl.col("status") == "ok")
    assert (ok["fk_rms_m"] < 5e-5).all() and (ok["fk_rms_m"] > 1e-6).all()  # metres
    assert (ok["clock_offset_s"].abs() < 1e-3).all()  # seconds
    for k in range(1, 4):
        assert (batch / f"session_{k}.dh.json").exists()
    assert not (batch / "session_0.dh.json").exists()


def test_the_trend_finds_the_changed_parameter(batch: Path, tmp_path: Path) -> None:
    """a_2 moved by 0.5 mm in the last session: flagged beyond 3σ with the change measured
    within 4σ of 0.5 mm; the recording is a real .rrd."""
    rrd = tmp_path / "trend.rrd"
    done = runner.invoke(app, ["compare", str(batch / "summary.parquet"), "--rrd", str(rrd)])
    assert done.exit_code == 0, done.output
    assert "moved beyond 3σ" in done.output and "a_2" in done.output.split("moved beyond")[1]
    from dhlog.fleet.compare import read_summary, trends

    _, _, found = trends(read_summary(batch / "summary.parquet"))
    a2 = next(t for t in found if t.name == "a_2")
    sigma = float(np.hypot(a2.sigmas[0], a2.sigmas[-1]))
    assert abs(a2.change - 0.5e-3) < 4 * sigma
    assert rrd.stat().st_size > 0


def test_a_summary_written_before_the_units_were_named_still_compares(
    batch: Path, tmp_path: Path
) -> None:
    """Summaries from before ``fk_rms`` became ``fk_rms_m`` (and the other renamed columns)
    read as before: the trends need only the log, its start, status, robot and parameters."""
    frame = pl.read_parquet(batch / "summary.parquet")
    old = frame.rename(
        {
            c: c.removesuffix("_m").removesuffix("_s")
            for c in frame.columns
            if c.startswith(("fk_", "clock_offset", "std_clock_offset"))
        }
    )
    assert "fk_rms" in old.columns and "clock_offset" in old.columns
    old.write_parquet(tmp_path / "old.parquet")
    done = runner.invoke(app, ["compare", str(tmp_path / "old.parquet")])
    assert done.exit_code == 0, done.output
    assert "moved beyond 3σ" in done.output and "a_2" in done.output.split("moved beyond")[1]


def test_holdout_columns_carry_their_unit(tmp_path: Path) -> None:
    from dhlog.fleet.batch import summary_row

    doc = {
        "joints": [{"name": "j1"}],
        "validation": {
            "fk_rms": 1e-5,
            "fk_max": 2e-5,
            "holdout": [
                {
                    "kind": "cross-validation",
                    "nominal": {"mean": 1e-3, "rms": 1.1e-3, "p95": 1.7e-3, "max": 2e-3},
                    "calibrated": {"mean": 5e-5, "rms": 6e-5, "p95": 9e-5, "max": 1e-4},
                }
            ],
        },
        "timing": {"clock_offset": 2e-4, "std": 1e-5},
    }
    row = summary_row(tmp_path / "a.mcap", doc, "ok", "", 1.0, None, None)
    assert row["fk_rms_m"] == 1e-5 and row["fk_max_m"] == 2e-5
    assert row["clock_offset_s"] == 2e-4 and row["std_clock_offset_s"] == 1e-5
    assert row["holdout_nominal_rms_m"] == 1.1e-3 and row["holdout_calibrated_max_m"] == 1e-4
    assert not [k for k in row if k.startswith(("fk_", "holdout_")) and not k.endswith("_m")]


def test_a_summary_of_different_robots_has_no_trend(tmp_path: Path) -> None:
    frame = pl.DataFrame(
        {
            "log": ["a", "b"],
            "session_start": ["2026-01-01T00:00:00+00:00", "2026-01-02T00:00:00+00:00"],
            "robot": ["6-joint", "4-joint"],
            "joints": ["j1,j2,j3,j4,j5,j6", "j1,j2,j3,j4"],
            "status": ["ok", "ok"],
            "a_1": [0.1, 0.2],
        }
    )
    frame.write_csv(tmp_path / "s.csv")
    done = runner.invoke(app, ["compare", str(tmp_path / "s.csv")])
    assert done.exit_code == 2 and "different robots" in done.output


def test_a_ctrl_c_another_thread_takes_while_workers_start_waits_for_the_block() -> None:
    """While the pool starts its workers (SIGINT held in the main thread), a Ctrl-C the kernel
    gives another thread is noted, not raised in the middle of a worker's start (which left the
    worker an empty pipe and a traceback): it is raised as KeyboardInterrupt when the block
    ends, and the handler before it is back."""
    import signal
    import threading

    from dhlog.fleet.executors import sigint_held

    outer = signal.signal(signal.SIGINT, signal.default_int_handler)  # as dhlog runs
    before = signal.getsignal(signal.SIGINT)
    go = threading.Event()

    def ctrl_c() -> None:  # a thread begun before the block (as the progress bar's is)
        go.wait(10.0)
        signal.raise_signal(signal.SIGINT)  # taken by this thread, which does not hold it

    other = threading.Thread(target=ctrl_c)
    other.start()
    steps = []
    with pytest.raises(KeyboardInterrupt):
        with sigint_held():
            go.set()
            other.join()
            for k in range(50):  # Python steps in which a handler would have run
                steps.append(k)
    after = signal.signal(signal.SIGINT, outer)
    assert steps == list(range(50))
    assert after is before


def test_a_ctrl_c_noted_while_workers_start_is_not_lost_to_a_failure() -> None:
    """A Ctrl-C noted in the block is raised even when the block fails (chained to the failure),
    the mask and the handler restored."""
    import signal
    import threading

    from dhlog.fleet.executors import sigint_held

    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    go = threading.Event()

    def ctrl_c() -> None:  # begun before the block: it does not hold SIGINT
        go.wait(10.0)
        signal.raise_signal(signal.SIGINT)

    taken = threading.Thread(target=ctrl_c)
    taken.start()
    with pytest.raises(KeyboardInterrupt) as caught:
        with sigint_held():
            go.set()
            taken.join()
            raise ValueError("a worker could not start")
    after = signal.signal(signal.SIGINT, outer)
    assert isinstance(caught.value.__cause__, ValueError)
    assert after is signal.default_int_handler
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])


def test_an_interrupted_pool_leaves_nothing_for_the_exit_hook_to_race() -> None:
    """When an interrupt has stopped the workers, the pool's manager thread has ended and its
    wake-up pipe is closed: Python 3.11's exit hook of ``concurrent.futures`` writes to that
    pipe without the lock its closing takes, and an exit while the thread was still closing it
    printed ``OSError: [Errno 9] Bad file descriptor`` and a traceback after ``dhlog batch``'s
    line (``test_ctrl_c_while_the_workers_start_stops_them_without_a_traceback``, 2 in 20 runs
    on a loaded machine)."""
    import _thread
    import signal
    import threading
    import time
    from concurrent.futures import process

    from dhlog.fleet.executors import run_in_processes

    def lost(item: float, why: str) -> dict[str, object]:
        return {"item": item, "why": why}

    # as dhlog runs (a batch run in this process before leaves SIGINT ignored: its summary's
    # writing holds signals)
    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        for delay in (0.1, 0.3, 0.6, 1.0):  # in the workers' start and after (a race: 4 tries)
            ctrl_c = threading.Timer(delay, _thread.interrupt_main)  # a Ctrl-C, in the main thread
            ctrl_c.start()
            start = time.monotonic()
            with pytest.raises(KeyboardInterrupt):
                run_in_processes(time.sleep, [20.0] * 3, 2, lost=lost)  # type: ignore[arg-type]
            ctrl_c.join()
            assert time.monotonic() - start < 10.0  # the workers were stopped, not waited for
            managers = process._ExecutorManagerThread
            assert [t for t in threading.enumerate() if isinstance(t, managers)] == [], delay
            assert all(w._closed for w in process._threads_wakeups.values()), delay
    finally:
        signal.signal(signal.SIGINT, outer)
