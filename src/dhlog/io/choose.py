"""Which pipeline reads a log: :func:`choose_pipeline` (a tracker log's, by the schemas and topics
its channels carry, the orientation on for a log whose ``dhlog.import`` record says
``orientation = true``: :func:`import_record`) and :func:`camera_pipeline` (a camera log's, by
its image topics).
"""

from __future__ import annotations

import struct
from pathlib import Path

from dhlog.errors import PipelineError
from dhlog.io.mcapwalk import ChannelInfo
from dhlog.io.pipeline import Pipeline, pipeline_by_name, shipped_pipelines

#: The metadata record ``dhlog import`` writes; ``orientation = "true"`` in it turns the point
#: stream's orientation on when no pipeline is named (the export carried a 6-DoF target's).
IMPORT_METADATA = "dhlog.import"


#: the schemas of camera images (those of :mod:`dhlog.identify.camera.frames.images`, named here
#: without its cv2)
_IMAGE_SCHEMAS = frozenset(
    {
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CompressedImage",
        "foxglove.RawImage",
        "foxglove.CompressedImage",
    }
)


def camera_pipeline(path: str | Path, pipeline: Pipeline | None) -> Pipeline | None:
    """The camera pipeline to read ``path`` with, or None for a tracker log: ``pipeline`` when it is
    a camera's; without one, when the log's channels (the summary's, else those before its 200th
    message) carry camera images, the shipped camera pipeline whose image topic the log has, else
    the shipped ``ros2_camera`` (``identify.camera.frames.observe`` takes the cameras on topics like
    its image topic in other namespaces, e.g. ``/camera_1/…``, ``/camera_2/…``)."""
    if pipeline is not None:
        return pipeline if pipeline.is_camera else None
    topics = _image_topics(Path(path))
    if not topics:
        return None
    named = [
        p
        for p in shipped_pipelines()
        if p.image is not None and {p.image.topic, *p.image.alternatives} & topics
    ]
    return pipeline_by_name(named[0].name if named else "ros2_camera")  # read whole


def _image_topics(path: Path) -> set[str]:
    """The topics of ``path`` (an MCAP file or a bag folder's first file) carrying camera
    images, read from its summary or, without one, from the records before the 200th message;
    an unreadable file gives none (the tracker reader then says what is wrong)."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    from dhlog.io.sqlitebag import sqlite3_storage

    if sqlite3_storage(path):  # its connections' types, from rosbags' reader of the bag
        return _sqlite3_image_topics(path)
    if path.is_dir():
        files = sorted(path.glob("*.mcap"))
        if not files:
            return set()
        path = files[0]
    try:
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
            if summary is not None:
                return {
                    c.topic
                    for c in summary.channels.values()
                    if c.schema_id in summary.schemas
                    and summary.schemas[c.schema_id].name in _IMAGE_SCHEMAS
                }
            f.seek(0)
            schemas: dict[int, str] = {}
            found: set[str] = set()
            seen = 0
            for record in StreamReader(f, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel) and schemas.get(record.schema_id) in (
                    _IMAGE_SCHEMAS
                ):
                    found.add(record.topic)
                elif isinstance(record, Message):
                    seen += 1
                    if seen >= 200:
                        break
            return found
    except (McapError, OSError, ValueError, KeyError, EOFError, AssertionError, struct.error):
        return set()  # a damaged summary or footer (struct.error from the mcap reader's reads)


def _sqlite3_image_topics(path: Path) -> set[str]:
    """The topics of a rosbag2 bag in sqlite3 storage (a folder or one ``.db3`` file) whose
    connections carry camera images; an unreadable bag gives none (the reader says why)."""
    from rosbags.rosbag2 import Reader

    try:
        with Reader(path) as bag:
            return {c.topic for c in bag.connections if c.msgtype in _IMAGE_SCHEMAS}
    except Exception:  # rosbags' errors of a damaged bag or database: the reader names them
        return set()


def _channels_for(scan_channels: dict[int, ChannelInfo], topic: str) -> list[ChannelInfo]:
    return [c for c in scan_channels.values() if c.topic == topic]


def choose_pipeline(path: str, channels: dict[int, ChannelInfo]) -> tuple[Pipeline, str]:
    """The shipped pipeline that fits the log's topics and encodings best, and why."""
    best: tuple[int, Pipeline] | None = None
    for pipeline in shipped_pipelines():
        if pipeline.is_camera:  # a camera log is read by identify.camera.frames, not here
            continue
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
        images = sorted({c.topic for c in channels.values() if c.schema_name in _IMAGE_SCHEMAS})
        if images:  # a vision log: said so, not taken for a tracker log without one
            described = [
                p.name
                for p in shipped_pipelines()
                if p.image is not None and {p.image.topic, *p.image.alternatives} & set(images)
            ]
            named = f" (the shipped pipeline {described[0]} describes it)" if described else ""
            raise PipelineError(
                path,
                f"a vision log (camera images on {', '.join(images)}){named}, not a tracker's: "
                "calibrate from it with dhlog process; this reads tracker logs.",
            )
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


def import_record(path: str | Path) -> dict[str, str]:
    """The ``dhlog.import`` metadata record of the MCAP file at ``path`` (empty when it has
    none or it cannot be read): ``orientation = "true"`` where the export carried the target's
    orientation, ``further_target_topics`` where it held several targets, ``timing``."""
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            for record in make_reader(f).iter_metadata():
                if record.name == IMPORT_METADATA:
                    return {str(k): str(v) for k, v in record.metadata.items()}
    except Exception:  # a record that cannot be read turns nothing on
        return {}
    return {}
