"""A camera pipeline's tables: ``[streams.image]`` (:data:`IMAGE_KEYS`: the topic, whether it is
needed, the topics read instead), ``[target]`` (the board, a :class:`dhlog.vision.boards.BoardSpec`)
and ``[camera]`` (:data:`CAMERA_KEYS`: the camera-info topic, or a calibration file read by
:func:`load_calibration` as :class:`dhlog.vision.camera.Intrinsics`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from dhlog.errors import PipelineError

if TYPE_CHECKING:  # OpenCV imported only when a camera pipeline is read
    from dhlog.vision.boards import BoardSpec
    from dhlog.vision.camera import Intrinsics
from dhlog.io.pipeline.spec import (
    DEFAULT_IMAGE_TOPIC,
    DEFAULT_INFO_TOPIC,
    CameraSpec,
    ImageStreamSpec,
)
from dhlog.io.pipeline.values import _check_keys, _flag, _shown, _table, _text, _texts

#: A camera pipeline's image stream: its topic, whether it is needed, and the topics read
#: instead where the log lacks ``topic`` (a raw stream where the compressed one is absent).
IMAGE_KEYS = ("topic", "required", "alternatives")


#: ``[camera]``: the camera-info topic (``CameraInfo`` / ``CameraCalibration``), or a
#: calibration file (ROS camera_info YAML, OpenCV YAML/XML) held instead; whether the images are
#: rectified (their intrinsics the camera info's projection P; default: the image topic's name).
CAMERA_KEYS = ("info_topic", "calibration", "rectified")


#: The largest camera calibration file read (bytes), and the most alternative image topics.
MAX_CALIBRATION_BYTES = 1 * 2**20


MAX_ALTERNATIVES = 16


#: The most entries of a list in ``[target]`` (no marker dictionary holds more ids).
MAX_TARGET_LIST = 1024


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
    rectified = None
    if "rectified" in camera_table:
        rectified = _flag(source, "[camera] rectified", camera_table["rectified"])
    if "calibration" not in camera_table:
        topic = _text(
            source, "[camera] info_topic", camera_table.get("info_topic", DEFAULT_INFO_TOPIC)
        )
        return target, CameraSpec(info_topic=topic, rectified=rectified)
    if rectified:
        raise PipelineError(
            source,
            "[camera] rectified = true reads the camera info's projection P; a calibration "
            "file is taken as the images' own intrinsics: give the rectified images' (their "
            "camera matrix, no distortion) and leave rectified out, or read the log's camera "
            "info with info_topic.",
        )
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
