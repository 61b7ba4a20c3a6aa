"""The simulator's vision logs (issue 32, item 8): every frame's board detected, and how far its
corners lie from the truth's projection.

    .venv/bin/python benchmarks/vision_simulate.py [--robots kr5 ur5] [--poses 12] [--format jpeg]

For each robot and set-up (eye-to-hand, eye-in-hand) ``dhlog.simulate.camera`` simulates a
``random-poses`` vision log (seed 0) and writes it; the frames are read back by
``io.images.ImageStream`` and ``vision.detect.detect`` runs on each with the intrinsics.
Printed: the frames with the board, the corners found of those on the board, their RMS and
largest distance (px) from ``Intrinsics.project`` of the true board pose, the board's distance
range, the simulation and the writing (rendering, encoding) times.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from dhlog.io.images import ImageStream
from dhlog.model.robots import load_robot
from dhlog.simulate.camera import TOPICS, simulate_vision, write_vision_log
from dhlog.simulate.config import SimulationConfig
from dhlog.vision.detect import Detection, detect


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["kr5", "ur5"])
    parser.add_argument("--poses", type=int, default=12)
    parser.add_argument("--format", default="jpeg", choices=("jpeg", "png", "raw"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.robots:
            for setup in ("eye-to-hand", "eye-in-hand"):
                robot = load_robot(name)
                cfg = SimulationConfig(protocol="random-poses", poses=args.poses)
                t0 = time.perf_counter()
                vision = simulate_vision(robot, cfg, setup, args.format)  # type: ignore[arg-type]
                t1 = time.perf_counter()
                path = Path(tmp) / f"{name}-{setup}.mcap"
                write_vision_log(vision, path, 0)
                t2 = time.perf_counter()
                topic = TOPICS["raw" if args.format == "raw" else "compressed"]
                frames = [f for b in ImageStream(path, topic).batches() for f in b]
                board, cam = vision.rig.board, vision.rig.camera
                errors, found_frames = [], 0
                for frame, T in zip(frames, vision.T_cam_board, strict=True):
                    found = detect(frame.pixels, board, camera=cam)
                    if not isinstance(found, Detection):
                        continue
                    found_frames += 1
                    truth = cam.project(found.object_points @ T[:3, :3].T + T[:3, 3])
                    errors.append(np.linalg.norm(found.corners_px - truth, axis=1))
                e = np.concatenate(errors) if errors else np.zeros(0)
                z = vision.T_cam_board[:, 2, 3]
                print(
                    f"{name} {setup}: {found_frames}/{len(frames)} frames, {e.size}/"
                    f"{len(frames) * len(board.object_points())} corners, "
                    f"{np.sqrt(np.mean(e**2)):.3f} px RMS (max {e.max():.3f}), board "
                    f"{z.min():.2f}-{z.max():.2f} m away; simulated in {t1 - t0:.2f} s, "
                    f"written in {t2 - t1:.2f} s"
                )


if __name__ == "__main__":
    main()
