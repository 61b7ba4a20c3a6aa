"""Pipelines: TOML files that map a log's channels to dhlog's four input streams.

A pipeline names, per stream (``point``, ``joints``, ``base``, ``phase``), the topic and, for JSON
messages of other shapes, the field paths; the length unit; the joints in chain order and their
types; and the segmentation tolerances. Shipped pipelines live in ``pipelines/`` and are chosen
from the schemas a log holds when none is named.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from dhlog.dh import JointType
from dhlog.errors import DhlogError, PipelineError
from dhlog.identify.noise import NoiseModel

STREAMS = ("point", "joints", "base", "phase")
DEFAULT_TOPICS = {
    "point": "/tracker/point",
    "joints": "/joint_states",
    "base": "/tracker/base_plane",
    "phase": "/calibration/phase",
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


def parse_pipeline(text: str, source: str) -> Pipeline:
    """Parse pipeline TOML ``text``; ``source`` names the file in error messages."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PipelineError(source, f"not valid TOML ({exc}).") from None
    _check_keys(source, "top level", data, TOP_KEYS)
    name = str(data.get("name", Path(source).stem))
    raw_enc = data.get("encoding", list(ENCODINGS))
    encodings = tuple([raw_enc] if isinstance(raw_enc, str) else raw_enc)
    bad = [e for e in encodings if e not in ENCODINGS]
    if bad:
        raise PipelineError(source, f"encoding {bad} unknown; use one of {list(ENCODINGS)}.")
    unit = str(data.get("length_unit", "m"))
    if unit not in ("m", "mm"):
        raise PipelineError(source, f"length_unit '{unit}' unknown; use 'm' or 'mm'.")
    angle_unit = str(data.get("angle_unit", "rad"))
    if angle_unit not in ("rad", "deg", "gon"):
        raise PipelineError(
            source, f"angle_unit '{angle_unit}' unknown; use 'rad', 'deg' or 'gon'."
        )
    streams_table = _table(source, data, "streams")
    unknown = sorted(set(streams_table) - set(STREAMS))
    if unknown:
        raise PipelineError(source, f"unknown stream(s) {unknown}; streams are {list(STREAMS)}.")
    streams: dict[str, StreamSpec] = {}
    for stream in STREAMS:
        spec = streams_table.get(stream)
        if spec is None:
            continue
        if not isinstance(spec, dict):
            raise PipelineError(source, f"[streams.{stream}] must be a table.")
        _check_keys(source, f"[streams.{stream}]", spec, STREAM_KEYS)
        required = bool(spec.get("required", stream == "point"))
        fields = {str(k): str(v) for k, v in _table(source, spec, "fields").items()}
        _check_keys(source, f"[streams.{stream}] fields", fields, FIELD_KEYS[stream])
        extra = spec.get("extra_topics", [])
        if stream != "point" and extra:
            raise PipelineError(source, f"[streams.{stream}] extra_topics is for the point stream.")
        if not isinstance(extra, list) or not all(isinstance(t, str) for t in extra):
            raise PipelineError(source, "[streams.point] extra_topics must be a list of topics.")
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
        if not isinstance(pose_index, int) or isinstance(pose_index, bool) or pose_index < 0:
            raise PipelineError(
                source, f"[streams.{stream}] pose_index must be a whole number >= 0."
            )
        if coordinates == "spherical" and orientation:
            raise PipelineError(
                source, "[streams.point] a spherical point stream has no orientation."
            )
        streams[stream] = StreamSpec(
            str(spec.get("topic", DEFAULT_TOPICS[stream])),
            required,
            fields,
            tuple(extra),
            orientation,
            str(spec.get("child_frame", "")),
            pose_index,
            str(coordinates),
            str(vertical),
        )
    if "point" not in streams:
        raise PipelineError(source, "it has no [streams.point]; the target stream is required.")
    joints = _table(source, data, "joints")
    _check_keys(source, "[joints]", joints, JOINT_KEYS)
    names = joints.get("names")
    types_raw = joints.get("types")
    types: tuple[JointType | None, ...] | None = None
    if types_raw is not None:
        try:
            types = tuple(None if t in ("", "auto") else JointType.parse(str(t)) for t in types_raw)
        except ValueError as exc:
            raise PipelineError(source, f"[joints] types: {exc}") from None
        if names is not None and len(types) != len(names):
            raise PipelineError(source, "[joints] names and types differ in length.")
    seg_table = _table(source, data, "segmentation")
    _check_keys(
        source, "[segmentation]", seg_table, tuple(SegmentationSettings.__dataclass_fields__)
    )
    for k, v in seg_table.items():
        want = type(getattr(SegmentationSettings, k))
        ok = (
            isinstance(v, bool)
            if want is bool
            else isinstance(v, int | float) and not isinstance(v, bool)
        )
        if not ok or (want is not bool and not math.isfinite(float(v))):
            kind = "true or false" if want is bool else "a finite number"
            raise PipelineError(source, f"[segmentation] {k} must be {kind}, not {v!r}.")
    try:
        seg = SegmentationSettings(
            **{k: type(getattr(SegmentationSettings, k))(v) for k, v in seg_table.items()}
        )
    except (TypeError, ValueError) as exc:
        raise PipelineError(source, f"[segmentation]: {exc}") from None
    noise_table = _table(source, data, "noise")
    _check_keys(source, "[noise]", noise_table, NOISE_KEYS)
    try:
        kwargs: dict[str, Any] = {
            k: (
                str(v)
                if k == "model"
                else tuple(float(x) for x in v)
                if k == "station"
                else float(v)
            )
            for k, v in noise_table.items()
        }
        if "station" in kwargs and len(kwargs["station"]) != 3:
            raise ValueError("station needs three coordinates [x, y, z] in metres")
        noise = NoiseModel(**kwargs)
    except (TypeError, ValueError, DhlogError) as exc:
        raise PipelineError(source, f"[noise]: {exc}") from None
    if streams["point"].coordinates == "spherical" and any(noise.station):
        raise PipelineError(
            source,
            "[noise] station: a spherical point stream is in the tracker's own frame, so the "
            "station is its origin; leave station out.",
        )
    return Pipeline(
        name=name,
        description=str(data.get("description", "")),
        source=source,
        encodings=encodings,
        length_unit=unit,
        angle_unit=angle_unit,
        streams=streams,
        joint_names=tuple(str(n) for n in names) if names is not None else None,
        joint_types=types,
        segmentation=seg,
        noise=noise,
    )


def load_pipeline(path: str | Path) -> Pipeline:
    """Read a pipeline file."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise PipelineError(str(path), f"cannot be read ({exc.strerror}).") from None
    return parse_pipeline(text, str(path))


def shipped_pipelines() -> list[Pipeline]:
    """The pipelines shipped with dhlog, in order of preference."""
    folder = resources.files("dhlog").joinpath("pipelines")
    if not folder.is_dir():  # a source checkout: pipelines/ at the top level
        repo = Path(__file__).resolve().parents[3] / "pipelines"
        files = sorted(repo.glob("*.toml"))
        found = [parse_pipeline(f.read_text(encoding="utf-8"), str(f)) for f in files]
    else:
        found = [
            parse_pipeline(f.read_text(encoding="utf-8"), f"pipelines/{f.name}")
            for f in sorted(folder.iterdir(), key=lambda f: f.name)
            if f.name.endswith(".toml")
        ]
    order = {"ros2_tracker": 0, "foxglove_json": 1, "foxglove_protobuf": 2}
    return sorted(found, key=lambda p: (order.get(p.name, 9), p.name))


def pipeline_by_name(name: str) -> Pipeline | None:
    """The shipped pipeline called ``name``, or None."""
    return next((p for p in shipped_pipelines() if p.name == name), None)


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
