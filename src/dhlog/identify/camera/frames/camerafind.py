"""A camera log's small streams and its cameras, found before any image is decoded.

The first walk (:func:`_first_walk`) reads the joint states (decoded as
:func:`dhlog.io.reader.read_log` decodes them: :func:`dhlog.io.decode.blocks.decode_stream`,
:func:`~dhlog.io.decode.frames.joints_frame`, :func:`~dhlog.io.decode.frames.clean`) and every
camera info, the images' payloads offered to a sink that drops them. The cameras
(:func:`_cameras`) are the pipeline's ``[streams.image]`` topic and the log's topics that differ
from it only in their namespace (``/camera_1/image_raw/compressed``, ``/camera_2/…``), each with
its camera-info topic named likewise; each camera's intrinsics come from its camera infos or the
pipeline's calibration file (:func:`_intrinsics`), a log without them refused
(:class:`VisionLogError`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, MissingTopicError
from dhlog.identify.camera.frames.imagedecode import (
    INFO_SCHEMAS,
)
from dhlog.identify.camera.frames.images import _log_files, read_camera_infos
from dhlog.identify.camera.frames.obeyed import Reading
from dhlog.io.mcapscan import scan_mcap
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.pipeline import DEFAULT_TOPICS, Pipeline, StreamSpec
from dhlog.io.ros2 import CameraInfo
from dhlog.vision.camera import CameraError, Intrinsics

if TYPE_CHECKING:
    from dhlog.io.decode.blocks import Block


class VisionLogError(InputError):
    """A camera log that cannot be observed as given: no intrinsics, images of another size
    than the intrinsics', no frame with the target, no frame with joint values."""


@dataclass(frozen=True)
class _Small:
    """What the first walk found: the topics present, the joint states (t, q, names), the
    camera infos, warnings."""

    topics: list[str]
    joint_t: NDArray[np.int64]
    joint_q: NDArray[np.float64]
    joint_names: list[str]
    infos: dict[str, list[CameraInfo]]
    warnings: tuple[str, ...]


def _joints_spec(pipeline: Pipeline) -> StreamSpec:
    spec = pipeline.streams.get("joints")
    return spec if spec is not None else StreamSpec(DEFAULT_TOPICS["joints"], True)


def _first_walk(
    name: str,
    pipeline: Pipeline,
    progress: Callable[[float], None],
    joint_names: Sequence[str] | None = None,
    joint_source: str = "model",
) -> _Small:
    """The joint states and every camera info of the log (each camera's), walking it once:
    the other channels' payloads (the images) are offered to a sink that drops them."""
    # polars (the joints' table) imported here, not by the workers: 0.15 s a worker
    from dhlog.io.decode.blocks import Damaged, Sources, decode_stream
    from dhlog.io.decode.frames import clean, joints_frame
    from dhlog.io.payloads import _unzstd_squeezed

    spec = _joints_spec(pipeline)
    present: set[str] = set()
    blocks: list[Block] = []
    infos: dict[str, list[CameraInfo]] = {}
    taken: dict[int, bool] = {}

    def drop(cid: int, info: ChannelInfo | None, _: RawMessages) -> bool:
        # the same answer for every offer of a channel (a channel not yet defined: kept)
        if cid not in taken:
            taken[cid] = (
                info is not None
                and info.topic != spec.topic
                and (info.schema_name not in INFO_SCHEMAS)
            )
        return taken[cid]

    warnings: list[str] = []
    damaged: list[Damaged] = []
    joint_channels = 0
    with contextlib.ExitStack() as stack:
        paths = _log_files(name, stack)
        for k, path in enumerate(paths):

            def step(f: float, k: int = k) -> None:
                progress((k + f) / len(paths))

            taken.clear()  # channel ids are the file's own
            scan = scan_mcap(path, None, progress=step, sink=drop)
            present.update(scan.topics())
            warnings.extend(scan.warnings)
            _unzstd_squeezed(scan.messages, name, False)
            channels = [c for c in scan.channels.values() if c.topic == spec.topic]
            joint_channels += len(channels)
            if channels:
                done = decode_stream("joints", spec, channels, Sources(scan.messages), name)
                blocks += done.blocks
                damaged.extend(done.damaged)
                warnings.extend(done.notes)
            for topic in sorted(
                {
                    c.topic
                    for c in scan.channels.values()
                    if c.schema_name in INFO_SCHEMAS and c.topic != spec.topic
                }
            ):
                infos.setdefault(topic, []).extend(read_camera_infos(path, topic, scan))
            del scan
    if not joint_channels:
        raise MissingTopicError(name, "joints", spec.topic, sorted(present))
    warnings.extend(d.warning(name) for d in damaged)
    frame, names, order = joints_frame(
        name, spec.topic, blocks, pipeline, joint_names, joint_source
    )
    if order.note:
        warnings.append(f"{name}: {order.note}")
    set_aside: dict[str, int] = {}
    frame = clean(frame, "joints", set_aside)
    if set_aside:
        warnings.append(
            f"{name}: {sum(set_aside.values())} joint state(s) on {spec.topic} with values no "
            "encoder gives (non-finite or out of range) were set aside."
        )
    t = np.asarray(frame["t_ns"].to_numpy(), dtype=np.int64)
    q = np.column_stack([np.asarray(frame[f"q_{j + 1}"].to_numpy()) for j in range(len(names))])
    return _Small(sorted(present), t, q.reshape(t.size, len(names)), names, infos, tuple(warnings))


@dataclass(frozen=True)
class _Camera:
    """A camera of the log: its image topic and camera-info topic (None: the pipeline's
    calibration file holds its intrinsics)."""

    image: str
    info: str | None


def _split(topic: str) -> tuple[str, str] | None:
    """``/ns/rest`` → (ns, rest); None for a topic without a namespace."""
    parts = topic.split("/", 2)
    if len(parts) < 3 or parts[0] or not parts[1] or not parts[2]:
        return None
    return parts[1], parts[2]


def _cameras(name: str, pipeline: Pipeline, present: list[str]) -> list[_Camera]:
    """The cameras of the log: the pipeline's ``[streams.image]`` topic (or the first of its
    alternatives the log has), and the log's topics that differ from one of those only in
    their first part, the camera's namespace (``/camera_1/image_raw/compressed`` and
    ``/camera_2/…`` for ``/camera/image_raw/compressed``), each with the camera-info topic
    named likewise (``/camera_1/camera_info``). The pipeline's own camera first."""
    assert pipeline.image is not None and pipeline.camera is not None
    wanted = [pipeline.image.topic, *pipeline.image.alternatives]
    info = pipeline.camera.info_topic
    held = pipeline.camera.intrinsics is not None
    found: list[_Camera] = []
    own = next((t for t in wanted if t in present), None)
    if own is not None:
        found.append(_Camera(own, None if held else info))
    own_ns = (_split(own) or ("", ""))[0] if own is not None else None
    info_parts = _split(info) if info else None
    for ns in sorted({parts[0] for t in present if (parts := _split(t)) is not None}):
        if ns == own_ns:
            continue
        for topic in wanted:
            parts = _split(topic)
            if parts is None or parts[0] == ns or f"/{ns}/{parts[1]}" not in present:
                continue
            beside = info_parts is not None and info_parts[0] == parts[0]
            info_rest = info_parts[1] if beside and info_parts is not None else "camera_info"
            found.append(_Camera(f"/{ns}/{parts[1]}", f"/{ns}/{info_rest}"))
            break
    if not found:
        raise MissingTopicError(name, "image", " or ".join(wanted), present)
    return found


def _intrinsics(
    name: str, pipeline: Pipeline, camera: _Camera, small: _Small
) -> tuple[Intrinsics, str, tuple[str, ...]]:
    """The camera's intrinsics, where they come from (the pipeline's calibration file, or the
    first camera info on its topic) and the warning when the camera infos change."""
    assert pipeline.camera is not None
    if camera.info is None:
        assert pipeline.camera.intrinsics is not None
        calibration = f"[camera] calibration {pipeline.camera.calibration}"
        return pipeline.camera.intrinsics, calibration, ()
    topic = camera.info
    infos = small.infos.get(topic, [])
    if not infos:
        lacking = (
            "is not in the log"
            if topic not in small.topics
            else "holds no camera info that can be read"
        )
        listed = ", ".join(small.topics) or "none"
        raise VisionLogError(
            f"{name}: no camera intrinsics for {camera.image}: the camera-info topic {topic} "
            f"{lacking} (topics present: {listed}); give the camera's calibration file as "
            "[camera] calibration in the pipeline, or its camera-info topic as [camera] "
            "info_topic."
        )
    first = infos[0]
    where = f"{name}: {topic}"
    told = pipeline.camera.rectified
    rectified = rectified_topic(camera.image) if told is None else told
    if rectified:
        found = _projection(first, f"{where} (its projection P: {camera.image} is rectified)")
        source = f"the projection P of the camera info on {topic}"
    else:
        found = Intrinsics.from_camera_info(
            first.width, first.height, first.distortion_model, first.d, first.k.ravel(), where=where
        )
        source = f"camera info on {topic}"
    changed = next(
        (
            k
            for k, info in enumerate(infos)
            if (info.width, info.height, info.distortion_model, info.d)
            != (first.width, first.height, first.distortion_model, first.d)
            or not np.array_equal(info.k, first.k)
            or (rectified and not np.array_equal(info.p, first.p))
        ),
        None,
    )
    if changed is None:
        return found, source, ()
    said = (
        f"{where}: the intrinsics change at camera info {changed} of {len(infos)}; "
        "the first are used for every frame (give a calibration file as [camera] "
        "calibration to choose them)."
    )
    return found, source, (said,)


def readings(
    name: str, pipeline: Pipeline, camera: _Camera, small: _Small, used: Intrinsics
) -> tuple[Reading, Reading] | None:
    """The camera info's reading ``used`` (:func:`_intrinsics`'s) and its other one — ``P``
    with no distortion where ``K`` and ``D`` were read, and the reverse — for
    :func:`~.obeyed.judged` to hold against the images; None with a calibration file, a ``P``
    that is not a camera's, or where the two are one (no distortion, ``P``'s 3×3 ``K``)."""
    assert pipeline.camera is not None
    infos = [] if camera.info is None else small.infos.get(camera.info, [])
    if not infos:
        return None
    first, where = infos[0], f"{name}: {camera.info}"
    told = pipeline.camera.rectified
    rectified = rectified_topic(camera.image) if told is None else told
    P = np.asarray(first.p, dtype=np.float64).reshape(3, 4)
    if not np.any(first.d) and np.allclose(P[:, :3], first.k.reshape(3, 3)):
        return None
    try:
        if rectified:
            other = Intrinsics.from_camera_info(
                first.width,
                first.height,
                first.distortion_model,
                first.d,
                first.k.ravel(),
                where=where,
            )
        else:
            other = _projection(first, where)
    except (VisionLogError, CameraError):
        return None
    return Reading(used, rectified), Reading(other, not rectified)


def rectified_topic(topic: str) -> bool:
    """Whether an image topic carries rectified images by image_pipeline's names
    (``image_rect``, ``image_rect_color``, ``…/image_rect_raw``; any transport after them, e.g.
    ``/camera/image_rect_color/compressed``)."""
    return any(part.startswith("image_rect") for part in topic.split("/"))


def _projection(info: CameraInfo, where: str) -> Intrinsics:
    """The intrinsics of rectified images: the camera info's projection ``P``'s left 3×3, no
    distortion (ROS's ``CameraInfo``: ``K`` and ``D`` are the raw images'). A ``P`` that is
    not a camera's (zero, as an uncalibrated driver leaves it) is a :class:`VisionLogError`."""
    P = np.asarray(info.p, dtype=np.float64).reshape(3, 4)
    if not (np.all(np.isfinite(P)) and P[0, 0] > 0 and P[1, 1] > 0 and P[2, 2] == 1.0):
        raise VisionLogError(
            f"{where}: the projection P {np.round(P, 3).tolist()} is not a camera's; give the "
            "rectified images' calibration as [camera] calibration, or set [camera] rectified "
            "= false if the images are not rectified."
        )
    return Intrinsics.from_camera_info(
        info.width, info.height, "plumb_bob", np.zeros(5), P[:, :3].ravel(), where=where
    )
