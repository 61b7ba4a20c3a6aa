"""Peak memory and speed of reading a camera topic of full-HD JPEG frames (issue 32, item 1).

    .venv/bin/python benchmarks/images_memory.py write [--frames 300] [--raw]
    /usr/bin/time -f %M .venv/bin/python benchmarks/images_memory.py read [--frames 300] [--raw]

``write`` makes (once, cached in $TMPDIR/dhlog-bench) a ROS 2 MCAP of ``--frames`` 1920x1080
CompressedImage JPEG frames (quality 90; ``--raw``: bgr8 Image frames, 6.2 MB each) at 30 Hz and a
CameraInfo, as a camera driver records them (the mcap writer's default 1 MiB zstd chunks). ``read``
walks the topic with ``dhlog.identify.camera.frames.images.ImageStream`` and prints the frames,
their mean, the file's size, the wall time and the Python heap's peak (tracemalloc is off: it would
slow the walk; ``/usr/bin/time -f %M`` gives the process's peak RSS in KiB).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from mcap.writer import CompressionType, Writer

from dhlog.identify.camera.frames.images import ImageStream
from dhlog.io import ros2

S = 1_000_000_000


def log_path(frames: int, raw: bool) -> Path:
    folder = Path(os.environ.get("TMPDIR", tempfile.gettempdir())) / "dhlog-bench"
    folder.mkdir(parents=True, exist_ok=True)
    return folder / f"camera_{'raw' if raw else 'jpeg'}_{frames}.mcap"


def write(frames: int, raw: bool) -> Path:
    path = log_path(frames, raw)
    if path.exists():
        return path
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:1080, 0:1920]
    base = np.stack([x // 8, y // 5, (x + y) // 12], axis=-1).astype(np.uint8)
    base = cv2.add(base, rng.integers(0, 24, base.shape, dtype=np.uint8))  # sensor noise
    k = [1400.0, 0.0, 960.0, 0.0, 1400.0, 540.0, 0.0, 0.0, 1.0]
    part = path.with_suffix(".part")
    with open(part, "wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="dhlog benchmark")
        schema = ros2.IMAGE if raw else ros2.COMPRESSED_IMAGE
        sid = writer.register_schema(schema, "ros2msg", ros2.MSGDEFS[schema].encode())
        iid = writer.register_schema(
            ros2.CAMERA_INFO, "ros2msg", ros2.MSGDEFS[ros2.CAMERA_INFO].encode()
        )
        image = writer.register_channel("/camera/image", "cdr", sid)
        info = writer.register_channel("/camera/camera_info", "cdr", iid)
        for i in range(frames):
            t = 10 * S + i * S // 30
            img = np.roll(base, 7 * i, axis=1)
            cv2.circle(img, (960 + 300 * (i % 3), 540), 200, (255, 255, 255), -1)
            if raw:
                payload = ros2.encode_image(t, "camera", img, "bgr8")
            else:
                jpeg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
                payload = ros2.encode_compressed_image(t, "camera", jpeg, "jpeg")
            writer.add_message(image, t, payload, t)
            if i % 30 == 0:
                cam = ros2.encode_camera_info(
                    ros2.CameraInfo.unrectified(
                        t, "camera", (1920, 1080), "plumb_bob", [0.0] * 5, k
                    )
                )
                writer.add_message(info, t, cam, t)
        writer.finish()  # type: ignore[no-untyped-call]
    part.rename(path)
    return path


def read(frames: int, raw: bool) -> None:
    path = log_path(frames, raw)
    if not path.exists():
        raise SystemExit(f"{path}: no log; run '{__file__} write' first")
    start = time.perf_counter()
    stream = ImageStream(path, "/camera/image", "/camera/camera_info")
    n, total = 0, 0.0
    for frame in stream:
        n += 1
        total += float(frame.pixels[::8, ::8].mean())
    wall = time.perf_counter() - start
    size = path.stat().st_size / 2**20
    print(
        f"{n} frames ({len(stream.faults)} faults, {len(stream.infos)} camera infos), "
        f"mean {total / max(n, 1):.2f}, file {size:.0f} MiB, {wall:.2f} s, "
        f"{n / wall:.1f} frames/s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["write", "read"])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--raw", action="store_true")
    args = parser.parse_args()
    if args.what == "write":
        print(write(args.frames, args.raw))
    else:
        read(args.frames, args.raw)


if __name__ == "__main__":
    main()
