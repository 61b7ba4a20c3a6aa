"""A camera log observed (issue 32): the board's corners detected in every frame, the encoders
joined at each frame's stamp, a few frames kept for the recording — :func:`observe`.

The log is walked first for the small streams — the joint states (decoded as
:func:`dhlog.io.reader.read_log` decodes them: :func:`dhlog.io.decode.blocks.decode_stream`,
:func:`~dhlog.io.decode.frames.joints_frame`, :func:`~dhlog.io.decode.frames.clean`) and every
camera info (the images' payloads offered to a sink that drops them) — so that a log without
intrinsics or encoders is refused before any image is decoded, and every frame is detected with
the intrinsics. The cameras are the pipeline's ``[streams.image]`` topic and the log's topics
that differ from it only in their namespace (``/camera_1/image_raw/compressed``,
``/camera_2/…``), each with its camera-info topic named likewise (:func:`_cameras`). Then the
log is walked once a camera for its images: their payloads
as recorded (:meth:`dhlog.io.images.ImageStream.payload_batches`, a few MiB at a time), handed
in tasks of :data:`TASK_FRAMES` to ``jobs`` worker processes that decode each
(:func:`dhlog.io.images.decode_payload`) and detect the board in it
(:func:`dhlog.vision.detect.detect`), at most :data:`IN_FLIGHT` tasks a worker waiting, and the
results taken back in the frames' order; with ``jobs=1`` the same work is done in the calling
process. Memory: the walk's queue (:data:`dhlog.io.images.QUEUED` batches of
:data:`PAYLOAD_BATCH_BYTES`), the tasks in flight, one decoded frame a worker and the
detections (a few hundred bytes a frame): a 10 000-frame full-HD log is never held.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
from collections import deque
from collections.abc import Callable, Generator, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, MissingTopicError, PipelineError
from dhlog.io import ros2
from dhlog.io.images import (
    INFO_SCHEMAS,
    CameraInfo,
    Decoder,
    Faults,
    ImageFaultError,
    ImagePayload,
    ImageStream,
    _Cdr,
    _foxglove_bytes,
    _kind,
    _log_files,
    decode_payload,
    payload_decoder,
    read_camera_infos,
    unzstd_payload,
)
from dhlog.io.mcapscan import scan_mcap
from dhlog.io.mcapwalk import ChannelInfo, RawMessages
from dhlog.io.pipeline import DEFAULT_TOPICS, Pipeline, StreamSpec
from dhlog.io.safetext import printable
from dhlog.model.dh import JointType
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics
from dhlog.vision.detect import REASONS, Detection, Rejected, Tally, detect
from dhlog.vision.observe import (
    MOVING_SPEED,
    NOMINAL_EXPOSURE_S,
    Decimation,
    Observations,
    joint_values_at,
)

if TYPE_CHECKING:
    from dhlog.io.decode.blocks import Block

#: Frames a task carries to a worker, and tasks a worker may have waiting: the bound on the
#: payloads in flight (a full-HD JPEG is 0.2–0.5 MB, a raw bgr8 frame 6.2 MB).
TASK_FRAMES = 4
IN_FLIGHT = 2
#: Payload bytes a batch of the image walk holds (:meth:`ImageStream.payload_batches`).
PAYLOAD_BATCH_BYTES = 8 << 20
#: A raw frame kept for the recording is JPEG-encoded at this quality.
KEPT_JPEG_QUALITY = 90
#: The share of the progress given to the first walk (the joint states and camera infos).
FIRST_WALK = 0.05


class VisionLogError(InputError):
    """A camera log that cannot be observed as given: no intrinsics, images of another size
    than the intrinsics', no frame with the target, no frame with joint values."""


@dataclass(frozen=True)
class _Setup:
    """What every frame is looked at with: the board, the intrinsics and the image size."""

    board: BoardSpec
    camera: Intrinsics


@dataclass(frozen=True)
class _Seen:
    """One frame looked at: its stamp (the header's, else the log time), and a fault (not
    decoded), or its size (w, h) when not the intrinsics', or the detection's outcome and
    the frame kept compressed (when asked)."""

    index: int
    stamp_ns: int = 0
    fault: str | None = None
    size: tuple[int, int] | None = None
    outcome: Detection | Rejected | None = None
    kept: tuple[str, bytes] | None = None


_WORKER_SETUP: _Setup | None = None
_DECODERS: dict[ChannelInfo, Decoder | None] = {}


def _worker_start(setup: _Setup) -> None:
    """A worker's set-up: what it looks with; one OpenCV thread (``jobs`` workers use ``jobs``
    cores); SIGINT ignored (Ctrl-C stops the parent, which stops the workers: no traceback
    from each)."""
    global _WORKER_SETUP
    _WORKER_SETUP = setup
    cv2.setNumThreads(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _look_in_worker(frames: list[tuple[ImagePayload, bool]]) -> list[_Seen]:
    assert _WORKER_SETUP is not None  # (set by the pool's initializer)
    return _look(_WORKER_SETUP, frames)


def _look(setup: _Setup, frames: list[tuple[ImagePayload, bool]]) -> list[_Seen]:
    """Decode each payload and detect the board in it; ``keep``: return it compressed too."""
    out = []
    for payload, keep in frames:
        info = payload.channel
        if info not in _DECODERS:
            _DECODERS[info] = payload_decoder(info)
        decode = _DECODERS[info]
        buf = np.frombuffer(payload.data, dtype=np.uint8)
        try:
            if decode is None:  # (ImageStream refuses such a channel before any payload)
                raise ImageFaultError(f"not an image ({printable(info.schema_name[:80])})")
            stamp, _, pixels = decode_payload(decode, buf)
        except ImageFaultError as exc:
            out.append(_Seen(payload.index, fault=str(exc)))
            continue
        stamp = stamp if stamp > 0 else payload.log_time
        h, w = pixels.shape[:2]
        if (w, h) != setup.camera.size:
            out.append(_Seen(payload.index, stamp, size=(w, h)))
            continue
        outcome = detect(pixels, setup.board, camera=setup.camera)
        kept = _kept(info, buf, pixels) if keep else None
        out.append(_Seen(payload.index, stamp, outcome=outcome, kept=kept))
    return out


def _kept(info: ChannelInfo, buf: NDArray[np.uint8], pixels: NDArray[Any]) -> tuple[str, bytes]:
    """A frame as the recording keeps it: a JPEG or PNG as recorded; any other (raw, or a
    compressed form the recording cannot show) encoded by OpenCV — JPEG for 8 bits, PNG for
    16."""
    with contextlib.suppress(ImageFaultError, ValueError, TypeError, AttributeError):
        data, fmt = _compressed(info, unzstd_payload(buf))
        if data is not None:
            kind = _kind(data, fmt)
            if kind in ("JPEG", "PNG") and data[:2].tobytes() in (b"\xff\xd8", b"\x89P"):
                return kind.lower(), data.tobytes()
    if pixels.dtype == np.uint16:
        return "png", cv2.imencode(".png", pixels)[1].tobytes()
    params = [cv2.IMWRITE_JPEG_QUALITY, KEPT_JPEG_QUALITY]
    return "jpeg", cv2.imencode(".jpg", pixels, params)[1].tobytes()


def _compressed(info: ChannelInfo, buf: NDArray[np.uint8]) -> tuple[NDArray[np.uint8] | None, str]:
    """A compressed image message's data and format (None for a raw image)."""
    if info.schema_name == ros2.COMPRESSED_IMAGE and info.message_encoding == "cdr":
        cdr = _Cdr(buf)
        cdr.stamp()
        cdr.string()  # the header's stamp and frame id
        fmt = cdr.string()
        return cdr.octets(), fmt
    if info.schema_name == "foxglove.CompressedImage":
        from dhlog.io.decode.messages import message_decoder

        decode = message_decoder(info)
        if decode is not None:
            msg = decode(buf.tobytes())

            def get(field: str) -> Any:
                return msg.get(field) if isinstance(msg, dict) else getattr(msg, field, None)

            return _foxglove_bytes(get("data")), str(get("format") or "")
    return None, ""


# ---------------------------------------------------------------------------------------------
# the first walk: joint states and camera infos


@dataclass
class _Small:
    """What the first walk found: the topics present, the joint states (t, q, names), the
    camera infos, warnings."""

    topics: list[str]
    joint_t: NDArray[np.int64]
    joint_q: NDArray[np.float64]
    joint_names: list[str]
    infos: dict[str, list[CameraInfo]]
    warnings: list[str]


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
    from dhlog.io.decode.blocks import decode_stream
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
    damaged: list[tuple[str, int, int, str]] = []
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
                blocks += decode_stream(
                    "joints", channels, scan.messages, None, spec.fields, name,
                    damaged=damaged, notes=warnings,
                )  # fmt: skip
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
    for topic, bad, total, first in damaged:
        warnings.append(
            f"{name}: {bad} of {total} message(s) on {topic} could not be decoded and were "
            f"skipped (first at {first})."
        )
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
    return _Small(sorted(present), t, q.reshape(t.size, len(names)), names, infos, warnings)


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
    name: str, pipeline: Pipeline, camera: _Camera, small: _Small, warnings: list[str]
) -> tuple[Intrinsics, str]:
    """The camera's intrinsics and where they come from (the pipeline's calibration file, or
    the first camera info on its topic)."""
    assert pipeline.camera is not None
    if camera.info is None:
        assert pipeline.camera.intrinsics is not None
        return pipeline.camera.intrinsics, f"[camera] calibration {pipeline.camera.calibration}"
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
    found = Intrinsics.from_camera_info(
        first.width, first.height, first.distortion_model, first.d, first.k.ravel(), where=where
    )
    changed = next(
        (
            k
            for k, info in enumerate(infos)
            if (info.width, info.height, info.distortion_model, info.d)
            != (first.width, first.height, first.distortion_model, first.d)
            or not np.array_equal(info.k, first.k)
        ),
        None,
    )
    if changed is not None:
        warnings.append(
            f"{where}: the intrinsics change at camera info {changed} of {len(infos)}; "
            "the first are used for every frame (give a calibration file as [camera] "
            "calibration to choose them)."
        )
    return found, f"camera info on {topic}"


# ---------------------------------------------------------------------------------------------
# the images


def _tasks(
    stream: ImageStream, decimation: Decimation
) -> Iterator[list[tuple[ImagePayload, bool]]]:
    task: list[tuple[ImagePayload, bool]] = []
    for batch in stream.payload_batches():
        for payload in batch:
            task.append((payload, decimation.wanted(payload.index)))
            if len(task) == TASK_FRAMES:
                yield task
                task = []
    if task:
        yield task


def _looked(
    stream: ImageStream, setup: _Setup, jobs: int, decimation: Decimation
) -> Generator[list[_Seen], None, None]:
    """Each task's frames looked at, in the frames' order: in ``jobs`` worker processes, or
    here when ``jobs`` is 1."""
    if jobs <= 1:
        for task in _tasks(stream, decimation):
            yield _look(setup, task)
        return
    context = multiprocessing.get_context("spawn")  # no fork of a process holding threads
    pool = ProcessPoolExecutor(jobs, context, initializer=_worker_start, initargs=(setup,))
    waiting: deque[Future[list[_Seen]]] = deque()
    try:
        for task in _tasks(stream, decimation):
            waiting.append(pool.submit(_look_in_worker, task))
            if len(waiting) >= IN_FLIGHT * jobs:
                yield waiting.popleft().result()
        while waiting:
            yield waiting.popleft().result()
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _frames(indices: list[int], total: int | None = None) -> str:
    shown = ", ".join(str(i) for i in indices[:5])
    n = len(indices) if total is None else total
    more = f" and {n - 5} more" if n > 5 else ""
    return f"frame{'s' if n > 1 else ''} {shown}{more}"


_FIX = {
    "wrong dictionary": (
        "the markers seen are of another dictionary: set the pipeline's [target] dictionary "
        "to the printed board's"
    ),
    "too few corners": (
        "check that the pipeline's [target] squares, square_m and marker_m describe the printed "
        "board, and that the frames show most of it"
    ),
    "blurred": "focus the camera or shorten its exposure, and record still poses",
    "no target": (
        "check that [streams.image] is the camera that sees the board and that the pipeline's "
        "[target] kind and dictionary describe it"
    ),
    "unreadable image": "the images are not ones OpenCV can read: check the camera's encoding",
}


def observe(
    path: str | Path,
    pipeline: Pipeline,
    *,
    jobs: int = 1,
    keep_frames: int = 200,
    progress: Callable[[float], None] | None = None,
    joint_names: Sequence[str] | None = None,
    joint_source: str = "model",
) -> list[Observations]:
    """The board's corners in every frame of the camera log at ``path`` (an MCAP file or a
    rosbag2 bag folder) read with the camera ``pipeline``, with the encoders at each frame's
    stamp: one :class:`Observations` per camera (the pipeline's ``[streams.image]`` topic
    first, then the topics like it in other namespaces: see the module). The warnings of the
    log (damaged joint states, cameras left out) are the first camera's.

    ``jobs``: worker processes decoding and detecting (1: this process). ``keep_frames``: the
    most frames kept compressed for the recording, evenly over the log. ``progress`` is called
    with the fraction done. One line each, as a :class:`VisionLogError` (or the reader's
    ``InputError``): no intrinsics, images of another size than the intrinsics', no frame with
    the target (the tally and the likely fix), no frame with joint values; as warnings: frames
    not decoded, frames without joint values within ``[segmentation] join_tolerance``, frames
    taken while the joints moved. With several cameras a camera that fails so is left out (a
    warning), and the error is raised only when every camera fails."""
    name = str(path)
    if pipeline.image is None or pipeline.target is None or pipeline.camera is None:
        raise PipelineError(
            pipeline.source,
            f"is not a camera pipeline ({pipeline.name}: no [streams.image] with [target] and "
            "[camera]); give a camera pipeline (the shipped ros2_camera, or a file of your own: "
            "docs/pipeline.md, Writing a pipeline file).",
        )
    if jobs < 1:
        raise InputError(f"jobs is {jobs}; give 1 or more worker processes.")

    done = [0.0]

    def report(fraction: float) -> None:  # never backwards
        done[0] = min(max(fraction, done[0]), 1.0)
        if progress is not None:
            progress(done[0])

    report(0.0)
    small = _first_walk(name, pipeline, lambda f: report(FIRST_WALK * f), joint_names, joint_source)
    cameras = _cameras(name, pipeline, small.topics)
    share = (1.0 - FIRST_WALK) / len(cameras)
    out: list[Observations] = []
    failed: list[VisionLogError] = []
    for k, cam in enumerate(cameras):

        def step(f: float, k: int = k) -> None:
            report(FIRST_WALK + share * (k + f))

        try:
            out.append(_observe_camera(name, pipeline, cam, small, jobs, keep_frames, step))
        except VisionLogError as exc:
            if len(cameras) == 1:
                raise
            failed.append(exc)
    if not out:  # every camera failed: the first one's reason (the others' are alike)
        more = f" ({len(failed) - 1} other camera(s) failed too)" if len(failed) > 1 else ""
        raise VisionLogError(f"{failed[0]}{more}")
    out[0].warnings[:0] = [*small.warnings, *(f"{exc} That camera is left out." for exc in failed)]
    report(1.0)
    return out


def _observe_camera(
    name: str,
    pipeline: Pipeline,
    cam: _Camera,
    small: _Small,
    jobs: int,
    keep_frames: int,
    report: Callable[[float], None],
) -> Observations:
    """One camera's observations (see :func:`observe`)."""
    assert pipeline.target is not None
    warnings: list[str] = []
    topic = cam.image
    camera, source = _intrinsics(name, pipeline, cam, small, warnings)
    setup = _Setup(pipeline.target, camera)
    stream = ImageStream(name, topic, batch_bytes=PAYLOAD_BATCH_BYTES)
    decimation = Decimation(keep_frames)
    tally, faults = Tally(), Faults()
    found: list[tuple[int, int, NDArray[np.int64], NDArray[np.float64]]] = []
    first_detail: dict[str, str] = {}
    with contextlib.closing(_looked(stream, setup, jobs, decimation)) as looked:
        for seen in looked:
            wrong = [s for s in seen if s.size is not None]
            if wrong:
                where = f"{name}: {_frames([s.index for s in wrong])} on {topic}"
                raise _size_error(where, len(wrong), wrong[0].size or (0, 0), camera, source)
            for s in seen:
                if s.fault is not None:
                    faults.add(s.fault, s.index)
                    continue
                assert s.outcome is not None
                tally.add(s.index, s.outcome)
                if isinstance(s.outcome, Detection):
                    found.append((s.index, s.stamp_ns, s.outcome.ids, s.outcome.corners_px))
                else:
                    first_detail.setdefault(s.outcome.reason, s.outcome.detail)
                if s.kept is not None:
                    decimation.add(s.index, *s.kept)
            report(stream.fraction)
    warnings.extend(stream.warnings)
    stream.faults = faults
    fault_line = stream.warning()
    if fault_line is not None:
        warnings.append(fault_line)
    if not found:
        raise VisionLogError(_nothing_found(name, topic, tally, first_detail, fault_line))

    t = np.array([f[1] for f in found], dtype=np.int64)
    at = joint_values_at(t, small.joint_t, small.joint_q, pipeline.segmentation.join_tolerance)
    tolerance = pipeline.segmentation.join_tolerance
    joints_topic = _joints_spec(pipeline).topic
    missing = [found[k][0] for k in np.flatnonzero(~at.ok)]
    if len(missing) == len(found):
        raise VisionLogError(
            f"{name}: none of the {len(found)} frame(s) with the target has joint states on "
            f"{joints_topic} within [segmentation] join_tolerance = {tolerance:g} s of its stamp "
            f"({_frames(missing)}); check that the joint states cover the frames (their "
            "clocks: [segmentation] clock_offset) or raise join_tolerance in the pipeline."
        )
    if missing:
        warnings.append(
            f"{name}: {len(missing)} of {len(found)} frame(s) with the target have no joint "
            f"states on {joints_topic} within [segmentation] join_tolerance = {tolerance:g} s "
            f"of their stamp ({_frames(missing)}), left out; raise join_tolerance in the "
            "pipeline if the encoders are sampled more sparsely."
        )
    speed = np.nanmax(np.abs(at.speed[at.ok]), axis=1) if at.ok.any() else np.zeros(0)
    moving = np.flatnonzero(at.ok)[speed > MOVING_SPEED]
    if moving.size:
        unit = _speed_unit(pipeline, small.joint_names)
        top = float(np.nanmax(speed))
        warnings.append(
            f"{name}: the joints moved while {moving.size} of {int(at.ok.sum())} frame(s) were "
            f"taken ({_frames([found[k][0] for k in moving])}: up to {top:.3g} {unit} at the "
            f"frame's stamp, above {MOVING_SPEED:g}): over an exposure of "
            f"{NOMINAL_EXPOSURE_S * 1e3:g} ms their corners are smeared by up to "
            f"{top * NOMINAL_EXPOSURE_S * 1e3:.2g} mm at a lever of 1 m; take the frames at "
            "still poses."
        )
    keep = np.flatnonzero(at.ok)
    # in time order: the headers' stamps need not be in the file's order
    keep = keep[np.argsort(t[keep], kind="stable")]
    return Observations(
        path=name,
        camera=topic,
        intrinsics=camera,
        board=pipeline.target,
        t_ns=t[keep],
        frame=np.array([found[k][0] for k in keep], dtype=np.int64),
        q=np.asarray(at.q[keep], dtype=np.float64),
        joint_names=list(small.joint_names),
        ids=[found[k][2].astype(np.int64) for k in keep],
        uv=[np.asarray(found[k][3], dtype=np.float64) for k in keep],
        tally=tally,
        kept=decimation.frames(),
        warnings=warnings,
    )


def _size_error(
    frames: str, count: int, size: tuple[int, int], camera: Intrinsics, source: str
) -> VisionLogError:
    w, h = size
    return VisionLogError(
        f"{frames} {'are' if count > 1 else 'is'} {w}×{h} px, but the intrinsics "
        f"({source}) are for {camera.width}×{camera.height} px; give the calibration of the "
        "camera at the images' resolution ([camera] calibration in the pipeline) or the "
        "camera-info topic recorded with these images ([camera] info_topic)."
    )


def _speed_unit(pipeline: Pipeline, names: list[str]) -> str:
    types = pipeline.joint_types or ()
    prismatic = any(t is JointType.PRISMATIC for t in types)
    revolute = len(types) < len(names) or any(t is not JointType.PRISMATIC for t in types)
    return "rad/s or m/s" if prismatic and revolute else "m/s" if prismatic else "rad/s"


def _nothing_found(
    name: str,
    topic: str,
    tally: Tally,
    detail: dict[str, str],
    fault_line: str | None,
) -> str:
    if tally.frames == 0:
        why = fault_line or f"{topic} holds no frame"
        return f"{name}: no frame of {topic} could be decoded ({why}); check the camera's topic."
    reason = max(REASONS, key=lambda r: tally.counts.get(r, 0))
    seen = f" (first: {detail[reason]})" if reason in detail else ""
    return (
        f"{name}: the board was found in no frame of {topic}: {tally.summary()}{seen}; "
        f"{_FIX[reason]}."
    )
