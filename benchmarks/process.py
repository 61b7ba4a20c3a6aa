"""The whole command, as users run it: ``dhlog process --no-rrd`` on generated 1 kHz ROS 2 logs.

    .venv/bin/python benchmarks/process.py [--samples 1000000 5000000 10000000] [--runs 3]
                                           [--baseline-max 5000000]

For each size, a simulated KR5 session (tracker 1 kHz ``geometry_msgs/msg/PointStamped``,
joint states 250 Hz, σ 10 µm) is written once as rosbag2 writes it (cached in
``$TMPDIR/dhlog-bench``, by a separate process). Then, in the same run:

* ``dhlog process LOG --no-rrd --force --out DIR``, timed as a whole process by ``farm-bench``
  (median, min, max of wall time and peak RSS), paired run by run against
* the baseline: ``benchmarks/process.py baseline LOG``, a process that decodes every message of
  the same file (points and joint states) through ``mcap_ros2``'s per-message decoder
  (``iter_decoded_messages``) and counts the points — the plain way to read such a log in
  Python, before any identification (sizes up to ``--baseline-max``; above it dhlog alone);
* the per-stage breakdown of one run (``benchmarks/process.py stages LOG``: ``process_log``
  with its progress callback, in its own process).

Without ``farm-bench`` on the PATH the script times each process itself (``wait4``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve()
DHLOG = str(Path(sys.executable).with_name("dhlog"))


def make(samples: int) -> Path:
    """The cached log of ``samples`` target samples, written by a separate process."""
    code = f"import ingest; print(ingest.make_log({samples}))"
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=HERE.parent, check=True, capture_output=True, text=True
    )
    return Path(out.stdout.strip().splitlines()[-1])


def baseline(path: str) -> None:
    """Decode every message of ``path`` through mcap_ros2 and print the number of points."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    n = 0
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, _message, msg in reader.iter_decoded_messages():
            if channel.topic == "/tracker/point":
                n += msg.point.x is not None
    print(n)


def stages(path: str) -> None:
    """Seconds per stage of one in-process run, as JSON."""
    from dhlog.identify.run import process_log
    from dhlog.result.document import result_csv, result_document

    marks: list[tuple[str, float]] = [("start", time.perf_counter())]

    def progress(stage: str, _fraction: float) -> None:
        if stage != marks[-1][0]:
            marks.append((stage, time.perf_counter()))

    result = process_log(path, progress=progress)
    marks.append(("writing", time.perf_counter()))
    json.dumps(result_document(result))
    result_csv(result)
    marks.append(("end", time.perf_counter()))
    parts = [(name, t1 - t0) for (name, t0), (_, t1) in itertools.pairwise(marks[1:])]
    print(json.dumps(parts))


def timed(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one run of ``cmd`` (fallback without farm-bench)."""
    started = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    if status != 0:
        raise SystemExit(f"{cmd} failed ({status})")
    return time.perf_counter() - started, usage.ru_maxrss / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--samples", type=int, nargs="+", default=[1_000_000, 5_000_000, 10_000_000]
    )
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--baseline-max", type=int, default=5_000_000)
    args = parser.parse_args()
    out_dir = Path(tempfile.mkdtemp(prefix="dhlog-process-"))
    farm = shutil.which("farm-bench")
    for samples in args.samples:
        path = make(samples)
        dhlog = [DHLOG, "process", str(path), "--no-rrd", "--force", "--out", str(out_dir)]
        base = [sys.executable, str(HERE), "baseline", str(path)]
        print(f"## {samples:,} samples ({path.stat().st_size / 1e6:.0f} MB)\n", flush=True)
        with_base = samples <= args.baseline_max
        if farm:
            cmd = [farm, "-n", str(args.runs), "--timeout", "3600"]
            if with_base:
                cmd += ["--vs", " ".join(base)]
            out = subprocess.run([*cmd, "--", *dhlog], capture_output=True, text=True)
            print("```\n" + out.stdout.strip() + "\n```\n", flush=True)
        else:
            runs = [timed(dhlog) for _ in range(args.runs)]
            walls = [w for w, _ in runs]
            print(
                f"dhlog process: {statistics.median(walls):.2f} s "
                f"[{min(walls):.2f}–{max(walls):.2f}], peak {max(p for _, p in runs):.0f} MB"
            )
            if with_base:
                wall, peak = timed(base)
                print(f"baseline: {wall:.1f} s, peak {peak:.0f} MB")
        parts = subprocess.run(
            [sys.executable, str(HERE), "stages", str(path)],
            capture_output=True,
            text=True,
            check=True,
        )
        breakdown = json.loads(parts.stdout.strip().splitlines()[-1])
        print(
            "per stage (s): " + ", ".join(f"{n} {v:.2f}" for n, v in breakdown) + "\n", flush=True
        )


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] in ("baseline", "stages"):
        {"baseline": baseline, "stages": stages}[sys.argv[1]](sys.argv[2])
    else:
        main()
