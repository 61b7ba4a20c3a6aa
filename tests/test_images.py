"""Camera images and intrinsics read back from MCAP logs written by the real ``mcap`` writer
(issue 32, item 1): every raw encoding, JPEG and PNG from ``cv2.imencode``, CameraInfo, the
Foxglove messages in JSON and protobuf; faults counted and named, never raised; the CDR written
checked against the rosbags library's (de)serialiser."""

from __future__ import annotations

import base64
import json
import struct
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mcap.writer import CompressionType, Writer
from numpy.typing import NDArray

from dhlog.errors import InputError, MissingTopicError, NotMcapError
from dhlog.identify.camera.frames.imagedecode import CameraImage, camera_info_cdr
from dhlog.identify.camera.frames.images import ImageStream, read_camera_infos
from dhlog.io import ros2

S = 1_000_000_000
K = np.array([[800.0, 0.0, 320.5], [0.0, 805.0, 240.25], [0.0, 0.0, 1.0]])
D = [-0.21, 0.05, 0.001, -0.002, 0.01]


def scene(h: int = 48, w: int = 64) -> NDArray[np.uint8]:
    """A smooth colour image with edges (BGR): what a camera sees, and what JPEG keeps."""
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([2 * x + 40, 3 * y + 20, (x + y) + 60], axis=-1).astype(np.uint8)
    img[h // 4 : h // 2, w // 4 : w // 2] = (30, 200, 90)
    return img


def psnr(a: NDArray[Any], b: NDArray[Any]) -> float:
    mse = float(np.mean((a.astype(float) - b.astype(float)) ** 2))
    return 10 * np.log10(255.0**2 / mse) if mse else float("inf")


def write_log(path: Path, topics: dict[str, tuple[str, list[bytes]]], **kw: Any) -> None:
    """One CDR channel per topic (schema name, payloads); message i at i/10 s log time."""
    with open(path, "wb") as f:
        writer = Writer(f, **kw)
        writer.start(profile="ros2", library="dhlog test")
        for topic, (schema, payloads) in topics.items():
            sid = writer.register_schema(schema, "ros2msg", ros2.MSGDEFS[schema].encode())
            cid = writer.register_channel(topic, "cdr", sid)
            for i, payload in enumerate(payloads):
                writer.add_message(cid, (100 + i) * S // 10, payload, (100 + i) * S // 10)
        writer.finish()  # type: ignore[no-untyped-call]


def read(path: Path, topic: str, **kw: Any) -> tuple[list[CameraImage], ImageStream]:
    stream = ImageStream(path, topic, **kw)
    return list(stream), stream


def test_raw_encodings_round_trip(tmp_path: Path) -> None:
    bgr = scene()
    grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    deep = (grey.astype(np.uint16) * 257 + 3).astype(np.uint16)  # uses both bytes
    as_written = {
        "mono8": (grey, grey),
        "mono16": (deep, deep),
        "bgr8": (bgr, bgr),
        "rgb8": (bgr[:, :, ::-1], bgr),
        "bgra8": (cv2.cvtColor(bgr, cv2.COLOR_BGR2BGRA), bgr),
        "rgba8": (cv2.cvtColor(bgr, cv2.COLOR_BGR2RGBA), bgr),
    }
    topics = {}
    for encoding, (pixels, _) in as_written.items():
        payloads = [
            ros2.encode_image(5 * S + 7, "cam_optical", pixels, encoding),
            ros2.encode_image(6 * S, "cam_optical", pixels, encoding, step=pixels[0].nbytes + 6),
        ]
        topics[f"/{encoding}"] = (ros2.IMAGE, payloads)
    path = tmp_path / "raw.mcap"
    write_log(path, topics)
    for encoding, (_, expected) in as_written.items():
        frames, stream = read(path, f"/{encoding}")
        assert stream.warning() is None, encoding
        assert [f.stamp_ns for f in frames] == [5 * S + 7, 6 * S]  # the padded row too
        for frame in frames:
            assert frame.frame_id == "cam_optical"
            assert frame.pixels.dtype == expected.dtype and frame.pixels.flags.c_contiguous
            np.testing.assert_array_equal(frame.pixels, expected, err_msg=encoding)


def _is_bigendian_at(payload: bytes) -> int:
    """Offset of an Image payload's ``is_bigendian`` byte."""
    (flen,) = struct.unpack_from("<I", payload, 12)
    p = 4 + ((8 + 4 + flen + 3) // 4 * 4) + 8
    (elen,) = struct.unpack_from("<I", payload, p)
    return p + 4 + elen


def test_big_endian_mono16_and_big_endian_cdr(tmp_path: Path) -> None:
    deep = (np.arange(48 * 64, dtype=np.uint16).reshape(48, 64) * 21).astype(np.uint16)
    payload = bytearray(ros2.encode_image(S, "cam", deep.byteswap(), "mono16"))
    payload[_is_bigendian_at(bytes(payload))] = 1
    # the same message as big-endian CDR, from the rosbags library's serialiser
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    msg = store.deserialize_cdr(ros2.encode_image(2 * S, "cam", deep, "mono16"), ros2.IMAGE)
    big_cdr = store.serialize_cdr(msg, ros2.IMAGE, little_endian=False)
    assert big_cdr[1] == 0  # CDR_BE
    path = tmp_path / "be.mcap"
    write_log(path, {"/depth": (ros2.IMAGE, [bytes(payload), bytes(big_cdr)])})
    frames, stream = read(path, "/depth")
    assert stream.warning() is None and len(frames) == 2
    for frame in frames:
        assert frame.pixels.dtype == np.uint16
        np.testing.assert_array_equal(frame.pixels, deep)


@pytest.mark.parametrize(
    ("encoding", "rows", "cols"),
    [
        ("bayer_rggb8", "RG", "GB"),
        ("bayer_bggr8", "BG", "GR"),
        ("bayer_gbrg8", "GB", "RG"),
        ("bayer_grbg8", "GR", "BG"),
    ],
)
def test_bayer_patterns_give_the_colours_of_the_scene(
    tmp_path: Path, encoding: str, rows: str, cols: str
) -> None:
    """A mosaic of flat colour patches, demosaiced: each patch's inside has its colour (a
    pattern read the wrong way round swaps red and blue)."""
    colours = np.array([[200, 40, 10], [10, 180, 60], [30, 60, 220], [120, 120, 120]], np.uint8)
    h = w = 32
    bgr = np.zeros((h, w, 3), np.uint8)
    for i, c in enumerate(colours):
        bgr[(i // 2) * 16 : (i // 2 + 1) * 16, (i % 2) * 16 : (i % 2 + 1) * 16] = c
    channel = {"B": 0, "G": 1, "R": 2}
    pattern = [[channel[rows[0]], channel[rows[1]]], [channel[cols[0]], channel[cols[1]]]]
    mosaic = np.zeros((h, w), np.uint8)
    for dy in (0, 1):
        for dx in (0, 1):
            mosaic[dy::2, dx::2] = bgr[dy::2, dx::2, pattern[dy][dx]]
    path = tmp_path / "bayer.mcap"
    write_log(path, {"/raw": (ros2.IMAGE, [ros2.encode_image(S, "cam", mosaic, encoding)])})
    (frame,), stream = read(path, "/raw")
    assert stream.warning() is None and frame.pixels.shape == (h, w, 3)
    for i, c in enumerate(colours):  # the inside of each patch, 3 px from its edges
        y0, x0 = (i // 2) * 16, (i % 2) * 16
        inside = frame.pixels[y0 + 3 : y0 + 13, x0 + 3 : x0 + 13].reshape(-1, 3).astype(int)
        assert np.abs(inside - c).max() <= 1, (encoding, c, inside.mean(axis=0))


def test_compressed_jpeg_and_png(tmp_path: Path) -> None:
    bgr = scene()
    deep = (cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.uint16) * 250).astype(np.uint16)
    jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes()
    png = cv2.imencode(".png", bgr)[1].tobytes()
    png16 = cv2.imencode(".png", deep)[1].tobytes()
    payloads = [
        ros2.encode_compressed_image(S, "cam", jpeg, "jpeg"),
        ros2.encode_compressed_image(2 * S, "cam", png, "png"),
        ros2.encode_compressed_image(3 * S, "cam", jpeg, "rgb8; jpeg compressed bgr8"),
        ros2.encode_compressed_image(4 * S, "cam", png16, "16UC1; png compressed"),
    ]
    path = tmp_path / "compressed.mcap"
    write_log(path, {"/cam/compressed": (ros2.COMPRESSED_IMAGE, payloads)})
    frames, stream = read(path, "/cam/compressed")
    assert stream.warning() is None
    assert [f.stamp_ns for f in frames] == [S, 2 * S, 3 * S, 4 * S]
    assert frames[0].pixels.shape == bgr.shape and psnr(frames[0].pixels, bgr) > 35
    np.testing.assert_array_equal(frames[1].pixels, bgr)  # PNG: lossless
    np.testing.assert_array_equal(frames[2].pixels, frames[0].pixels)
    assert frames[3].pixels.dtype == np.uint16
    np.testing.assert_array_equal(frames[3].pixels, deep)


def test_camera_info_in_the_walk_and_alone(tmp_path: Path) -> None:
    r = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    p = np.hstack([K * 1.01, [[1.5], [2.5], [0.0]]])
    info = ros2.encode_camera_info(
        replace(
            ros2.CameraInfo.unrectified(7 * S, "cam_optical", (640, 480), "plumb_bob", D, K),
            r=r,
            p=p,
        )
    )
    eight = ros2.encode_camera_info(
        ros2.CameraInfo.unrectified(
            8 * S, "cam_optical", (640, 480), "rational_polynomial", [*D, 0.0, 0.0, 0.001], K
        )
    )
    path = tmp_path / "info.mcap"
    image = ros2.encode_image(7 * S, "cam_optical", scene(), "bgr8")
    write_log(
        path,
        {
            "/cam/image_raw": (ros2.IMAGE, [image]),
            "/cam/camera_info": (ros2.CAMERA_INFO, [info, eight]),
        },
    )
    stream = ImageStream(path, "/cam/image_raw", "/cam/camera_info")
    assert len(list(stream)) == 1
    for found in (stream.infos, read_camera_infos(path, "/cam/camera_info")):
        first, second = found
        assert (first.width, first.height, first.frame_id) == (640, 480, "cam_optical")
        assert first.stamp_ns == 7 * S and first.distortion_model == "plumb_bob"
        assert first.d == tuple(D)
        np.testing.assert_array_equal(first.k, K)
        np.testing.assert_array_equal(first.r, r)
        np.testing.assert_array_equal(first.p, p)
        assert second.distortion_model == "rational_polynomial" and len(second.d) == 8
        np.testing.assert_array_equal(second.p[:, :3], K)  # [K | 0] by default
        np.testing.assert_array_equal(second.r, np.eye(3))


def test_faults_are_counted_and_named_not_raised(tmp_path: Path) -> None:
    bgr = scene()
    jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
    garbage = jpeg[:3] + bytes(np.random.default_rng(1).integers(0, 256, 600, np.uint8)) + jpeg[-2:]
    raw_ok = ros2.encode_image(S, "cam", bgr, "bgr8")
    truncated_raw = raw_ok[:-100]
    lying_height = bytearray(raw_ok)  # height 49 where the data hold 48 rows
    flen = struct.unpack_from("<I", raw_ok, 12)[0]
    struct.pack_into("<I", lying_height, 4 + (12 + flen + 3) // 4 * 4, 49)
    raw_topic = [
        raw_ok,
        truncated_raw,
        bytes(lying_height),
        ros2.encode_image(S, "c", bgr, "yuv444x"),
        raw_ok,
    ]
    compressed_topic = [
        ros2.encode_compressed_image(S, "cam", jpeg, "jpeg"),
        ros2.encode_compressed_image(S, "cam", garbage, "jpeg"),
        ros2.encode_compressed_image(S, "cam", jpeg[: len(jpeg) // 2], "jpeg"),
        ros2.encode_compressed_image(S, "cam", b"", "png"),
    ]
    path = tmp_path / "bad.mcap"
    write_log(
        path,
        {"/raw": (ros2.IMAGE, raw_topic), "/compressed": (ros2.COMPRESSED_IMAGE, compressed_topic)},
    )
    frames, stream = read(path, "/raw")
    assert [f.index for f in frames] == [0, 4] and stream.count == 5
    reasons = stream.faults.by_reason
    assert reasons["size does not match width x height x channels"] == (2,)
    assert reasons["unknown encoding 'yuv444x'"] == (3,)
    assert sorted(i for indices in reasons.values() for i in indices) == [1, 2, 3]
    line = stream.warning()
    assert line is not None and "\n" not in line and "3 of 5 frame(s) on /raw" in line
    assert "frame 3" in line and str(path) in line
    frames, stream = read(path, "/compressed")
    assert [f.index for f in frames] == [0] and len(stream.faults) == 3
    assert stream.faults.by_reason["corrupt JPEG"] == (1,)
    assert stream.faults.by_reason["truncated JPEG (no end marker)"] == (2,)
    assert stream.faults.by_reason["corrupt PNG"] == (3,)


def test_cdr_against_the_rosbags_library() -> None:
    """What dhlog writes, rosbags reads; what rosbags writes, dhlog reads (a real peer)."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    bgr = scene()
    msg = store.deserialize_cdr(
        ros2.encode_image(3 * S + 9, "cam", bgr, "bgr8", step=200), ros2.IMAGE
    )
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (3, 9, "cam")
    assert (msg.height, msg.width, msg.encoding, msg.step, msg.is_bigendian) == (
        48,
        64,
        "bgr8",
        200,
        0,
    )
    np.testing.assert_array_equal(msg.data.reshape(48, 200)[:, :192].reshape(48, 64, 3), bgr)
    png = cv2.imencode(".png", bgr)[1].tobytes()
    msg_c = store.deserialize_cdr(
        ros2.encode_compressed_image(S, "cam", png, "png"), ros2.COMPRESSED_IMAGE
    )
    assert msg_c.format == "png" and msg_c.data.tobytes() == png
    msg_i = store.deserialize_cdr(
        ros2.encode_camera_info(
            ros2.CameraInfo.unrectified(S, "cam", (640, 480), "equidistant", D[:4], K)
        ),
        ros2.CAMERA_INFO,
    )
    assert (msg_i.width, msg_i.height, msg_i.distortion_model) == (640, 480, "equidistant")
    np.testing.assert_array_equal(msg_i.d, D[:4])
    np.testing.assert_array_equal(msg_i.k.reshape(3, 3), K)
    # the other way: rosbags' serialisation of a CameraInfo with a region of interest and binning
    msg_i.binning_x, msg_i.roi.width, msg_i.roi.do_rectify = 2, 100, True
    for little in (True, False):
        back = camera_info_cdr(store.serialize_cdr(msg_i, ros2.CAMERA_INFO, little_endian=little))
        assert (back.width, back.height, back.frame_id, back.stamp_ns) == (640, 480, "cam", S)
        assert back.d == tuple(D[:4])
        np.testing.assert_array_equal(back.k, K)
    # the schema text registered is one the mcap library's ROS 2 decoder parses
    from dhlog.io.decode.messages import message_decoder
    from dhlog.io.mcapwalk import ChannelInfo

    for name, payload in [
        (ros2.IMAGE, ros2.encode_image(S, "cam", bgr, "bgr8")),
        (ros2.COMPRESSED_IMAGE, ros2.encode_compressed_image(S, "cam", png, "png")),
        (
            ros2.CAMERA_INFO,
            ros2.encode_camera_info(
                ros2.CameraInfo.unrectified(S, "cam", (640, 480), "plumb_bob", D, K)
            ),
        ),
    ]:
        info = ChannelInfo(1, "/t", "cdr", name, "ros2msg", ros2.MSGDEFS[name].encode())
        decode = message_decoder(info)
        assert decode is not None
        assert decode(payload).header.frame_id == "cam"


def _foxglove_messages(bgr: NDArray[np.uint8]) -> dict[str, dict[str, Any]]:
    png = cv2.imencode(".png", bgr)[1].tobytes()
    stamp = {"sec": 12, "nsec": 345}
    return {
        "foxglove.CompressedImage": {
            "timestamp": stamp,
            "frame_id": "cam",
            "format": "png",
            "data": png,
        },
        "foxglove.RawImage": {
            "timestamp": stamp,
            "frame_id": "cam",
            "width": 64,
            "height": 48,
            "encoding": "rgb8",
            "step": 64 * 3,
            "data": bgr[:, :, ::-1].tobytes(),
        },
        "foxglove.CameraCalibration": {
            "timestamp": stamp,
            "frame_id": "cam",
            "width": 640,
            "height": 480,
            "distortion_model": "plumb_bob",
            "D": D,
            "K": K.reshape(-1).tolist(),
            "R": np.eye(3).reshape(-1).tolist(),
            "P": np.hstack([K, np.zeros((3, 1))]).reshape(-1).tolist(),
        },
    }


def _check_foxglove(path: Path, bgr: NDArray[np.uint8]) -> None:
    for topic in ("/compressed", "/raw"):
        stream = ImageStream(path, topic, "/calibration")
        (frame,) = list(stream)
        assert stream.warning() is None
        assert (frame.stamp_ns, frame.frame_id) == (12 * S + 345, "cam")
        np.testing.assert_array_equal(frame.pixels, bgr)
        (info,) = stream.infos
        assert (info.width, info.height, info.distortion_model, info.frame_id) == (
            640,
            480,
            "plumb_bob",
            "cam",
        )
        assert info.d == tuple(D) and info.stamp_ns == 12 * S + 345
        np.testing.assert_array_equal(info.k, K)


def test_foxglove_json(tmp_path: Path) -> None:
    bgr = scene()
    path = tmp_path / "foxglove.mcap"
    topics = {
        "foxglove.CompressedImage": "/compressed",
        "foxglove.RawImage": "/raw",
        "foxglove.CameraCalibration": "/calibration",
    }
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="dhlog test")
        for name, msg in _foxglove_messages(bgr).items():
            sid = writer.register_schema(name, "jsonschema", b"{}")
            cid = writer.register_channel(topics[name], "json", sid)
            if "data" in msg:
                msg = {**msg, "data": base64.b64encode(msg["data"]).decode()}
            writer.add_message(cid, S, json.dumps(msg).encode(), S)
        writer.finish()  # type: ignore[no-untyped-call]
    _check_foxglove(path, bgr)


def test_foxglove_protobuf(tmp_path: Path) -> None:
    from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
    from google.protobuf.timestamp_pb2 import Timestamp
    from mcap_protobuf.schema import register_schema

    bgr = scene()
    path = tmp_path / "foxglove.mcap"
    kinds = {
        "foxglove.CompressedImage": (CompressedImage, "/compressed"),
        "foxglove.RawImage": (RawImage, "/raw"),
        "foxglove.CameraCalibration": (CameraCalibration, "/calibration"),
    }
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="protobuf", library="dhlog test")
        for name, msg in _foxglove_messages(bgr).items():
            kind, topic = kinds[name]
            cid = writer.register_channel(topic, "protobuf", register_schema(writer, kind))
            fields = {**msg, "timestamp": Timestamp(seconds=12, nanos=345)}
            writer.add_message(cid, S, kind(**fields).SerializeToString(), S)
        writer.finish()  # type: ignore[no-untyped-call]
    _check_foxglove(path, bgr)


def test_a_long_topic_a_batch_at_a_time(tmp_path: Path) -> None:
    """Many chunks, batches bounded by ``batch_bytes``, the frames in order; a consumer that
    stops early ends the walk's thread."""
    bgr = scene()
    frames_in = [np.roll(bgr, i, axis=1) for i in range(60)]
    payloads = [ros2.encode_image(S + i, "cam", img, "bgr8") for i, img in enumerate(frames_in)]
    path = tmp_path / "long.mcap"
    write_log(
        path, {"/cam": (ros2.IMAGE, payloads)}, chunk_size=20_000, compression=CompressionType.ZSTD
    )
    stream = ImageStream(path, "/cam", batch_bytes=3 * bgr.nbytes)
    batches = list(stream.batches())
    assert len(batches) >= 20 and max(len(b) for b in batches) <= 3
    got = [f for b in batches for f in b]
    assert len(list(stream)) == 60 and stream.count == 60  # walked again, counted afresh
    assert [f.index for f in got] == list(range(60))
    assert [f.stamp_ns for f in got] == [S + i for i in range(60)]
    for frame, img in zip(got, frames_in, strict=True):
        np.testing.assert_array_equal(frame.pixels, img)
    before = threading.active_count()
    early = iter(ImageStream(path, "/cam", batch_bytes=bgr.nbytes))
    next(early)
    early.close()  # type: ignore[attr-defined]
    assert threading.active_count() <= before


def test_not_an_mcap_is_the_readers_error(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    path.write_bytes(b"not an mcap at all")
    with pytest.raises(NotMcapError):
        list(ImageStream(path, "/cam"))


def test_payloads_compressed_one_by_one(tmp_path: Path) -> None:
    """rosbag2 ``--compression-mode message``: each payload zstd-compressed on its own."""
    import zstandard

    bgr = scene()
    png = cv2.imencode(".png", bgr)[1].tobytes()
    plain = ros2.encode_compressed_image(S, "cam", png, "png")
    squeezed = zstandard.ZstdCompressor().compress(plain)
    path = tmp_path / "squeezed.mcap"
    write_log(path, {"/c": (ros2.COMPRESSED_IMAGE, [squeezed, squeezed[:-9], plain])})
    frames, stream = read(path, "/c")
    assert [f.index for f in frames] == [0, 2]
    np.testing.assert_array_equal(frames[0].pixels, bgr)
    assert stream.faults.by_reason == {"zstd payload that cannot be decompressed": (1,)}


def test_damaged_payloads_are_faults_never_exceptions(tmp_path: Path) -> None:
    """Every kind of message with bytes overwritten, cut or grown at random: each frame is
    either decoded or counted as a fault, and the walk never raises."""
    bgr = scene(16, 24)
    jpeg = cv2.imencode(".jpg", bgr)[1].tobytes()
    rng = np.random.default_rng(32)
    valid = {
        "/raw": (ros2.IMAGE, ros2.encode_image(S, "cam", bgr, "bgr8")),
        "/yuv": (ros2.IMAGE, ros2.encode_image(S, "cam", bgr[:, :, :2], "uyvy")),
        "/c": (ros2.COMPRESSED_IMAGE, ros2.encode_compressed_image(S, "cam", jpeg, "jpeg")),
        "/i": (
            ros2.CAMERA_INFO,
            ros2.encode_camera_info(
                ros2.CameraInfo.unrectified(S, "c", (24, 16), "plumb_bob", D, K)
            ),
        ),
    }
    topics = {}
    for topic, (schema, payload) in valid.items():
        damaged = []
        for _ in range(150):
            data = bytearray(payload)
            kind = rng.integers(3)
            if kind == 0:  # bytes overwritten (more often in the header)
                at = rng.integers(0, min(len(data), 80 if rng.random() < 0.7 else len(data)), 3)
                data[at[0]] = rng.integers(256)
                data[at[1]] = 0xFF
            elif kind == 1:
                data = data[: rng.integers(0, len(data))]
            else:
                data += bytes(rng.integers(0, 256, rng.integers(1, 40), np.uint8))
            damaged.append(bytes(data))
        topics[topic] = (schema, damaged)
    path = tmp_path / "fuzz.mcap"
    write_log(path, topics)
    for topic in ("/raw", "/yuv", "/c"):
        frames, stream = read(path, topic)
        assert stream.count == 150 and len(frames) + len(stream.faults) == 150
        assert len(stream.faults) > 0
        line = stream.warning()
        assert line is not None and "\n" not in line and len(line) < 600
        faulted = [i for indices in stream.faults.by_reason.values() for i in indices]
        assert sorted([f.index for f in frames] + faulted) == list(range(150))
    infos = read_camera_infos(path, "/i")  # those that can be read; no exception
    assert all(i.k.shape == (3, 3) for i in infos)


def test_a_missing_or_wrong_topic_is_one_line_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "js.mcap"
    joints = ros2.encode_joint_state([S], ["a1"], np.zeros((1, 1)))
    info = ros2.encode_camera_info(ros2.CameraInfo.unrectified(S, "c", (24, 16), "plumb_bob", D, K))
    write_log(
        path, {"/joint_states": (ros2.JOINT_STATE, joints), "/info": (ros2.CAMERA_INFO, [info])}
    )
    with pytest.raises(
        MissingTopicError, match=r"no topic /cam .*topics present: /info, /joint_states"
    ):
        list(ImageStream(path, "/cam"))
    with pytest.raises(
        InputError, match=r"carries 'sensor_msgs/msg/JointState' \(cdr\), not images"
    ):
        list(ImageStream(path, "/joint_states"))
    with pytest.raises(
        InputError, match=r"carries 'sensor_msgs/msg/CameraInfo' \(cdr\), not images"
    ):
        list(ImageStream(path, "/info"))
    with pytest.raises(MissingTopicError, match="camera info"):
        read_camera_infos(path, "/camera_info")


def test_an_unset_stamp_is_the_log_time(tmp_path: Path) -> None:
    path = tmp_path / "unset.mcap"
    write_log(path, {"/cam": (ros2.IMAGE, [ros2.encode_image(0, "cam", scene(), "bgr8")])})
    (frame,), _ = read(path, "/cam")
    assert frame.stamp_ns == 10 * S  # write_log's log time of message 0


def test_a_rosbag2_bag_written_by_rosbags(tmp_path: Path) -> None:
    """A bag folder from an independent writer (rosbags' rosbag2 MCAP storage, each message
    zstd-compressed on its own): JPEG frames and the camera info read back."""
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
    from rosbags.rosbag2 import Writer as BagWriter
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    bgr = scene()
    jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 95])[1]
    bag = tmp_path / "bag"
    writer = BagWriter(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer:
        ic = writer.add_connection("/cam/compressed", ros2.COMPRESSED_IMAGE, typestore=store)
        cc = writer.add_connection("/cam/camera_info", ros2.CAMERA_INFO, typestore=store)
        for i in range(5):
            t = 20 * S + i * S // 30
            header = T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=t // S, nanosec=t % S), frame_id="cam"
            )
            msg = T[ros2.COMPRESSED_IMAGE](header=header, format="jpeg", data=jpeg)
            writer.write(ic, t, store.serialize_cdr(msg, ros2.COMPRESSED_IMAGE))
        info = store.deserialize_cdr(
            ros2.encode_camera_info(
                ros2.CameraInfo.unrectified(20 * S, "cam", (64, 48), "plumb_bob", D, K)
            ),
            ros2.CAMERA_INFO,
        )
        writer.write(cc, 20 * S, store.serialize_cdr(info, ros2.CAMERA_INFO))
    stream = ImageStream(bag, "/cam/compressed", "/cam/camera_info")
    frames = list(stream)
    assert stream.warning() is None and len(frames) == 5
    assert [f.stamp_ns for f in frames] == [20 * S + i * S // 30 for i in range(5)]
    assert all(psnr(f.pixels, bgr) > 35 for f in frames)
    (found,) = stream.infos
    assert found.d == tuple(D) and found.width == 64
    with pytest.raises(InputError, match="not a rosbag2 bag"):
        list(ImageStream(tmp_path, "/cam/compressed"))


def test_yuv_422_both_orders(tmp_path: Path) -> None:
    """uyvy (ROS's yuv422) and yuyv from OpenCV's own conversion, read back within the chroma
    subsampling's loss (about 50 dB on this smooth scene; the other order gives about 11)."""
    bgr = scene()
    path = tmp_path / "yuv.mcap"
    topics = {}
    for encoding, code in [
        ("uyvy", cv2.COLOR_BGR2YUV_UYVY),
        ("yuv422", cv2.COLOR_BGR2YUV_UYVY),
        ("yuyv", cv2.COLOR_BGR2YUV_YUYV),
    ]:
        packed = cv2.cvtColor(bgr, code)
        topics[f"/{encoding}"] = (ros2.IMAGE, [ros2.encode_image(S, "cam", packed, encoding)])
    write_log(path, topics)
    for topic in topics:
        (frame,), stream = read(path, topic)
        assert stream.warning() is None and psnr(frame.pixels, bgr) > 40, topic
