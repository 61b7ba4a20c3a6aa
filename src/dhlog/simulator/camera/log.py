"""What a simulated vision session gives: the MCAP log as a ROS 2 camera records it
(:func:`write_vision_log`: each frame rendered, raw or compressed, with its camera info and the
joint states; several cameras on :func:`camera_topics`), the true corners with Gaussian pixel
noise and no rendering (:func:`simulate_detections`: fast Monte Carlo) and the truth block
(:func:`vision_truth`). The truth is ``Intrinsics.project`` of the board's corners through the
true chain (:meth:`Rig.board_in_camera`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
from mcap.writer import CompressionType, Writer
from numpy.typing import NDArray

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.simulator.camera.frames import VisionSession
from dhlog.simulator.camera.render import (
    BLUR_SIGMA,
    EXPOSURE,
    PIXEL_NOISE,
    render,
)

JPEG_QUALITY = 95


TOPICS = {
    "raw": "/camera/image_raw",
    "compressed": "/camera/image_raw/compressed",
    "info": "/camera/camera_info",
    "joints": "/joint_states",
}


def camera_topics(index: int, cameras: int) -> dict[str, str]:
    """The topics of camera ``index`` (0-based) of ``cameras``: :data:`TOPICS` for one camera,
    ``/camera_1/…``, ``/camera_2/…`` for several."""
    if cameras == 1:
        return {k: v for k, v in TOPICS.items() if k != "joints"}
    name = f"/camera_{index + 1}"
    return {k: v.replace("/camera/", f"{name}/") for k, v in TOPICS.items() if k != "joints"}


def write_vision_log(vision: VisionSession, path: str | Path, seed: int) -> None:
    """Write ``vision`` to ``path`` (atomically) as rosbag2 records it: ``/joint_states``, and
    for each camera its images (raw mono8, or JPEG / PNG compressed) with a ``CameraInfo`` each
    (:func:`camera_topics`)."""
    from dhlog.io import ros2
    from dhlog.io.writer import atomic_output

    s, fmt, views = vision.session, vision.image_format, vision.cameras
    rng = np.random.default_rng([seed, 34])
    image_schema = ros2.IMAGE if fmt == "raw" else ros2.COMPRESSED_IMAGE
    topics = [camera_topics(c, len(views)) for c in range(len(views))]
    with atomic_output(path) as f:
        writer = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD, enable_crcs=False)
        writer.start(profile="ros2", library="rosbag2 (simulated by dhlog)")
        ids = {
            name: writer.register_schema(name, "ros2msg", ros2.MSGDEFS[name].encode())
            for name in (ros2.JOINT_STATE, image_schema, ros2.CAMERA_INFO)
        }
        qos = {"offered_qos_profiles": ""}
        ch_joints = writer.register_channel(TOPICS["joints"], "cdr", ids[ros2.JOINT_STATE], qos)
        channels = []
        counts = {TOPICS["joints"]: int(s.joint_t_ns.size)}
        for view, topic in zip(views, topics, strict=True):
            image_topic = topic["raw" if fmt == "raw" else "compressed"]
            channels.append(
                (
                    writer.register_channel(image_topic, "cdr", ids[image_schema], qos),
                    writer.register_channel(topic["info"], "cdr", ids[ros2.CAMERA_INFO], qos),
                )
            )
            counts[image_topic] = counts[topic["info"]] = int(view.frame_t_ns.size)
        joints = ros2.encode_joint_state(s.joint_t_ns, s.joint_names, s.joint_q)
        events = [(int(t), 0, 0, i) for i, t in enumerate(s.joint_t_ns)]
        for c, view in enumerate(views):
            events += [(int(t), 1, c, i) for i, t in enumerate(view.frame_t_ns)]
        for t, kind, c, i in sorted(events):
            if kind == 0:
                writer.add_message(ch_joints, t, joints[i], t)
                continue
            view, (ch_image, ch_info) = views[c], channels[c]
            frame_id = "camera" if len(views) == 1 else f"camera_{c + 1}"
            T_exp = None if view.T_exposure is None else view.T_exposure[i]
            pixels = render(view.rig, view.T_cam_board[i], rng, T_exp)
            if fmt == "raw":
                payload = ros2.encode_image(t, frame_id, pixels, "mono8")
            else:
                ext = ".jpg" if fmt == "jpeg" else ".png"
                params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if fmt == "jpeg" else []
                ok, data = cv2.imencode(ext, pixels, params)
                assert ok
                payload = ros2.encode_compressed_image(t, frame_id, data.tobytes(), fmt)
            writer.add_message(ch_image, t, payload, t)
            cam = view.rig.camera
            size = (cam.width, cam.height)
            info = ros2.encode_camera_info(
                ros2.CameraInfo.unrectified(
                    t, frame_id, size, cam.model, cam.coefficients.tolist(), cam.K
                )
            )
            writer.add_message(ch_info, t, info, t)
        writer.add_metadata(
            "rosbag2",
            {
                "serialized_metadata": json.dumps(
                    {"version": 9, "storage_identifier": "mcap", "message_counts": counts}
                )
            },
        )
        writer.finish()  # type: ignore[no-untyped-call]


def simulate_detections(
    vision: VisionSession, sigma_px: float, rng: np.random.Generator, *, camera: int = 0
) -> list[tuple[NDArray[np.int64], FloatArray]]:
    """Synthetic detections without rendering, for fast Monte Carlo: for each frame of camera
    ``camera`` (0-based), the ids (k,) of the board's corners whose true projection
    (``Intrinsics.project`` of the corners through the true chain: the frame's
    ``T_cam_board``) falls inside the image (``0 ≤ u ≤ w − 1``, ``0 ≤ v ≤ h − 1``, in
    front of the camera) and those projections (k, 2) px with independent Gaussian noise of
    σ ``sigma_px`` on each coordinate. The frames' joint values are :attr:`CameraFrames.frame_q`."""
    if not (math.isfinite(sigma_px) and sigma_px >= 0):
        raise DhlogError(f"the corner noise must be a finite σ ≥ 0 px (got {sigma_px!r})")
    views = vision.cameras
    if not 0 <= camera < len(views):
        raise DhlogError(f"camera {camera} of {len(views)}: name 0 to {len(views) - 1}")
    view = views[camera]
    cam, P = view.rig.camera, view.rig.board.object_points()
    T = view.T_cam_board
    if not len(T):
        return []
    pts = np.einsum("fij,kj->fki", T[:, :3, :3], P) + T[:, None, :3, 3]
    uv = cam.project(pts.reshape(-1, 3)).reshape(len(T), len(P), 2)
    w, h = cam.size
    with np.errstate(invalid="ignore"):
        inside = (
            (pts[..., 2] > 0)
            & (uv[..., 0] >= 0)
            & (uv[..., 0] <= w - 1)
            & (uv[..., 1] >= 0)
            & (uv[..., 1] <= h - 1)
        )
    out = []
    for f in range(len(T)):
        ids = np.flatnonzero(inside[f]).astype(np.int64)
        out.append((ids, uv[f, ids] + rng.normal(0.0, sigma_px, (ids.size, 2))))
    return out


def vision_truth(vision: VisionSession, **source: str) -> dict[str, object]:
    """The truth document of a vision log: the session's (:func:`truth_document`; its tracker
    samples were not written) with a ``camera`` block: the rig (the camera's pose in the base
    frame for eye-to-hand or on the flange for eye-in-hand, the board's mount, the board and
    the intrinsics), the preset, the images' format, count, noise and blur, the frame rate and
    the frames of each move (a moving protocol), the warnings; with several cameras, a
    ``cameras`` list too (each camera's rig, topics and frames; the ``camera`` block the
    first's)."""
    from dhlog.simulator.truth import truth_document

    doc = truth_document(vision.session, **source)
    views = vision.cameras
    blocks = []
    for c, view in enumerate(views):
        topics = camera_topics(c, len(views))
        moves: dict[str, int] = {}
        for label in view.frame_move:
            moves[label] = moves.get(label, 0) + 1
        blocks.append(
            {
                **view.rig.document(),
                "preset": vision.preset,
                "image_format": vision.image_format,
                "frames": int(view.frame_t_ns.size),
                "frames_per_move": moves,
                "frame_rate_hz": vision.frame_rate,
                "exposure_s": vision.exposure,
                "pixel_noise": PIXEL_NOISE,
                "blur_sigma_px": BLUR_SIGMA,
                "exposure_gain": list(EXPOSURE),
                "image_topic": topics["raw" if vision.image_format == "raw" else "compressed"],
                "info_topic": topics["info"],
            }
        )
    doc["camera"] = {**blocks[0], "warnings": list(vision.warnings)}
    if len(blocks) > 1:
        doc["cameras"] = blocks
    simulation = doc["simulation"]
    assert isinstance(simulation, dict)
    simulation["instrument"] = "camera"
    return doc
