"""Target detection at issue 32's benchmark set-up: speed and corner accuracy (items 1–2).

    .venv/bin/python benchmarks/vision_detect.py [--frames 8] [--distance 2.0] [--jpeg 90]

A 1920×1080 camera (f = 1600 px, plumb_bob k1 = −0.1) sees a ChArUco board of about 0.3 m
(10×7 squares of 30 mm, 22 mm DICT_5X5_100 markers) ``--distance`` m away at random poses
(tilts up to 35°, any turn), rendered as tests/test_vision.py renders (every pixel undistorted
onto the board plane, the flat drawing remapped bilinearly), with Gaussian noise of 2 grey levels
and, with ``--jpeg Q``, a JPEG round trip at quality Q (``cv2.imencode``/``imdecode``, as a
CompressedImage topic holds it). For each frame ``dhlog.identify.camera.frames.detect.detect`` runs
with and without the intrinsics; printed: the corners found, their RMS and largest distance (px)
from the true projections, and the median time of a detection (the rendering is not timed).
Then the time of a frame without the board: a blank one, one of clutter (the first frame cut
in 60 px tiles and shuffled: pieces of markers and squares, and some whole markers) and one of
uniform noise.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dhlog.identify.camera.frames.detect import Detection, detect
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics
from test_vision import errors, render, rotation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--distance", type=float, default=2.0)
    parser.add_argument("--jpeg", type=int, default=0, help="JPEG quality (0: raw)")
    args = parser.parse_args()
    K = np.array([[1600.0, 0, 959.5], [0, 1600.0, 539.5], [0, 0, 1]])
    cam = Intrinsics(1920, 1080, K, "plumb_bob", np.array([-0.1, 0.0, 0.0, 0.0, 0.0]))
    board = BoardSpec(squares=(10, 7), square_m=0.03, marker_m=0.022)
    rng = np.random.default_rng(7)
    rows = {"without camera": [], "with camera": []}
    times = {"without camera": [], "with camera": []}
    images = []
    for i in range(args.frames):
        tilt = rng.uniform(-0.6, 0.6, 2)
        R = rotation(tilt[0], tilt[1], rng.uniform(-np.pi, np.pi))
        w, h = board.size_m
        offset = np.array([*rng.uniform(-0.3, 0.3, 2), args.distance])
        t = -R @ np.array([w / 2, h / 2, 0.0]) + offset
        image = render(cam, board, R, t, px_per_m=1600 * 1.2 / args.distance, noise=2.0, seed=i)
        if args.jpeg:
            _, buf = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, args.jpeg])
            image = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
        images.append(image)
        for label, camera in (("without camera", None), ("with camera", cam)):
            start = time.perf_counter()
            found = detect(image, board, camera=camera)
            times[label].append(time.perf_counter() - start)
            if isinstance(found, Detection):
                e = errors(cam, found, R, t, board)
                rows[label].append((len(found), float(np.sqrt(np.mean(e**2))), float(e.max())))
            else:
                rows[label].append((0, float("nan"), float("nan")))
                print(f"frame {i} {label}: {found.reason} ({found.detail})")
    total = len(board.object_points())
    for label in rows:
        found = [r for r in rows[label] if r[0]]
        n = sum(r[0] for r in found)
        rms = np.sqrt(np.mean([r[1] ** 2 for r in found])) if found else float("nan")
        worst = max((r[2] for r in found), default=float("nan"))
        print(
            f"{label}: {len(found)}/{args.frames} frames, {n}/{total * args.frames} corners, "
            f"RMS {rms:.3f} px, max {worst:.3f} px, "
            f"median {1e3 * statistics.median(times[label]):.1f} ms a frame"
        )
    blank = np.full((1080, 1920), 128, np.uint8)
    tiles = images[0].reshape(1080 // 60, 60, 1920 // 60, 60).swapaxes(1, 2).reshape(-1, 60, 60)
    clutter = tiles[rng.permutation(len(tiles))].reshape(18, 32, 60, 60).swapaxes(1, 2)
    clutter = np.ascontiguousarray(clutter.reshape(1080, 1920))
    noise = rng.integers(0, 256, (1080, 1920), dtype=np.uint8)
    for name, image in (("blank", blank), ("clutter", clutter), ("noise", noise)):
        spent = []
        for _ in range(3):
            start = time.perf_counter()
            outcome = detect(image, board, camera=cam)
            spent.append(time.perf_counter() - start)
        reason = getattr(outcome, "reason", "detected")
        print(f"{name} frame: {reason}, median {1e3 * statistics.median(spent):.1f} ms")


if __name__ == "__main__":
    main()
