"""ROS 2 CDR for the message types of the input contract, in bulk with numpy.

Decoding works on :class:`~dhlog.io.mcapwalk.RawMessages` without a Python step per message:
``geometry_msgs/msg/PointStamped`` and ``PoseStamped`` have a fixed layout once the length of the
``frame_id`` is known; ``sensor_msgs/msg/JointState`` has a fixed layout per distinct name list,
which is parsed once per distinct header. Encoding builds the same layouts for the simulator.

CDR (XCDR1, little endian): a 4-byte encapsulation header ``00 01 00 00``, then each primitive
aligned to its size relative to the end of that header; strings are ``u32 length`` (with the NUL)
followed by the bytes and a NUL; sequences are ``u32 count`` followed by the elements.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from dhlog.io.mcapwalk import RawMessages, gather, gather_rows

CDR_LE = b"\x00\x01\x00\x00"

POINT_STAMPED = "geometry_msgs/msg/PointStamped"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_WITH_COVARIANCE = "geometry_msgs/msg/PoseWithCovarianceStamped"
JOINT_STATE = "sensor_msgs/msg/JointState"
STRING = "std_msgs/msg/String"
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"

_SEP = "=" * 80 + "\n"
_HEADER_DEFS = (
    _SEP
    + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
    + _SEP
    + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
)
_POINT_DEF = _SEP + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
_POSE_DEFS = (
    _SEP
    + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\n"
    + "geometry_msgs/Quaternion orientation\n"
    + _POINT_DEF
    + _SEP
    + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
)
MSGDEFS = {
    POINT_STAMPED: "std_msgs/Header header\ngeometry_msgs/Point point\n"
    + _HEADER_DEFS
    + _POINT_DEF,
    POSE_STAMPED: "std_msgs/Header header\ngeometry_msgs/Pose pose\n" + _HEADER_DEFS + _POSE_DEFS,
    POSE_WITH_COVARIANCE: "std_msgs/Header header\ngeometry_msgs/PoseWithCovariance pose\n"
    + _HEADER_DEFS
    + _SEP
    + "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n"
    + _POSE_DEFS,
    JOINT_STATE: "std_msgs/Header header\nstring[] name\nfloat64[] position\n"
    + "float64[] velocity\nfloat64[] effort\n"
    + _HEADER_DEFS,
    STRING: "string data\n",
    IMAGE: "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
    + "uint8 is_bigendian\nuint32 step\nuint8[] data\n"
    + _HEADER_DEFS,
    COMPRESSED_IMAGE: "std_msgs/Header header\nstring format\nuint8[] data\n" + _HEADER_DEFS,
    CAMERA_INFO: "std_msgs/Header header\nuint32 height\nuint32 width\n"
    + "string distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\n"
    + "uint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi\n"
    + _HEADER_DEFS
    + _SEP
    + "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\n"
    + "uint32 width\nbool do_rectify\n",
}


def _align(n: int, k: int) -> int:
    return (n + k - 1) // k * k


def _block_stamps(rows: NDArray[np.uint8]) -> NDArray[np.int64]:
    sec = rows[:, 4:8].copy().view("<i4").reshape(-1).astype(np.int64)
    nsec = rows[:, 8:12].copy().view("<u4").reshape(-1).astype(np.int64)
    return sec * 1_000_000_000 + nsec


def little_endian(raw: RawMessages) -> NDArray[np.bool_]:
    """True for each message encoded as little-endian CDR (the fast path reads only those)."""
    if len(raw) == 0:
        return np.zeros(0, dtype=bool)
    return np.asarray(raw.data[raw.starts + 1] == 1)


def decode_point_bulk(
    raw: RawMessages, *, covariance: bool = False, orientation: bool = False
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Header stamps (ns) and positions (m, 3) of PointStamped or PoseStamped messages; with
    ``covariance`` (PoseWithCovarianceStamped) also the position block of the covariance, as
    (m, 9): ``x, y, z, cxx, cxy, cxz, cyy, cyz, czz``; with ``orientation`` (PoseStamped) the
    orientation quaternion, as (m, 7): ``x, y, z, qx, qy, qz, qw``.

    The point (or the pose's position) follows the header at the next multiple of 8 after
    ``stamp (8) + frame_id length (4) + frame_id``; the 6×6 covariance (row-major) follows the
    orientation. Messages are grouped by frame-id length; each group's fixed-layout prefix is
    copied out in one row gather.
    """
    frame_len = gather(raw.data, raw.starts + 12, 4, "<u4").astype(np.int64)
    rel = ((12 + frame_len + 7) // 8) * 8
    span = 24 + (32 + 36 * 8 if covariance else 32 if orientation else 0)
    if np.any(rel + span + 4 > raw.lengths):
        raise ValueError("PointStamped payload shorter than its layout")
    stamps = np.empty(len(raw), dtype=np.int64)
    xyz = np.empty((len(raw), 9 if covariance else 7 if orientation else 3), dtype=np.float64)
    uniform = bool(np.all(rel == rel[0])) if rel.size else True
    for r in rel[:1] if uniform else np.unique(rel):
        sel = slice(None) if uniform else np.flatnonzero(rel == r)
        width = 4 + int(r) + span
        rows = gather_rows(raw.data, raw.starts[sel], width)
        stamps[sel] = _block_stamps(rows)
        at = 4 + int(r)
        xyz[sel, :3] = rows[:, at : at + 24].copy().view("<f8").reshape(-1, 3)
        if covariance:
            cov = rows[:, at + 56 : at + 56 + 288].copy().view("<f8").reshape(-1, 6, 6)
            xyz[sel, 3:] = cov[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
        elif orientation:
            xyz[sel, 3:] = rows[:, at + 24 : at + 56].copy().view("<f8").reshape(-1, 4)
    return stamps, xyz


def _parse_joint_layout(buf: bytes) -> tuple[list[str], int, int]:
    """Names, position count and byte offset (relative to the CDR body) of one JointState."""
    (flen,) = struct.unpack_from("<I", buf, 8)
    p = _align(12 + flen, 4)
    (count,) = struct.unpack_from("<I", buf, p)
    p += 4
    names = []
    for _ in range(count):
        p = _align(p, 4)
        (n,) = struct.unpack_from("<I", buf, p)
        names.append(buf[p + 4 : p + 4 + n - 1].decode("utf-8", "replace"))
        p += 4 + n
    p = _align(p, 4)
    (n_pos,) = struct.unpack_from("<I", buf, p)
    p += 4
    if n_pos:
        p = _align(p, 8)
    return names, n_pos, p


class JointGroup(NamedTuple):
    """JointState messages of one layout: header stamps (ns), names, positions (k, len(names));
    the layout's payload ``length``, the bytes that fix it (``layout``: frame id and names,
    between stamp and positions), the index of its ``first`` message and the ``width`` read
    of each payload."""

    stamps: NDArray[np.int64]
    names: list[str]
    positions: NDArray[np.float64]
    length: int
    layout: bytes
    first: int
    width: int


def joint_state_groups(raw: RawMessages) -> list[JointGroup]:
    """JointState messages grouped by payload length (ascending, when they differ) and by the
    bytes between stamp and positions (in order of first appearance): each distinct layout is
    parsed once and its messages copied out in one row gather."""
    groups: list[JointGroup] = []
    same_length = bool(np.all(raw.lengths == raw.lengths[0])) if len(raw) else True
    for length in raw.lengths[:1] if same_length else np.unique(raw.lengths):
        remaining = np.arange(len(raw)) if same_length else np.flatnonzero(raw.lengths == length)
        while remaining.size:
            first = int(remaining[0])
            names, n_pos, offset = _parse_joint_layout(raw.payload(first)[4:])
            n_use = min(n_pos, len(names))
            width = 4 + offset + 8 * n_use
            rows = gather_rows(raw.data, raw.starts[remaining], width)
            # the bytes between stamp and positions (frame id, names) fix the layout
            same = np.all(rows[:, 12 : 4 + offset] == rows[0, 12 : 4 + offset], axis=1)
            remaining = remaining[~same]
            rows = rows[same]
            vals = rows[:, 4 + offset :].copy().view("<f8").reshape(-1, n_use)
            groups.append(
                JointGroup(
                    _block_stamps(rows),
                    names[:n_use],
                    np.asarray(vals, dtype=np.float64),
                    int(length),
                    rows[0, 12 : 4 + offset].tobytes(),
                    first,
                    width,
                )
            )
    return groups


# ---------------------------------------------------------------------------------------------
# encoding (simulator)


def _header(t_ns: int, frame_id: str) -> bytes:
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    fid = frame_id.encode() + b"\x00"
    return struct.pack("<iiI", sec, nsec, len(fid)) + fid


def encode_point_stamped(
    t_ns: Sequence[int] | NDArray[np.int64], xyz: NDArray[np.float64], frame_id: str
) -> list[bytes]:
    """CDR payloads of PointStamped messages (also readable as the prefix of PoseStamped)."""
    out = []
    for t, p in zip(np.asarray(t_ns).tolist(), np.asarray(xyz, dtype="<f8"), strict=True):
        body = _header(t, frame_id)
        body += b"\x00" * (_align(len(body), 8) - len(body))
        out.append(CDR_LE + body + p.tobytes())
    return out


def encode_pose_stamped(
    t_ns: Sequence[int] | NDArray[np.int64],
    xyz: NDArray[np.float64],
    frame_id: str,
    quaternions: NDArray[np.float64] | None = None,
) -> list[bytes]:
    """CDR payloads of PoseStamped messages (orientation ``x, y, z, w`` per message, identity
    when ``quaternions`` (m, 4) is None)."""
    points = encode_point_stamped(t_ns, xyz, frame_id)
    if quaternions is None:
        quat = np.array([0.0, 0.0, 0.0, 1.0], dtype="<f8").tobytes()
        return [p + quat for p in points]
    return [p + q.tobytes() for p, q in zip(points, np.asarray(quaternions, "<f8"), strict=True)]


def encode_pose_with_covariance(
    t_ns: Sequence[int] | NDArray[np.int64],
    xyz: NDArray[np.float64],
    frame_id: str,
    position_covariance: NDArray[np.float64],
) -> list[bytes]:
    """CDR payloads of PoseWithCovarianceStamped messages: identity orientation, the position
    block of the 6×6 covariance from ``position_covariance`` (m, 6: ``cxx, cxy, cxz, cyy, cyz,
    czz``, m²) and the orientation block 1e6 rad² on its diagonal (not measured)."""
    out = []
    full = np.zeros((len(xyz), 6, 6), dtype="<f8")
    rows, cols = [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]
    full[:, rows, cols] = position_covariance
    full[:, cols, rows] = position_covariance
    full[:, [3, 4, 5], [3, 4, 5]] = 1e6
    for pose, cov in zip(encode_pose_stamped(t_ns, xyz, frame_id), full, strict=True):
        out.append(pose + cov.tobytes())
    return out


def encode_joint_state(
    t_ns: Sequence[int] | NDArray[np.int64], names: Sequence[str], positions: NDArray[np.float64]
) -> list[bytes]:
    """CDR payloads of JointState messages with positions only (empty velocity and effort)."""
    out = []
    for t, q in zip(np.asarray(t_ns).tolist(), np.asarray(positions, dtype="<f8"), strict=True):
        body = bytearray(_header(t, ""))
        body += b"\x00" * (_align(len(body), 4) - len(body)) + struct.pack("<I", len(names))
        for name in names:
            raw_name = name.encode() + b"\x00"
            body += b"\x00" * (_align(len(body), 4) - len(body))
            body += struct.pack("<I", len(raw_name)) + raw_name
        body += b"\x00" * (_align(len(body), 4) - len(body)) + struct.pack("<I", len(q))
        body += b"\x00" * (_align(len(body), 8) - len(body)) + q.tobytes()
        body += struct.pack("<II", 0, 0)  # velocity, effort
        out.append(CDR_LE + bytes(body))
    return out


def encode_string(text: str) -> bytes:
    """CDR payload of a std_msgs/msg/String."""
    data = text.encode() + b"\x00"
    return CDR_LE + struct.pack("<I", len(data)) + data


def _pad(body: bytearray, k: int) -> None:
    body += b"\x00" * (_align(len(body), k) - len(body))


def _cdr_string(body: bytearray, text: str) -> None:
    raw = text.encode() + b"\x00"
    _pad(body, 4)
    body += struct.pack("<I", len(raw)) + raw


def encode_image(
    t_ns: int, frame_id: str, pixels: NDArray[np.generic], encoding: str, *, step: int = 0
) -> bytes:
    """CDR payload of a sensor_msgs/msg/Image: ``pixels`` (h, w) or (h, w, c), uint8 or uint16,
    written little-endian row after row as ``encoding`` names them (the caller's channel
    order: ``rgb8`` pixels are R, G, B); ``step`` (bytes a row, 0: packed) pads each row."""
    img = np.ascontiguousarray(pixels)
    if img.dtype.itemsize > 1:
        img = img.astype(img.dtype.newbyteorder("<"))
    h, w = img.shape[:2]
    row = img.reshape(h, -1).view(np.uint8).reshape(h, -1)
    step = step or row.shape[1]
    rows = np.zeros((h, step), dtype=np.uint8)
    rows[:, : row.shape[1]] = row
    body = bytearray(_header(t_ns, frame_id))
    _pad(body, 4)
    body += struct.pack("<II", h, w)
    _cdr_string(body, encoding)
    body += struct.pack("<B", 0)  # is_bigendian
    _pad(body, 4)
    body += struct.pack("<II", step, rows.size) + rows.tobytes()
    return CDR_LE + bytes(body)


def encode_compressed_image(t_ns: int, frame_id: str, data: bytes, fmt: str) -> bytes:
    """CDR payload of a sensor_msgs/msg/CompressedImage (``data`` as encoded, e.g. by
    ``cv2.imencode``; ``fmt`` ``jpeg``, ``png``, ``rgb8; jpeg compressed bgr8``)."""
    body = bytearray(_header(t_ns, frame_id))
    _cdr_string(body, fmt)
    _pad(body, 4)
    body += struct.pack("<I", len(data)) + bytes(data)
    return CDR_LE + bytes(body)


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

    @classmethod
    def unrectified(
        cls,
        stamp_ns: int,
        frame_id: str,
        size: tuple[int, int],
        distortion_model: str,
        d: Sequence[float],
        k: Sequence[float] | NDArray[np.float64],
    ) -> CameraInfo:
        """The intrinsics of an unrectified camera of image ``size`` (width, height): ``k``
        the camera matrix (9 values, row-major), the rectification the identity and the
        projection ``[k | 0]``."""
        k33 = np.asarray(k, dtype=np.float64).reshape(3, 3)
        p34 = np.hstack([k33, np.zeros((3, 1))])
        d_ = tuple(float(v) for v in d)
        return cls(stamp_ns, frame_id, size[0], size[1], distortion_model, d_, k33, np.eye(3), p34)


def encode_camera_info(info: CameraInfo) -> bytes:
    """CDR payload of a sensor_msgs/msg/CameraInfo of ``info``; binning 0 and an empty
    region of interest, as an unrectified camera writes."""
    k9 = np.asarray(info.k, dtype="<f8").reshape(9)
    r9 = np.asarray(info.r, dtype="<f8").reshape(9)
    p12 = np.asarray(info.p, dtype="<f8").reshape(12)
    d, height, width = info.d, info.height, info.width
    body = bytearray(_header(info.stamp_ns, info.frame_id))
    _pad(body, 4)
    body += struct.pack("<II", height, width)
    _cdr_string(body, info.distortion_model)
    _pad(body, 4)
    body += struct.pack("<I", len(d))
    _pad(body, 8)
    body += np.asarray(d, dtype="<f8").tobytes() + k9.tobytes() + r9.tobytes() + p12.tobytes()
    body += struct.pack("<IIIIIIB", 0, 0, 0, 0, 0, 0, 0)  # binning x, y; roi; do_rectify
    return CDR_LE + bytes(body)
