"""Pipelines: TOML files that map a log's channels to dhlog's four input streams.

A pipeline names, per stream (``point``, ``joints``, ``base``, ``phase``), the topic and, for JSON
messages of other shapes, the field paths; the length unit; the joints in chain order and their
types; and the segmentation tolerances. A camera pipeline reads ``[streams.image]`` instead of
``[streams.point]``, with its ``[target]`` (the board, :class:`dhlog.vision.boards.BoardSpec`)
and ``[camera]`` (the camera-info topic, or a calibration file read as
:class:`dhlog.vision.camera.Intrinsics`). Shipped pipelines live in ``pipelines/`` and are chosen
from the schemas a log holds when none is named.

The parts: :mod:`~dhlog.io.pipeline.spec` (the pipeline as data), :mod:`~dhlog.io.pipeline.values`
(values checked), :mod:`~dhlog.io.pipeline.parse` (the text parsed),
:mod:`~dhlog.io.pipeline.camera` (a camera pipeline's tables) and :mod:`~dhlog.io.pipeline.files`
(files and the shipped pipelines); every public name of theirs is importable from here.
"""

from dhlog.io.pipeline.camera import (
    CAMERA_KEYS,
    IMAGE_KEYS,
    MAX_ALTERNATIVES,
    MAX_CALIBRATION_BYTES,
    MAX_TARGET_LIST,
    load_calibration,
)
from dhlog.io.pipeline.files import (
    MAX_BYTES,
    load_pipeline,
    pipeline_by_name,
    pipeline_from,
    shipped_pipelines,
)
from dhlog.io.pipeline.parse import (
    COORDINATES,
    FIELD_KEYS,
    JOINT_KEYS,
    MAX_STATION_M,
    NOISE_KEYS,
    NOISE_RANGES,
    SEGMENTATION_RANGES,
    STREAM_KEYS,
    TOP_KEYS,
    VERTICAL,
    parse_pipeline,
)
from dhlog.io.pipeline.spec import (
    DEFAULT_IMAGE_TOPIC,
    DEFAULT_INFO_TOPIC,
    DEFAULT_TOPICS,
    ENCODINGS,
    STREAMS,
    CameraSpec,
    ImageStreamSpec,
    Pipeline,
    SegmentationSettings,
    StreamSpec,
)
from dhlog.io.pipeline.values import MAX_JOINTS, MAX_TEXT

__all__ = [
    "CAMERA_KEYS",
    "COORDINATES",
    "DEFAULT_IMAGE_TOPIC",
    "DEFAULT_INFO_TOPIC",
    "DEFAULT_TOPICS",
    "ENCODINGS",
    "FIELD_KEYS",
    "IMAGE_KEYS",
    "JOINT_KEYS",
    "MAX_ALTERNATIVES",
    "MAX_BYTES",
    "MAX_CALIBRATION_BYTES",
    "MAX_JOINTS",
    "MAX_STATION_M",
    "MAX_TARGET_LIST",
    "MAX_TEXT",
    "NOISE_KEYS",
    "NOISE_RANGES",
    "SEGMENTATION_RANGES",
    "STREAMS",
    "STREAM_KEYS",
    "TOP_KEYS",
    "VERTICAL",
    "CameraSpec",
    "ImageStreamSpec",
    "Pipeline",
    "SegmentationSettings",
    "StreamSpec",
    "load_calibration",
    "load_pipeline",
    "parse_pipeline",
    "pipeline_by_name",
    "pipeline_from",
    "shipped_pipelines",
]
