"""``dhlog batch``: many logs, each processed as ``dhlog process`` would, in a process pool.

Each log is one job in a worker process: its results (``<stem>.dh.json``, ``.dh.csv``, and the
recording unless ``no_rrd``) are written into the output folder as ``dhlog process --out`` writes
them, and the job returns one summary row. A log that fails is a row with status ``failed`` and
its one-line reason; nothing stops the batch. The summary (one row per log: its time, robot,
every parameter with σ, FK residual, clock offset, status) is written as CSV and Parquet through
polars, atomically, in the order the logs were given.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
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


def stem_of(log: Path) -> str:
    """The results' name of a log (``run.mcap`` → ``run``; a bag folder by its name)."""
    return log.name.removesuffix(".zstd").removesuffix(".mcap")


def process_job(job: BatchJob) -> dict[str, Any]:
    """Process one log into ``job.folder`` and return its summary row (never raises for the
    log's own faults: they are its status and reason)."""
    import numpy as np

    np.seterr(all="ignore")
    start = time.perf_counter()
    log = Path(job.log)
    stem = stem_of(log)
    folder = Path(job.folder)
    outputs = [folder / f"{stem}.dh.json", folder / f"{stem}.dh.csv"]
    if not job.no_rrd:
        outputs.append(folder / f"{stem}.rrd")
    if job.holdout:
        outputs.append(folder / f"{stem}{HOLDOUT_SUFFIX}")
    try:
        from dhlog.dhfile import dh_model_from
        from dhlog.io.pipeline import pipeline_from
        from dhlog.process import process_log

        pipe = pipeline_from(job.pipeline) if job.pipeline is not None else None
        nom = dh_model_from(job.nominal) if job.nominal is not None else None
        result = process_log(
            log,
            pipeline=pipe,
            nominal=nom,
            analytic_only=job.analytic_only,
            holdout=job.holdout,
        )
        document = write_results(result, outputs, job.units)
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


def write_results(
    result: Any,
    outputs: list[Path],
    units: str,
    *,
    hold_signals: bool = False,
    with_log: bool = False,
) -> dict[str, Any]:
    """Write a result's JSON, CSV and the further outputs named (a recording, or the held-out
    poses' CSV for a name ending in ``HOLDOUT_SUFFIX``), moved into place together; returns the
    JSON document. ``with_log``: the log's own channels in the recording."""
    from dhlog.io.writer import staged_outputs
    from dhlog.result import holdout_csv, result_csv, result_document

    document = result_document(result)
    with staged_outputs(outputs, hold_signals=hold_signals) as temps:
        temps[0].write_bytes((json.dumps(document, indent=2) + "\n").encode())
        temps[1].write_bytes(result_csv(result, units=units).encode())
        for path, temp in zip(outputs[2:], temps[2:], strict=True):
            if path.name.endswith(HOLDOUT_SUFFIX):
                temp.write_bytes(holdout_csv(result, units=units).encode())
            else:
                from dhlog.recording import write_process_recording

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
    from dhlog.compare import parameters

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
        "fk_rms": val.get("fk_rms"),
        "fk_max": val.get("fk_max"),
        "clock_offset": timing.get("clock_offset"),
        "std_clock_offset": timing.get("std"),
    }
    for check in val.get("holdout") or []:  # the first cross-validation's statistics
        if isinstance(check, dict) and check.get("kind") == "cross-validation":
            for model in ("nominal", "calibrated"):
                stats = check.get(model) or {}
                for key in ("mean", "rms", "p95", "max"):
                    row[f"holdout_{model}_{key}"] = stats.get(key)
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
    text = {"log", "session_start", "robot", "joints", "status", "reason"}
    schema = {c: (pl.String if c in text else pl.Float64) for c in columns}
    return pl.DataFrame([{c: r.get(c) for c in columns} for r in rows], schema=schema, orient="row")


def write_summary(frame: pl.DataFrame, folder: Path) -> list[Path]:
    """``summary.csv`` and ``summary.parquet`` in ``folder``, moved into place together."""
    from dhlog.io.writer import staged_outputs

    paths = [folder / f"{SUMMARY_STEM}.csv", folder / f"{SUMMARY_STEM}.parquet"]
    with staged_outputs(paths) as temps:
        frame.write_csv(temps[0])
        frame.write_parquet(temps[1])
    return paths


def run_batch(
    jobs: list[BatchJob],
    workers: int,
    on_done: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Every job in a pool of ``workers`` processes (1: in this process); rows in job order.
    ``on_done`` is called with each row as its job finishes."""
    if not jobs:
        raise InputError("no logs to process.")
    rows: list[dict[str, Any] | None] = [None] * len(jobs)
    if workers <= 1:
        for k, job in enumerate(jobs):
            rows[k] = process_job(job)
            if on_done is not None:
                on_done(rows[k])  # type: ignore[arg-type]
        return [r for r in rows if r is not None]
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    context = multiprocessing.get_context("spawn")  # no fork of a process holding threads
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futures = {pool.submit(process_job, job): k for k, job in enumerate(jobs)}
        try:
            for future in as_completed(futures):
                k = futures[future]
                try:
                    rows[k] = future.result()
                except Exception as exc:  # a worker that died (out of memory, killed)
                    rows[k] = _failed(Path(jobs[k].log), f"the worker stopped ({exc}).", 0.0)
                if on_done is not None:
                    on_done(rows[k])  # type: ignore[arg-type]
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    return [r for r in rows if r is not None]
