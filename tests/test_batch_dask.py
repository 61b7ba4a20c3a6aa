"""``dhlog batch --executor dask``: the logs of ``test_batch`` (three KR5 sessions and a damaged
log) on a real Dask cluster of two worker processes, reached by ``--scheduler``, and on one the
command starts itself, against the process pool's summary; a scheduler that is not there; Dask
missing; a stopped batch; and the thread stop (``dhlog.io.writer.stop_thread``) it rests on."""

from __future__ import annotations

import socket
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from dhlog.cli.app import app
from test_batch import batch, runner

__all__ = ["batch"]  # the fixture: the logs, processed by a pool of two workers

LOGS = [f"session_{k}.mcap" for k in range(4)]  # the damaged one first, as test_batch gives them


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """The address of a real cluster: two worker processes of one thread each."""
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},  # not 8787: others may use it
    ) as cluster:
        yield cluster.scheduler_address


def _logs(batch: Path) -> list[str]:
    return [str(batch.parent / name) for name in LOGS]


def _same_summary(folder: Path, pool: Path) -> None:
    """The same rows, in the same order, with the same statuses, reasons and values (to 1e-12;
    the seconds each log took aside), in the CSV and the Parquet."""
    expected = pl.read_parquet(pool / "summary.parquet").drop("seconds")
    got = pl.read_parquet(folder / "summary.parquet").drop("seconds")
    assert got.columns == expected.columns
    assert got.schema == expected.schema
    text = [c for c, t in expected.schema.items() if t == pl.String]
    assert got.select(text).equals(expected.select(text))
    assert got["status"].to_list() == ["failed", "ok", "ok", "ok"]
    assert "session_0.mcap" in got["reason"][0]
    for column in (c for c in expected.columns if c not in text):
        a, b = got[column].to_numpy(), expected[column].to_numpy()
        assert np.allclose(a, b, rtol=0.0, atol=1e-12, equal_nan=True), column
    csv = pl.read_csv(folder / "summary.csv")
    assert csv.height == 4 and csv["log"].to_list() == got["log"].to_list()
    for k in range(1, 4):
        assert (folder / f"session_{k}.dh.json").exists()
    assert not (folder / "session_0.dh.json").exists()


def test_a_batch_on_a_dask_cluster_gives_the_process_pools_summary(
    batch: Path, scheduler: str, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    args = ["batch", *_logs(batch), "--out", str(out), "--no-rrd", "--executor", "dask"]
    done = runner.invoke(app, [*args, "--scheduler", scheduler])
    assert done.exit_code == 3, done.output  # one log failed: the others are done
    said = " ".join(done.stdout.split())
    assert "4 log(s) in" in said and f"on the Dask cluster at {scheduler}: 3 ok," in said
    assert "3 ok, 0 partial, 1 failed" in said
    assert "session_0.mcap: failed: " in done.stderr and "Traceback" not in done.output
    _same_summary(out, batch)


def test_a_dask_cluster_of_its_own_without_a_scheduler(batch: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["batch", *_logs(batch), "--out", str(out), "--no-rrd", "--executor", "dask", "-j", "2"]
    done = runner.invoke(app, args)
    assert done.exit_code == 3, done.output
    said = " ".join(done.stdout.split())
    assert "on a Dask cluster of 2 worker(s): 3 ok, 0 partial, 1 failed" in said
    _same_summary(out, batch)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
    return port  # closed again: nothing answers there


def test_an_unreachable_scheduler_is_one_line_and_exit_2(
    batch: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from dhlog.fleet import executors

    monkeypatch.setattr(executors, "CONNECT_TIMEOUT", 1.0)
    address = f"tcp://127.0.0.1:{_free_port()}"
    out = tmp_path / "out"
    start = time.monotonic()
    args = ["batch", *_logs(batch), "--out", str(out), "--executor", "dask"]
    done = runner.invoke(app, [*args, "--scheduler", address])
    assert time.monotonic() - start < 5.0
    assert done.exit_code == 2, done.output
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and not done.stdout.strip(), done.output
    assert f"cannot reach a Dask scheduler at {address} (no answer within 1 s)" in lines[0]
    assert "--scheduler" in lines[0] and "Nothing was written" in lines[0]
    assert not out.exists() or not list(out.iterdir())
    done = runner.invoke(app, [*args, "--scheduler", "not an address"])
    assert done.exit_code == 2 and "missing port number" in done.stderr, done.output


def test_without_dask_the_line_says_what_to_install(
    batch: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed: ImportError
    out = tmp_path / "out"
    done = runner.invoke(app, ["batch", *_logs(batch), "--out", str(out), "--executor", "dask"])
    assert done.exit_code == 2, done.output
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "pip install 'dhlog[dask]'" in lines[0], done.output
    assert not out.exists() or not list(out.iterdir())


def test_a_stopped_batch_stops_its_running_tasks(
    batch: Path, scheduler: str, tmp_path: Path
) -> None:
    """An interrupt as the first row comes in: the running tasks (20-fold cross-validations,
    8 s each) end at once, leave nothing behind, and the workers are free for the next batch."""
    from distributed import Client

    from dhlog.fleet.batch import BatchJob, run_batch

    out = tmp_path / "out"
    out.mkdir()
    jobs = [BatchJob(log, str(out), no_rrd=True, holdout=20) for log in _logs(batch)[:3]]

    def interrupt(row: dict[str, object]) -> None:
        time.sleep(1.0)  # both workers are well into a slow log
        raise KeyboardInterrupt

    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        run_batch(jobs, 2, interrupt, executor="dask", scheduler=scheduler)
    assert time.monotonic() - start < 4.0
    with Client(scheduler, set_as_default=False) as client:
        free = time.monotonic()
        assert client.gather(client.map(abs, [-1, -2], pure=False)) == [1, 2]
        assert time.monotonic() - free < 3.0  # both threads free: no task ran on
        assert not any(client.processing().values())
    # no temporary file; each log's results complete or absent (on a quiet machine a slow log
    # can finish within the second before the interrupt: its results then stand, whole)
    from dhlog.fleet.batch import job_outputs

    left = set(out.iterdir())
    for job in jobs:
        outputs = set(job_outputs(job))
        assert outputs <= left or not outputs & left, (job.log, sorted(left))
        left -= outputs
    assert not left, sorted(left)


# ------------------------------------------------------- the thread stop the Dask path rests on


class _Stop(BaseException):
    pass


def test_a_thread_stop_waits_for_the_moves_of_staged_outputs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A stop asked while a thread moves a set of results into place is raised after the last
    move: the set is complete, never half moved."""
    from dhlog.io import writer

    moving, asked = threading.Event(), threading.Event()
    publish = writer.publish

    def slow_publish(tmp: str | Path, target: str | Path) -> None:
        moving.set()
        asked.wait(5.0)
        publish(tmp, target)

    monkeypatch.setattr(writer, "publish", slow_publish)
    targets = [tmp_path / "a.json", tmp_path / "a.csv"]
    seen: list[BaseException] = []

    def job() -> None:
        try:
            with writer.staged_outputs(targets) as temps:
                for temp in temps:
                    temp.write_text("done")
        except _Stop as exc:
            seen.append(exc)

    thread = threading.Thread(target=job)
    thread.start()
    assert moving.wait(5.0)
    assert thread.ident is not None
    writer.stop_thread(thread.ident, _Stop)
    asked.set()
    thread.join(5.0)
    assert len(seen) == 1 and all(t.read_text() == "done" for t in targets)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "a.json"]


def test_a_thread_stop_outside_such_a_block_is_raised_at_once(tmp_path: Path) -> None:
    """Raised where the thread is: its staged files are removed on the way out."""
    from dhlog.io import writer

    writing = threading.Event()
    seen: list[BaseException] = []

    def job() -> None:
        try:
            with writer.staged_outputs([tmp_path / "a.json"]):
                writing.set()
                while True:
                    time.sleep(0.01)
        except _Stop as exc:
            seen.append(exc)

    thread = threading.Thread(target=job)
    thread.start()
    assert writing.wait(5.0) and thread.ident is not None
    writer.stop_thread(thread.ident, _Stop)
    thread.join(5.0)
    assert not thread.is_alive() and len(seen) == 1
    assert list(tmp_path.iterdir()) == []
