"""One message at a time: the decoder of a channel's encoding (the mcap library's ``mcap_ros2``
and protobuf decoders, or JSON) and, per schema, the extractor of a stream's sample from a
decoded message — the target's position (with its orientation, its covariance), the joint
names and positions, a phase marker — with the message's own stamp where it has one. Both read
paths (bulk and general) use them for every message they do not decode in bulk.

To read a new message type: its schema name and field paths here (and, if it is hot and
fixed-layout CDR, a bulk decoder in :mod:`dhlog.io.ros2`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable
from typing import Any

from dhlog.io import ros2
from dhlog.io.mcapwalk import ChannelInfo

#: Point schemas and where the position sits in them.
POINT_SCHEMAS = {
    ros2.POINT_STAMPED: "point",
    ros2.POSE_STAMPED: "pose.position",
    "foxglove.Point3InFrame": "point",
    "foxglove.PoseInFrame": "pose.position",
    ros2.POSE_WITH_COVARIANCE: "pose.pose.position",
}
#: Point schemas that carry a covariance: the path of the row-major 6×6 (pose) covariance.
COVARIANCE_SCHEMAS = {ros2.POSE_WITH_COVARIANCE: "pose.covariance"}
#: Point schemas that carry the target frame's orientation, and where.
ORIENTATION_SCHEMAS = {
    ros2.POSE_STAMPED: "pose.orientation",
    "foxglove.PoseInFrame": "pose.orientation",
    ros2.POSE_WITH_COVARIANCE: "pose.pose.orientation",
}
#: Point schemas that are transforms (the target is a frame's origin): single, and lists of
#: them, selected by ``[streams.point] child_frame``.
TRANSFORM_SCHEMAS = ("geometry_msgs/msg/TransformStamped", "foxglove.FrameTransform")
TRANSFORM_LISTS = ("tf2_msgs/msg/TFMessage", "foxglove.FrameTransforms")
#: Foxglove's list of poses in one frame: the target is ``poses[pose_index]``.
POSES_IN_FRAME = "foxglove.PosesInFrame"
#: JSON field keys of a spherical point stream (horizontal angle, vertical angle, distance).
SPHERICAL_FIELDS = ("horizontal", "vertical", "distance")
JOINT_SCHEMAS = (ros2.JOINT_STATE, "foxglove.JointStates")
PHASE_SCHEMAS = (ros2.STRING,)


def _get(obj: Any, path: str) -> Any:
    for part in path.split("."):
        if isinstance(obj, dict):
            obj = obj[part]
        elif isinstance(obj, list | tuple) or (part.isdigit() and not hasattr(obj, part)):
            obj = obj[int(part)]  # a list item by index (ValueError on a name: unreadable)
        else:
            obj = getattr(obj, part)
    return obj


def _first(obj: Any, names: Iterable[str]) -> Any:
    for name in names:
        try:
            return _get(obj, name)
        except (KeyError, AttributeError, TypeError):
            continue
    return None


def _stamp_ns(obj: Any) -> int | None:
    """The message's own stamp: ROS ``header.stamp`` or Foxglove ``timestamp``; None if absent."""
    stamp = _first(obj, ("header.stamp", "timestamp"))
    if stamp is None:
        return None
    sec = _first(stamp, ("sec", "seconds"))
    nsec = _first(stamp, ("nanosec", "nsec", "nanos"))
    if sec is None:
        return None
    value = int(sec) * 1_000_000_000 + int(nsec or 0)
    return value if value != 0 else None


Extracted = tuple[int | None, Any]


class OtherFrameError(Exception):
    """A transform message without the frame the pipeline selects: not this stream's sample."""


class TransformExtractor:
    """Translation (and rotation) of the transform to ``child_frame`` in a TransformStamped,
    FrameTransform or a list of them (TFMessage, FrameTransforms); without ``child_frame``, the
    first child frame met (``frames``: every child frame seen, for the reader's warning)."""

    def __init__(self, schema: str, child_frame: str, orientation: bool) -> None:
        self.schema, self.orientation = schema, orientation
        self.chosen: str | None = child_frame or None
        self.frames: set[str] = set()

    def __call__(self, msg: Any) -> Extracted:
        items = list(_get(msg, "transforms")) if self.schema in TRANSFORM_LISTS else [msg]
        children = [str(_get(item, "child_frame_id")) for item in items]
        self.frames.update(children)
        if self.chosen is None and children:
            self.chosen = children[0]
        if self.chosen not in children:
            raise OtherFrameError
        item = items[children.index(self.chosen)]
        if self.schema.startswith("foxglove"):
            t, r = _get(item, "translation"), _get(item, "rotation")
        else:
            t, r = _get(item, "transform.translation"), _get(item, "transform.rotation")
        xyz = [float(_get(t, "x")), float(_get(t, "y")), float(_get(t, "z"))]
        if self.orientation:
            xyz += [float(_get(r, c)) for c in ("x", "y", "z", "w")]
        return _stamp_ns(item), xyz


def _point_extractor(
    schema: str,
    fields: dict[str, str],
    orientation: bool = False,
    child_frame: str = "",
    pose_index: int = 0,
) -> Callable[[Any], Extracted] | None:
    if schema in TRANSFORM_SCHEMAS or schema in TRANSFORM_LISTS:
        return TransformExtractor(schema, child_frame, orientation)
    if schema == POSES_IN_FRAME and not fields:

        def pose_of_many(msg: Any) -> Extracted:
            pose = _get(msg, "poses")[pose_index]  # IndexError: counted as unreadable
            p = _get(pose, "position")
            xyz = [float(_get(p, "x")), float(_get(p, "y")), float(_get(p, "z"))]
            if orientation:
                r = _get(pose, "orientation")
                xyz += [float(_get(r, c)) for c in ("x", "y", "z", "w")]
            return _stamp_ns(msg), xyz

        return pose_of_many
    if fields:
        spherical = any(k in fields for k in SPHERICAL_FIELDS)
        keys = SPHERICAL_FIELDS if spherical else ("x", "y", "z")
        paths = [fields.get(k, k) for k in keys]
        stamp_path = fields.get("stamp_ns")

        def custom(msg: Any) -> Extracted:
            stamp = int(_get(msg, stamp_path)) if stamp_path else _stamp_ns(msg)
            return stamp, [float(_get(msg, p)) for p in paths]

        return custom
    base = POINT_SCHEMAS.get(schema)
    if base is None:
        return None

    cov_path = COVARIANCE_SCHEMAS.get(schema)
    rot_path = ORIENTATION_SCHEMAS.get(schema) if orientation else None
    if orientation and rot_path is None:
        return None

    def standard(msg: Any) -> Extracted:
        p = _get(msg, base)
        xyz = [float(_get(p, "x")), float(_get(p, "y")), float(_get(p, "z"))]
        if rot_path is not None:
            r = _get(msg, rot_path)
            xyz += [float(_get(r, c)) for c in ("x", "y", "z", "w")]
        if cov_path is not None:
            c = [float(v) for v in _get(msg, cov_path)]
            if len(c) != 36:
                raise ValueError(f"covariance has {len(c)} entries, not 36")
            xyz += [c[0], c[1], c[2], c[7], c[8], c[14]]
        return _stamp_ns(msg), xyz

    return standard


def _joint_extractor(schema: str, fields: dict[str, str]) -> Callable[[Any], Extracted] | None:
    if schema == "foxglove.JointStates" or fields.get("joints"):
        key = fields.get("joints", "joints")

        def foxglove(msg: Any) -> Extracted:
            joints = _get(msg, key)
            return _stamp_ns(msg), (
                [str(_get(j, "name")) for j in joints],
                [float(_get(j, "position")) for j in joints],
            )

        return foxglove
    if schema == ros2.JOINT_STATE or fields.get("names"):
        names_path, pos_path = fields.get("names", "name"), fields.get("positions", "position")

        def ros(msg: Any) -> Extracted:
            return _stamp_ns(msg), (
                [str(n) for n in _get(msg, names_path)],
                [float(v) for v in _get(msg, pos_path)],
            )

        return ros
    return None


_JOINT_IN_TEXT = re.compile(r"(\d+)\s*$")


def phase_value(value: Any, joint_names: list[str]) -> int | None:
    """A phase marker as a 1-based joint index, or None for 'no joint is being moved'."""
    if value is None or isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return int(value) if int(value) > 0 else None
    text = str(value).strip()
    if text.startswith("{"):
        try:
            return phase_value(json.loads(text).get("joint"), joint_names)
        except (ValueError, AttributeError):
            return None
    if text in joint_names:
        return joint_names.index(text) + 1
    match = _JOINT_IN_TEXT.search(text)
    return int(match.group(1)) if match and int(match.group(1)) > 0 else None


def _phase_extractor(schema: str, fields: dict[str, str]) -> Callable[[Any], Extracted]:
    key = fields.get("joint")

    def phase(msg: Any) -> Extracted:
        if key:
            return _stamp_ns(msg), _get(msg, key)
        value = _first(msg, ("joint", "data"))
        return _stamp_ns(msg), value

    return phase


def json_decoder(data: bytes) -> Any:
    return json.loads(data)


def message_decoder(info: ChannelInfo) -> Callable[[bytes], Any] | None:
    """Per-message decoder for a channel's encoding (the mcap library's, or json)."""
    if info.message_encoding == "json":
        return json_decoder
    schema = _schema_record(info)
    if info.message_encoding == "cdr":
        from mcap_ros2.decoder import DecoderFactory as Ros2Factory

        return Ros2Factory().decoder_for("cdr", schema)
    if info.message_encoding == "protobuf":
        from mcap_protobuf.decoder import DecoderFactory as ProtobufFactory

        return ProtobufFactory().decoder_for("protobuf", schema)
    return None


def _schema_record(info: ChannelInfo) -> Any:
    from mcap.records import Schema

    return Schema(id=1, name=info.schema_name, encoding=info.schema_encoding, data=info.schema_data)


ACCEPTED = {
    "point": "geometry_msgs/msg/PointStamped, geometry_msgs/msg/PoseStamped, "
    "geometry_msgs/msg/PoseWithCovarianceStamped, geometry_msgs/msg/TransformStamped, "
    "tf2_msgs/msg/TFMessage, foxglove.Point3InFrame, foxglove.PoseInFrame, "
    "foxglove.PosesInFrame, foxglove.FrameTransform(s), or JSON with field paths",
    "base": "the same types as the point stream",
    "joints": "sensor_msgs/msg/JointState, foxglove.JointStates, or JSON with field paths",
    "phase": 'std_msgs/msg/String or JSON {"joint": k}',
}


def extractor(
    stream: str,
    info: ChannelInfo,
    fields: dict[str, str],
    orientation: bool = False,
    child_frame: str = "",
    pose_index: int = 0,
) -> Callable[[Any], Extracted] | None:
    if stream in ("point", "base"):
        return _point_extractor(
            info.schema_name, fields, orientation and stream == "point", child_frame, pose_index
        )
    if stream == "joints":
        return _joint_extractor(info.schema_name, fields)
    if info.schema_name in PHASE_SCHEMAS or info.message_encoding == "json" or fields:
        return _phase_extractor(info.schema_name, fields)
    return None
