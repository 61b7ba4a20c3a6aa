"""A stream's channels decoded into blocks of (times, values): bulk CDR for little-endian
PointStamped, PoseStamped, PoseWithCovarianceStamped and JointState (:mod:`dhlog.io.ros2`),
message by message otherwise (:mod:`dhlog.io.decode.messages`). A message any decoder fails on
is skipped and counted, unless none of its channel's can be read (then the error names the
topic and the first failure); a bulk decode that meets a payload lying about its layout falls
back to the per-message path.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, UnknownSchemaError
from dhlog.io import ros2
from dhlog.io.decode.messages import (
    ACCEPTED,
    OtherFrameError,
    TransformExtractor,
    extractor,
    message_decoder,
)
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.pipeline.spec import StreamSpec

#: A stream's samples from one channel (or one joint-name layout): times (ns) and values.
Block = tuple[NDArray[np.int64], Any]


#: The bulk decodes: the target's position (PointStamped, PoseStamped) with its covariance's
#: position block (``_cov``: PoseWithCovarianceStamped) and with its orientation (``pose``);
#: joint states.
BULK_LAYOUTS = ("point", "point_cov", "pose", "pose_cov", "joints")
#: What a bulk decode raises on a payload that lies about its layout.
BULK_ERRORS = (ValueError, IndexError, struct.error, UnicodeDecodeError, OverflowError)


def bulk_layout(
    stream: str, info: ChannelInfo, fields: dict[str, str], orientation: bool
) -> str | None:
    """The bulk decode (one of ``BULK_LAYOUTS``) that reads ``stream`` from the channel's
    messages, told by its schema and encoding alone; None where they are read one by one.
    (Bulk also needs every message little-endian: :func:`bulk_decode` does not check.)"""
    if info.message_encoding != "cdr" or fields:
        return None
    schema = info.schema_name
    if orientation and stream == "point":
        return {ros2.POSE_STAMPED: "pose", ros2.POSE_WITH_COVARIANCE: "pose_cov"}.get(schema)
    if stream in ("point", "base") and schema in (ros2.POINT_STAMPED, ros2.POSE_STAMPED):
        return "point"
    if stream in ("point", "base") and schema == ros2.POSE_WITH_COVARIANCE:
        return "point_cov"
    if stream in ("joints", "commanded") and schema == ros2.JOINT_STATE:
        return "joints"  # the commanded joints (ISO 9283's) are a JointState stream too
    return None


def bulk_decode(layout: str, raw: RawMessages) -> list[Block]:
    """The messages of ``raw`` decoded in bulk as ``layout`` says (one of ``BULK_ERRORS`` on a
    payload that lies about its layout). Point values: ``x, y, z``, then the orientation
    quaternion (``pose``), then the covariance's position block (``_cov``); a zero stamp is
    replaced by the log time. Joint states: one block of (names, positions) per layout."""
    if layout == "joints":
        return [(g.stamps, (g.names, g.positions)) for g in ros2.joint_state_groups(raw)]
    if layout == "pose_cov":
        # the pose's orientation sits where PoseStamped's does: x, y, z, q (4), cov (6)
        stamps, rot = ros2.decode_point_bulk(raw, orientation=True)
        _, cov = ros2.decode_point_bulk(raw, covariance=True)
        xyz = np.hstack([rot, cov[:, 3:]])
    else:
        stamps, xyz = ros2.decode_point_bulk(
            raw, covariance=layout == "point_cov", orientation=layout == "pose"
        )
    return [(np.where(stamps != 0, stamps, raw.log_time), xyz)]


#: What a damaged payload can make a decoder raise (struct, UTF-8, JSON, protobuf, CDR parsers,
#: recursion on nesting): caught per message, where it is understood, and counted.
_DAMAGED = (Exception,)


@dataclass(frozen=True)
class Sources:
    """Where a stream's messages come from: the fast path's payloads by channel (``raw``:
    bulk CDR where the layout allows, per-message decoding otherwise) with the channels
    already decoded in bulk while the log was walked (``decoded``), or the mcap library's
    decoded messages by channel (``general``)."""

    raw: dict[int, RawMessages] | None
    general: dict[int, list[tuple[int, Any]]] | None = None
    decoded: Mapping[int, list[Block]] | None = None


@dataclass(frozen=True)
class Damaged:
    """A channel's messages that could not be decoded and were skipped: how many of how
    many, and the first's log time and reason."""

    topic: str
    bad: int
    total: int
    first: str

    def warning(self, path: str) -> str:
        """The reader's warning of these messages, in the log ``path``."""
        return (
            f"{path}: {self.bad} of {self.total} message(s) on {self.topic} could not be "
            f"decoded and were skipped (first at {self.first})."
        )


@dataclass(frozen=True)
class Decoded:
    """A stream decoded (:func:`decode_stream`): its blocks, the channels with messages
    skipped, and what the reader is to say (a transform stream's choice of frame)."""

    blocks: list[Block]
    damaged: tuple[Damaged, ...] = ()
    notes: tuple[str, ...] = ()


def decode_stream(
    stream: str, spec: StreamSpec, infos: list[ChannelInfo], sources: Sources, path: str
) -> Decoded:
    """Blocks of (times, values) of one stream (``spec``: its fields, orientation, child
    frame and pose index) over its channels ``infos``, read from ``sources``.

    Values are an (m, 3) array for point streams, ``(names, (m, k) array)`` for joints and a
    list for phase markers. Messages that cannot be decoded are skipped and reported in the
    value's ``damaged``; when none of a channel's messages can be read, that is an error.
    """
    fields, child_frame, pose_index = spec.fields, spec.child_frame, spec.pose_index
    orientation = spec.orientation and stream == "point"
    raw_by_channel, general, decoded = sources.raw, sources.general, sources.decoded
    damaged: list[Damaged] = []
    notes: list[str] = []
    blocks: list[Block] = []
    for info in infos:
        extract = extractor(stream, info, fields, orientation, child_frame, pose_index)
        if extract is None:
            accepted = ACCEPTED[stream]
            if orientation:
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
            if decoded is not None and info.id in decoded:
                blocks.extend(decoded[info.id])
                continue
            raw = raw_by_channel.get(info.id)
            if raw is None or len(raw) == 0:
                continue
            bulk = _bulk_blocks(stream, info, raw, fields, orientation)
            if bulk is not None:
                blocks.extend(bulk)
                continue
            try:
                decode = message_decoder(info)
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
            except OtherFrameError:  # a transform of another frame: not a sample
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
        if bad:
            damaged.append(Damaged(info.topic, bad, total, first_bad))
        if isinstance(extract, TransformExtractor):
            frames = ", ".join(sorted(extract.frames)) or "none"
            if len(extract.frames) > 1 and not child_frame:
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
    return Decoded(blocks, tuple(damaged), tuple(notes))


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
    layout = bulk_layout(stream, info, fields, orientation)
    if layout is None:
        return None
    try:
        if not np.all(ros2.little_endian(raw)):
            return None
        return bulk_decode(layout, raw)
    except BULK_ERRORS:
        return None
