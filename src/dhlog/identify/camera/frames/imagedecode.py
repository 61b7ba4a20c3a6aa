"""Camera images and intrinsics one payload at a time, as cameras record them.

``sensor_msgs/msg/Image`` (raw: mono8, mono16, rgb8, bgr8, rgba8, bgra8, their 16-bit forms,
bayer_*8/16, uyvy/yuyv; ``step`` and ``is_bigendian`` honoured: :func:`raw_pixels`) and
``sensor_msgs/msg/CompressedImage`` (JPEG, PNG: ``cv2.imdecode``, :func:`compressed_pixels`) in
CDR, read by hand (only the header is parsed; an image's bytes are viewed, never copied through
a generic decoder); ``foxglove.RawImage`` and ``foxglove.CompressedImage`` in JSON or protobuf
(through :mod:`dhlog.io.decode.messages`); ``sensor_msgs/msg/CameraInfo`` and
``foxglove.CameraCalibration`` as :class:`CameraInfo` (:func:`camera_info_cdr`). Pixels come as
OpenCV has them: (h, w) grey or (h, w, 3) **BGR**, uint8 or uint16 (alpha dropped, Bayer and YUV
converted with ``cv2.cvtColor``). A payload compressed on its own (rosbag2 ``--compression-mode
message``) is decompressed first (:func:`unzstd_payload`, at most :data:`MAX_PAYLOAD` bytes). A
payload that cannot be read is an :class:`ImageFaultError` naming the reason;
:func:`payload_decoder` gives a channel's decoder and :func:`decode_payload` runs it, in the
calling process or a worker's.
"""

from __future__ import annotations

import base64
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.io import ros2
from dhlog.io.mcapscan import ZSTD_MAGIC
from dhlog.io.mcapwalk import ChannelInfo
from dhlog.io.ros2 import CameraInfo
from dhlog.io.safetext import printable

#: (h, w) grey or (h, w, 3) BGR, uint8 or uint16
Pixels = NDArray[Any]


RAW_SCHEMAS = (ros2.IMAGE, "foxglove.RawImage")


COMPRESSED_SCHEMAS = (ros2.COMPRESSED_IMAGE, "foxglove.CompressedImage")


IMAGE_SCHEMAS = RAW_SCHEMAS + COMPRESSED_SCHEMAS


INFO_SCHEMAS = (ros2.CAMERA_INFO, "foxglove.CameraCalibration")


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
