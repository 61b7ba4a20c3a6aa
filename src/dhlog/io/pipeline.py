"""Pipelines: TOML files that map a log's channels to dhlog's four input streams.

A pipeline names, per stream (``point``, ``joints``, ``base``, ``phase``), the topic and, for JSON
messages of other shapes, the field paths; the length unit; the joints in chain order and their
types; and the segmentation tolerances. A camera pipeline reads ``[streams.image]`` instead of
``[streams.point]``, with its ``[target]`` (the board, :class:`dhlog.vision.boards.BoardSpec`)
and ``[camera]`` (the camera-info topic, or a calibration file read as
:class:`dhlog.vision.camera.Intrinsics`). Shipped pipelines live in ``pipelines/`` and are chosen
from the schemas a log holds when none is named.
"""

from __future__ import annotations

import datetime
import math
import sys
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dhlog.errors import DhlogError, PipelineError
from dhlog.model.dh import JointType
from dhlog.model.noise import NoiseModel

if TYPE_CHECKING:  # OpenCV imported only when a camera pipeline is read
    from dhlog.vision.boards import BoardSpec
    from dhlog.vision.camera import Intrinsics

STREAMS = ("point", "joints", "base", "phase", "commanded")
DEFAULT_TOPICS = {
    "point": "/tracker/point",
    "joints": "/joint_states",
    "base": "/tracker/base_plane",
    "phase": "/calibration/phase",
    "commanded": "/joint_command",
}
ENCODINGS = ("cdr", "json", "protobuf")
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
#: A camera pipeline's image stream: its topic, whether it is needed, and the topics read
#: instead where the log lacks ``topic`` (a raw stream where the compressed one is absent).
IMAGE_KEYS = ("topic", "required", "alternatives")
#: ``[camera]``: the camera-info topic (``CameraInfo`` / ``CameraCalibration``), or a
#: calibration file (ROS camera_info YAML, OpenCV YAML/XML) held instead.
CAMERA_KEYS = ("info_topic", "calibration")
DEFAULT_IMAGE_TOPIC = "/camera/image_raw/compressed"
DEFAULT_INFO_TOPIC = "/camera/camera_info"
#: The largest camera calibration file read (bytes), and the most alternative image topics.
MAX_CALIBRATION_BYTES = 1 * 2**20
MAX_ALTERNATIVES = 16
#: The most entries of a list in ``[target]`` (no marker dictionary holds more ids).
MAX_TARGET_LIST = 1024
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
#: The largest pipeline file read (bytes).
MAX_BYTES = 1 * 2**20
#: The most characters a string value may have, and the most joints.
MAX_TEXT, MAX_JOINTS = 1000, 64


def _shown(value: object) -> str:
    """A value as the file spells it, cut short (``true``, ``"abc"``, ``[1, 2]``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int) and abs(value) > 10**30:
        return "an integer of more than 30 digits"
    if isinstance(value, datetime.date | datetime.time):  # a TOML date or time
        return f"the date/time {value.isoformat()}"
    text = f'"{value}"' if isinstance(value, str) else repr(value)
    return text if len(text) <= 40 else text[:37] + "…"


def _text(source: str, where: str, value: object) -> str:
    """A string value (the key named in ``where``)."""
    if not isinstance(value, str):
        raise PipelineError(source, f"{where} must be a string, not {_shown(value)}.")
    if len(value) > MAX_TEXT:
        raise PipelineError(
            source, f"{where} is a string of {len(value)} characters (at most {MAX_TEXT})."
        )
    return value


def _flag(source: str, where: str, value: object) -> bool:
    if not isinstance(value, bool):
        raise PipelineError(source, f"{where} must be true or false, not {_shown(value)}.")
    return value


def _texts(source: str, where: str, value: object) -> list[str]:
    if not isinstance(value, list):
        raise PipelineError(source, f"{where} must be a list of strings, not {_shown(value)}.")
    if len(value) > MAX_JOINTS:
        raise PipelineError(source, f"{where} has {len(value)} entries (at most {MAX_JOINTS}).")
    return [_text(source, f"{where}[{k}]", v) for k, v in enumerate(value)]


def _number(
    source: str, where: str, value: object, lo: float, hi: float, unit: str, *, whole: bool = False
) -> float:
    """A finite number (not a boolean; a whole one when ``whole``) within ``[lo, hi]``."""
    span = f"{int(lo)} to {int(hi)}" if whole else f"{lo:g} to {hi:g} {unit}"
    whole_one = ", a whole one" if whole else ""
    refused = PipelineError(
        source,
        f"{where} must be a finite number from {span}{whole_one}, not {_shown(value)}; correct "
        "it in the pipeline.",
    )
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise refused
    try:
        x = float(value)
    except OverflowError:
        raise refused from None
    if not math.isfinite(x) or not lo <= x <= hi or (whole and not x.is_integer()):
        raise refused
    return x


def _check_keys(source: str, where: str, given: dict[str, Any], known: tuple[str, ...]) -> None:
    """A one-line error for the first key of ``given`` not in ``known``, with the nearest."""
    import difflib

    for key in given:
        if key not in known:
            near = difflib.get_close_matches(key, known, n=1, cutoff=0.5)
            hint = f"did you mean '{near[0]}'? " if near else ""
            raise PipelineError(
                source, f"{where}: unknown key '{key}'; {hint}known keys: {', '.join(known)}."
            )


@dataclass(frozen=True)
class StreamSpec:
    """One input stream: its topic, whether the pipeline needs it, and JSON field paths."""

    topic: str
    required: bool
    fields: dict[str, str] = field(default_factory=dict)
    extra_topics: tuple[str, ...] = ()
    orientation: bool = False
    child_frame: str = ""
    pose_index: int = 0
    coordinates: str = "cartesian"
    vertical: str = "zenith"


@dataclass(frozen=True)
class SegmentationSettings:
    """Tolerances of the segmentation, in SI units (rad for revolute, m for prismatic joints).

    ``lock_tolerance``: a joint is locked while it stays this close to its locked value.
    ``motion_window``: half-width (s) of the window over which a joint's motion is judged.
    ``join_tolerance``: largest gap (s) between a target sample and the encoder samples around it.
    ``min_samples``: fewest target samples a sweep needs. ``min_sweep``: smallest sweep (rad)
    and ``min_travel`` (m) a segment needs to count as a sweep. ``clock_offset``: seconds added
    to the joint-state stamps to bring them onto the tracker's clock — the start of the
    estimate from the data, or, with ``clock_offset_fixed``, the offset used as it is.
    """

    lock_tolerance: float = 2e-5
    motion_window: float = 0.05
    join_tolerance: float = 0.05
    min_samples: int = 3
    min_sweep: float = math.radians(5.0)
    min_travel: float = 1e-3
    clock_offset: float = 0.0
    clock_offset_fixed: bool = False


@dataclass(frozen=True)
class ImageStreamSpec:
    """A camera pipeline's image stream: ``topic``, and ``alternatives`` read instead of it
    (in order) where the log lacks it."""

    topic: str = DEFAULT_IMAGE_TOPIC
    required: bool = True
    alternatives: tuple[str, ...] = ()


@dataclass(frozen=True)
class CameraSpec:
    """Where a camera pipeline's intrinsics come from: ``info_topic`` (the log's
    ``CameraInfo``), or ``intrinsics`` read from the calibration file ``calibration`` (the
    path as resolved against the pipeline's folder)."""

    info_topic: str | None = DEFAULT_INFO_TOPIC
    calibration: str | None = None
    intrinsics: Intrinsics | None = None


@dataclass(frozen=True)
class Pipeline:
    """A parsed pipeline file."""

    name: str
    description: str
    source: str
    encodings: tuple[str, ...]
    length_unit: str
    streams: dict[str, StreamSpec]
    joint_names: tuple[str, ...] | None
    joint_types: tuple[JointType | None, ...] | None
    segmentation: SegmentationSettings
    noise: NoiseModel = field(default_factory=NoiseModel)
    angle_unit: str = "rad"
    image: ImageStreamSpec | None = None
    camera: CameraSpec | None = None
    target: BoardSpec | None = None

    @property
    def is_camera(self) -> bool:
        """Whether the pipeline reads camera images (``[streams.image]``), not a tracker."""
        return self.image is not None

    @property
    def length_scale(self) -> float:
        """Factor from the log's length unit to metres."""
        return 1e-3 if self.length_unit == "mm" else 1.0

    @property
    def angle_scale(self) -> float:
        """Factor from the log's angle unit (revolute encoders) to radians."""
        return {"deg": math.pi / 180.0, "gon": math.pi / 200.0}.get(self.angle_unit, 1.0)


def _table(where: str, data: dict[str, Any], key: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise PipelineError(where, f"[{key}] must be a table.")
    return value


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


def _image_stream(source: str, spec: object) -> ImageStreamSpec | None:
    """``[streams.image]``, checked (None where the pipeline has none)."""
    if spec is None:
        return None
    where = "[streams.image]"
    if not isinstance(spec, dict):
        raise PipelineError(source, f"{where} must be a table.")
    _check_keys(source, where, spec, IMAGE_KEYS)
    alternatives = _texts(source, f"{where} alternatives", spec.get("alternatives", []))
    if len(alternatives) > MAX_ALTERNATIVES:
        raise PipelineError(
            source,
            f"{where} alternatives has {len(alternatives)} topics (at most {MAX_ALTERNATIVES}).",
        )
    return ImageStreamSpec(
        _text(source, f"{where} topic", spec.get("topic", DEFAULT_IMAGE_TOPIC)),
        _flag(source, f"{where} required", spec.get("required", True)),
        tuple(alternatives),
    )


def _camera_tables(
    data: dict[str, Any], source: str, folder: Path, camera_pipeline: bool
) -> tuple[BoardSpec | None, CameraSpec | None]:
    """``[target]`` and ``[camera]`` of a camera pipeline (refused in any other)."""
    if not camera_pipeline:
        for key in ("target", "camera"):
            if key in data:
                raise PipelineError(
                    source,
                    f"[{key}] is for a camera pipeline, which reads [streams.image]; add that "
                    f"stream or leave [{key}] out.",
                )
        return None, None
    from dhlog.vision.boards import BoardError, BoardSpec  # OpenCV: for a camera pipeline only

    if "target" not in data:
        raise PipelineError(
            source,
            "a camera pipeline needs a [target] table: the board's kind, dictionary, squares, "
            "square_m and marker_m (docs/pipeline.md: Writing a pipeline file).",
        )
    target_table = _table(source, data, "target")
    for key, value in target_table.items():
        where = f"[target] {key}"
        if isinstance(value, str):
            _text(source, where, value)
        elif isinstance(value, list):
            if len(value) > MAX_TARGET_LIST:
                raise PipelineError(
                    source, f"{where} has {len(value)} entries (at most {MAX_TARGET_LIST})."
                )
            for k, v in enumerate(value):
                if isinstance(v, bool) or not isinstance(v, int) or abs(v) > 10**9:
                    raise PipelineError(
                        source, f"{where}[{k}] must be a whole number, not {_shown(v)}."
                    )
        elif isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10**9:
            raise PipelineError(source, f"{where} is {_shown(value)}, out of any board's range.")
    try:
        target = BoardSpec.from_table(target_table, "[target]")
    except BoardError as exc:
        raise PipelineError(source, str(exc)) from None
    camera_table = _table(source, data, "camera")
    _check_keys(source, "[camera]", camera_table, CAMERA_KEYS)
    if "info_topic" in camera_table and "calibration" in camera_table:
        raise PipelineError(
            source,
            "[camera] gives both info_topic and calibration; give the calibration file to hold "
            "its intrinsics, or the camera-info topic to read the log's.",
        )
    if "calibration" not in camera_table:
        topic = _text(
            source, "[camera] info_topic", camera_table.get("info_topic", DEFAULT_INFO_TOPIC)
        )
        return target, CameraSpec(info_topic=topic)
    given = _text(source, "[camera] calibration", camera_table["calibration"])
    path = Path(given)
    if not path.is_absolute():
        path = folder / path
    intrinsics = load_calibration(path, source)
    return target, CameraSpec(info_topic=None, calibration=str(path), intrinsics=intrinsics)


def load_calibration(path: str | Path, pipeline: str) -> Intrinsics:
    """A camera calibration file named by ``pipeline``'s ``[camera] calibration``: at most
    :data:`MAX_CALIBRATION_BYTES`, UTF-8, read by :meth:`Intrinsics.from_yaml_text`; every
    failure one :class:`PipelineError` naming the pipeline, the key and the file."""
    from dhlog.io.textfile import decode_utf8, read_capped
    from dhlog.vision.camera import CameraError, Intrinsics

    def fail(problem: str) -> PipelineError:
        return PipelineError(pipeline, f"[camera] calibration: {path} {problem}")

    data = read_capped(
        path,
        MAX_CALIBRATION_BYTES,
        fail,
        what="calibration file",
        hint="give the camera's calibration file (ROS camera_info YAML or OpenCV YAML/XML).",
        check="check the path (a relative one is taken from the pipeline file's folder).",
    )
    text = decode_utf8(data, fail, what="calibration file")
    try:
        return Intrinsics.from_yaml_text(text, str(path))
    except CameraError as exc:
        raise PipelineError(pipeline, f"[camera] calibration: {exc}") from None


def load_pipeline(path: str | Path) -> Pipeline:
    """Read a pipeline file (a regular file of at most :data:`MAX_BYTES`, UTF-8)."""
    from dhlog.io.textfile import decode_utf8, read_capped

    def fail(problem: str) -> PipelineError:
        return PipelineError(str(path), problem)

    data = read_capped(path, MAX_BYTES, fail, what="pipeline", hint="give the pipeline file.")
    return parse_pipeline(
        decode_utf8(data, fail, what="pipeline file"), str(path), folder=Path(path).parent
    )


def _shipped_files() -> list[tuple[str, str, Path | None]]:
    """The shipped pipelines' texts, names for messages and folders (None: a package's)."""
    folder = resources.files("dhlog").joinpath("pipelines")
    if not folder.is_dir():  # a source checkout: pipelines/ at the top level
        repo = Path(__file__).resolve().parents[3] / "pipelines"
        return [(f.read_text(encoding="utf-8"), str(f), None) for f in sorted(repo.glob("*.toml"))]
    return [
        (f.read_text(encoding="utf-8"), f"pipelines/{f.name}", None)
        for f in sorted(folder.iterdir(), key=lambda f: f.name)
        if f.name.endswith(".toml")
    ]


def shipped_pipelines(*, boards: bool = False) -> list[Pipeline]:
    """The pipelines shipped with dhlog, in order of preference; a camera pipeline's board and
    camera read only with ``boards`` (:func:`pipeline_by_name` reads them)."""
    found = [parse_pipeline(text, source, boards=boards) for text, source, _ in _shipped_files()]
    order = {"ros2_tracker": 0, "foxglove_json": 1, "foxglove_protobuf": 2}
    return sorted(found, key=lambda p: (order.get(p.name, 9), p.name))


def pipeline_by_name(name: str) -> Pipeline | None:
    """The shipped pipeline called ``name`` (a camera pipeline with its board), or None."""
    found = next((p for p in shipped_pipelines() if p.name == name), None)
    if found is None or not found.is_camera:
        return found
    text, source, _ = next(f for f in _shipped_files() if f[1] == found.source)
    return parse_pipeline(text, source)


def pipeline_from(spec: str) -> Pipeline:
    """A pipeline file, or a shipped pipeline by name (``dhlog pipelines`` lists them).

    A ``spec`` that is neither is an error listing the shipped names, with the nearest one
    (``ros2_trackr`` → ``ros2_tracker``)."""
    if not Path(spec).exists():
        shipped = pipeline_by_name(spec)
        if shipped is not None:
            return shipped
        import difflib

        names = [p.name for p in shipped_pipelines()]
        listed = ", ".join(names)
        if Path(spec).suffix == ".toml" or "/" in spec or "\\" in spec:  # meant as a file
            raise PipelineError(
                spec,
                f"no such pipeline file; check the path, or name a shipped pipeline ({listed}).",
            )
        near = difflib.get_close_matches(spec, names, n=1, cutoff=0.6)
        hint = f" (did you mean '{near[0]}'?)" if near else ""
        raise PipelineError(
            spec,
            f"is not a shipped pipeline{hint}; the shipped ones are {listed} (dhlog pipelines "
            "describes them), and a pipeline file of your own is given by its path.",
        )
    return load_pipeline(spec)
