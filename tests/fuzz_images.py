"""Seeded mutations of small simulated vision logs, read frame by frame and through the CLI.

Shared by ``tests/test_fuzz_images.py`` (a few dozen cases in CI) and ``benchmarks/fuzz.py
--kind images`` (long runs). The logs start as a small simulated vision session
(:func:`dhlog.simulator.camera.simulate_vision`: the KR5, eye-in-hand, four still poses, the
simulator's ChArUco board) rendered through the simulator's camera scaled to 640×400 (the same
field of view, so the same poses see the board), written by
:func:`dhlog.simulator.camera.write_vision_log` as JPEG ``CompressedImage`` frames, each with
``CameraInfo`` and joint states; the same log with the frames as PNG ``CompressedImage`` and as
raw mono8 ``Image`` is written by the mcap writer. The mutations come in four families:

* ``bytes``, ``records``, ``payloads``: ``tests/fuzzing.py``'s own (byte flips and cuts, lying
  records and chunks, message payloads rewritten inside their chunks);
* ``image``: image messages rewritten field by field and the log written again by the mcap
  writer: an ``Image``'s width, height, step, encoding, byte order or data length lying, its
  data cut or flipped; a JPEG or PNG cut (with or without JPEG's end marker), bytes flipped
  in it, its header's size lying (JPEG's SOF0, PNG's IHDR with its CRC made good), its format
  named wrong, a PNG (8- or 16-bit, BGRA, another size) in its place; a ``CameraInfo`` of
  another size, with NaN, infinite or zero K, 0 to 100 coefficients, an unknown model.

:func:`run_library` reads a case with :class:`dhlog.identify.camera.frames.images.ImageStream`
(every frame) and passes each frame to :func:`dhlog.identify.camera.frames.detect.detect` with the
simulator's board, without and with the log's intrinsics: frames, counted faults and rejections, or
a ``DhlogError`` of one line are the only outcomes allowed. :func:`run_cli` runs ``dhlog process``
on it: exit 2 with one line on stderr, nothing written.
"""

from __future__ import annotations

import dataclasses
import hashlib
import random
import struct
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fuzzing import Case, Outcome, _bytes_case, _payloads_case, _records_case

FAMILIES = ("bytes", "records", "payloads", "image")
FORMATS = ("jpeg", "png", "raw")
IMAGE_TOPICS = {
    "jpeg": "/camera/image_raw/compressed",
    "png": "/camera/image_raw/compressed",
    "raw": "/camera/image_raw",
}
INFO_TOPIC = "/camera/camera_info"
#: the simulator's camera scaled by this (1280×800 → 640×400)
SCALE = 0.5
POSES = 4
LIES = (0, 1, 7, 639, 641, 2**16, 2**31 - 1, 2**32 - 1)


@dataclass(frozen=True)
class Message:
    topic: str
    schema: str
    log_time: int
    data: bytes


@dataclass(frozen=True)
class Base:
    """The base logs (format → bytes, and their messages in order), their frames' pixels, the
    board."""

    logs: dict[str, bytes]
    messages: dict[str, tuple[Message, ...]]
    pixels: tuple[np.ndarray[Any, Any], ...]
    board: Any


def make_base(folder: Path) -> Base:
    """The small vision logs: the JPEG one as ``write_vision_log`` writes it (0.4 s to
    simulate, 0.9 s to render its 4 frames), the PNG and raw ones with the same frames (the
    JPEG's, decoded by OpenCV) and the same other messages, encoded by ``io.ros2`` and written
    by the mcap writer (each render costs 0.2 s)."""
    import cv2
    from mcap.reader import make_reader

    from dhlog.io import ros2
    from dhlog.model.robots import load_robot
    from dhlog.simulator.camera import simulate_vision, write_vision_log
    from dhlog.simulator.config import SimulationConfig
    from dhlog.vision.camera import Intrinsics

    folder.mkdir(parents=True, exist_ok=True)
    cfg = SimulationConfig(
        seed=1,
        poses=POSES,
        protocol="random-poses",
        joint_rate=20.0,
        instrument="camera",
        camera_setup="eye-in-hand",
    )
    vision = simulate_vision(load_robot("kr5"), cfg, "eye-in-hand", "jpeg")
    cam = vision.rig.camera
    K = cam.K.copy()
    K[:2] *= SCALE
    small = Intrinsics(round(cam.width * SCALE), round(cam.height * SCALE), K, cam.model,
                       cam.coefficients)  # fmt: skip
    vision = dataclasses.replace(vision, rig=dataclasses.replace(vision.rig, camera=small))
    path = folder / "vision_jpeg.mcap"
    write_vision_log(vision, path, cfg.seed)
    with path.open("rb") as f:
        jpeg = tuple(
            Message(c.topic, s.name if s else "", m.log_time, bytes(m.data))
            for s, c, m in make_reader(f).iter_messages()
        )
    frames = [m for m in jpeg if m.topic == IMAGE_TOPICS["jpeg"]]
    pixels = tuple(
        cv2.imdecode(np.frombuffer(_compressed_fields(m.data)[1], np.uint8), cv2.IMREAD_UNCHANGED)
        for m in frames
    )
    logs, messages = {"jpeg": path.read_bytes()}, {"jpeg": jpeg}
    for fmt in ("png", "raw"):
        out = []
        for m in jpeg:
            if m.topic == IMAGE_TOPICS["jpeg"]:
                img = pixels[frames.index(m)]
                if fmt == "raw":
                    data = ros2.encode_image(_stamp(m.data), "camera", img, "mono8")
                    m = Message(IMAGE_TOPICS["raw"], ros2.IMAGE, m.log_time, data)
                else:
                    png = cv2.imencode(".png", img)[1].tobytes()
                    data = ros2.encode_compressed_image(_stamp(m.data), "camera", png, "png")
                    m = dataclasses.replace(m, data=data)
            out.append(m)
        messages[fmt] = tuple(out)
        logs[fmt] = _write(out)
    return Base(logs, messages, pixels, vision.rig.board)


# ---------------------------------------------------------------------------- CDR offsets


def _align(pos: int, size: int) -> int:
    return 4 + (pos - 4 + size - 1) // size * size


def _after_header(data: bytes) -> int:
    """The offset after a message's std_msgs/Header (stamp, frame_id)."""
    (n,) = struct.unpack_from("<I", data, 12)
    return 16 + n


def _image_fields(data: bytes) -> dict[str, int]:
    """Offsets of an Image payload's fields (little-endian CDR, as dhlog writes it)."""
    pos = _align(_after_header(data), 4)
    out = {"height": pos, "width": pos + 4, "encoding": pos + 8}
    (n,) = struct.unpack_from("<I", data, pos + 8)
    pos += 12 + n
    out["is_bigendian"] = pos
    out["step"] = _align(pos + 1, 4)
    out["data"] = out["step"] + 4
    return out


def _compressed_fields(data: bytes) -> tuple[str, bytes]:
    """A CompressedImage payload's format and data."""
    pos = _align(_after_header(data), 4)
    (n,) = struct.unpack_from("<I", data, pos)
    fmt = data[pos + 4 : pos + 4 + n].rstrip(b"\0").decode()
    pos = _align(pos + 4 + n, 4)
    (m,) = struct.unpack_from("<I", data, pos)
    return fmt, data[pos + 4 : pos + 4 + m]


def _stamp(data: bytes) -> int:
    sec, nsec = struct.unpack_from("<iI", data, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


# ---------------------------------------------------------------------------- the image family


def _raw_case(data: bytes, pixels: np.ndarray[Any, Any], rng: random.Random) -> tuple[str, bytes]:
    from dhlog.io import ros2

    buf = bytearray(data)
    at = _image_fields(data)
    kind = rng.choice(
        ["width", "height", "step", "encoding", "is_bigendian", "data_length", "cut", "flip"]
    )
    if kind in ("width", "height", "step", "data_length"):
        lie = rng.choice(LIES)
        struct.pack_into("<I", buf, at[kind if kind != "data_length" else "data"], lie)
        return f"{kind}={lie}", bytes(buf)
    if kind == "encoding":
        name = rng.choice(
            ["rgb8", "bgra8", "mono16", "bayer_rggb16", "bayer_grbg8", "uyvy", "16UC1", "jpeg",
             "", "\x1b[31m", "x" * 5000]
        )  # fmt: skip
        return f"encoding={name[:12]!r}", ros2.encode_image(_stamp(data), "camera", pixels, name)
    if kind == "is_bigendian":
        buf[at["is_bigendian"]] = rng.choice([1, 2, 255])
        return "is_bigendian", bytes(buf)
    if kind == "cut":
        cut = rng.randrange(4, len(buf))
        return f"cut@{cut}", bytes(buf[:cut])
    for _ in range(rng.choice([1, 8, 64])):
        i = rng.randrange(len(buf))
        buf[i] ^= 1 << rng.randrange(8)
    return "flip", bytes(buf)


def _compressed_case(
    data: bytes, pixels: np.ndarray[Any, Any], rng: random.Random
) -> tuple[str, bytes]:
    import cv2

    from dhlog.io import ros2

    fmt, jpeg = _compressed_fields(data)
    stamp = _stamp(data)
    kind = rng.choice(["cut", "cut_ended", "flip", "flip_head", "sof", "format", "png"])
    out = bytearray(jpeg)
    if kind in ("cut", "cut_ended"):
        cut = rng.randrange(len(out))
        out = out[:cut] + (b"\xff\xd9" if kind == "cut_ended" else b"")
        kind = f"{kind}@{cut}"
    elif kind in ("flip", "flip_head"):
        hi = min(len(out), 700) if kind == "flip_head" else len(out)
        for _ in range(rng.choice([1, 4, 32])):
            i = rng.randrange(hi)
            out[i] ^= 1 << rng.randrange(8)
    elif kind == "sof":  # the frame header's height and width: JPEG's SOF0, PNG's IHDR
        h, w = rng.choice([0, 1, 8, 400, 4000, 20000, 65535]), rng.choice([0, 1, 8, 640, 65535])
        at = bytes(out).find(b"\xff\xc0")
        if bytes(out[:8]) == b"\x89PNG\r\n\x1a\n":  # IHDR: width, height; its CRC made good
            struct.pack_into(">II", out, 16, w, h)
            struct.pack_into(">I", out, 29, zlib.crc32(bytes(out[12:29])))
        elif at >= 0:
            struct.pack_into(">HH", out, at + 5, h, w)
        kind = f"sof={w}x{h}"
    elif kind == "format":
        fmt = rng.choice(
            ["png", "jpeg", "", "rgb8; jpeg compressed bgr8", "compressedDepth", "\xff" * 9]
        )
        kind = f"format={fmt[:12]!r}"
    else:
        size = rng.choice([(pixels.shape[1], pixels.shape[0]), (320, 200), (8, 8), (7, 3)])
        img = cv2.resize(pixels, size)
        if rng.random() < 0.5:
            img = img.astype(np.uint16) * 257
        if rng.random() < 0.3:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGRA)
        ok, png = cv2.imencode(".png", img)
        assert ok
        out = bytearray(png.tobytes())
        kind = f"png{size[0]}x{size[1]}{img.dtype}"
    return kind, ros2.encode_compressed_image(stamp, "camera", bytes(out), fmt)


def _info_case(data: bytes, rng: random.Random) -> tuple[str, bytes]:
    from dhlog.identify.camera.frames.imagedecode import camera_info_cdr
    from dhlog.io import ros2

    info = camera_info_cdr(data)
    w, h, model, d, k = info.width, info.height, info.distortion_model, list(info.d), info.k
    kind = rng.choice(["size", "nan", "zero_k", "coefficients", "model"])
    if kind == "size":
        w, h = rng.choice([(1280, 800), (0, 0), (641, 400), (2**31 - 1, 1)])
        kind = f"size={w}x{h}"
    elif kind == "nan":
        k = k.copy()
        k[rng.randrange(2), rng.randrange(3)] = rng.choice([np.nan, np.inf, -1e308])
    elif kind == "zero_k":
        k = np.zeros((3, 3))
    elif kind == "coefficients":
        d = [rng.uniform(-1e3, 1e3) for _ in range(rng.choice([0, 1, 3, 100]))]
        kind = f"coefficients={len(d)}"
    else:
        model = rng.choice(["equidistant", "rational_polynomial", "fisheye", "", "\x00x"])
        kind = f"model={model!r}"
    return f"info_{kind}", ros2.encode_camera_info(
        ros2.CameraInfo.unrectified(info.stamp_ns, info.frame_id, (w, h), model, d, k.ravel())
    )


def _write(messages: list[Message]) -> bytes:
    import io

    from mcap.writer import CompressionType, Writer

    from dhlog.io import ros2

    f = io.BytesIO()
    writer = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD, enable_crcs=False)
    writer.start(profile="ros2", library="dhlog fuzz")
    channels: dict[str, int] = {}
    for m in messages:
        if m.topic not in channels:
            sid = writer.register_schema(m.schema, "ros2msg", ros2.MSGDEFS[m.schema].encode())
            channels[m.topic] = writer.register_channel(m.topic, "cdr", sid)
        writer.add_message(channels[m.topic], m.log_time, m.data, m.log_time)
    writer.finish()  # type: ignore[no-untyped-call]
    return f.getvalue()


def _image_case(base: Base, fmt: str, rng: random.Random) -> tuple[str, bytes]:
    """Some of the log's image (or camera-info) messages rewritten, the log written again."""
    messages = list(base.messages[fmt])
    topic = INFO_TOPIC if rng.random() < 0.2 else IMAGE_TOPICS[fmt]
    at = [i for i, m in enumerate(messages) if m.topic == topic]
    chosen = sorted(rng.sample(range(len(at)), rng.choice([1, 1, 2, len(at)])))
    names = []
    for j in chosen:
        m = messages[at[j]]
        if topic == INFO_TOPIC:
            name, data = _info_case(m.data, rng)
        elif fmt == "raw":
            name, data = _raw_case(m.data, base.pixels[j], rng)
        else:
            name, data = _compressed_case(m.data, base.pixels[j], rng)
        names.append(f"{j}:{name}")
        messages[at[j]] = dataclasses.replace(m, data=data)
    return ",".join(names), _write(messages)


def cases(n: int, seed: int, base: Base, families: tuple[str, ...] = FAMILIES) -> Any:
    """``n`` seeded cases, families in turn, formats at random."""
    rng = random.Random(seed)
    for k in range(n):
        family = families[k % len(families)]
        fmt = rng.choice(FORMATS)
        data = base.logs[fmt]
        if family == "bytes":
            name, out = _bytes_case(data, rng)
        elif family == "records":
            name, out = _records_case(data, rng)
        elif family == "payloads":
            name, out = _payloads_case(data, rng, "ros2")
        else:
            name, out = _image_case(base, fmt, rng)
        yield Case(family, f"images/{family}/{fmt}/{name[:200]}#{k}", out)


# ---------------------------------------------------------------------------- running


def _fmt(case: Case) -> str:
    return case.name.split("/")[2]


def run_library(case: Case, folder: Path, board: Any) -> Outcome:
    """Every frame of ``case`` read by ``ImageStream`` and passed to ``detect`` (without the
    log's intrinsics, then with them where they build an ``Intrinsics``)."""
    import traceback

    from dhlog.errors import DhlogError
    from dhlog.identify.camera.frames.detect import Detection, Rejected, detect
    from dhlog.identify.camera.frames.images import ImageStream
    from dhlog.vision.camera import Intrinsics

    log = folder / "case.mcap"
    log.write_bytes(case.data)
    problems: list[str] = []
    text = ""
    start = time.monotonic()
    code = 0
    try:
        stream = ImageStream(log, IMAGE_TOPICS[_fmt(case)], INFO_TOPIC)
        frames = [frame.pixels for frame in stream]
        if len(frames) + len(stream.faults) != stream.count:
            problems.append(f"{len(frames)} frames + {len(stream.faults)} faults != {stream.count}")
        warning = stream.warning()
        if warning is not None and "\n" in warning:
            problems.append("warning of several lines")
        text = warning or ""
        cameras: list[Any] = [None]
        if stream.infos:
            info = stream.infos[0]
            try:
                cameras.append(
                    Intrinsics.from_camera_info(
                        info.width, info.height, info.distortion_model, info.d, info.k
                    )
                )
            except DhlogError as exc:  # the intrinsics refused: one line, named
                if "\n" in str(exc).strip():
                    problems.append("intrinsics error of several lines")
                text = f"{text} | {exc}"
        for pixels in frames:
            for camera in cameras:
                found = detect(pixels, board, camera=camera)
                if not isinstance(found, Detection | Rejected):
                    problems.append(f"detect returned {type(found).__name__}")
    except DhlogError as exc:
        code, text = 2, str(exc)
    except Exception as exc:
        code = 1
        problems.append("traceback")
        text = "".join(traceback.format_exception(exc))
    if code == 2 and (not text.strip() or "\n" in text.strip()):
        problems.append("error of several lines" if text.strip() else "empty error")
    if "Traceback" in text and "traceback" not in problems:
        problems.append("traceback")
    seconds = time.monotonic() - start
    return Outcome(case.name, case.family, code, tuple(problems), text.strip()[-600:], seconds)


def run_cli(case: Case, folder: Path) -> Outcome:
    """``dhlog process LOG --no-rrd --out DIR`` in this process: exit 2, one line on stderr,
    the input unchanged, nothing written."""
    from fuzzing import invoke

    log = folder / "case.mcap"
    log.write_bytes(case.data)
    out = folder / "out"
    before = hashlib.sha256(case.data).hexdigest()
    done = invoke(["process", str(log), "--no-rrd", "--out", str(out)], timeout=60.0)
    if done is None:
        return Outcome(case.name, case.family, -9, ("hang",), "")
    problems = []
    if done.crashed or "Traceback" in done.stderr:
        problems.append("traceback")
    if done.code != 2:
        problems.append(f"exit {done.code}")
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    if len(lines) != 1:
        problems.append(f"{len(lines)} lines on stderr")
    if hashlib.sha256(log.read_bytes()).hexdigest() != before:
        problems.append("input modified")
    if out.exists() and any(out.iterdir()):
        problems.append(f"partial output {sorted(p.name for p in out.iterdir())}")
    return Outcome(
        case.name, case.family, done.code, tuple(problems), done.stderr.strip()[-600:],
        done.seconds,
    )  # fmt: skip


def run_case(case: Case, folder: Path, timeout: float = 60.0) -> Outcome:
    """The long runs' (``benchmarks/fuzz.py --kind images``): :func:`run_library` with the
    simulator's board, then :func:`run_cli`; their problems together."""
    from dhlog.simulator.camera import BOARD
    from fuzzing import Hang, time_limit

    try:
        with time_limit(timeout):
            lib = run_library(case, folder, BOARD)
    except Hang:
        return Outcome(case.name, case.family, -9, ("hang (library)",), "")
    cli = run_cli(case, folder)
    problems = tuple(f"library: {p}" for p in lib.problems) + cli.problems
    text = lib.stderr if lib.problems else cli.stderr
    return Outcome(case.name, case.family, cli.exit_code, problems, text, lib.seconds + cli.seconds)
