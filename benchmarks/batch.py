"""Batch throughput as users run it: ``dhlog batch`` over many session logs against the same logs
processed one ``dhlog process`` after another (the shell loop a site runs without ``batch``).

    .venv/bin/python benchmarks/batch.py [--logs 16] [--jobs 1 2] [--runs 3] [--no-rrd]
                                         [--tracker-rate 100] [--executor process dask]

The logs are simulated KR5 sessions off their nominal (0.2 mm, 0.02°; tracker 100 Hz — about
7 500 target samples each — or ``--tracker-rate``, σ 10 µm), written once by ``dhlog simulate`` into
``$TMPDIR/dhlog-bench-batch``. Each ``--jobs`` value is timed as a whole command by
``farm-bench``, paired run by run against the loop (``--vs``), recordings included unless
``--no-rrd``, for each ``--executor``: ``process`` (the pool of worker processes) and ``dask`` (a
Dask cluster of ``--jobs`` worker processes that the command starts and closes: its start and
close are in the figures). Prints farm-bench's report for each.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

DHLOG = str(Path(sys.executable).with_name("dhlog"))


def make_logs(count: int, rate: float) -> list[Path]:
    folder = Path(tempfile.gettempdir()) / "dhlog-bench-batch"
    folder.mkdir(exist_ok=True)
    logs = []
    for k in range(count):
        log = folder / f"kr5_{rate:g}Hz_{k:03d}.mcap"
        if not log.exists():
            subprocess.run(
                [
                    DHLOG,
                    "simulate",
                    "kr5",
                    "-o",
                    str(log),
                    "--perturb-mm",
                    "0.2",
                    "--perturb-deg",
                    "0.02",
                    "--seed",
                    str(k),
                    "--start-day",
                    str(k),
                    "--tracker-rate",
                    str(rate),
                ],
                check=True,
                capture_output=True,
            )
        logs.append(log)
    return logs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logs", type=int, default=16)
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--no-rrd", action="store_true")
    parser.add_argument("--tracker-rate", type=float, default=100.0, help="Hz")
    parser.add_argument("--executor", nargs="+", default=["process"], choices=["process", "dask"])
    args = parser.parse_args()
    logs = make_logs(args.logs, args.tracker_rate)
    out = Path(tempfile.mkdtemp(prefix="dhlog-batch-out-"))
    rrd = ["--no-rrd"] if args.no_rrd else []
    names = " ".join(str(p) for p in logs)
    flags = " ".join(rrd)
    loop = (
        f"sh -c 'for f in {names}; do {DHLOG} process $f --out {out}/loop --force {flags} "
        ">/dev/null 2>&1; done'"
    )
    for executor, jobs in ((e, j) for e in args.executor for j in args.jobs):
        command = [
            DHLOG,
            "batch",
            *map(str, logs),
            "--out",
            str(out / f"{executor}{jobs}"),
            "--force",
            "--jobs",
            str(jobs),
            "--executor",
            executor,
            *rrd,
        ]
        print(
            f"== dhlog batch --executor {executor} --jobs {jobs} ({len(logs)} logs"
            f"{', no recordings' if rrd else ''}) vs one dhlog process after another",
            flush=True,
        )
        subprocess.run(
            ["farm-bench", "-n", str(args.runs), "--timeout", "3000", "--vs", loop, "--", *command],
            check=False,
        )
    shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
