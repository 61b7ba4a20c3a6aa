"""Decode a calibration log's streams (point, joints, base, phase) into polars tables.

Two paths give identical tables: the fast path walks the file with numpy
(:mod:`dhlog.io.mcapscan`) and decodes the fixed-layout ROS 2 messages in bulk
(:mod:`dhlog.io.ros2`), chunk by chunk as the walk meets them, so their payloads are never all
held (:mod:`dhlog.io.decode.columns`); the general path reads every message through the mcap
library's decoders (``mcap_ros2``, protobuf, JSON). JSON and protobuf messages are decoded one
by one on both paths, by the same field extractors. Time is the message's own stamp where it has
one, else log time.

Here: each stream's channels found and checked, the streams assembled into
:class:`~dhlog.io.logdata.LogData`, a rosbag2 bag folder read as one log; the pipeline's choice
is :mod:`dhlog.io.choose`'s, the payloads made ready (decoded by the walk, decompressed, or read
through the mcap library) :mod:`dhlog.io.payloads`', the decoding itself :mod:`dhlog.io.decode`'s.
:data:`__all__` is what the rest of dhlog imports from here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from dhlog.errors import InputError, MissingTopicError, PipelineError
from dhlog.io import scratch
from dhlog.io.choose import (
    IMPORT_METADATA,
    _channels_for,
    camera_pipeline,
    choose_pipeline,
    import_record,
)
from dhlog.io.decode.blocks import Block, Damaged, Sources, decode_stream
from dhlog.io.decode.columns import ColumnSink, layout_plan
from dhlog.io.decode.frames import (
    COVARIANCE_COLUMNS,
    ORIENTATION_COLUMNS,
    cartesian,
    clean,
    joints_frame,
    merged,
    points_frame,
    spilled,
)
from dhlog.io.decode.messages import (
    TRANSFORM_LISTS,
    TRANSFORM_SCHEMAS,
    phase_value,
)
from dhlog.io.decode.setback import unfolded
from dhlog.io.logdata import LogData
from dhlog.io.mcapscan import McapScan, scan_mcap
from dhlog.io.mcapwalk import ChannelInfo
from dhlog.io.payloads import _decoded_columns, _read_general, _unzstd_squeezed
from dhlog.io.pipeline import Pipeline, StreamSpec, shipped_pipelines
from dhlog.io.pointids import POINT_IDS_METADATA, read_point_ids

#: What the rest of dhlog reads from here (the columns of the point table among them).
__all__ = [
    "COVARIANCE_COLUMNS",
    "IMPORT_METADATA",
    "ORIENTATION_COLUMNS",
    "LogData",
    "camera_pipeline",
    "choose_pipeline",
    "read_log",
]

#: No robot dhlog identifies has more joints than this (phase markers beyond it are damage).
MAX_JOINTS = 64


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


def read_log(
    path: str | Path,
    pipeline: Pipeline | None = None,
    *,
    fast: bool = True,
    progress: Callable[[float], None] | None = None,
    unzstd: bool = False,
    hint_unread: bool = True,
    joint_names: Sequence[str] | None = None,
    joint_source: str = "model",
) -> LogData:
    """Decode the streams of the log at ``path`` with ``pipeline`` (chosen from the log if None).

    ``path`` may be a rosbag2 bag folder (its splits read as one log) or a zstd-compressed
    ``.mcap.zstd``; ``unzstd``: the payloads are compressed one by one.

    ``progress`` is called with the fraction of the file read so far.

    ``hint_unread``: warn of topics beside the point stream's, of its type, that no stream reads
    (a further target the pipeline does not name).

    ``joint_names``: the model's joint names (a nominal's, ``joint_source`` naming it): the
    joint-state stream's joints matched to them by name (:func:`dhlog.io.jointnames.chain_order`).

    ``fast=False`` reads through the mcap library's per-message decoders (the reference path).
    Non-finite samples are set aside and counted; a truncated file keeps what precedes the damage.
    """
    name = str(path)
    if pipeline is not None and pipeline.image is not None:
        raise PipelineError(
            pipeline.source,
            f"is a camera pipeline ({pipeline.name}: images on {pipeline.image.topic}), not a "
            "tracker's: dhlog process calibrates from camera logs with it; this reads tracker "
            "logs.",
        )
    if Path(path).is_dir() or Path(path).suffix == ".db3":  # a bag; a sqlite3 storage file
        return _read_bag(
            Path(path),
            pipeline,
            fast=fast,
            progress=progress,
            joint_names=joint_names,
            joint_source=joint_source,
        )
    topics = (
        None
        if pipeline is None
        else [t for s in pipeline.streams.values() for t in (s.topic, *s.extra_topics)]
    )
    # the fixed-layout ROS 2 messages decoded chunk by chunk as the walk meets them (their
    # payloads never all held); the rest kept for decoding below
    sink = None
    if fast and not unzstd:
        sink = ColumnSink(layout_plan([pipeline] if pipeline else shipped_pipelines()))
    scan = scan_mcap(path, topics=topics, progress=progress, sink=sink)
    warnings = list(scan.warnings)
    _unzstd_squeezed(scan.messages, name, unzstd)
    reason = None
    record = import_record(path) if IMPORT_METADATA in scan.metadata_names else {}
    if pipeline is None:
        try:
            pipeline, why = choose_pipeline(name, scan.channels)
        except PipelineError:
            damage = _damage_error(scan, "so no pipeline can be chosen")
            if damage is not None:  # what is missing is most likely lost to the damage
                raise damage from None
            raise
        reason = f"using pipeline '{pipeline.name}' ({why})"
        if record.get("orientation") == "true":
            point = replace(pipeline.streams["point"], orientation=True)
            pipeline = replace(pipeline, streams={**pipeline.streams, "point": point})
            reason += (
                ", with the target's orientation (dhlog import wrote it from the export: "
                "its dhlog.import record says orientation = true)"
            )
        further = tuple(t for t in record.get("further_target_topics", "").split(",") if t)
        if further and not pipeline.streams["point"].extra_topics:
            point = replace(pipeline.streams["point"], extra_topics=further)
            pipeline = replace(pipeline, streams={**pipeline.streams, "point": point})
            reason += (
                f", with the further targets on {', '.join(further)} (dhlog import wrote them "
                "from the export's --targets)"
            )
            # read again with their topics named: the scan decoded the pipeline's streams only
            again = read_log(path, pipeline, fast=fast, unzstd=unzstd, hint_unread=hint_unread)
            return replace(again, pipeline_reason=reason)
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
    unread = _unread_targets(scan.channels, infos, targets) if hint_unread else []
    if unread:
        warnings.append(
            f"{name}: {', '.join(unread)} {'carries' if len(unread) == 1 else 'carry'} the "
            f"target's message type but {'is' if len(unread) == 1 else 'are'} not read: "
            "further targets on the end-effector are fitted when the pipeline names their "
            "topics in extra_topics (docs/pipeline.md, Writing a pipeline file)."
        )
    decoded: dict[int, list[Block]] = {}
    if sink is not None:
        decoded = _decoded_columns(sink, scan, infos, targets, pipeline, topics)
    general: dict[int, list[tuple[int, Any]]] | None = None
    if not fast:
        wanted = [c for cs in infos.values() for c in cs] + [c for cs in targets for c in cs]
        general = _read_general(name, wanted)
    set_aside: dict[str, int] = {}
    damaged: list[Damaged] = []
    sources = Sources(scan.messages if fast else None, general, decoded)

    def decoded_as(stream: str, spec: StreamSpec, channels: list[ChannelInfo]) -> list[Block]:
        done = decode_stream(stream, spec, channels, sources, name)
        damaged.extend(done.damaged)
        warnings.extend(done.notes)
        return done.blocks

    def blocks_of(stream: str, channels: list[ChannelInfo] | None = None) -> list[Block]:
        spec = pipeline.streams[stream]
        return decoded_as(stream, spec, infos[stream] if channels is None else channels)

    with_rot = pipeline.streams["point"].orientation

    def points_of(channels: list[ChannelInfo] | None = None) -> pl.DataFrame:
        blocks = blocks_of("point", channels)
        if pipeline.streams["point"].coordinates == "spherical":
            blocks = [(t, cartesian(v, pipeline)) for t, v in blocks]
        frame = points_frame(blocks, pipeline.length_scale, with_rot)
        return clean(frame, "point", set_aside)

    def release(*later: str) -> None:
        """Drop the payloads no stream still to be decoded reads (they were all held until the
        end: the joint states' beside the decoded points)."""
        if not fast:
            return
        needed = {c.id for s in later if s in infos for c in infos[s]}
        for cid in [c for c in scan.messages if c not in needed]:
            del scan.messages[cid]

    points = points_of()
    if targets:  # one frame per target, labelled 0 (the primary one), 1, 2, …
        points = merged([points, *(points_of(channels) for channels in targets)], "target")
    release("base", "joints", "phase", "commanded")
    base = None
    if "base" in infos:
        base = clean(points_frame(blocks_of("base"), pipeline.length_scale), "base", set_aside)
    release("joints", "phase", "commanded")
    joints, chain, order = None, list(pipeline.joint_names or []), None
    set_back = None
    if "joints" in infos:
        topic = infos["joints"][0].topic
        joints, chain, order = joints_frame(
            name,
            topic,
            blocks_of("joints"),
            pipeline,
            joint_names,
            joint_source,
            in_chain_order=record.get("joint_order") == "chain",
        )
        if order.note:
            warnings.append(f"{name}: {order.note}")
        joints, set_back = unfolded(joints)
        joints = clean(joints, "joints", set_aside)
    commanded = None
    if "commanded" in infos:  # decoded as the joint states are (a JointState stream)
        # decoded as the joint states are, with its own stream's fields
        blocks = decoded_as("joints", pipeline.streams["commanded"], infos["commanded"])
        commanded, _, _ = joints_frame(
            name, infos["commanded"][0].topic, blocks, pipeline, joint_names, joint_source
        )
        commanded = clean(commanded, "commanded", set_aside)
    release("phase")
    phase = None
    if "phase" in infos:
        marks_blocks = blocks_of("phase")
        t = np.concatenate([b[0] for b in marks_blocks]) if marks_blocks else np.zeros(0, np.int64)
        marks = [phase_value(v, chain) for b in marks_blocks for v in b[1]]
        limit = len(chain) if chain else MAX_JOINTS
        absurd = sum(1 for m in marks if m is not None and m > limit)
        if absurd:  # a marker naming joint 999999999 is damage, not a joint to allocate
            set_aside["phase_beyond_joints"] = absurd
            warnings.append(
                f"{name}: {absurd} phase marker(s) name a joint beyond {limit}; they were "
                "set aside (check the phase topic)."
            )
            marks = [None if m is not None and m > limit else m for m in marks]
        phase = pl.DataFrame({"t_ns": t, "joint": pl.Series(marks, dtype=pl.Int32)}).sort("t_ns")
    for d in damaged:
        set_aside["damaged_message"] = set_aside.get("damaged_message", 0) + d.bad
        warnings.append(d.warning(name))
    point_ids = None
    if POINT_IDS_METADATA in scan.metadata_names:
        point_ids = read_point_ids(path, warnings)
    return LogData(
        name,
        pipeline,
        points,
        joints,
        chain,
        base,
        phase,
        set_aside,
        warnings,
        reason,
        commanded,
        order,
        point_ids,
        set_back,
    )


def _read_bag(
    folder: Path,
    pipeline: Pipeline | None,
    *,
    fast: bool,
    progress: Callable[[float], None] | None,
    joint_names: Sequence[str] | None = None,
    joint_source: str = "model",
) -> LogData:
    """A rosbag2 folder as rosbag2 writes it: its ``metadata.yaml`` read by the rosbags library
    (which also decompresses a file-compressed bag), every split file read in order as one log;
    per-message compressed payloads decompressed before decoding. A bag in sqlite3 storage
    (its ``.db3`` files; or one ``.db3`` file) is read through a temporary MCAP copy
    (:mod:`dhlog.io.sqlitebag`)."""
    from rosbags.rosbag2 import Reader, ReaderError

    from dhlog.io.sqlitebag import as_mcap, sqlite3_storage

    if sqlite3_storage(folder):  # read as the MCAP file it is copied into
        with as_mcap(folder, progress) as copy:
            log = read_log(
                copy.path,
                pipeline,
                fast=fast,
                progress=copy.reading,
                joint_names=joint_names,
                joint_source=joint_source,
            )
        return replace(
            log,
            path=str(folder),
            warnings=[copy.renamed(w) for w in log.warnings],
            pipeline_reason=None
            if log.pipeline_reason is None
            else f"{log.pipeline_reason}; {copy.stored}",
        )
    try:
        with Reader(folder) as bag:
            paths = [Path(s.path) for s in bag.storage.storages]  # type: ignore[attr-defined]
            per_message = bag.compression_mode == "message"
            # a long bag's files, each perhaps under the spill limit, wait for the join in
            # scratch files rather than all in memory
            spill = len(paths) > 1 and scratch.spills(sum(_size(p) for p in paths))
            parts = []
            for k, part in enumerate(paths):

                def step(f: float, k: int = k) -> None:
                    if progress is not None:
                        progress((k + f) / len(paths))

                log = read_log(
                    part,
                    pipeline,
                    fast=fast,
                    progress=step,
                    unzstd=per_message,
                    hint_unread=k == 0,  # said once for the bag
                    joint_names=joint_names,
                    joint_source=joint_source,
                )
                pipeline = log.pipeline
                if spill:
                    log = replace(
                        log,
                        points=spilled(log.points),
                        joints=None if log.joints is None else spilled(log.joints),
                        base=None if log.base is None else spilled(log.base),
                        commanded=None if log.commanded is None else spilled(log.commanded),
                    )
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
        return merged(present) if present else None

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
        joined([log.commanded for log in parts]),
        first.joint_order,
    )


def _unread_targets(
    channels: dict[int, ChannelInfo],
    infos: dict[str, list[ChannelInfo]],
    targets: list[list[ChannelInfo]],
) -> list[str]:
    """Topics of the log of the point stream's message type, beside its topic (the same
    namespace), that no stream reads: a further SMR the pipeline does not name, most often.
    Transforms are left out (a transform stream carries many frames: ``child_frame`` picks
    one, and ``/tf_static`` is not a target)."""
    points = infos.get("point", [])
    kinds = {c.schema_name for c in points if c.schema_name}
    kinds -= {*TRANSFORM_SCHEMAS, *TRANSFORM_LISTS}
    spaces = {c.topic.rpartition("/")[0] for c in points}
    read = {c.topic for cs in (*infos.values(), *targets) for c in cs}
    beside = {
        c.topic
        for c in channels.values()
        if c.schema_name in kinds and c.topic.rpartition("/")[0] in spaces
    }
    return sorted(beside - read)


def _size(path: Path) -> int:
    """The bytes of the file at ``path`` (0 when it cannot be read: the read says why)."""
    try:
        return path.stat().st_size
    except OSError:
        return 0
