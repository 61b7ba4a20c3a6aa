"""Decode a calibration log's streams (point, joints, base, phase) into polars tables.

Two paths give identical tables: the fast path walks the file with numpy
(:mod:`dhlog.io.mcapscan`) and decodes the fixed-layout ROS 2 messages in bulk
(:mod:`dhlog.io.ros2`); the general path reads every message through the mcap library's decoders
(``mcap_ros2``, protobuf, JSON). JSON and protobuf messages are decoded one by one on both paths,
by the same field extractors. Time is the message's own stamp where it has one, else log time.
"""

from __future__ import annotations

import json
import math
import re
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import (
    InputError,
    JointNamesError,
    MissingTopicError,
    PipelineError,
    UnknownSchemaError,
)
from dhlog.io import ros2
from dhlog.io.mcapscan import ZSTD_MAGIC, ChannelInfo, McapScan, RawMessages, scan_mcap
from dhlog.io.pipeline import Pipeline, shipped_pipelines
from dhlog.model.dh import JointType

POINT_SCHEMAS = {
    ros2.POINT_STAMPED: "point",
    ros2.POSE_STAMPED: "pose.position",
    "foxglove.Point3InFrame": "point",
    "foxglove.PoseInFrame": "pose.position",
    ros2.POSE_WITH_COVARIANCE: "pose.pose.position",
}
#: Point schemas that carry a covariance: the path of the row-major 6×6 (pose) covariance.
COVARIANCE_SCHEMAS = {ros2.POSE_WITH_COVARIANCE: "pose.covariance"}
#: Columns of the position covariance (m²) in the point frames and the measurement table.
COVARIANCE_COLUMNS = ("cxx", "cxy", "cxz", "cyy", "cyz", "czz")
#: Point schemas that carry the target frame's orientation, and where.
ORIENTATION_SCHEMAS = {
    ros2.POSE_STAMPED: "pose.orientation",
    "foxglove.PoseInFrame": "pose.orientation",
    ros2.POSE_WITH_COVARIANCE: "pose.pose.orientation",
}
#: The metadata record ``dhlog import`` writes; ``orientation = "true"`` in it turns the point
#: stream's orientation on when no pipeline is named (the export carried a 6-DoF target's).
IMPORT_METADATA = "dhlog.import"
#: Columns of the target frame's orientation (unit quaternion) with ``orientation = true``.
ORIENTATION_COLUMNS = ("rot_x", "rot_y", "rot_z", "rot_w")
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


@dataclass
class LogData:
    """The decoded streams of one log, in SI units, sorted by time.

    ``points``/``base``: ``t_ns, x, y, z``; ``joints``: ``t_ns, q_1 … q_n`` in chain order
    (``joint_names``); ``phase``: ``t_ns, joint`` (1-based, null between sweeps).
    ``set_aside`` counts samples dropped on reading, by reason.
    """

    path: str
    pipeline: Pipeline
    points: pl.DataFrame
    joints: pl.DataFrame | None
    joint_names: list[str]
    base: pl.DataFrame | None
    phase: pl.DataFrame | None
    set_aside: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    pipeline_reason: str | None = None


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


class _OtherFrameError(Exception):
    """A transform message without the frame the pipeline selects: not this stream's sample."""


class _TransformExtractor:
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
            raise _OtherFrameError
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
        return _TransformExtractor(schema, child_frame, orientation)
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


def _phase_value(value: Any, joint_names: list[str]) -> int | None:
    """A phase marker as a 1-based joint index, or None for 'no joint is being moved'."""
    if value is None or isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return int(value) if int(value) > 0 else None
    text = str(value).strip()
    if text.startswith("{"):
        try:
            return _phase_value(json.loads(text).get("joint"), joint_names)
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


def _json_decoder(data: bytes) -> Any:
    return json.loads(data)


def _message_decoder(info: ChannelInfo) -> Callable[[bytes], Any] | None:
    """Per-message decoder for a channel's encoding (the mcap library's, or json)."""
    if info.message_encoding == "json":
        return _json_decoder
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


def _extractor(
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


def _channels_for(scan_channels: dict[int, ChannelInfo], topic: str) -> list[ChannelInfo]:
    return [c for c in scan_channels.values() if c.topic == topic]


def choose_pipeline(path: str, channels: dict[int, ChannelInfo]) -> tuple[Pipeline, str]:
    """The shipped pipeline that fits the log's topics and encodings best, and why."""
    best: tuple[int, Pipeline] | None = None
    for pipeline in shipped_pipelines():
        score = 0
        fits = True
        for spec in pipeline.streams.values():
            found = [
                c
                for c in _channels_for(channels, spec.topic)
                if c.message_encoding in pipeline.encodings
            ]
            if found:
                score += 1
            elif spec.required:
                fits = False
        if fits and (best is None or score > best[0]):
            best = (score, pipeline)
    if best is None:
        listed = ", ".join(
            sorted(
                {f"{c.topic} ({c.schema_name or c.message_encoding})" for c in channels.values()}
            )
        )
        raise PipelineError(
            path,
            f"no shipped pipeline matches its topics ({listed or 'none'}); "
            "write a pipeline file for it and pass --pipeline.",
        )
    pipeline = best[1]
    point = _channels_for(channels, pipeline.streams["point"].topic)[0]
    reason = f"{pipeline.streams['point'].topic} is {point.schema_name} ({point.message_encoding})"
    return pipeline, reason


Block = tuple[NDArray[np.int64], Any]


def _damage_error(scan: McapScan, lacking: str) -> InputError | None:
    """The error for a file whose damage left too little to read (a pipeline or a required
    topic missing), naming where the damage is and what was recovered before it; None for an
    undamaged file (then the log itself lacks it). ``lacking`` ends the recovered part's
    sentence: what it does not hold."""
    if scan.truncated_at is not None:
        where = f"is cut short (or damaged) at byte {scan.truncated_at} of {scan.size}"
    elif scan.damaged:
        more = f" and {len(scan.damaged) - 1} more" if len(scan.damaged) > 1 else ""
        where = f"is damaged ({scan.damaged[0]}{more})"
    else:
        return None
    topics = scan.topics()
    if topics:
        got = f"{scan.recovered} message(s) on {', '.join(topics)} were recovered, {lacking}"
    else:
        got = f"no channel could be recovered, {lacking}"
    return InputError(
        f"{scan.path}: the file {where}: {got}. Copy the log again from where it was recorded "
        "(a recording or copy cut short?)."
    )


def _bulk_ok(
    raw: RawMessages, info: ChannelInfo, schemas: tuple[str, ...], fields: dict[str, str]
) -> bool:
    return (
        info.message_encoding == "cdr"
        and info.schema_name in schemas
        and not fields
        and bool(np.all(ros2.little_endian(raw)))
    )


#: What a damaged payload can make a decoder raise (struct, UTF-8, JSON, protobuf, CDR parsers,
#: recursion on nesting): caught per message, where it is understood, and counted.
_DAMAGED = (Exception,)


def _decode_stream(
    stream: str,
    infos: list[ChannelInfo],
    raw_by_channel: dict[int, RawMessages] | None,
    general: dict[int, list[tuple[int, Any]]] | None,
    fields: dict[str, str],
    path: str,
    orientation: bool = False,
    damaged: list[tuple[str, int, int, str]] | None = None,
    child_frame: str = "",
    notes: list[str] | None = None,
    pose_index: int = 0,
) -> list[Block]:
    """Blocks of (times, values) of one stream over all its channels.

    Values are an (m, 3) array for point streams, ``(names, (m, k) array)`` for joints and a
    list for phase markers. ``raw_by_channel`` is the fast path's input (bulk CDR where the
    layout allows, per-message decoding otherwise); ``general`` the mcap library's messages.
    Messages that cannot be decoded are skipped and reported in ``damaged`` as (topic, count,
    total, first reason); when none of a channel's messages can be read, that is an error.
    """
    blocks: list[Block] = []
    for info in infos:
        extract = _extractor(stream, info, fields, orientation, child_frame, pose_index)
        if extract is None:
            accepted = ACCEPTED[stream]
            if orientation and stream == "point":
                accepted = (
                    "geometry_msgs/msg/PoseStamped, foxglove.PoseInFrame, foxglove.PosesInFrame "
                    "or transforms (the pipeline asks "
                    "for the target's orientation: orientation = true)"
                )
            raise UnknownSchemaError(
                path, info.topic, info.schema_name, info.message_encoding, accepted
            )
        bad, first_bad = 0, ""
        if raw_by_channel is not None:
            raw = raw_by_channel.get(info.id)
            if raw is None or len(raw) == 0:
                continue
            bulk = _bulk_blocks(stream, info, raw, fields, orientation)
            if bulk is not None:
                blocks.extend(bulk)
                continue
            try:
                decode = _message_decoder(info)
            except _DAMAGED as exc:  # the schema itself is damaged
                raise UnknownSchemaError(
                    path,
                    info.topic,
                    info.schema_name,
                    info.message_encoding,
                    f"{ACCEPTED[stream]} (its schema cannot be parsed: {_reason(exc)})",
                ) from None
            if decode is None:
                raise UnknownSchemaError(
                    path, info.topic, info.schema_name, info.message_encoding, ACCEPTED[stream]
                )
            msgs = []
            for i in range(len(raw)):
                try:
                    msgs.append((int(raw.log_time[i]), decode(raw.payload(i))))
                except _DAMAGED as exc:
                    bad += 1
                    first_bad = first_bad or f"log time {int(raw.log_time[i])}: {_reason(exc)}"
        else:
            assert general is not None
            msgs = general.get(info.id, [])
        total = len(msgs) + bad
        t_list, values = [], []
        for log_time, msg in msgs:
            try:
                stamp, value = extract(msg)
                value = _checked(stream, value)
                if stamp is not None and not 0 <= stamp < 2**63:
                    raise ValueError(f"stamp {stamp} ns out of range")
            except _OtherFrameError:  # a transform of another frame: not a sample
                total -= 1
                continue
            except _DAMAGED as exc:
                bad += 1
                first_bad = first_bad or f"log time {log_time}: {_reason(exc)}"
                continue
            t_list.append(stamp if stamp is not None else log_time)
            values.append(value)
        if bad and not values:
            if fields:
                raise InputError(
                    f"{path}: {info.topic}: the pipeline's [streams.{stream}] fields "
                    f"({', '.join(f'{k} = {v!r}' for k, v in fields.items())}) do not fit its "
                    f"messages ({first_bad}); fix the field paths."
                )
            raise UnknownSchemaError(
                path,
                info.topic,
                info.schema_name,
                info.message_encoding,
                f"{ACCEPTED[stream]} (none of its {total} message(s) could be read; first: "
                f"{first_bad})",
            )
        if bad and damaged is not None:
            damaged.append((info.topic, bad, total, first_bad))
        if isinstance(extract, _TransformExtractor):
            frames = ", ".join(sorted(extract.frames)) or "none"
            if len(extract.frames) > 1 and not child_frame and notes is not None:
                notes.append(
                    f"{path}: {info.topic} carries the frames {frames}; the target is "
                    f"'{extract.chosen}' (set child_frame in [streams.{stream}] to choose)."
                )
            if not values and not bad:
                raise InputError(
                    f"{path}: {info.topic} has no transform to the frame '{child_frame}' "
                    f"(frames: {frames}); set child_frame in "
                    f"[streams.{stream}]."
                )
        t = np.asarray(t_list, dtype=np.int64)
        if stream in ("point", "base"):
            width = max((len(v) for v in values), default=3)
            rows = [v + [math.nan] * (width - len(v)) for v in values]
            blocks.append((t, np.asarray(rows, dtype=np.float64).reshape(-1, width)))
        elif stream == "joints":
            layouts: dict[tuple[str, ...], list[int]] = {}
            for i, (names, _) in enumerate(values):
                layouts.setdefault(tuple(names), []).append(i)
            for names_key, rows_of in layouts.items():
                q = np.asarray([values[r][1] for r in rows_of], dtype=np.float64)
                blocks.append((t[rows_of], (list(names_key), q.reshape(len(rows_of), -1))))
        else:
            blocks.append((t, values))
    return blocks


def _reason(exc: BaseException) -> str:
    """One line on why a message or schema could not be read."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:120]}" if text else type(exc).__name__


def _checked(stream: str, value: Any) -> Any:
    """``value`` as the stream needs it, or ValueError: numbers for points; names and as many
    positions for joint states (a message with fewer positions than names keeps the names that
    have one)."""
    if stream in ("point", "base"):
        return [float(v) for v in value]
    if stream == "joints":
        names, positions = value
        positions = [float(v) for v in positions]
        names = [str(n) for n in names][: len(positions)]
        if not names:
            raise ValueError("a joint state without positions")
        return names, positions[: len(names)]
    return value


def _bulk_blocks(
    stream: str, info: ChannelInfo, raw: RawMessages, fields: dict[str, str], orientation: bool
) -> list[Block] | None:
    """The bulk CDR decode of a channel where its type and layout allow, else None (also when
    the bulk decode meets a payload that lies about its layout: the per-message path then reads
    what can be read and counts the rest)."""
    with_rot = orientation and stream == "point"
    try:
        if with_rot and _bulk_ok(raw, info, (ros2.POSE_STAMPED,), fields):
            stamps, xyz = ros2.decode_point_bulk(raw, orientation=True)
            return [(np.where(stamps != 0, stamps, raw.log_time), xyz)]
        if with_rot and _bulk_ok(raw, info, (ros2.POSE_WITH_COVARIANCE,), fields):
            # the pose's orientation sits where PoseStamped's does: x, y, z, q (4), cov (6)
            stamps, rot = ros2.decode_point_bulk(raw, orientation=True)
            _, cov = ros2.decode_point_bulk(raw, covariance=True)
            xyz = np.hstack([rot, cov[:, 3:]])
            return [(np.where(stamps != 0, stamps, raw.log_time), xyz)]
        if (
            not with_rot
            and stream in ("point", "base")
            and _bulk_ok(raw, info, (ros2.POINT_STAMPED, ros2.POSE_STAMPED), fields)
        ):
            stamps, xyz = ros2.decode_point_bulk(raw)
            return [(np.where(stamps != 0, stamps, raw.log_time), xyz)]
        if (
            not with_rot
            and stream in ("point", "base")
            and _bulk_ok(raw, info, (ros2.POSE_WITH_COVARIANCE,), fields)
        ):
            stamps, xyz = ros2.decode_point_bulk(raw, covariance=True)
            return [(np.where(stamps != 0, stamps, raw.log_time), xyz)]
        if stream == "joints" and _bulk_ok(raw, info, (ros2.JOINT_STATE,), fields):
            return [(stamps, (names, q)) for stamps, names, q in ros2.decode_joint_state_bulk(raw)]
    except (ValueError, IndexError, struct.error, UnicodeDecodeError, OverflowError):
        return None
    return None


def _points_frame(blocks: list[Block], scale: float, orientation: bool = False) -> pl.DataFrame:
    """``t_ns, x, y, z`` (m), with ``orientation`` the target frame's orientation
    (``ORIENTATION_COLUMNS``, a unit quaternion), and the position covariance (m²,
    ``COVARIANCE_COLUMNS``) when any channel carries one (null for samples of channels that do
    not). Block values: ``x, y, z``, then with ``orientation`` the quaternion (4), then the
    covariance (6) where the channel has one."""
    t = np.concatenate([b[0] for b in blocks]) if blocks else np.zeros(0, dtype=np.int64)
    first_cov = 7 if orientation else 3
    with_cov = any(b[1].shape[1] == first_cov + 6 for b in blocks)
    width = first_cov + 6 if with_cov else first_cov
    parts = []
    for b in blocks:
        v = b[1]
        if v.shape[1] < width:
            v = np.hstack([v, np.full((v.shape[0], width - v.shape[1]), np.nan)])
        parts.append(v)
    arr = np.concatenate(parts) if parts else np.zeros((0, width))
    cols: dict[str, Any] = {
        "t_ns": t.astype(np.int64),
        "x": arr[:, 0] * scale,
        "y": arr[:, 1] * scale,
        "z": arr[:, 2] * scale,
    }
    if with_cov:
        for k, name in enumerate(COVARIANCE_COLUMNS):
            cols[name] = pl.Series(name, arr[:, first_cov + k] * scale**2, nan_to_null=True)
    if orientation:
        quat = arr[:, 3:7]
        quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
        for k, name in enumerate(ORIENTATION_COLUMNS):
            cols[name] = quat[:, k]
    return pl.DataFrame(cols)


def _cartesian(values: NDArray[np.float64], pipeline: Pipeline) -> NDArray[np.float64]:
    """A spherical stream's (horizontal angle, vertical angle, distance) as x, y, z in the
    tracker's own frame (length unit unchanged): the horizontal angle turns from +x towards +y
    about +z, the vertical angle is from the zenith (+z) or, with ``vertical = "elevation"``,
    from the horizon; angles in the pipeline's ``angle_unit``."""
    scale = pipeline.angle_scale
    hz, v, d = values[:, 0] * scale, values[:, 1] * scale, values[:, 2]
    if pipeline.streams["point"].vertical == "elevation":
        v = math.pi / 2 - v
    out = values.copy()
    out[:, 0] = d * np.sin(v) * np.cos(hz)
    out[:, 1] = d * np.sin(v) * np.sin(hz)
    out[:, 2] = d * np.cos(v)
    return out


def read_log(
    path: str | Path,
    pipeline: Pipeline | None = None,
    *,
    fast: bool = True,
    progress: Callable[[float], None] | None = None,
    unzstd: bool = False,
) -> LogData:
    """Decode the streams of the log at ``path`` with ``pipeline`` (chosen from the log if None).

    ``path`` may be a rosbag2 bag folder (its splits read as one log) or a zstd-compressed
    ``.mcap.zstd``; ``unzstd``: the payloads are compressed one by one.

    ``progress`` is called with the fraction of the file read so far.

    ``fast=False`` reads through the mcap library's per-message decoders (the reference path).
    Non-finite samples are set aside and counted; a truncated file keeps what precedes the damage.
    """
    name = str(path)
    if Path(path).is_dir():
        return _read_bag(Path(path), pipeline, fast=fast, progress=progress)
    scan = scan_mcap(
        path,
        topics=None
        if pipeline is None
        else [t for s in pipeline.streams.values() for t in (s.topic, *s.extra_topics)],
        progress=progress,
    )
    warnings = list(scan.warnings)
    # payloads compressed one by one (rosbag2 --compression-mode message): said by the bag's
    # metadata, or seen in the payloads themselves (no CDR, JSON or protobuf message starts
    # with zstd's magic number)
    squeezed = {
        cid: raw
        for cid, raw in scan.messages.items()
        if unzstd or (len(raw) and raw.payload(0)[:4] == ZSTD_MAGIC)
    }
    if squeezed:
        scan.messages.update(_unzstd_messages(squeezed, name))
    reason = None
    if pipeline is None:
        try:
            pipeline, why = choose_pipeline(name, scan.channels)
        except PipelineError:
            damage = _damage_error(scan, "so no pipeline can be chosen")
            if damage is not None:  # what is missing is most likely lost to the damage
                raise damage from None
            raise
        reason = f"using pipeline '{pipeline.name}' ({why})"
        if IMPORT_METADATA in scan.metadata_names and _imported_orientation(path):
            point = replace(pipeline.streams["point"], orientation=True)
            pipeline = replace(pipeline, streams={**pipeline.streams, "point": point})
            reason += (
                ", with the target's orientation (dhlog import wrote it from the export: "
                "its dhlog.import record says orientation = true)"
            )
    present = scan.topics()
    infos: dict[str, list[ChannelInfo]] = {}
    for stream, spec in pipeline.streams.items():
        found = _channels_for(scan.channels, spec.topic)
        if not found:
            if spec.required:
                damage = _damage_error(
                    scan, f"not {spec.topic}, which the pipeline {pipeline.name} needs"
                )
                if damage is not None:
                    raise damage from None
                raise MissingTopicError(name, stream, spec.topic, present)
            continue
        wrong = [
            c
            for c in found
            if stream in ("point", "joints") and c.message_encoding not in pipeline.encodings
        ]
        if wrong:
            c = wrong[0]
            raise PipelineError(
                pipeline.source,
                f"{name}: {c.topic} is encoded as '{c.message_encoding}' but the pipeline "
                f"declares encoding = {list(pipeline.encodings)}; use a pipeline for "
                f"'{c.message_encoding}' (dhlog chooses one when --pipeline is left out).",
            )
        infos[stream] = found
    # further targets (extra_topics): their channels, one list per target, labelled 1, 2, …
    targets = []
    for k, topic in enumerate(pipeline.streams["point"].extra_topics):
        found = _channels_for(scan.channels, topic)
        if not found:
            raise MissingTopicError(name, f"point (target {k + 2})", topic, present)
        targets.append(found)
    general: dict[int, list[tuple[int, Any]]] | None = None
    if not fast:
        wanted = [c for cs in infos.values() for c in cs] + [c for cs in targets for c in cs]
        general = _read_general(name, wanted)
    set_aside: dict[str, int] = {}
    damaged: list[tuple[str, int, int, str]] = []

    with_rot = pipeline.streams["point"].orientation

    def blocks_of(stream: str, channels: list[ChannelInfo] | None = None) -> list[Block]:
        return _decode_stream(
            stream,
            infos[stream] if channels is None else channels,
            scan.messages if fast else None,
            general,
            pipeline.streams[stream].fields,
            name,
            with_rot,
            damaged,
            pipeline.streams[stream].child_frame,
            warnings,
            pipeline.streams[stream].pose_index,
        )

    def points_of(channels: list[ChannelInfo] | None = None) -> pl.DataFrame:
        blocks = blocks_of("point", channels)
        if pipeline.streams["point"].coordinates == "spherical":
            blocks = [(t, _cartesian(v, pipeline)) for t, v in blocks]
        frame = _points_frame(blocks, pipeline.length_scale, with_rot)
        return _clean(frame, "point", set_aside)

    points = points_of()
    if targets:  # one frame per target, labelled 0 (the primary one), 1, 2, …
        frames = [points.with_columns(pl.lit(0, dtype=pl.Int32).alias("target"))]
        for k, channels in enumerate(targets):
            frame = points_of(channels)
            frames.append(frame.with_columns(pl.lit(k + 1, dtype=pl.Int32).alias("target")))
        points = pl.concat(frames, how="diagonal").sort("t_ns", maintain_order=True)
    base = None
    if "base" in infos:
        base = _clean(_points_frame(blocks_of("base"), pipeline.length_scale), "base", set_aside)
    joints, joint_names = None, list(pipeline.joint_names or [])
    if "joints" in infos:
        joints, joint_names = _joints_frame(
            name, infos["joints"][0].topic, blocks_of("joints"), pipeline
        )
        joints = _clean(joints, "joints", set_aside)
    phase = None
    if "phase" in infos:
        marks_blocks = blocks_of("phase")
        t = np.concatenate([b[0] for b in marks_blocks]) if marks_blocks else np.zeros(0, np.int64)
        marks = [_phase_value(v, joint_names) for b in marks_blocks for v in b[1]]
        limit = len(joint_names) if joint_names else MAX_JOINTS
        absurd = sum(1 for m in marks if m is not None and m > limit)
        if absurd:  # a marker naming joint 999999999 is damage, not a joint to allocate
            set_aside["phase_beyond_joints"] = absurd
            warnings.append(
                f"{name}: {absurd} phase marker(s) name a joint beyond {limit}; they were "
                "set aside (check the phase topic)."
            )
            marks = [None if m is not None and m > limit else m for m in marks]
        phase = pl.DataFrame({"t_ns": t, "joint": pl.Series(marks, dtype=pl.Int32)}).sort("t_ns")
    for topic, bad, total, first in damaged:
        set_aside["damaged_message"] = set_aside.get("damaged_message", 0) + bad
        warnings.append(
            f"{name}: {bad} of {total} message(s) on {topic} could not be decoded and were "
            f"skipped (first at {first})."
        )
    return LogData(
        name, pipeline, points, joints, joint_names, base, phase, set_aside, warnings, reason
    )


#: No robot dhlog identifies has more joints than this (phase markers beyond it are damage).
MAX_JOINTS = 64
#: Larger coordinates (m) or encoder values (rad, m) are not measurements.
MAX_VALUE = 1e5


def _imported_orientation(path: str | Path) -> bool:
    """True when the ``dhlog.import`` metadata record of the MCAP file at ``path`` says the
    export carried the target's orientation (``orientation = "true"``)."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            for record in make_reader(f).iter_metadata():
                if record.name == IMPORT_METADATA:
                    return record.metadata.get("orientation") == "true"
    except Exception:  # a record that cannot be read turns nothing on
        return False
    return False


def _read_bag(
    folder: Path,
    pipeline: Pipeline | None,
    *,
    fast: bool,
    progress: Callable[[float], None] | None,
) -> LogData:
    """A rosbag2 folder as rosbag2 writes it: its ``metadata.yaml`` read by the rosbags library
    (which also decompresses a file-compressed bag), every split file read in order as one log;
    per-message compressed payloads decompressed before decoding."""
    from rosbags.rosbag2 import Reader, ReaderError

    try:
        with Reader(folder) as bag:
            paths = [Path(s.path) for s in bag.storage.storages]  # type: ignore[attr-defined]
            per_message = bag.compression_mode == "message"
            parts = []
            for k, part in enumerate(paths):

                def step(f: float, k: int = k) -> None:
                    if progress is not None:
                        progress((k + f) / len(paths))

                log = read_log(part, pipeline, fast=fast, progress=step, unzstd=per_message)
                pipeline = log.pipeline
                parts.append(log)
    except (ReaderError, FileNotFoundError, KeyError, ValueError) as exc:
        raise InputError(
            f"{folder}: a folder, but not a rosbag2 bag dhlog can read ({exc}); give the "
            "bag folder (with metadata.yaml) or one .mcap file."
        ) from None
    if not parts:
        raise InputError(f"{folder}: the bag lists no storage files.")
    first = parts[0]

    def joined(frames: list[pl.DataFrame | None]) -> pl.DataFrame | None:
        present = [f for f in frames if f is not None]
        return pl.concat(present, how="diagonal").sort("t_ns") if present else None

    set_aside: dict[str, int] = {}
    for log in parts:
        for key, value in log.set_aside.items():
            set_aside[key] = set_aside.get(key, 0) + value
    points = joined([log.points for log in parts])
    assert points is not None
    return LogData(
        str(folder),
        first.pipeline,
        points,
        joined([log.joints for log in parts]),
        first.joint_names,
        joined([log.base for log in parts]),
        joined([log.phase for log in parts]),
        set_aside,
        [w for log in parts for w in log.warnings],
        None
        if first.pipeline_reason is None
        else f"{first.pipeline_reason}; a rosbag2 bag of {len(parts)} file(s)"
        + (", messages zstd-compressed" if per_message else ""),
    )


def _unzstd_messages(messages: dict[int, RawMessages], path: str) -> dict[int, RawMessages]:
    """Payloads compressed one by one (rosbag2 ``--compression-mode message``), decompressed
    into one buffer per channel; a payload that is not zstd is damage (left out, counted by
    the decoders as an empty message)."""
    import zstandard

    out = {}
    for cid, raw in messages.items():
        d = zstandard.ZstdDecompressor()
        parts = []
        for i in range(len(raw)):
            payload = raw.payload(i)
            try:
                parts.append(d.decompress(payload, max_output_size=64 * len(payload) + 4096))
            except zstandard.ZstdError:
                parts.append(b"")
        lengths = np.array([len(p) for p in parts], dtype=np.int64)
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        data = np.frombuffer(b"".join(parts), dtype=np.uint8)
        out[cid] = RawMessages(data, starts, lengths, raw.log_time)
    return out


def _clean(frame: pl.DataFrame, stream: str, set_aside: dict[str, int]) -> pl.DataFrame:
    value_cols = [c for c in frame.columns if c != "t_ns"]
    finite = (
        pl.all_horizontal(
            [
                pl.col(c).is_finite().fill_null(c in COVARIANCE_COLUMNS)  # no covariance: kept
                for c in value_cols
            ]
        )
        if value_cols
        else pl.lit(True)
    )
    kept = frame.filter(finite)
    dropped = frame.height - kept.height
    if dropped:
        set_aside[f"non_finite_{stream}"] = dropped
    # values no measurement has (beyond 100 km, or 10⁶ rad of encoder travel) and stamps
    # outside 1970-2262 are damage, not data: set aside before any arithmetic overflows
    ranged = [c for c in value_cols if c in ("x", "y", "z") or c.startswith("q_")]
    sane = pl.all_horizontal([pl.col(c).abs() < MAX_VALUE for c in ranged]) if ranged else True
    before = kept.height
    kept = kept.filter(sane & (pl.col("t_ns") >= 0))
    if kept.height < before:
        set_aside[f"out_of_range_{stream}"] = before - kept.height
    return kept.sort("t_ns", maintain_order=True)


def _joints_frame(
    path: str, topic: str, blocks: list[Block], pipeline: Pipeline
) -> tuple[pl.DataFrame, list[str]]:
    """The joints table in chain order from blocks of (times, (names, positions))."""
    seen: list[str] = []
    for _, (names, _) in blocks:
        seen.extend(n for n in names if n not in seen)
    expected = list(pipeline.joint_names) if pipeline.joint_names else seen
    missing = [n for n in expected if n not in seen]
    if missing or not expected:
        raise JointNamesError(path, topic, expected, seen)
    column = {n: i for i, n in enumerate(expected)}
    t = np.concatenate([b[0] for b in blocks]).astype(np.int64)
    q = np.full((t.size, len(expected)), np.nan)
    row = 0
    for times, (names, values) in blocks:
        src = [k for k, n in enumerate(names) if n in column]
        dst = [column[names[k]] for k in src]
        q[row : row + times.size, dst] = values[:, src]
        row += times.size
    types = pipeline.joint_types or (None,) * len(expected)
    if len(types) != len(expected):
        raise PipelineError(
            pipeline.source,
            f"[joints] types lists {len(types)} joint(s) but {path} has {len(expected)} on "
            f"{topic} ({', '.join(expected)}); give one type per joint.",
        )
    for j, jt in enumerate(types):  # prismatic in the length unit, the rest in the angle unit
        q[:, j] *= pipeline.length_scale if jt is JointType.PRISMATIC else pipeline.angle_scale
    offset_ns = round(pipeline.segmentation.clock_offset * 1e9)
    data: dict[str, Any] = {"t_ns": t + offset_ns}
    data.update({f"q_{j + 1}": q[:, j] for j in range(len(expected))})
    return pl.DataFrame(data), expected


def _read_general(path: str, infos: list[ChannelInfo]) -> dict[int, list[tuple[int, Any]]]:
    """Every message of ``infos``' topics through the mcap library's reader and decoders."""
    from mcap.decoder import DecoderFactory
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory as ProtobufFactory
    from mcap_ros2.decoder import DecoderFactory as Ros2Factory

    class JsonFactory(DecoderFactory):
        def decoder_for(self, message_encoding: str, schema: Any) -> Callable[[bytes], Any] | None:
            return _json_decoder if message_encoding == "json" else None

    out: dict[int, list[tuple[int, Any]]] = {}
    topics = sorted({i.topic for i in infos})
    by_topic = {(i.topic, i.schema_name): i.id for i in infos}
    try:
        with open(path, "rb") as f:
            reader = make_reader(
                f, decoder_factories=[Ros2Factory(), ProtobufFactory(), JsonFactory()]
            )
            for schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=topics, log_time_order=False
            ):
                key = by_topic.get((channel.topic, schema.name if schema else ""))
                if key is not None:
                    out.setdefault(key, []).append((message.log_time, decoded))
    except (McapError, EOFError, ValueError) as exc:
        raise InputError(f"{path}: the mcap library could not read it ({exc}).") from None
    return out
