"""The whole command on long logs laid out as users record them: a rosbag2 bag split into several
files (``ros2 bag record --max-bag-size``) and a session measuring several targets at once.

    .venv/bin/python benchmarks/layouts.py [--samples 5000000] [--files 5] [--targets 3]
                                           [--target-samples 2000000] [--runs 3]
                                           [--vs-src OLD/src]

For ``--samples`` target samples of the KR5 sweeps ``benchmarks/process.py`` times (1 kHz
tracker, 250 Hz joint states, σ 10 µm), written once and cached in ``$TMPDIR/dhlog-bench`` by a
separate process:

* ``split``: the session cut by time into ``--files`` MCAP files as rosbag2 writes them, in a bag
  folder whose ``metadata.yaml`` lists them (as ``ros2 bag record --max-bag-size`` leaves it);
* ``targets``: one file of ``--target-samples`` tracker samples in which ``--targets`` SMRs on
  the flange are each measured (``/tracker/point``, ``/tracker/point_2``, …), read with a
  pipeline naming the further targets' topics (``extra_topics``).

Each is timed as a whole process (``dhlog process LOG --no-rrd``; ``farm-bench`` when on the
PATH: median, min, max of wall time and peak RSS), paired run by run with ``--vs-src``: the
same command run from another source tree through ``PYTHONPATH`` (an earlier commit).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve()
DHLOG = str(Path(sys.executable).with_name("dhlog"))


def _session(samples: int, targets: int = 1):  # type: ignore[no-untyped-def]
    from dhlog.model.robots import load_robot
    from dhlog.simulator.config import SimulationConfig
    from dhlog.simulator.session import simulate_session

    speed = 6 * math.radians(90) * 1.34 / (samples / 1000.0)
    extra = tuple((0.03 * k, -0.02 * k, 0.01) for k in range(1, targets))
    cfg = SimulationConfig(
        noise=1e-5, tracker_rate=1000.0, joint_rate=250.0, speed=speed, base_points=12, seed=7
    )
    if extra:
        cfg = replace(cfg, extra_tools=extra)
    return simulate_session(load_robot("kr5"), cfg)


def _folder() -> Path:
    folder = Path(os.environ.get("TMPDIR", tempfile.gettempdir())) / "dhlog-bench"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def make_split(samples: int, files: int) -> Path:
    """The session of ``samples`` target samples as a rosbag2 bag of ``files`` MCAP files."""
    import yaml
    from mcap.reader import make_reader

    from dhlog.io.writer import write_session

    bag = _folder() / f"kr5_1khz_{samples}_split{files}"
    if (bag / "metadata.yaml").exists():
        return bag
    shutil.rmtree(bag, ignore_errors=True)
    bag.mkdir()
    s = _session(samples)
    t0, span = int(s.point_t_ns[0]), int(s.point_t_ns[-1]) + 1 - int(s.point_t_ns[0])
    cuts = [t0 + span * k // files for k in range(files + 1)]  # whole ns: no float rounding
    entries, topics = [], {}
    for k in range(files):
        # the first file from the first message, the last to the last (joint states too)
        lo = cuts[k] if k else np.iinfo(np.int64).min
        hi = cuts[k + 1] if k < files - 1 else np.iinfo(np.int64).max
        pt = (s.point_t_ns >= lo) & (s.point_t_ns < hi)
        jt = (s.joint_t_ns >= lo) & (s.joint_t_ns < hi)
        part = replace(
            s,
            point_t_ns=s.point_t_ns[pt],
            point_xyz=s.point_xyz[pt],
            joint_t_ns=s.joint_t_ns[jt],
            joint_q=s.joint_q[jt],
            base_t_ns=s.base_t_ns if k == 0 else s.base_t_ns[:0],
            base_xyz=s.base_xyz if k == 0 else s.base_xyz[:0],
            phase=[(t, j) for t, j in s.phase if lo <= t < hi],
        )
        name = f"{bag.name}_{k}.mcap"
        write_session(part, bag / name, "ros2")
        with open(bag / name, "rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics is not None
        stats = summary.statistics
        for cid, channel in summary.channels.items():
            schema = summary.schemas[channel.schema_id]
            count = stats.channel_message_counts.get(cid, 0)
            if channel.topic in topics:
                topics[channel.topic]["message_count"] += count
            else:
                topics[channel.topic] = {
                    "message_count": count,
                    "topic_metadata": {
                        "name": channel.topic,
                        "offered_qos_profiles": [],
                        "serialization_format": "cdr",
                        "type": schema.name,
                        "type_description_hash": "",
                    },
                }
        entries.append(
            {
                "duration": {"nanoseconds": stats.message_end_time - stats.message_start_time},
                "message_count": stats.message_count,
                "path": name,
                "starting_time": {"nanoseconds_since_epoch": stats.message_start_time},
            }
        )
    start = entries[0]["starting_time"]["nanoseconds_since_epoch"]
    end = max(
        e["starting_time"]["nanoseconds_since_epoch"] + e["duration"]["nanoseconds"]
        for e in entries
    )
    info = {
        "compression_format": "",
        "compression_mode": "",
        "custom_data": None,
        "duration": {"nanoseconds": end - start},
        "files": entries,
        "message_count": sum(e["message_count"] for e in entries),
        "relative_file_paths": [e["path"] for e in entries],
        "ros_distro": "jazzy",
        "starting_time": {"nanoseconds_since_epoch": start},
        "storage_identifier": "mcap",
        "topics_with_message_count": list(topics.values()),
        "version": 9,
    }
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))
    return bag


def make_targets(samples: int, targets: int) -> Path:
    """The session of ``samples`` tracker samples measuring ``targets`` SMRs, as one file."""
    from dhlog.io.writer import write_session

    path = _folder() / f"kr5_1khz_{samples}_targets{targets}.mcap"
    if not path.exists():
        write_session(_session(samples, targets), path, "ros2")
    return path


def _made(kind: str, samples: int, count: int) -> Path:
    """``make_split`` / ``make_targets`` in a separate process (its memory not in the runs')."""
    code = (
        "import layouts; print(layouts.make_"
        + ("split" if kind == "split" else "targets")
        + f"({samples}, {count}))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=HERE.parent, check=True, capture_output=True, text=True
    )
    return Path(out.stdout.strip().splitlines()[-1])


#: The shipped ROS 2 pipeline with the further targets' topics.
PIPELINE = """name = "ros2_targets"
encoding = "cdr"

[streams.point]
topic = "/tracker/point"
extra_topics = [{extra}]

[streams.joints]
topic = "/joint_states"
required = true

[streams.base]
topic = "/tracker/base_plane"
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=5_000_000)
    parser.add_argument("--files", type=int, default=5)
    parser.add_argument("--targets", type=int, default=3)
    parser.add_argument("--target-samples", type=int, default=2_000_000)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--vs-src", help="another source tree, run through PYTHONPATH")
    args = parser.parse_args()
    out_dir = Path(tempfile.mkdtemp(prefix="dhlog-layouts-"))
    farm = shutil.which("farm-bench")
    pipeline = out_dir / "targets.toml"
    extra = ", ".join(f'"/tracker/point_{k}"' for k in range(2, args.targets + 1))
    pipeline.write_text(PIPELINE.format(extra=extra))
    for kind, count, samples in (
        ("split", args.files, args.samples),
        ("targets", args.targets, args.target_samples),
    ):
        path = _made(kind, samples, count)
        dhlog = [DHLOG, "process", str(path), "--no-rrd", "--force"]
        if kind == "targets":
            dhlog += ["--pipeline", str(pipeline)]
        dhlog += ["--out", str(out_dir / "a")]
        print(f"## {kind}: {path.name}\n", flush=True)
        if farm:
            cmd = [farm, "-n", str(args.runs), "--timeout", "3600"]
            if args.vs_src:
                old = [f"PYTHONPATH={args.vs_src}", *dhlog[:-1], str(out_dir / "b")]
                cmd += ["--vs", " ".join(["env", *old])]
            out = subprocess.run([*cmd, "--", *dhlog], capture_output=True, text=True)
            print("```\n" + out.stdout.strip() + "\n```\n", flush=True)
        else:
            for _ in range(args.runs):
                proc = subprocess.Popen(dhlog, stdout=subprocess.DEVNULL)
                _, status, usage = os.wait4(proc.pid, 0)
                print(f"exit {status >> 8}, peak {usage.ru_maxrss / 1024:.0f} MiB", flush=True)


if __name__ == "__main__":
    main()
