"""``dhlog batch``: many logs, each processed as ``dhlog process`` would, in a process pool or
on a Dask cluster (:mod:`dhlog.fleet.executors`).

Each log is one job in a worker: its results (``<stem>.dh.json``, ``.dh.csv``, and the
recording unless ``no_rrd``) are written into the output folder as ``dhlog process --out`` writes
them, and the job returns one summary row. A log that fails is a row with status ``failed`` and
its one-line reason; nothing stops the batch; a log whose result dhlog judges implausible is
written and has status ``implausible``, its reasons the row's reason (over ``partial``, as
``dhlog process`` exits 4 over 3). The summary (one row per log: its time, robot,
every parameter with σ, FK residual, clock offset, status) is written as CSV and Parquet through
polars, atomically, in the order the logs were given. Lengths in the summary are metres and
times seconds, as its column names say (``fk_rms_m``, ``clock_offset_s``; the parameters, as in
the result JSON, are metres and radians).

An interrupt (SIGINT, or the command line's SIGTERM) stops the workers at once (how, each
executor says), their temporary files removed; :func:`written_logs` then says which logs'
results are in place.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from functools import partial
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
    return log.name.removesuffix(".zstd").removesuffix(".mcap").removesuffix(".db3")


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
        from dhlog.identify.model.select import ModelRequest
        from dhlog.identify.run import ProcessOptions, process_log
        from dhlog.io.dhfile import dh_model_from
        from dhlog.io.pipeline import pipeline_from

        pipe = pipeline_from(job.pipeline) if job.pipeline is not None else None
        nom = dh_model_from(job.nominal) if job.nominal is not None else None
        result = process_log(
            log,
            ProcessOptions(
                pipeline=pipe,
                nominal=nom,
                analytic_only=job.analytic_only,
                holdout=job.holdout,
                model=ModelRequest(job.model),
            ),
        )
        with _handlers_restored() if hold_signals else nullcontext():
            document = write_results(result, outputs, job.units, hold_signals=hold_signals)
        t0 = result.log.points["t_ns"].min() if result.log.points.height else None
        status = "ok" if result.complete else "partial"
        reason = "; ".join(f"joint {j.index} ({j.name}): {j.reason}" for j in result.failed)
        if result.implausible:  # as dhlog process: implausible wins over partial
            status = "implausible"
            reason = " ".join([*result.implausible, *([reason] if reason else [])])
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
    document: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write a result's JSON, CSV and the further outputs named (a recording, the held-out
    poses' CSV for a name ending in ``HOLDOUT_SUFFIX``, the terms' for ``TERMS_SUFFIX``), moved
    into place together; returns the JSON document (``document``: the result's, already made —
    a :class:`dhlog.Calibration`'s — else made here). ``with_log``: the log's own channels in
    the recording."""
    from dhlog.io.writer import staged_outputs
    from dhlog.result.document import holdout_csv, result_csv, result_document, terms_csv

    if document is None:
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
    of its outputs (:class:`~dhlog.io.paths.InputIsOutputError`), and no output may be a
    folder (an :class:`~dhlog.errors.InputError`); nothing is written either way."""
    from dhlog.io.paths import refuse_inputs_as_outputs
    from dhlog.io.safetext import printable

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
    *,
    executor: str = "process",
    scheduler: str | None = None,
) -> list[dict[str, Any]]:
    """Every job, rows in job order; ``on_done`` is called with each row as its job finishes.

    ``executor``: ``"process"``, a pool of ``workers`` processes (1: in this process), or
    ``"dask"``, a Dask cluster (:func:`~dhlog.fleet.executors.run_on_dask`: the one at
    ``scheduler``, or one started here with ``workers`` worker processes), which gets the jobs
    with absolute paths (:func:`absolute`; the rows name the logs as given). A job whose worker
    died is a ``failed`` row with the reason.

    An exception here (an interrupt above all) stops the workers before it goes on: no job runs
    on, and no temporary file is left; :func:`written_logs` says what was done."""
    from dhlog.fleet.executors import EXECUTORS, run_in_processes, run_on_dask

    if not jobs:
        raise InputError("no logs to process.")
    if executor not in EXECUTORS:
        raise InputError(f"no executor '{executor}'; the executors are {', '.join(EXECUTORS)}.")
    if executor == "process" and workers <= 1:
        rows = []
        for job in jobs:
            rows.append(process_job(job, hold_signals=_main_thread()))
            if on_done is not None:
                on_done(rows[-1])
        return rows
    try:
        if executor == "dask":
            pairs = [(absolute(job), job) for job in jobs]
            return run_on_dask(
                process_sent, pairs, workers, scheduler=scheduler, lost=_lost_pair, on_done=on_done
            )
        work = partial(process_job, hold_signals=True)
        return run_in_processes(work, jobs, workers, lost=_lost, on_done=on_done)
    except BaseException:
        remove_staged(jobs)  # what a killed worker left
        raise


def absolute(job: BatchJob) -> BatchJob:
    """The job with its log, folder, and pipeline or nominal file (when it names one) as
    absolute paths: what a worker on another machine, reading the same shared file system at
    the same paths, needs."""

    def file(spec: str | None) -> str | None:
        return os.path.abspath(spec) if spec is not None and Path(spec).exists() else spec

    return replace(
        job,
        log=os.path.abspath(job.log),
        folder=os.path.abspath(job.folder),
        pipeline=file(job.pipeline),
        nominal=file(job.nominal),
    )


def process_sent(pair: tuple[BatchJob, BatchJob]) -> dict[str, Any]:
    """:func:`process_job` of the job sent to a worker (:func:`absolute`), its row naming the
    log (in its reason too) and robot as the job given did."""
    sent, given = pair
    row = process_job(sent)
    row["log"] = given.log
    if row.get("reason"):
        row["reason"] = row["reason"].replace(sent.log, given.log)
    if sent.nominal is not None and row.get("robot") == sent.nominal:
        row["robot"] = given.nominal
    return row


def _lost(job: BatchJob, reason: str) -> dict[str, Any]:
    return _failed(Path(job.log), reason, 0.0)


def _lost_pair(pair: tuple[BatchJob, BatchJob], reason: str) -> dict[str, Any]:
    return _lost(pair[1], reason)


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
