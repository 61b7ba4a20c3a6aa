"""A camera log observed (:func:`observe`): the board's corners detected in every frame, the
encoders joined at each frame's stamp, a few frames kept for the recording.

The log is walked first for the small streams — the joint states and every camera info — so
that a log without intrinsics or encoders is refused before any image is decoded, and every
frame is detected with the intrinsics; the cameras are the pipeline's image topic and those
like it in other namespaces (:mod:`~dhlog.identify.camera.frames.camerafind`). Then the log is
walked once a camera for its images: their payloads as recorded
(:meth:`~dhlog.identify.camera.frames.images.ImageStream.payload_batches`,
:data:`PAYLOAD_BATCH_BYTES` at a time), decoded and detected in worker processes
(:mod:`~dhlog.identify.camera.frames.framedetect`) and taken back in the frames' order. Memory:
the walk's queue (:data:`~dhlog.identify.camera.frames.images.QUEUED` batches of
:data:`PAYLOAD_BATCH_BYTES`), the tasks in flight, one decoded frame a worker and the
detections (a few hundred bytes a frame): a 10 000-frame full-HD log is never held. A log that
cannot be observed as given is a :class:`~dhlog.identify.camera.frames.camerafind.VisionLogError`
naming what to fix.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, PipelineError
from dhlog.identify.camera.frames.camerafind import VisionLogError as VisionLogError
from dhlog.identify.camera.frames.camerafind import (
    _Camera,
    _cameras,
    _first_walk,
    _intrinsics,
    _joints_spec,
    _Small,
    readings,
)
from dhlog.identify.camera.frames.detect import REASONS, Detection, Tally, reason_of
from dhlog.identify.camera.frames.framedetect import _looked, _Setup
from dhlog.identify.camera.frames.images import Faults, ImageStream
from dhlog.identify.camera.frames.obeyed import judged
from dhlog.identify.camera.frames.observations import (
    MOVING_SPEED,
    NOMINAL_EXPOSURE_S,
    Decimation,
    Observations,
    joint_values_at,
)
from dhlog.io.pipeline import Pipeline
from dhlog.io.sqlitebag import Copy, as_mcap, sqlite3_storage
from dhlog.model.dh import JointType
from dhlog.vision.camera import Intrinsics

#: Payload bytes a batch of the image walk holds (:meth:`ImageStream.payload_batches`).
PAYLOAD_BATCH_BYTES = 8 << 20
#: The share of the progress given to the first walk (the joint states and camera infos).
FIRST_WALK = 0.05


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
    if sqlite3_storage(Path(path)):  # as ROS 2 Humble records by default: read as its MCAP copy
        with as_mcap(Path(path), progress) as copy:
            found = observe(
                copy.path,
                pipeline,
                jobs=jobs,
                keep_frames=keep_frames,
                progress=copy.reading,
                joint_names=joint_names,
                joint_source=joint_source,
            )
        return [_of_bag(obs, copy) for obs in found]

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
    said = (*small.warnings, *(f"{exc} That camera is left out." for exc in failed))
    out[0] = replace(out[0], warnings=(*said, *out[0].warnings))
    report(1.0)
    return out


def _of_bag(obs: Observations, copy: Copy) -> Observations:
    """``obs`` read from a sqlite3 bag's MCAP copy, naming the bag where it named the copy."""
    intrinsics = replace(obs.intrinsics, where=copy.renamed(obs.intrinsics.where))
    return replace(
        obs,
        path=str(copy.bag),
        intrinsics=intrinsics,
        warnings=tuple(copy.renamed(w) for w in obs.warnings),
    )


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
    topic = cam.image
    camera, source, said = _intrinsics(name, pipeline, cam, small)
    walked = _walk(name, topic, _Setup(pipeline.target, camera), source, jobs, keep_frames, report)
    both = readings(name, pipeline, cam, small, camera)
    obeyed: tuple[str, ...] = ()
    if both is not None:  # the reading the images obey: K and D, or P (rectified)
        told = pipeline.camera is not None and pipeline.camera.rectified is not None
        corners = [(f[2], f[3]) for f in walked.found]
        reading, obeyed = judged(name, pipeline.target, corners, *both, told=told)
        if reading.intrinsics != camera:  # detected again: the corners placed with its lens
            camera, source = reading.intrinsics, reading.source
            setup = _Setup(pipeline.target, camera)
            walked = _walk(name, topic, setup, source, jobs, keep_frames, report)
    warnings = [*said, *walked.warnings, *obeyed]
    found, tally, decimation = walked.found, walked.tally, walked.decimation

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
        warnings=tuple(warnings),
    )


@dataclass(frozen=True)
class _Walked:
    """One walk over a camera's images: the frames with the board (index, stamp, corner ids,
    corners in px), the tally of every frame, the frames kept for the recording and the walk's
    warnings (damaged images, frames not decoded)."""

    found: list[tuple[int, int, NDArray[np.int64], NDArray[np.float64]]]
    tally: Tally
    decimation: Decimation
    warnings: tuple[str, ...]


def _walk(
    name: str,
    topic: str,
    setup: _Setup,
    source: str,
    jobs: int,
    keep_frames: int,
    report: Callable[[float], None],
) -> _Walked:
    """The board looked for in every image on ``topic`` with ``setup`` (the board and the
    intrinsics from ``source``); images of another size than the intrinsics', or no frame with
    the board, are a :class:`VisionLogError`."""
    stream = ImageStream(name, topic, batch_bytes=PAYLOAD_BATCH_BYTES)
    decimation = Decimation(keep_frames)
    outcomes: list[tuple[int, str | None]] = []  # every frame's: the reason, None detected
    faulted: list[tuple[str, int]] = []  # the frames not decoded: (reason, index)
    found: list[tuple[int, int, NDArray[np.int64], NDArray[np.float64]]] = []
    first_detail: dict[str, str] = {}
    with contextlib.closing(_looked(stream, setup, jobs, decimation)) as looked:
        for seen in looked:
            wrong = [s for s in seen if s.size is not None]
            if wrong:
                where = f"{name}: {_frames([s.index for s in wrong])} on {topic}"
                size = wrong[0].size or (0, 0)
                raise _size_error(where, len(wrong), size, setup.camera, source)
            for s in seen:
                if s.fault is not None:
                    faulted.append((s.fault, s.index))
                    continue
                assert s.outcome is not None
                outcomes.append((s.index, reason_of(s.outcome)))
                if isinstance(s.outcome, Detection):
                    found.append((s.index, s.stamp_ns, s.outcome.ids, s.outcome.corners_px))
                else:
                    first_detail.setdefault(s.outcome.reason, s.outcome.detail)
                if s.kept is not None:
                    decimation.add(s.index, *s.kept)
            report(stream.fraction)
    tally = Tally.of(outcomes)
    fault_line = Faults.of(faulted).warning(name, topic, stream.count)
    if not found:
        raise VisionLogError(_nothing_found(name, topic, tally, first_detail, fault_line))
    warnings = (*stream.warnings, *(() if fault_line is None else (fault_line,)))
    return _Walked(found, tally, decimation, warnings)


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
