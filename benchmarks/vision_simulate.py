"""The simulator's vision logs (issue 32, item 8): every frame's board detected, and how far its
corners lie from the truth's projection.

    .venv/bin/python benchmarks/vision_simulate.py [--robots kr5 ur5] [--setups eye-to-hand]
        [--protocol random-poses|sweeps|coupled] [--poses 12] [--frame-rate 10]
        [--camera default|full-hd|small] [--format jpeg]

For each robot and set-up (eye-to-hand, eye-in-hand) ``dhlog.simulator.camera`` simulates a
vision log of the protocol (seed 0) with the camera preset and writes it; the frames are read
back by ``frames.images.ImageStream`` and ``frames.detect.detect`` runs on each with the
intrinsics. Printed: the frames with the board, the corners found of those on the board, their
RMS and largest distance (px) from ``Intrinsics.project`` of the true board pose, the board's
distance range, the simulation and the writing (rendering, encoding) times; for a moving
protocol each move's frames (written / detected) and the joint range they span.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from dhlog.identify.camera.frames.detect import Detection, detect
from dhlog.identify.camera.frames.images import ImageStream
from dhlog.model.robots import load_robot
from dhlog.simulator.camera import (
    CAMERA_PRESETS,
    camera_topics,
    protocol_moves,
    simulate_vision,
    write_vision_log,
)
from dhlog.simulator.config import SimulationConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", nargs="+", default=["kr5", "ur5"])
    parser.add_argument("--setups", nargs="+", default=["eye-to-hand", "eye-in-hand"])
    parser.add_argument(
        "--protocol", default="random-poses", choices=("random-poses", "sweeps", "coupled")
    )
    parser.add_argument("--poses", type=int, default=12)
    parser.add_argument("--frame-rate", type=float, default=10.0)
    parser.add_argument("--camera", default="default", choices=CAMERA_PRESETS)
    parser.add_argument("--format", default="jpeg", choices=("jpeg", "png", "raw"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.robots:
            for setup in args.setups:
                robot = load_robot(name)
                cfg = SimulationConfig(protocol=args.protocol, poses=args.poses)
                t0 = time.perf_counter()
                vision = simulate_vision(
                    robot,
                    cfg,
                    setup,
                    args.format,
                    preset=args.camera,
                    frame_rate=args.frame_rate,
                )
                t1 = time.perf_counter()
                path = Path(tmp) / f"{name}-{setup}.mcap"
                write_vision_log(vision, path, 0)
                t2 = time.perf_counter()
                topic = camera_topics(0, 1)["raw" if args.format == "raw" else "compressed"]
                frames = [f for b in ImageStream(path, topic).batches() for f in b]
                board, cam = vision.rig.board, vision.rig.camera
                errors, found = [], []
                for frame, T in zip(frames, vision.T_cam_board, strict=True):
                    got = detect(frame.pixels, board, camera=cam)
                    found.append(isinstance(got, Detection))
                    if isinstance(got, Detection):
                        truth = cam.project(got.object_points @ T[:3, :3].T + T[:3, 3])
                        errors.append(np.linalg.norm(got.corners_px - truth, axis=1))
                e = np.concatenate(errors) if errors else np.full(1, np.nan)
                z = np.linalg.norm(vision.T_cam_board[:, :3, 3], axis=1)
                print(
                    f"{name} {setup} {args.protocol} ({args.camera}): {sum(found)}/{len(frames)} "
                    f"frames, {len(e)}/{len(frames) * len(board.object_points())} corners, "
                    f"{np.sqrt(np.mean(e**2)):.3f} px RMS (max {e.max():.3f}), board "
                    f"{z.min():.2f}-{z.max():.2f} m away; simulated in {t1 - t0:.2f} s, "
                    f"written in {t2 - t1:.2f} s ({(t2 - t1) / max(1, len(frames)) * 1e3:.0f} "
                    "ms a frame)"
                )
                labels = np.array(vision.frame_move)
                ok = np.array(found, dtype=bool)
                for mv in protocol_moves(robot, cfg):
                    sel = labels == mv.label
                    v = mv.direction
                    s = (vision.frame_q[sel] - vision.session.reference_pose) @ v / (v @ v)
                    span = float(np.ptp(s)) if s.size else 0.0
                    shown = (
                        f"{math.degrees(span):.1f} deg" if mv.revolute else f"{span * 1e3:.1f} mm"
                    )
                    print(
                        f"  {mv.label}: {int(sel.sum())} frames ({int((sel & ok).sum())} "
                        f"detected) over {shown}"
                    )
                for warning in vision.warnings:
                    print(f"  warning: {warning}")


if __name__ == "__main__":
    main()
