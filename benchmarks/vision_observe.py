"""Speed and peak memory of observing a camera log (issue 32, "Done when": decoding and
detection of full-HD JPEG frames at >= 20 frames a second per core, ``--jobs`` using the cores,
a 10 000-frame log within 1 GiB).

    .venv/bin/python benchmarks/vision_observe.py write [--frames 2000] [--camera full-hd]
    .venv/bin/python benchmarks/vision_observe.py run [--frames 2000] [--camera full-hd] [--jobs 1]

``write`` makes (once, cached in $TMPDIR/dhlog-bench) a ROS 2 vision log as
``dhlog simulate kr5 --instrument camera --camera full-hd --camera-setup eye-to-hand`` makes
it (``dhlog.simulator.camera``: the KR5's ``random-poses`` session, its ChArUco board rendered
through the plumb_bob camera with blur, noise and exposure, JPEG quality 95; ``full-hd`` is
issue 32's 1920x1080 camera, f 1600 px, with a 10x7 board of 30 mm squares 2 m away), but
``--frames`` long at 30 frames a second: the ``--poses`` (20) rendered frames repeat in turn,
each held for its frame's 33 ms by joint states at 100 Hz (rendering 10 000 frames would take an
hour; decoding and detecting a repeated frame costs the same). ``run`` observes it with
``dhlog.identify.camera.frames.observe.observe`` (the shipped ros2_camera pipeline with the preset's
board) and prints the frames, the wall time, the CPU time of this process and its workers (user +
sys), frames per second and per CPU second (per core), and the peak RSS of this process and of the
largest worker (``resource.getrusage``; the whole command's peak is at most this process's
plus ``jobs`` times the worker's).

Measured on a 2-core machine shared with other work (load 4-8 besides): ``run --frames 10000
--jobs 2`` (4.1 GiB): 10 000 of 10 000 frames observed, 492 000 corners, 358.9 s CPU (27.9
frames per CPU second), peak RSS 251 MiB and 151 MiB the largest worker (at most 553 MiB for the
command), 452 s wall at 79 % of the two cores; ``run --frames 200 --jobs 1``: 25.9 frames per
CPU second, peak 213 MiB; ``--jobs 2``: 22.8 (the workers' start included, 0.2 s of imports
each). The wall time of --jobs 2 against 1 could not be measured cleanly here: 13.8 s and 13.0 s
with the second core held by other work (on the earlier 1920x1200 log, 5.4-6.2 s against
7.4-11.9 s when it was free).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from mcap.writer import CompressionType, Writer

from dhlog.identify.camera.frames.observe import observe
from dhlog.io import ros2
from dhlog.io.pipeline import pipeline_by_name
from dhlog.model.robots import load_robot
from dhlog.simulator.camera import JPEG_QUALITY, PRESETS, TOPICS, render, simulate_vision
from dhlog.simulator.config import SimulationConfig

S = 1_000_000_000
FPS = 30
JOINT_RATE = 100


def log_path(frames: int, preset: str, poses: int) -> Path:
    folder = Path(os.environ.get("TMPDIR", tempfile.gettempdir())) / "dhlog-bench"
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"vision_{frames}_{preset}_p{poses}.mcap"


def write(frames: int, preset: str, poses: int) -> Path:
    path = log_path(frames, preset, poses)
    if path.exists():
        return path
    cfg = SimulationConfig(
        seed=0,
        poses=poses,
        protocol="random-poses",
        instrument="camera",
        camera_setup="eye-to-hand",
    )
    vision = simulate_vision(load_robot("kr5"), cfg, "eye-to-hand", "jpeg", preset=preset)
    rig = vision.rig
    rng = np.random.default_rng([cfg.seed, 34])
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY]
    jpegs = [
        cv2.imencode(".jpg", render(rig, T, rng), params)[1].tobytes() for T in vision.T_cam_board
    ]
    q, names = vision.session.poses, vision.session.joint_names
    part = path.with_suffix(".part")
    with open(part, "wb") as f:
        writer = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD, enable_crcs=False)
        writer.start(profile="ros2", library="dhlog benchmark")
        ids = {
            name: writer.register_schema(name, "ros2msg", ros2.MSGDEFS[name].encode())
            for name in (ros2.JOINT_STATE, ros2.COMPRESSED_IMAGE, ros2.CAMERA_INFO)
        }
        joints = writer.register_channel(TOPICS["joints"], "cdr", ids[ros2.JOINT_STATE])
        image = writer.register_channel(TOPICS["compressed"], "cdr", ids[ros2.COMPRESSED_IMAGE])
        info = writer.register_channel(TOPICS["info"], "cdr", ids[ros2.CAMERA_INFO])
        t0, period = 10 * S, S // FPS
        step = S // JOINT_RATE
        next_joint = t0
        for i in range(frames):
            start, k = t0 + i * period, i % poses
            while next_joint < start + period:  # the frame's pose held through its period
                (payload,) = ros2.encode_joint_state([next_joint], names, q[k][None, :])
                writer.add_message(joints, next_joint, payload, next_joint)
                next_joint += step
            t = start + period // 2
            data = ros2.encode_compressed_image(t, "camera", jpegs[k], "jpeg")
            writer.add_message(image, t, data, t)
            if i % FPS == 0:
                c = rig.camera
                cal = ros2.encode_camera_info(
                    ros2.CameraInfo.unrectified(
                        t, "camera", (c.width, c.height), c.model, c.coefficients.tolist(), c.K
                    )
                )
                writer.add_message(info, t, cal, t)
        writer.finish()  # type: ignore[no-untyped-call]
    part.rename(path)
    return path


def run(frames: int, preset: str, poses: int, jobs: int, keep: int) -> None:
    path = log_path(frames, preset, poses)
    if not path.exists():
        raise SystemExit(f"{path}: no log; run '{__file__} write' first")
    shipped = pipeline_by_name("ros2_camera")
    assert shipped is not None
    pipeline = dataclasses.replace(shipped, target=PRESETS[preset].board)
    start = time.perf_counter()
    (obs,) = observe(path, pipeline, jobs=jobs, keep_frames=keep)
    wall = time.perf_counter() - start
    own = resource.getrusage(resource.RUSAGE_SELF)
    workers = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = own.ru_utime + own.ru_stime + workers.ru_utime + workers.ru_stime
    n = obs.tally.frames
    print(
        f"{path.name} ({path.stat().st_size / 2**20:.0f} MiB, {obs.intrinsics.width}x"
        f"{obs.intrinsics.height}), jobs {jobs}: {n} frames, {obs.frames} observed "
        f"({sum(i.size for i in obs.ids)} corners), {len(obs.kept)} kept; {wall:.1f} s wall, "
        f"{n / wall:.1f} frames/s; CPU {cpu:.1f} s (workers {workers.ru_utime:.1f} s user), "
        f"{n / cpu:.1f} frames per CPU second; peak RSS {own.ru_maxrss / 1024:.0f} MiB, largest "
        f"worker {workers.ru_maxrss / 1024:.0f} MiB; warnings: {obs.warnings or 'none'}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["write", "run"])
    parser.add_argument("--frames", type=int, default=2000)
    parser.add_argument("--camera", default="full-hd", choices=list(PRESETS))
    parser.add_argument("--poses", type=int, default=20)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--keep", type=int, default=200)
    args = parser.parse_args()
    if args.what == "write":
        print(write(args.frames, args.camera, args.poses))
    else:
        run(args.frames, args.camera, args.poses, args.jobs, args.keep)


if __name__ == "__main__":
    main()
