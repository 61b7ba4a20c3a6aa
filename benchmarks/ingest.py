"""Throughput of reading + segmenting a 1 kHz ROS 2 tracker log, fast path against the baseline.

    .venv/bin/python benchmarks/ingest.py [--samples 1000000] [--repeat 3]

Writes (once, cached in $TMPDIR/dhlog-bench) a simulated KR5 session with ``--samples`` target
samples at 1 kHz and joint states at 250 Hz as rosbag2 would, then times in the same run:

* fast: ``read_log`` (numpy record walk + bulk CDR) + ``segment_log``;
* baseline: ``read_log(fast=False)`` (every message through ``mcap_ros2``) + ``segment_log``.

Both must give the same measurement table; the script checks that.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

from dhlog.identify.segment.segment import segment_log
from dhlog.io.reader import read_log
from dhlog.io.writer import write_session
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session


def make_log(samples: int) -> Path:
    folder = Path(os.environ.get("TMPDIR", tempfile.gettempdir())) / "dhlog-bench"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"kr5_1khz_{samples}.mcap"
    if path.exists():
        return path
    # six 90-degree sweeps at a speed that makes the session last `samples` milliseconds
    speed = 6 * math.radians(90) * 1.34 / (samples / 1000.0)
    cfg = SimulationConfig(
        noise=1e-5, tracker_rate=1000.0, joint_rate=250.0, speed=speed, base_points=12, seed=7
    )
    session = simulate_session(load_robot("kr5"), cfg)
    started = time.perf_counter()
    write_session(session, path, "ros2")
    print(
        f"wrote {path} ({session.point_xyz.shape[0]} target samples, "
        f"{session.joint_t_ns.size} joint states) in {time.perf_counter() - started:.1f} s"
    )
    return path


def timed(path: Path, fast: bool) -> tuple[float, int, object]:
    started = time.perf_counter()
    log = read_log(path, fast=fast)
    seg = segment_log(log)
    return time.perf_counter() - started, log.points.height, seg.table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    path = make_log(args.samples)
    size = path.stat().st_size / 1e6
    fast_times = []
    for _ in range(args.repeat):
        seconds, n, fast_table = timed(path, fast=True)
        fast_times.append(seconds)
    best = min(fast_times)
    print(f"file: {size:.1f} MB, {n} target samples")
    print(
        f"fast path     : read+segment {best:.3f} s (best of {args.repeat}) "
        f"-> {n / best / 1e6:.2f} M target samples/s"
    )
    seconds, n_base, base_table = timed(path, fast=False)
    print(
        f"baseline path : read+segment {seconds:.3f} s (mcap_ros2 per message) "
        f"-> {n_base / seconds / 1e3:.0f} k target samples/s"
    )
    print(f"speed-up {seconds / best:.1f}x; identical tables: {fast_table.equals(base_table)}")  # type: ignore[attr-defined]


if __name__ == "__main__":
    main()
