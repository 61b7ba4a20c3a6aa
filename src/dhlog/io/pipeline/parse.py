"""A pipeline's TOML text parsed and checked (:func:`parse_pipeline`): every table's keys
(:data:`TOP_KEYS`, :data:`STREAM_KEYS`, :data:`FIELD_KEYS`, :data:`JOINT_KEYS`,
:data:`NOISE_KEYS`), the units, the streams (cartesian or spherical, :data:`COORDINATES`), the
joints, the segmentation values within :data:`SEGMENTATION_RANGES` and ``[noise]`` within
:data:`NOISE_RANGES` as a :class:`dhlog.model.noise.NoiseModel`.
"""

from __future__ import annotations

import math
import sys
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dhlog.errors import DhlogError, PipelineError
from dhlog.model.dh import JointType
from dhlog.model.noise import NoiseModel

if TYPE_CHECKING:  # OpenCV imported only when a camera pipeline is read
    from dhlog.vision.boards import BoardSpec
from dhlog.io.pipeline.camera import _camera_tables, _image_stream
from dhlog.io.pipeline.spec import (
    DEFAULT_TOPICS,
    ENCODINGS,
    STREAMS,
    CameraSpec,
    Pipeline,
    SegmentationSettings,
    StreamSpec,
)
from dhlog.io.pipeline.values import _check_keys, _flag, _number, _shown, _table, _text, _texts

#: Every key a pipeline may hold, per table (unknown keys are errors, with the nearest known).
TOP_KEYS = (
    "name",
    "description",
    "encoding",
    "length_unit",
    "angle_unit",
    "streams",
    "joints",
    "segmentation",
    "noise",
    "target",
    "camera",
)


STREAM_KEYS = (
    "topic",
    "required",
    "fields",
    "extra_topics",
    "orientation",
    "child_frame",
    "pose_index",
    "coordinates",
    "vertical",
)


#: How a point stream gives the target: ``cartesian`` (x, y, z) or ``spherical`` (a tracker's
#: own horizontal angle, vertical angle and distance, in that order where x, y, z would be).
COORDINATES = ("cartesian", "spherical")


#: What a spherical stream's vertical angle is measured from: the zenith (+z, a tracker's usual
#: "V", 90° at the horizon) or the horizon (elevation, 0° at the horizon).
VERTICAL = ("zenith", "elevation")


FIELD_KEYS = {
    "point": ("x", "y", "z", "stamp_ns", "horizontal", "vertical", "distance"),
    "base": ("x", "y", "z", "stamp_ns"),
    "joints": ("joints", "names", "positions"),
    "phase": ("joint",),
    "commanded": ("joints", "names", "positions"),
}


JOINT_KEYS = ("names", "types")


NOISE_KEYS = (
    "model",
    "sigma",
    "radial",
    "transverse",
    "transverse_per_m",
    "station",
    "orientation",
)


#: The range of each [segmentation] value (SI units: s, rad, m; a count for min_samples).
SEGMENTATION_RANGES: dict[str, tuple[float, float, str]] = {
    "lock_tolerance": (0.0, 1.0, "rad (m for prismatic joints)"),
    "motion_window": (0.0, 3600.0, "s"),
    "join_tolerance": (0.0, 3600.0, "s"),
    "min_samples": (1, 1_000_000, "samples"),
    "min_sweep": (0.0, 2.0 * math.pi, "rad"),
    "min_travel": (0.0, 10.0, "m"),
    "clock_offset": (-3e9, 3e9, "s"),
}


#: The range of each [noise] standard deviation (m, rad; transverse_per_m in m per m).
NOISE_RANGES: dict[str, tuple[float, float, str]] = {
    "sigma": (1e-9, 1.0, "m"),
    "radial": (1e-9, 1.0, "m"),
    "transverse": (1e-9, 1.0, "m"),
    "transverse_per_m": (0.0, 1.0, "m per m of distance"),
    "orientation": (1e-9, math.pi, "rad"),
}


#: The farthest a tracker station may be from the measurement frame's origin (m).
MAX_STATION_M = 1000.0


def parse_pipeline(
    text: str, source: str, *, folder: str | Path | None = None, boards: bool = True
) -> Pipeline:
    """Parse pipeline TOML ``text``; ``source`` names the file in error messages. Every value
    is checked for its type and range, each failure one :class:`PipelineError` naming the key.
    ``folder`` (default: ``source``'s) is where a relative ``[camera] calibration`` path is.
    ``boards`` False leaves a camera pipeline's ``[target]`` and ``[camera]`` unread (None):
    the shipped pipelines listed to choose a tracker log's (no OpenCV imported for it)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PipelineError(source, f"not valid TOML ({exc}).") from None
    except RecursionError:
        raise PipelineError(
            source, "is nested too deeply to be a pipeline (not valid TOML)."
        ) from None
    except ValueError:  # an integer beyond Python's digit limit
        raise PipelineError(
            source,
            f"holds an integer of more than {sys.get_int_max_str_digits()} digits; not a "
            "pipeline: check what the file holds.",
        ) from None
    try:
        return _parse(data, source, Path(source).parent if folder is None else Path(folder), boards)
    except RecursionError:
        raise PipelineError(source, "is nested too deeply to be a pipeline.") from None


def _parse(data: dict[str, Any], source: str, folder: Path, boards: bool = True) -> Pipeline:
    _check_keys(source, "top level", data, TOP_KEYS)
    name = _text(source, "name", data.get("name", Path(source).stem))
    description = _text(source, "description", data.get("description", ""))
    raw_enc = data.get("encoding", list(ENCODINGS))
    if isinstance(raw_enc, str):
        raw_enc = [raw_enc]
    encodings = tuple(_texts(source, "encoding", raw_enc))
    bad = [e for e in encodings if e not in ENCODINGS]
    if bad or not encodings:
        raise PipelineError(source, f"encoding {bad} unknown; use one of {list(ENCODINGS)}.")
    unit = _text(source, "length_unit", data.get("length_unit", "m"))
    if unit not in ("m", "mm"):
        raise PipelineError(source, f"length_unit '{unit}' unknown; use 'm' or 'mm'.")
    angle_unit = _text(source, "angle_unit", data.get("angle_unit", "rad"))
    if angle_unit not in ("rad", "deg", "gon"):
        raise PipelineError(
            source, f"angle_unit '{angle_unit}' unknown; use 'rad', 'deg' or 'gon'."
        )
    streams_table = _table(source, data, "streams")
    unknown = sorted(set(streams_table) - {*STREAMS, "image"})
    if unknown:
        raise PipelineError(
            source, f"unknown stream(s) {unknown}; streams are {[*STREAMS, 'image']}."
        )
    image = _image_stream(source, streams_table.get("image"))
    streams: dict[str, StreamSpec] = {}
    for stream in STREAMS:
        spec = streams_table.get(stream)
        if spec is None:
            continue
        if not isinstance(spec, dict):
            raise PipelineError(source, f"[streams.{stream}] must be a table.")
        _check_keys(source, f"[streams.{stream}]", spec, STREAM_KEYS)
        where = f"[streams.{stream}]"
        required = _flag(source, f"{where} required", spec.get("required", stream == "point"))
        fields = {
            str(k): _text(source, f"{where} fields.{k}", v)
            for k, v in _table(source, spec, "fields").items()
        }
        _check_keys(source, f"[streams.{stream}] fields", fields, FIELD_KEYS[stream])
        extra = spec.get("extra_topics", [])
        if stream != "point" and extra:
            raise PipelineError(source, f"[streams.{stream}] extra_topics is for the point stream.")
        if not isinstance(extra, list) or not all(isinstance(t, str) for t in extra):
            raise PipelineError(source, "[streams.point] extra_topics must be a list of topics.")
        extra = _texts(source, f"{where} extra_topics", extra)
        orientation = spec.get("orientation", False)
        if not isinstance(orientation, bool) or (orientation and stream != "point"):
            raise PipelineError(
                source, "[streams.point] orientation must be true or false (point stream only)."
            )
        coordinates = spec.get("coordinates", "cartesian")
        vertical = spec.get("vertical", "zenith")
        pose_index = spec.get("pose_index", 0)
        if coordinates not in COORDINATES or (coordinates != "cartesian" and stream != "point"):
            raise PipelineError(
                source,
                f"[streams.{stream}] coordinates must be one of {list(COORDINATES)} "
                "('spherical' for the point stream only).",
            )
        if vertical not in VERTICAL:
            raise PipelineError(
                source, f"[streams.{stream}] vertical must be one of {list(VERTICAL)}."
            )
        if (
            not isinstance(pose_index, int)
            or isinstance(pose_index, bool)
            or not 0 <= pose_index <= 1_000_000
        ):
            raise PipelineError(
                source, f"[streams.{stream}] pose_index must be a whole number from 0 to 1000000."
            )
        if coordinates == "spherical" and orientation:
            raise PipelineError(
                source, "[streams.point] a spherical point stream has no orientation."
            )
        angles = [k for k in ("horizontal", "vertical", "distance") if k in fields]
        if coordinates == "spherical" and not angles:
            raise PipelineError(
                source,
                f'[streams.point] coordinates = "spherical" but its fields name no '
                "horizontal angle, vertical angle and distance: the messages of "
                f"{spec.get('topic', DEFAULT_TOPICS[stream])!s} carry x, y, z (a PointStamped "
                "or PoseStamped is Cartesian); leave coordinates out, or name the fields of a "
                'spherical stream: fields = { horizontal = "hz", vertical = "v", distance = '
                '"d" }.',
            )
        if angles and coordinates != "spherical":
            raise PipelineError(
                source,
                f"[streams.point] fields name {', '.join(angles)} (a tracker's angles and "
                'distance) but coordinates is not "spherical": they would be read as x, y, z; '
                'set coordinates = "spherical".',
            )
        streams[stream] = StreamSpec(
            _text(source, f"{where} topic", spec.get("topic", DEFAULT_TOPICS[stream])),
            required,
            fields,
            tuple(extra),
            orientation,
            _text(source, f"{where} child_frame", spec.get("child_frame", "")),
            pose_index,
            str(coordinates),
            str(vertical),
        )
    if image is not None and "point" in streams:
        raise PipelineError(
            source,
            "it has both [streams.point] and [streams.image]; a pipeline reads a tracker's "
            "target or a camera's images: give one of them.",
        )
    if image is None and "point" not in streams:
        raise PipelineError(
            source,
            "it has no [streams.point]; the target stream is required ([streams.image] for a "
            "camera).",
        )
    target: BoardSpec | None = None
    camera: CameraSpec | None = None
    if boards or image is None:
        target, camera = _camera_tables(data, source, folder, image is not None)
    joints = _table(source, data, "joints")
    _check_keys(source, "[joints]", joints, JOINT_KEYS)
    names = None if "names" not in joints else _texts(source, "[joints] names", joints["names"])
    if names is not None and len(set(names)) != len(names):
        twice = next(n for n in names if names.count(n) > 1)
        raise PipelineError(source, f"[joints] names holds '{twice}' twice; name each joint once.")
    types_raw = None if "types" not in joints else _texts(source, "[joints] types", joints["types"])
    types: tuple[JointType | None, ...] | None = None
    if types_raw is not None:
        try:
            types = tuple(None if t in ("", "auto") else JointType.parse(t) for t in types_raw)
        except ValueError as exc:
            raise PipelineError(source, f"[joints] types: {exc}") from None
        if names is not None and len(types) != len(names):
            raise PipelineError(source, "[joints] names and types differ in length.")
    seg_table = _table(source, data, "segmentation")
    _check_keys(
        source, "[segmentation]", seg_table, tuple(SegmentationSettings.__dataclass_fields__)
    )
    seg_values: dict[str, Any] = {}
    for k, v in seg_table.items():
        where = f"[segmentation] {k}"
        if k == "clock_offset_fixed":
            seg_values[k] = _flag(source, where, v)
            continue
        x = _number(source, where, v, *SEGMENTATION_RANGES[k], whole=k == "min_samples")
        seg_values[k] = int(x) if k == "min_samples" else x
    seg = SegmentationSettings(**seg_values)
    noise_table = _table(source, data, "noise")
    _check_keys(source, "[noise]", noise_table, NOISE_KEYS)
    kwargs: dict[str, Any] = {}
    for k, v in noise_table.items():
        where = f"[noise] {k}"
        if k == "model":
            kwargs[k] = _text(source, where, v)
        elif k == "station":
            if not isinstance(v, list) or len(v) != 3:
                raise PipelineError(
                    source, f"{where} needs three coordinates [x, y, z] in metres, not {_shown(v)}."
                )
            kwargs[k] = tuple(
                _number(source, f"{where}[{i}]", x, -MAX_STATION_M, MAX_STATION_M, "m")
                for i, x in enumerate(v)
            )
        else:
            kwargs[k] = _number(source, where, v, *NOISE_RANGES[k])
    try:
        noise = NoiseModel(**kwargs)
    except DhlogError as exc:
        raise PipelineError(source, f"[noise]: {exc}") from None
    if "point" in streams and streams["point"].coordinates == "spherical" and any(noise.station):
        raise PipelineError(
            source,
            "[noise] station: a spherical point stream is in the tracker's own frame, so the "
            "station is its origin; leave station out.",
        )
    return Pipeline(
        name=name,
        description=description,
        source=source,
        encodings=encodings,
        length_unit=unit,
        angle_unit=angle_unit,
        streams=streams,
        joint_names=tuple(names) if names is not None else None,
        joint_types=types,
        segmentation=seg,
        noise=noise,
        image=image,
        camera=camera,
        target=target,
    )
