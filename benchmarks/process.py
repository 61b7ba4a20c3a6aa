"""The whole command, as users run it: ``dhlog process --no-rrd`` on generated 1 kHz ROS 2 logs.

    .venv/bin/python benchmarks/process.py [--samples 1000000 5000000 10000000] [--repeat 3]
                                           [--baseline-max 5000000]

For each size, a simulated KR5 session (tracker 1 kHz ``geometry_msgs/msg/PointStamped``,
joint states 250 Hz, σ 10 µm) is written once as rosbag2 writes it (cached in
``$TMPDIR/dhlog-bench``). Then, in the same run:

* ``dhlog process LOG --no-rrd --force --out DIR`` as a separate process, ``--repeat`` times:
  wall time (median, min, max) and peak RSS of that process (``wait4``);
* the baseline: a separate process that decodes every message of the same file (points and
  joint states) through ``mcap_ros2``'s per-message decoder (``iter_decoded_messages``) and
  counts the points — the plain way to read such a log in Python, before any identification
  (sizes up to ``--baseline-max``);
* the per-stage breakdown of one in-process run (``process_log`` with its progress callback).
"""

from __future__ import annotations

import argparse
import itertools
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from ingest import make_log  # noqa: E402

DHLOG = str(Path(sys.executable).with_name("dhlog"))
BASELINE = """
import sys
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
n = 0
with open(sys.argv[1], "rb") as f:
    for _schema, channel, _message, msg in make_reader(
        f, decoder_factories=[DecoderFactory()]
    ).iter_decoded_messages():
        if channel.topic == "/tracker/point":
            n += msg.point.x is not None
print(n)
"""


def run(cmd: list[str]) -> tuple[float, float, str]:
    """Wall seconds, peak RSS (MB) of the child, and its stdout."""
    started = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stderr is not None
    out = proc.stdout.read()
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - started
    if status != 0:
        raise SystemExit(f"{cmd} failed ({status}): {err}")
    return wall, usage.ru_maxrss / 1024.0, out


def stages(path: Path) -> list[tuple[str, float]]:
    """Seconds spent in each stage of one in-process run."""
    from dhlog.process import process_log
    from dhlog.result import result_csv, result_document

    marks: list[tuple[str, float]] = [("start", time.perf_counter())]

    def progress(stage: str, _fraction: float) -> None:
        if stage != marks[-1][0]:
            marks.append((stage, time.perf_counter()))

    result = process_log(path, progress=progress)
    marks.append(("writing", time.perf_counter()))
    result_document(result)
    result_csv(result)
    marks.append(("end", time.perf_counter()))
    return [(name, t1 - t0) for (name, t0), (_, t1) in itertools.pairwise(marks[1:])]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--samples", type=int, nargs="+", default=[1_000_000, 5_000_000, 10_000_000]
    )
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--baseline-max", type=int, default=5_000_000)
    args = parser.parse_args()
    out_dir = Path(tempfile.mkdtemp(prefix="dhlog-process-"))
    print(
        "| samples | log | dhlog process: median [min–max] | samples/s | peak RSS | "
        "baseline (mcap_ros2 per message) | baseline peak RSS | speed-up |"
    )
    print("|---|---|---|---|---|---|---|---|")
    breakdowns = {}
    for samples in args.samples:
        path = make_log(samples)
        size = path.stat().st_size / 1e6
        walls, peaks = [], []
        n_points = samples
        for _ in range(args.repeat):
            wall, peak, _ = run(
                [DHLOG, "process", str(path), "--no-rrd", "--force", "--out", str(out_dir)]
            )
            walls.append(wall)
            peaks.append(peak)
        base = "–"
        base_peak = "–"
        ratio = "–"
        if samples <= args.baseline_max:
            b_wall, b_peak, b_out = run([sys.executable, "-c", BASELINE, str(path)])
            n_points = int(b_out.strip())
            base = f"{b_wall:.1f} s ({n_points / b_wall / 1e3:.0f} k samples/s)"
            base_peak = f"{b_peak:.0f} MB"
            ratio = f"{b_wall / statistics.median(walls):.1f}×"
        med = statistics.median(walls)
        print(
            f"| {n_points:,} | {size:.0f} MB | {med:.2f} s [{min(walls):.2f}–{max(walls):.2f}] | "
            f"{n_points / med / 1e6:.2f} M | {max(peaks):.0f} MB | {base} | {base_peak} | "
            f"{ratio} |",
            flush=True,
        )
        breakdowns[samples] = stages(path)
    print("\nPer stage (one in-process run, s):\n")
    names = [n for n, _ in next(iter(breakdowns.values()))]
    print("| samples | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for samples, parts in breakdowns.items():
        values = dict(parts)
        print(f"| {samples:,} | " + " | ".join(f"{values.get(n, 0.0):.2f}" for n in names) + " |")


if __name__ == "__main__":
    main()
