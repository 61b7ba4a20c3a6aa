"""``dhlog batch``: many logs, each processed as ``dhlog process`` would, in a process pool.

Each log is one job in a worker process: its results (``<stem>.dh.json``, ``.dh.csv``, and the
recording unless ``no_rrd``) are written into the output folder as ``dhlog process --out`` writes
them, and the job returns one summary row. A log that fails is a row with status ``failed`` and
its one-line reason; nothing stops the batch. The summary (one row per log: its time, robot,
every parameter with σ, FK residual, clock offset, status) is written as CSV and Parquet through
polars, atomically, in the order the logs were given. Lengths in the summary are metres and
times seconds, as its column names say (``fk_rms_m``, ``clock_offset_s``; the parameters, as in
the result JSON, are metres and radians).

An interrupt (SIGINT, or the command line's SIGTERM) stops the workers at once: they never see
the terminal's Ctrl-C themselves (SIGINT is held while they are started, so they begin with it
held, and they ignore it), and are sent SIGTERM, on which a worker removes its temporary files
and exits (killed when it has not within ``STOP_GRACE`` seconds, its temporary files removed for
it). :func:`written_logs` then says which logs' results are in place.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import polars as pl

from dhlog.errors import DhlogError, InputError

SUMMARY_STEM = "summary"


@dataclass(frozen=True)
class BatchJob:
    """One log and how to process it (the options of ``dhlog process`` a batch takes)."""

    log: str
    folder: str
    pipeline: str | None = None
    nominal: str | None = None
    no_rrd: bool = False
    analytic_only: bool = False
    units: str = "mm"
    #: K-fold cross-validation of each log (0: none), as ``dhlog process --holdout``
    holdout: int = 0
    #: the terms beyond the geometry, as ``dhlog process --model``
    model: str = "auto"


def stem_of(log: Path) -> str:
    """The results' name of a log (``run.mcap`` → ``run``; a bag folder by its name)."""
    return log.name.removesuffix(".zstd").removesuffix(".mcap")


def job_outputs(job: BatchJob) -> list[Path]:
    """The files a job writes: ``<stem>.dh.json``, ``.dh.csv``, the recording unless
    ``no_rrd``, the held-out poses' CSV with ``holdout``, the terms' CSV unless the model is
    geometric (or the result analytic)."""
    stem = stem_of(Path(job.log))
    folder = Path(job.folder)
    outputs = [folder / f"{stem}.dh.json", folder / f"{stem}.dh.csv"]
    if not job.no_rrd:
        outputs.append(folder / f"{stem}.rrd")
    if job.holdout:
        outputs.append(folder / f"{stem}{HOLDOUT_SUFFIX}")
    if job.model != "geometric" and not job.analytic_only:
        outputs.append(folder / f"{stem}{TERMS_SUFFIX}")
    return outputs


def process_job(job: BatchJob, *, hold_signals: bool = False) -> dict[str, Any]:
    """Process one log into ``job.folder`` and return its summary row (never raises for the
    log's own faults: they are its status and reason). ``hold_signals``: SIGINT and SIGTERM
    cannot cut the moving of the results into place in half (the handlers are restored after)."""
    import numpy as np

    np.seterr(all="ignore")
    start = time.perf_counter()
    log = Path(job.log)
    folder = Path(job.folder)
    outputs = job_outputs(job)
    try:
        from dhlog.identify.run import process_log
        from dhlog.identify.select import ModelRequest
        from dhlog.io.dhfile import dh_model_from
        from dhlog.io.pipeline import pipeline_from

        pipe = pipeline_from(job.pipeline) if job.pipeline is not None else None
        nom = dh_model_from(job.nominal) if job.nominal is not None else None
        result = process_log(
            log,
            pipeline=pipe,
            nominal=nom,
            analytic_only=job.analytic_only,
            holdout=job.holdout,
            model=ModelRequest(job.model),
        )
        with _handlers_restored() if hold_signals else nullcontext():
            document = write_results(result, outputs, job.units, hold_signals=hold_signals)
        t0 = result.log.points["t_ns"].min() if result.log.points.height else None
        status = "ok" if result.complete else "partial"
        reason = "; ".join(f"joint {j.index} ({j.name}): {j.reason}" for j in result.failed)
        return summary_row(
            log, document, status, reason, time.perf_counter() - start, t0, job.nominal
        )
    except DhlogError as exc:
        return _failed(log, str(exc), time.perf_counter() - start)
    except OSError as exc:
        return _failed(log, f"cannot write the results into {folder} ({exc.strerror}).", 0.0)
    except Exception as exc:  # a fault of dhlog itself: recorded, the batch goes on
        return _failed(log, f"internal error {type(exc).__name__}: {exc}", 0.0)


#: The file name ending of the held-out poses' CSV (``--holdout``, ``--validate``).
HOLDOUT_SUFFIX = ".holdout.csv"
#: The file name ending of the terms beyond the geometry (``--model``).
TERMS_SUFFIX = ".terms.csv"


def write_results(
    result: Any,
    outputs: list[Path],
    units: str,
    *,
    hold_signals: bool = False,
    with_log: bool = False,
) -> dict[str, Any]:
    """Write a result's JSON, CSV and the further outputs named (a recording, the held-out
    poses' CSV for a name ending in ``HOLDOUT_SUFFIX``, the terms' for ``TERMS_SUFFIX``), moved
    into place together; returns the JSON document. ``with_log``: the log's own channels in the
    recording."""
    from dhlog.io.writer import staged_outputs
    from dhlog.result.document import holdout_csv, result_csv, result_document, terms_csv

    document = result_document(result)
    with staged_outputs(outputs, hold_signals=hold_signals) as temps:
        temps[0].write_bytes((json.dumps(document, indent=2) + "\n").encode())
        temps[1].write_bytes(result_csv(result, units=units).encode())
        for path, temp in zip(outputs[2:], temps[2:], strict=True):
            if path.name.endswith(HOLDOUT_SUFFIX):
                temp.write_bytes(holdout_csv(result, units=units).encode())
            elif path.name.endswith(TERMS_SUFFIX):
                temp.write_bytes(terms_csv(result).encode())
            else:
                from dhlog.present.recording import write_process_recording

                write_process_recording(result, temp, with_log=with_log)
    return document


def _failed(log: Path, reason: str, seconds: float) -> dict[str, Any]:
    return {
        "log": str(log),
        "session_start": None,
        "seconds": round(seconds, 3),
        "robot": None,
        "joints": None,
        "status": "failed",
        "reason": " ".join(reason.split()),
    }


def summary_row(
    log: Path,
    doc: dict[str, Any],
    status: str,
    reason: str,
    seconds: float,
    t0_ns: Any,
    nominal: str | None,
) -> dict[str, Any]:
    """One summary row of a processed log from its result document."""
    from dhlog.fleet.compare import parameters

    names = [j["name"] for j in doc.get("joints", [])]
    start = (
        datetime.fromtimestamp(int(t0_ns) / 1e9, tz=UTC).isoformat(timespec="milliseconds")
        if t0_ns is not None
        else None
    )
    val = doc.get("validation") or {}
    timing = doc.get("timing") or {}
    row: dict[str, Any] = {
        "log": str(log),
        "session_start": start,
        "seconds": round(seconds, 3),
        "robot": nominal or f"{len(names)}-joint",
        "joints": ",".join(names),
        "status": status,
        "reason": reason or None,
        "fk_rms_m": val.get("fk_rms"),
        "fk_max_m": val.get("fk_max"),
        "clock_offset_s": timing.get("clock_offset"),
        "std_clock_offset_s": timing.get("std"),
        "model": ((doc.get("nongeometric") or {}).get("selection") or {}).get("chosen"),
    }
    for check in val.get("holdout") or []:  # the first cross-validation's statistics
        if isinstance(check, dict) and check.get("kind") == "cross-validation":
            for model in ("nominal", "calibrated"):
                stats = check.get(model) or {}
                for key in ("mean", "rms", "p95", "max"):
                    row[f"holdout_{model}_{key}_m"] = stats.get(key)
            break
    if doc.get("standard_dh"):
        for name, value, sigma, _ in parameters(doc):
            row[name] = value
            row[f"std_{name}"] = sigma
    return row


def summary_frame(rows: list[dict[str, Any]]) -> pl.DataFrame:
    """The rows as one table (columns in first-seen order; parameters missing from a row null)."""
    columns: dict[str, None] = {}
    for r in rows:
        columns.update(dict.fromkeys(r))
    text = {"log", "session_start", "robot", "joints", "status", "reason", "model"}
    schema = {c: (pl.String if c in text else pl.Float64) for c in columns}
    return pl.DataFrame([{c: r.get(c) for c in columns} for r in rows], schema=schema, orient="row")


def summary_paths(folder: Path) -> list[Path]:
    """``summary.csv`` and ``summary.parquet`` in ``folder``."""
    return [folder / f"{SUMMARY_STEM}.csv", folder / f"{SUMMARY_STEM}.parquet"]


def write_summary(frame: pl.DataFrame, folder: Path, *, hold_signals: bool = False) -> list[Path]:
    """``summary.csv`` and ``summary.parquet`` in ``folder``, moved into place together
    (``hold_signals``: as ``staged_outputs`` says): both written to temporary files first, and
    when the second cannot be moved into place the first one moved is removed again — never a
    summary.csv without its summary.parquet."""
    from dhlog.io.writer import staged_outputs

    paths = summary_paths(folder)
    for path in paths:
        if path.is_dir():
            raise OSError(21, f"{path.name} is a folder", str(path))
    before = [_stamp(path) for path in paths]
    try:
        with staged_outputs(paths, hold_signals=hold_signals) as temps:
            frame.write_csv(temps[0])
            frame.write_parquet(temps[1])
    except BaseException:
        moved = [p for p, old in zip(paths, before, strict=True) if _stamp(p) not in (old, None)]
        if len(moved) < len(paths):  # a partial set: take back what was moved
            for path in moved:
                path.unlink(missing_ok=True)
        raise
    return paths


def _stamp(path: Path) -> Stamp | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_ino, st.st_mtime_ns)


def check_paths(jobs: list[BatchJob], folder: Path) -> None:
    """Before any work: no input of the batch (a log, the nominal or pipeline file) may be one
    of its outputs (:class:`~dhlog.result.check.InputIsOutputError`), and no output may be a
    folder (an :class:`~dhlog.errors.InputError`); nothing is written either way."""
    from dhlog.result.check import printable, refuse_inputs_as_outputs

    outputs = [path for job in jobs for path in job_outputs(job)] + summary_paths(folder)
    inputs = [(Path(job.log), "log") for job in jobs]
    if jobs:
        for spec, what in ((jobs[0].nominal, "nominal DH file"), (jobs[0].pipeline, "pipeline")):
            if spec is not None and Path(spec).is_file():
                inputs.append((Path(spec), what))
    refuse_inputs_as_outputs(inputs, outputs)
    for path in outputs:
        if path.is_dir():
            raise InputError(
                f"{printable(str(path))}: is a folder where dhlog batch writes a file; move it "
                "away or choose another --out. Nothing was written."
            )


def run_batch(
    jobs: list[BatchJob],
    workers: int,
    on_done: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Every job in a pool of ``workers`` processes (1: in this process); rows in job order.
    ``on_done`` is called with each row as its job finishes.

    An exception here (an interrupt above all) stops the workers before it goes on: no worker
    outlives the call, and no temporary file either; :func:`written_logs` says what was done."""
    if not jobs:
        raise InputError("no logs to process.")
    rows: list[dict[str, Any] | None] = [None] * len(jobs)
    if workers <= 1:
        for k, job in enumerate(jobs):
            rows[k] = process_job(job, hold_signals=_main_thread())
            if on_done is not None:
                on_done(rows[k])  # type: ignore[arg-type]
        return [r for r in rows if r is not None]
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    context = multiprocessing.get_context("spawn")  # no fork of a process holding threads
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_worker_start)
    try:
        with _sigint_held():  # the workers start with SIGINT held (a mask is inherited)
            futures = {pool.submit(_worker_job, job): k for k, job in enumerate(jobs)}
        pending = set(futures)
        while pending:  # short waits: a signal another thread took is acted on within one
            finished, pending = wait(pending, timeout=WAKE_EVERY, return_when=FIRST_COMPLETED)
            for future in sorted(finished, key=futures.__getitem__):
                k = futures[future]
                try:
                    rows[k] = future.result()
                except Exception as exc:  # a worker that died (out of memory, killed)
                    rows[k] = _failed(Path(jobs[k].log), f"the worker stopped ({exc}).", 0.0)
                if on_done is not None:
                    on_done(rows[k])  # type: ignore[arg-type]
    except BaseException:
        _stop_workers(pool)
        remove_staged(jobs)
        raise
    pool.shutdown()
    return [r for r in rows if r is not None]


#: Seconds a worker has to end after SIGTERM before it is killed.
STOP_GRACE = 2.0
#: Seconds between the pool's checks for a signal: Python acts on a signal in its main thread
#: only, and a signal the kernel gave another thread does not wake a main thread that waits.
WAKE_EVERY = 0.2


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def _handlers_restored() -> Iterator[None]:
    """The SIGINT and SIGTERM handlers as they were before the block (``staged_outputs`` with
    ``hold_signals`` ignores both from the moves on: the rest of a batch must stay
    interruptible). Only in the main thread, the only one that has handlers."""
    if not _main_thread():
        yield
        return
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in saved.items():
            if handler is not None:
                signal.signal(s, handler)


@contextmanager
def _sigint_held() -> Iterator[None]:
    """SIGINT held (blocked, not lost: delivered after the block) in this thread: processes
    started in the block begin with it held, so the terminal's Ctrl-C, sent to every process
    of the foreground group, never reaches a worker (a worker importing its modules would print
    a traceback)."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        yield
        return
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


class _WorkerStopped(BaseException):
    """SIGTERM in a worker busy with a job: raised where it is, so the job's temporary files
    are removed on the way out."""


_BUSY = False


def _on_worker_sigterm(signum: int, frame: object) -> None:
    if _BUSY:
        raise _WorkerStopped()
    os._exit(128 + signum)  # idle: nothing to clean up, nothing to say


def _worker_start() -> None:
    """A worker's set-up: SIGINT ignored (the parent stops the workers), SIGTERM ends it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _on_worker_sigterm)


def _worker_job(job: BatchJob) -> dict[str, Any]:
    """:func:`process_job` in a worker: on SIGTERM the worker leaves no temporary file and ends
    without a word (``os._exit``: no traceback, no finaliser of a half-built recording)."""
    global _BUSY
    _BUSY = True
    try:
        return process_job(job, hold_signals=True)
    except _WorkerStopped:
        os._exit(128 + signal.SIGTERM)
    finally:
        _BUSY = False


def _stop_workers(pool: Any) -> None:
    """Cancel what has not started and end every worker: SIGTERM, then SIGKILL after
    ``STOP_GRACE`` seconds."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    deadline = time.monotonic() + STOP_GRACE
    for p in processes:
        p.join(max(0.0, deadline - time.monotonic()))
    for p in processes:
        if p.is_alive():
            p.kill()
            p.join(1.0)


def remove_staged(jobs: list[BatchJob]) -> None:
    """Remove the temporary files of the jobs' outputs (``.<name>.*.part`` beside each, as
    ``staged_outputs`` names them) that a killed worker left."""
    import glob

    for job in jobs:
        for path in job_outputs(job):
            for temp in path.parent.glob(f".{glob.escape(path.name)}.*.part"):
                temp.unlink(missing_ok=True)


#: What identifies a file version: inode and modification time.
Stamp = tuple[int, int]


def output_stamps(jobs: list[BatchJob]) -> dict[Path, Stamp | None]:
    """The outputs of ``jobs`` as they are now (None: absent), to tell later which were
    written since (:func:`written_logs`)."""
    stamps: dict[Path, Stamp | None] = {}
    for job in jobs:
        for path in job_outputs(job):
            try:
                st = path.stat()
            except OSError:
                stamps[path] = None
            else:
                stamps[path] = (st.st_ino, st.st_mtime_ns)
    return stamps


def written_logs(jobs: list[BatchJob], before: dict[Path, Stamp | None]) -> list[str]:
    """The logs of ``jobs`` whose every output was written since ``before``
    (:func:`output_stamps`): results are moved into place as new files, so a new inode or
    modification time is a new result."""
    done = []
    for job in jobs:
        fresh = True
        for path in job_outputs(job):
            try:
                st = path.stat()
            except OSError:
                fresh = False
                break
            if before.get(path) == (st.st_ino, st.st_mtime_ns):
                fresh = False
                break
        if fresh:
            done.append(job.log)
    return done
