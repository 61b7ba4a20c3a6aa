"""Camera images and intrinsics out of a log, as cameras record them (issue 32, item 1).

One payload at a time: ``sensor_msgs/msg/Image`` (raw: mono8, mono16, rgb8, bgr8, rgba8, bgra8,
their 16-bit forms, bayer_*8/16, uyvy/yuyv; ``step`` and ``is_bigendian`` honoured) and
``sensor_msgs/msg/CompressedImage`` (JPEG, PNG: ``cv2.imdecode``) in CDR, read by hand (an
image's bytes are never copied through a generic decoder); ``foxglove.RawImage`` and
``foxglove.CompressedImage`` in JSON or protobuf (through :mod:`dhlog.io.decode.messages`);
``sensor_msgs/msg/CameraInfo`` and ``foxglove.CameraCalibration`` as :class:`CameraInfo`.
Pixels come as OpenCV has them: (h, w) grey or (h, w, 3) **BGR**, uint8 or uint16 (alpha
dropped, Bayer and YUV converted with ``cv2.cvtColor``). A payload compressed on its own
(rosbag2 ``--compression-mode message``) is decompressed first; a ``.mcap.zstd`` is read as
:mod:`dhlog.io.mcapscan` reads it; a rosbag2 bag folder's split files are walked in order as
one log (its ``metadata.yaml`` read by the rosbags library).

A whole topic: :class:`ImageStream` walks the MCAP with :func:`dhlog.io.mcapscan.scan_mcap` in
a thread, its sink decoding each chunk's images as the walk meets them and dropping the chunk's
bytes, and hands the frames on through a queue of at most ``QUEUED`` batches of at most
``BATCH_BYTES`` decoded bytes: the log is never held whole. A frame that cannot be decoded
(a size that does not match its layout, a corrupt JPEG, an unknown encoding) is a counted fault
named by its index on the topic, never an exception (:meth:`ImageStream.warning`).
:meth:`ImageStream.payload_batches` hands on the payloads as recorded instead, for decoding in
worker processes (:func:`payload_decoder`, :func:`decode_payload`; :mod:`dhlog.io.observe`).
"""

from __future__ import annotations

import base64
import contextlib
import functools
import queue
import struct
import threading
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, MissingTopicError
from dhlog.io import ros2
from dhlog.io.mcapscan import ZSTD_MAGIC, McapScan, scan_mcap
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.safetext import printable

#: (h, w) grey or (h, w, 3) BGR, uint8 or uint16
Pixels = NDArray[Any]

RAW_SCHEMAS = (ros2.IMAGE, "foxglove.RawImage")
COMPRESSED_SCHEMAS = (ros2.COMPRESSED_IMAGE, "foxglove.CompressedImage")
IMAGE_SCHEMAS = RAW_SCHEMAS + COMPRESSED_SCHEMAS
INFO_SCHEMAS = (ros2.CAMERA_INFO, "foxglove.CameraCalibration")
ACCEPTED_IMAGES = (
    "sensor_msgs/msg/Image, sensor_msgs/msg/CompressedImage (cdr), foxglove.RawImage, "
    "foxglove.CompressedImage (json, protobuf)"
)
ACCEPTED_INFOS = "sensor_msgs/msg/CameraInfo (cdr), foxglove.CameraCalibration (json, protobuf)"

#: Raw encodings: channels in the message, bytes a channel, the conversion to grey/BGR.
ENCODINGS: dict[str, tuple[int, int, int | None]] = {
    "mono8": (1, 1, None),
    "8UC1": (1, 1, None),
    "mono16": (1, 2, None),
    "16UC1": (1, 2, None),
    "bgr8": (3, 1, None),
    "8UC3": (3, 1, None),
    "rgb8": (3, 1, cv2.COLOR_RGB2BGR),
    "bgra8": (4, 1, cv2.COLOR_BGRA2BGR),
    "rgba8": (4, 1, cv2.COLOR_RGBA2BGR),
    "bgr16": (3, 2, None),
    "rgb16": (3, 2, cv2.COLOR_RGB2BGR),
    "bgra16": (4, 2, cv2.COLOR_BGRA2BGR),
    "rgba16": (4, 2, cv2.COLOR_RGBA2BGR),
    "bayer_rggb8": (1, 1, cv2.COLOR_BayerRGGB2BGR),
    "bayer_bggr8": (1, 1, cv2.COLOR_BayerBGGR2BGR),
    "bayer_gbrg8": (1, 1, cv2.COLOR_BayerGBRG2BGR),
    "bayer_grbg8": (1, 1, cv2.COLOR_BayerGRBG2BGR),
    "bayer_rggb16": (1, 2, cv2.COLOR_BayerRGGB2BGR),
    "bayer_bggr16": (1, 2, cv2.COLOR_BayerBGGR2BGR),
    "bayer_gbrg16": (1, 2, cv2.COLOR_BayerGBRG2BGR),
    "bayer_grbg16": (1, 2, cv2.COLOR_BayerGRBG2BGR),
    "uyvy": (2, 1, cv2.COLOR_YUV2BGR_UYVY),
    "yuv422": (2, 1, cv2.COLOR_YUV2BGR_UYVY),  # ROS's name for UYVY
    "yuyv": (2, 1, cv2.COLOR_YUV2BGR_YUYV),
    "yuv422_yuy2": (2, 1, cv2.COLOR_YUV2BGR_YUYV),
}

#: Decoded bytes in one batch handed on, and batches waiting: the stream's memory bound.
BATCH_BYTES = 64 << 20
QUEUED = 2
#: A payload compressed on its own (rosbag2 ``--compression-mode message``) may decompress to
#: at most this many bytes (a 7680x4320 16-bit RGB frame is 199 MB).
MAX_PAYLOAD = 512 << 20


class ImageFaultError(Exception):
    """One payload that cannot be read as an image; the message is the reason, counted."""


@dataclass(frozen=True)
class CameraImage:
    """One decoded frame: its stamp (the header's, else the log time; ns), frame id, pixels
    ((h, w) or (h, w, 3) BGR; uint8 or uint16) and its index among the topic's messages."""

    stamp_ns: int
    frame_id: str
    pixels: Pixels
    index: int = 0


@dataclass(frozen=True)
class CameraInfo:
    """A camera's intrinsics as recorded (``CameraInfo`` / ``CameraCalibration``): ``k`` (3, 3),
    ``r`` (3, 3), ``p`` (3, 4), the distortion coefficients ``d`` in the order of
    ``distortion_model`` (plumb_bob, rational_polynomial, equidistant)."""

    stamp_ns: int
    frame_id: str
    width: int
    height: int
    distortion_model: str
    d: tuple[float, ...]
    k: NDArray[np.float64]
    r: NDArray[np.float64]
    p: NDArray[np.float64]


# ---------------------------------------------------------------------------------------------
# CDR by hand: only the image's header is parsed; its bytes are viewed, not copied


class _Cdr:
    """A reader of one CDR payload (``buf``, a uint8 view), aligned from the end of the
    4-byte encapsulation header; little- or big-endian as the header says."""

    def __init__(self, buf: NDArray[np.uint8]) -> None:
        if buf.shape[0] < 4 or buf[0] != 0 or buf[1] not in (0, 1):
            raise ImageFaultError("not plain CDR (encapsulation header)")
        self.buf, self.pos = buf, 4
        self.end = "<" if buf[1] == 1 else ">"

    def _take(self, fmt: str, size: int) -> tuple[Any, ...]:
        self.pos = 4 + (self.pos - 4 + size - 1) // size * size
        n = struct.calcsize(fmt)
        if self.pos + n > self.buf.shape[0]:
            raise ImageFaultError("payload shorter than its layout")
        out = struct.unpack_from(self.end + fmt, self.buf.data, self.pos)
        self.pos += n
        return out

    def u32(self) -> int:
        return int(self._take("I", 4)[0])

    def u8(self) -> int:
        return int(self._take("B", 1)[0])

    def string(self) -> str:
        n = self.u32()
        if self.pos + n > self.buf.shape[0]:
            raise ImageFaultError("a string runs past the payload")
        text = self.buf[self.pos : self.pos + n].tobytes().rstrip(b"\x00")
        self.pos += n
        return text.decode("utf-8", "replace")

    def stamp(self) -> int:
        sec, nsec = self._take("iI", 4)
        return int(sec) * 1_000_000_000 + int(nsec)

    def octets(self) -> NDArray[np.uint8]:
        n = self.u32()
        if self.pos + n > self.buf.shape[0]:
            raise ImageFaultError("data runs past the payload")
        out = self.buf[self.pos : self.pos + n]
        self.pos += n
        return out

    def floats(self, n: int | None = None) -> NDArray[np.float64]:
        n = self.u32() if n is None else n
        if n:
            self.pos = 4 + (self.pos - 4 + 7) // 8 * 8
        if n > self.buf.shape[0] or self.pos + 8 * n > self.buf.shape[0]:
            raise ImageFaultError("payload shorter than its layout")
        out = np.frombuffer(self.buf, dtype=self.end + "f8", count=n, offset=self.pos)
        self.pos += 8 * n
        return out.astype(np.float64)


def raw_pixels(
    data: NDArray[np.uint8],
    width: int,
    height: int,
    encoding: str,
    step: int,
    big_endian: bool,
) -> Pixels:
    """Pixels of a raw image's ``data`` (grey or BGR, a copy owning its memory)."""
    layout = ENCODINGS.get(encoding)
    if layout is None:
        raise ImageFaultError(f"unknown encoding '{printable(encoding[:40])}'")
    channels, depth, code = layout
    row = width * channels * depth
    step = step or row
    if width <= 0 or height <= 0 or step < row or data.shape[0] != step * height:
        raise ImageFaultError("size does not match width x height x channels")
    rows = np.array(data.reshape(height, step)[:, :row])  # a copy: the chunk is dropped
    dtype = np.dtype(np.uint8) if depth == 1 else np.dtype(">u2" if big_endian else "<u2")
    img = rows.view(dtype).reshape(height, width, channels)
    if depth > 1 and img.dtype != np.uint16:  # big-endian on this machine's order
        img = img.astype(np.uint16)
    if code is not None:
        return np.asarray(cv2.cvtColor(img if channels > 1 else img[:, :, 0], code))
    return img.reshape(height, width) if channels == 1 else img


def _kind(data: NDArray[np.uint8], fmt: str) -> str:
    if data[:3].tobytes() == b"\xff\xd8\xff":
        return "JPEG"
    if data[:8].tobytes() == b"\x89PNG\r\n\x1a\n":
        return "PNG"
    return "JPEG" if "jp" in fmt.lower() else "PNG" if "png" in fmt.lower() else "image"


def compressed_pixels(data: NDArray[np.uint8], fmt: str) -> Pixels:
    """Pixels of a compressed image (JPEG, PNG; what ``cv2.imdecode`` reads): grey or BGR."""
    if "compresseddepth" in fmt.lower().replace(" ", ""):
        data = data[12:]  # image_transport's depth header (format, quantisation)
    kind = _kind(data, fmt)
    if kind == "JPEG" and data[-256:].tobytes().rstrip(b"\x00").rfind(b"\xff\xd9") < 0:
        raise ImageFaultError("truncated JPEG (no end marker)")
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.shape[0] else None
    if img is None or img.dtype not in (np.uint8, np.uint16):
        raise ImageFaultError(f"corrupt {kind}")
    if img.ndim == 3 and img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    return np.asarray(img)


def _ros_image(schema: str, buf: NDArray[np.uint8]) -> tuple[int, str, Pixels]:
    cdr = _Cdr(buf)
    stamp, frame_id = cdr.stamp(), cdr.string()
    if schema == ros2.IMAGE:
        height, width = cdr.u32(), cdr.u32()
        encoding = cdr.string()
        big, step = cdr.u8(), cdr.u32()
        pixels = raw_pixels(cdr.octets(), width, height, encoding, step, bool(big))
    else:
        fmt = cdr.string()
        pixels = compressed_pixels(cdr.octets(), fmt)
    return stamp, frame_id, pixels


def _info_from(obj: Any, stamp: int, frame_id: str) -> CameraInfo:
    def field_of(*names: str) -> Any:
        for name in names:
            value = obj.get(name) if isinstance(obj, dict) else getattr(obj, name, None)
            if value is not None:
                return value
        raise ImageFaultError(f"no field {names[0]}")

    k = np.asarray(field_of("k", "K"), dtype=np.float64)
    r = np.asarray(field_of("r", "R"), dtype=np.float64)
    p = np.asarray(field_of("p", "P"), dtype=np.float64)
    if k.size != 9 or r.size != 9 or p.size != 12:
        raise ImageFaultError("k, r, p are not 9, 9, 12 numbers")
    return CameraInfo(
        stamp_ns=stamp,
        frame_id=frame_id,
        width=int(field_of("width")),
        height=int(field_of("height")),
        distortion_model=str(field_of("distortion_model")),
        d=tuple(float(v) for v in field_of("d", "D")),
        k=k.reshape(3, 3),
        r=r.reshape(3, 3),
        p=p.reshape(3, 4),
    )


def camera_info_cdr(payload: bytes | bytearray | memoryview | NDArray[np.uint8]) -> CameraInfo:
    """The intrinsics of a ``sensor_msgs/msg/CameraInfo`` CDR payload (else ImageFaultError)."""
    cdr = _Cdr(np.frombuffer(payload, dtype=np.uint8))
    stamp, frame_id = cdr.stamp(), cdr.string()
    height, width = cdr.u32(), cdr.u32()
    model = cdr.string()
    d = cdr.floats()
    k, r, p = cdr.floats(9), cdr.floats(9), cdr.floats(12)
    return CameraInfo(
        stamp, frame_id, width, height, model, tuple(d.tolist()), k.reshape(3, 3),
        r.reshape(3, 3), p.reshape(3, 4),
    )  # fmt: skip


def unzstd_payload(buf: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """A payload compressed on its own with zstd (rosbag2 ``--compression-mode message``),
    decompressed (at most ``MAX_PAYLOAD`` bytes); any other payload as it is."""
    if buf[:4].tobytes() != ZSTD_MAGIC:
        return buf
    import zstandard

    parts, total, data = [], 0, buf.tobytes()
    try:
        size = zstandard.frame_content_size(data)  # -1: not stated
        with zstandard.ZstdDecompressor().stream_reader(data) as reader:
            while block := reader.read(1 << 22):
                total += len(block)
                if total > MAX_PAYLOAD:
                    raise ImageFaultError(f"zstd payload beyond {MAX_PAYLOAD >> 20} MiB")
                parts.append(block)
    except zstandard.ZstdError:
        total, size = -1, 0
    if size >= 0 and total != size:  # (a frame cut short decompresses without an error)
        raise ImageFaultError("zstd payload that cannot be decompressed")
    return np.frombuffer(b"".join(parts), dtype=np.uint8)


def _foxglove_stamp(msg: Any) -> int:
    from dhlog.io.decode.messages import _stamp_ns

    return _stamp_ns(msg) or 0


def _foxglove_bytes(value: Any) -> NDArray[np.uint8]:
    if not isinstance(value, str | bytes | bytearray | memoryview):
        raise ImageFaultError("data is not bytes (or base64 text)")
    if isinstance(value, str):  # JSON: base64
        try:
            value = base64.b64decode(value, validate=True)
        except ValueError:
            raise ImageFaultError("data is not base64") from None
    return np.frombuffer(bytes(value), dtype=np.uint8)


def _foxglove_image(schema: str, msg: Any) -> tuple[int, str, Pixels]:
    def get(name: str) -> Any:
        value = msg.get(name) if isinstance(msg, dict) else getattr(msg, name, None)
        if value is None:
            raise ImageFaultError(f"no field {name}")
        return value

    stamp, frame_id = _foxglove_stamp(msg), str(get("frame_id"))
    data = _foxglove_bytes(get("data"))
    if schema == "foxglove.RawImage":
        encoding = str(get("encoding"))
        w, h, step = int(get("width")), int(get("height")), int(get("step"))
        return stamp, frame_id, raw_pixels(data, w, h, encoding, step, False)
    return stamp, frame_id, compressed_pixels(data, str(get("format")))


Decoder = Callable[[NDArray[np.uint8]], tuple[int, str, Any]]

#: What a damaged payload can make a decoder raise besides ImageFaultError: one fault each.
_FAULTS = (
    ValueError, cv2.error, struct.error, TypeError, OverflowError, AttributeError, KeyError,
    IndexError,
)  # fmt: skip


def decode_payload(decode: Decoder, buf: NDArray[np.uint8]) -> tuple[int, str, Any]:
    """``decode`` (of :func:`payload_decoder`) on one payload, decompressed first where it was
    compressed on its own; every fault of the payload an :class:`ImageFaultError` (its message
    the reason counted)."""
    try:
        return decode(unzstd_payload(buf))
    except _FAULTS as exc:
        raise ImageFaultError(f"unreadable ({type(exc).__name__})") from None


def payload_decoder(info: ChannelInfo) -> Decoder | None:
    """For a channel of an image or camera-info schema: payload → (stamp, frame id, pixels or
    :class:`CameraInfo`), raising :class:`ImageFaultError`; None for another schema or encoding."""
    schema = info.schema_name
    if schema not in IMAGE_SCHEMAS + INFO_SCHEMAS:
        return None
    if info.message_encoding == "cdr" and schema.startswith("sensor_msgs"):
        if schema == ros2.CAMERA_INFO:

            def ros_info(buf: NDArray[np.uint8]) -> tuple[int, str, Any]:
                found = camera_info_cdr(buf)
                return found.stamp_ns, found.frame_id, found

            return ros_info
        return lambda buf: _ros_image(schema, buf)
    from dhlog.io.decode.messages import message_decoder

    generic = message_decoder(info)
    if generic is None or schema.startswith("sensor_msgs"):
        return None
    decode = generic

    def foxglove(buf: NDArray[np.uint8]) -> tuple[int, str, Any]:
        try:
            msg = decode(buf.tobytes())
        except ImageFaultError:
            raise
        except Exception as exc:  # the generic decoders' errors are many: unreadable
            kind = f"{info.message_encoding} message ({type(exc).__name__})"
            raise ImageFaultError(f"unreadable {kind}") from None
        if schema in INFO_SCHEMAS:
            frame = msg.get("frame_id", "") if isinstance(msg, dict) else msg.frame_id
            found = _info_from(msg, _foxglove_stamp(msg), str(frame))
            return found.stamp_ns, found.frame_id, found
        return _foxglove_image(schema, msg)

    return foxglove


# ---------------------------------------------------------------------------------------------
# a topic a block at a time


@dataclass
class Faults:
    """Frames that could not be decoded: per reason, their indices on the topic."""

    by_reason: dict[str, list[int]] = field(default_factory=dict)

    def add(self, reason: str, index: int) -> None:
        self.by_reason.setdefault(reason, []).append(index)

    def __len__(self) -> int:
        return sum(len(v) for v in self.by_reason.values())


@dataclass(frozen=True)
class ImagePayload:
    """One image message as recorded (:meth:`ImageStream.payload_batches`): its index among the
    topic's messages, log time (ns: the stamp where the header's is unset), channel (its
    schema decides the decoding) and payload bytes."""

    index: int
    log_time: int
    channel: ChannelInfo
    data: bytes


_T = TypeVar("_T")


class _StoppedError(Exception):
    """The consumer stopped reading: the walk ends."""


class ImageStream:
    """The frames of one image topic of an MCAP, in the order of the file, decoded a chunk at a
    time while the walk goes on in a thread (:meth:`batches`, or the frames one by one).

    ``info_topic`` (optional) is read in the same walk: its intrinsics in :attr:`infos`. After
    the walk: :attr:`count` (messages on the topic), :attr:`faults`, :attr:`warnings` (the
    scan's: damage, truncation) and :meth:`warning`. The iteration raises the reader's errors
    (``InputError``: not an MCAP, unreadable; ``MissingTopicError``; a topic of another
    type), never one for a single frame."""

    def __init__(
        self, path: str | Path, topic: str, info_topic: str | None = None, *, batch_bytes: int = 0
    ) -> None:
        self.path, self.topic, self.info_topic = str(path), topic, info_topic
        self.batch_bytes = batch_bytes or BATCH_BYTES
        self.count = 0
        self.faults = Faults()
        self.infos: list[CameraInfo] = []
        self.warnings: list[str] = []
        self.schema = ""
        #: how far the last walk has read the log (0 to 1; set in the walk's thread)
        self.fraction = 0.0
        self._decoders: dict[int, Decoder] = {}

    def _decoder(self, cid: int, info: ChannelInfo) -> Decoder:
        """The decoder of channel ``cid`` (made at its first offer); a channel of another type
        than its topic's stream is an InputError."""
        if cid not in self._decoders:
            is_image = info.topic == self.topic
            made = payload_decoder(info)
            if made is None or (info.schema_name in INFO_SCHEMAS) == is_image:
                raise InputError(
                    f"{self.path}: topic {printable(info.topic)} carries "
                    f"'{printable(info.schema_name[:80])}' ({printable(info.message_encoding)}), "
                    f"not {'images' if is_image else 'camera intrinsics'}; accepted: "
                    f"{ACCEPTED_IMAGES if is_image else ACCEPTED_INFOS}. Give the camera's "
                    f"{'image' if is_image else 'camera-info'} topic."
                )
            self._decoders[cid] = made
        return self._decoders[cid]

    def _decode(self, cid: int, info: ChannelInfo, raw: RawMessages) -> Iterator[CameraImage]:
        """The frames of one offer of the image topic, decoded one at a time as they are
        taken (faults counted; a chunk's frames are never all decoded at once), and the camera
        infos kept."""
        is_image = info.topic == self.topic
        decode = self._decoder(cid, info)
        if is_image:
            self.schema = info.schema_name
        for i in range(len(raw)):
            index = self.count
            if is_image:
                self.count += 1
            start = int(raw.starts[i])
            buf = raw.data[start : start + int(raw.lengths[i])]
            try:
                stamp, frame_id, value = decode_payload(decode, buf)
            except ImageFaultError as exc:
                if is_image:
                    self.faults.add(str(exc), index)
                continue
            stamp = stamp if stamp > 0 else int(raw.log_time[i])  # unset: the log time
            if is_image:
                yield CameraImage(stamp, frame_id, value, index)
            else:
                self.infos.append(value)

    def batches(self) -> Iterator[list[CameraImage]]:
        """The frames, in batches of at most ``batch_bytes`` decoded bytes (a single frame
        larger than that alone). Each iteration walks the log again, its tallies afresh."""
        return self._batches(self._decode, lambda frame: frame.pixels.nbytes)

    def payload_batches(self) -> Iterator[list[ImagePayload]]:
        """The image topic's payloads as recorded, not decoded (each copied out of its chunk),
        in batches of at most ``batch_bytes`` payload bytes: for decoding elsewhere (in worker
        processes, with :func:`payload_decoder` of the payload's channel and
        :func:`decode_payload`; its faults are then the decoder's to count). The camera infos
        are read as :meth:`batches` reads them."""
        return self._batches(self._payloads, lambda payload: len(payload.data))

    def _payloads(self, cid: int, info: ChannelInfo, raw: RawMessages) -> Iterator[ImagePayload]:
        if info.topic != self.topic:
            for _ in self._decode(cid, info, raw):  # camera infos: kept in self.infos
                pass
            return
        self._decoder(cid, info)  # (a channel of another type refused)
        self.schema = info.schema_name
        for i in range(len(raw)):
            start = int(raw.starts[i])
            data = raw.data[start : start + int(raw.lengths[i])].tobytes()
            yield ImagePayload(self.count, int(raw.log_time[i]), info, data)
            self.count += 1

    def _batches(
        self,
        produce: Callable[[int, ChannelInfo, RawMessages], Iterable[_T]],
        size_of: Callable[[_T], int],
    ) -> Iterator[list[_T]]:
        self.count, self.faults, self.infos, self.warnings = 0, Faults(), [], []
        self.fraction = 0.0
        hand: queue.Queue[list[_T] | BaseException | None] = queue.Queue(QUEUED)
        stop = threading.Event()

        def put(item: list[_T] | BaseException | None) -> None:
            while True:
                if stop.is_set():
                    raise _StoppedError
                try:
                    hand.put(item, timeout=0.1)
                    return
                except queue.Full:
                    continue

        def offer(frames: Iterable[_T]) -> None:
            batch: list[_T] = []
            size = 0
            for frame in frames:
                if batch and size + size_of(frame) > self.batch_bytes:
                    put(batch)
                    batch, size = [], 0
                batch.append(frame)
                size += size_of(frame)
            if batch:
                put(batch)

        def sink(cid: int, info: ChannelInfo | None, raw: RawMessages) -> bool:
            if info is None:
                return False  # defined later: decoded from the scan's kept payloads
            offer(produce(cid, info, raw))
            return True

        def check(done: float, file: int = 0, files: int = 1) -> None:
            # every few chunks: has the consumer stopped? (and how far the walk is)
            self.fraction = (file + min(max(done, 0.0), 1.0)) / files
            if stop.is_set():
                raise _StoppedError

        def walk() -> None:
            try:
                topics = [self.topic] + ([self.info_topic] if self.info_topic else [])
                present: set[str] = set()
                with contextlib.ExitStack() as stack:
                    paths = _log_files(self.path, stack)
                    for k, path in enumerate(paths):
                        self._decoders = {}  # channel ids are the file's own
                        step = functools.partial(check, file=k, files=len(paths))
                        scan = scan_mcap(path, topics, progress=step, sink=sink)
                        for cid, raw in scan.messages.items():  # channels defined late
                            info = scan.channels.get(cid)
                            if info is not None:
                                offer(produce(cid, info, raw))
                        present.update(scan.topics())
                        self.warnings.extend(scan.warnings)
                wanted = [("image", self.topic), ("camera info", self.info_topic)]
                _check_topics(self.path, sorted(present), wanted)
                put(None)
            except _StoppedError:
                pass
            except BaseException as exc:  # handed to the consumer, raised there
                try:
                    put(exc)
                except _StoppedError:
                    pass

        worker = threading.Thread(target=walk, name="dhlog-images", daemon=True)
        worker.start()
        try:
            while True:
                item = hand.get()
                if item is None:
                    return
                if isinstance(item, BaseException):
                    raise item
                yield item
        finally:
            stop.set()
            worker.join()

    def __iter__(self) -> Iterator[CameraImage]:
        for batch in self.batches():
            yield from batch

    def warning(self) -> str | None:
        """One line naming the frames not decoded, by reason (None when every frame was)."""
        if not self.faults.by_reason:
            return None
        parts = []
        reasons = sorted(self.faults.by_reason.items(), key=lambda kv: -len(kv[1]))
        for reason, indices in reasons[:4]:
            shown = ", ".join(str(i) for i in indices[:5])
            more = f" and {len(indices) - 5} more" if len(indices) > 5 else ""
            parts.append(f"{reason}: {len(indices)} (frame {shown}{more})")
        if len(reasons) > 4:
            parts.append(
                f"{sum(len(v) for _, v in reasons[4:])} for {len(reasons) - 4} other reasons"
            )
        topic = printable(self.topic)
        return (
            f"{self.path}: {len(self.faults)} of {self.count} frame(s) on {topic} not decoded, "
            f"skipped — {'; '.join(parts)}."
        )


def _check_topics(path: str, present: list[str], wanted: list[tuple[str, str | None]]) -> None:
    for what, topic in wanted:
        if topic and topic not in present:
            raise MissingTopicError(path, what, topic, present)


def _log_files(path: str, stack: contextlib.ExitStack) -> list[Path]:
    """The MCAP files of a log: the file itself, or a rosbag2 bag folder's split files in
    order (its ``metadata.yaml`` read by the rosbags library, open on ``stack`` while the
    files are walked)."""
    folder = Path(path)
    if not folder.is_dir():
        return [folder]
    from rosbags.rosbag2 import Reader, ReaderError

    try:
        bag = stack.enter_context(Reader(folder))
        files = [Path(s.path) for s in bag.storage.storages]  # type: ignore[attr-defined]
    except (ReaderError, FileNotFoundError, KeyError, ValueError, AttributeError) as exc:
        raise InputError(
            f"{path}: a folder, but not a rosbag2 bag dhlog can read ({exc}); give the bag "
            "folder (with metadata.yaml) or one .mcap file."
        ) from None
    if not files:
        raise InputError(f"{path}: the bag lists no storage files.")
    return files


def read_camera_infos(
    path: str | Path, topic: str, scan: McapScan | None = None
) -> list[CameraInfo]:
    """Every ``CameraInfo`` / ``CameraCalibration`` on ``topic`` (the walk reads no other
    topic's payloads; messages that cannot be read are left out). ``scan``: a walk of ``path``
    already made that kept ``topic``'s payloads (read from it, not walked again)."""
    stream = ImageStream(path, "", topic)
    if scan is None:
        scan = scan_mcap(path, [topic])
    _check_topics(str(path), scan.topics(), [("camera info", topic)])
    for cid, raw in scan.messages.items():
        info = scan.channels.get(cid)
        if info is not None and info.topic == topic:
            for _ in stream._decode(cid, info, raw):
                pass
    return stream.infos
