"""The cameras of a camera calibration in a result's recording, drawn from
:class:`~dhlog.vision.view.CameraView`: each kept frame's image stored compressed (the log's
JPEG or PNG bytes, never decoded pixels) with its detected corners, where the result reprojects
them and the error vectors between them magnified; the camera as a pinhole (its frustum) at its
pose in the robot's base frame; the board's corners in 3D.

Entities (``world/base`` is the robot's base frame as the 3D views show it; ``<cam>`` the image
topic made a path part, :func:`camera_paths`):

* ``world/base/cameras/<cam>`` the camera frame (OpenCV's: x right, y down, z along the optical
  axis) at ``T_base_camera`` — static when the camera is fixed (eye-to-hand), on the
  ``sensor_time`` line at each frame's stamp when it moves (eye-in-hand);
* ``.../<cam>/image`` the pinhole (``K``, the resolution, ``camera_xyz`` RDF; its image plane
  at the board's median distance, so the frustum reaches the board) and the frame's image
  (``rr.EncodedImage``) at its stamp;
* ``.../<cam>/image/detected`` the detected corners (fitted frames blue, held-out frames
  amber), ``.../image/reprojected`` where the result puts them (magenta), ``.../image/errors``
  detected → reprojected magnified ``k`` times (:func:`pixel_magnification`: the 1-2-5 rule of
  the FK-residual tab, in pixels), all in pixels;
* ``world/base/boards/<cam>`` the board's corners at ``T_base_board`` (static when the board is
  fixed, eye-in-hand; at each frame's stamp when it rides on the flange, eye-to-hand);
* ``report/cameras/<cam>`` one Markdown paragraph: the camera, its frames, the RMS and the
  magnification.

Only frames that carry an image are drawn when any does (the image, its corners and the poses
stay together at one stamp); a view without images draws every frame's corners.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dhlog.geometry._checks import FloatArray
from dhlog.present.recording.scene import TIMELINE, Shown, _nice, time_column

if TYPE_CHECKING:
    from dhlog.vision.view import CameraView, FrameView

#: Corners of frames that fitted the result, of held-out frames, and reprojected corners.
FITTED_COLOR = [60, 170, 255]
HELD_OUT_COLOR = [255, 170, 40]
REPROJECTED_COLOR = [240, 60, 200]
#: The board's corners in 3D.
BOARD_COLOR = [230, 230, 230]
#: Two poses closer than this (m, and rad through the rotation's entries) are one fixed pose.
SAME_POSE = 1e-9
#: What an error vector is magnified to: this share of the image's diagonal at the RMS (the
#: FK-residual tab's 2 % of the robot's extent, in pixels).
ERROR_SHARE = 0.02

#: The images are handed to the SDK in batches of about this many bytes.
IMAGE_BATCH_BYTES = 16 << 20
#: The media types by the images' first bytes.
_MAGIC = ((b"\xff\xd8\xff", "image/jpeg"), (b"\x89PNG\r\n\x1a\n", "image/png"))


def camera_paths(views: Sequence[CameraView]) -> list[str]:
    """Each view's entity path ``world/base/cameras/<cam>``: its name (the image topic) with
    every run of characters other than letters, digits and ``_`` made one ``_`` (``cam`` when
    nothing is left), ``_2``, ``_3``, … added where two names become one."""
    out: list[str] = []
    for view in views:
        base = re.sub(r"[^A-Za-z0-9_]+", "_", view.name).strip("_") or "cam"
        part, k = base, 1
        while f"world/base/cameras/{part}" in out:
            k += 1
            part = f"{base}_{k}"
        out.append(f"world/base/cameras/{part}")
    return out


def base_in_world(shown: Shown) -> FloatArray:
    """The robot's base frame in the recording's ``world`` (4, 4): ``Shown.T`` (M → world) after
    ``T_measurement_base`` (base → M) — the identity, or the base turned over when the 3D views
    stand the robot the other way up; the identity without an extraction."""
    ex = shown.result.extraction
    if ex is None:
        return np.eye(4)
    return np.asarray(shown.T @ ex.T_measurement_base, dtype=np.float64)


def pixel_magnification(view: CameraView) -> float:
    """The factor that makes the reprojection RMS about :data:`ERROR_SHARE` of the image's
    diagonal: the FK-residual tab's rule (``Shown.magnification``, a 1-2-5 number ≥ 1), in
    pixels."""
    rms = view.rms_px
    if not math.isfinite(rms) or rms <= 0:
        return 1.0
    return _nice(ERROR_SHARE * math.hypot(view.intrinsics.width, view.intrinsics.height) / rms)


def media_type(frame: FrameView) -> str | None:
    """The image's media type by its first bytes (JPEG, PNG: what the viewer decodes, whatever
    ``image_format`` says); None when there is no image or it is neither."""
    data = frame.image
    if not data:
        return None
    for magic, kind in _MAGIC:
        if data.startswith(magic):
            return kind
    return None


@dataclass(frozen=True)
class _Drawn:
    """What is drawn of one view: the frames (those with an image when any has one), their
    stamps (ns), each frame's corners (finite detected and reprojected rows) and their
    counts."""

    frames: list[FrameView]
    t_ns: np.ndarray
    detected: FloatArray
    reprojected: FloatArray
    held_out: np.ndarray
    counts: list[int]
    unreadable: int

    @classmethod
    def of(cls, view: CameraView) -> _Drawn:
        frames = [f for f in view.frames if f.image]
        frames = frames if frames else list(view.frames)
        frames.sort(key=lambda f: f.t_ns)
        detected, reprojected, held, counts = [], [], [], []
        for f in frames:
            d = np.asarray(f.detected_px, dtype=np.float64).reshape(-1, 2)
            r = np.asarray(f.reprojected_px, dtype=np.float64).reshape(-1, 2)
            n = min(len(d), len(r))
            ok = np.all(np.isfinite(d[:n]), axis=1) & np.all(np.isfinite(r[:n]), axis=1)
            detected.append(d[:n][ok])
            reprojected.append(r[:n][ok])
            held.append(np.full(int(ok.sum()), bool(f.held_out)))
            counts.append(int(ok.sum()))
        unreadable = sum(1 for f in frames if f.image and media_type(f) is None)
        return cls(
            frames,
            np.array([f.t_ns for f in frames], dtype=np.int64),
            np.concatenate(detected) if detected else np.zeros((0, 2)),
            np.concatenate(reprojected) if reprojected else np.zeros((0, 2)),
            np.concatenate(held) if held else np.zeros(0, dtype=bool),
            counts,
            unreadable,
        )


def _fixed(poses: FloatArray) -> bool:
    """Whether every pose (F, 4, 4) is the first."""
    return bool(poses.shape[0] and np.all(np.abs(poses - poses[0]) <= SAME_POSE))


def _poses(frames: list[FrameView], name: str) -> FloatArray:
    return np.asarray([getattr(f, name) for f in frames], dtype=np.float64).reshape(-1, 4, 4)


def log_cameras(
    rec: rr.RecordingStream,
    views: Sequence[CameraView],
    *,
    T_world_base: FloatArray | None = None,
) -> None:
    """Draw each camera of ``views`` (see the module for the entities). ``T_world_base`` (4, 4)
    places the robot's base frame in the recording's ``world`` (:func:`base_in_world`); the
    identity when None."""
    if not views:
        return
    T = np.eye(4) if T_world_base is None else np.asarray(T_world_base, dtype=np.float64)
    rec.log("world/base", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True)
    for view, path in zip(views, camera_paths(views), strict=True):
        _log_camera(rec, view, path)


def _log_camera(rec: rr.RecordingStream, view: CameraView, path: str) -> None:
    drawn = _Drawn.of(view)
    frames = drawn.frames
    cam = view.intrinsics
    part = path.rsplit("/", 1)[1]
    index = [time_column(drawn.t_ns)]
    T_cam = _poses(frames, "T_base_camera")
    T_board = _poses(frames, "T_base_board")
    board = np.asarray(view.board_points, dtype=np.float64).reshape(-1, 3)
    k = pixel_magnification(view)
    summary = rr.TextDocument(_summary(view, drawn, k), media_type=rr.MediaType.MARKDOWN)
    rec.log(f"report/cameras/{part}", summary, static=True)
    if not frames:  # nothing places the camera or the board
        return
    # the image plane at the board's median distance along the optical axis
    centre = board.mean(axis=0) if len(board) else np.zeros(3)
    depth = np.einsum(
        "fi,fi->f",
        T_cam[:, :3, 2],
        T_board[:, :3, 3] + T_board[:, :3, :3] @ centre - T_cam[:, :3, 3],
    )
    depth = depth[np.isfinite(depth) & (depth > 0)]
    plane = float(np.median(depth)) if depth.size else None
    pinhole = rr.Pinhole(
        image_from_camera=cam.K,
        resolution=[cam.width, cam.height],
        camera_xyz=rr.ViewCoordinates.RDF,
        image_plane_distance=plane,
    )
    # the camera's axes (x red right, y green down, z blue along the optical axis), short
    axes = 0.15 * (plane or 1.0)
    F = len(frames)
    if _fixed(T_cam):
        Tc = T_cam[0]
        rec.log(path, rr.Transform3D(translation=Tc[:3, 3], mat3x3=Tc[:3, :3]), static=True)
        rec.log(path, rr.TransformAxes3D(axes), static=True)
        rec.log(f"{path}/image", pinhole, static=True)
    else:  # on the flange: the camera, its axes and pinhole only where a frame places them
        rec.send_columns(
            path,
            indexes=index,
            columns=[
                *rr.Transform3D.columns(translation=T_cam[:, :3, 3], mat3x3=T_cam[:, :3, :3]),
                *rr.TransformAxes3D.columns(axis_length=np.full(F, axes)),
            ],
        )
        rec.send_columns(
            f"{path}/image",
            indexes=index,
            columns=rr.Pinhole.columns(
                image_from_camera=np.broadcast_to(cam.K, (F, 3, 3)),
                resolution=np.tile([cam.width, cam.height], (F, 1)),
                camera_xyz=[rr.ViewCoordinates.RDF] * F,
                image_plane_distance=np.full(F, plane if plane is not None else 1.0),
            ),
        )
    _send_images(rec, f"{path}/image", frames, drawn.t_ns)
    colors = np.where(drawn.held_out[:, None], HELD_OUT_COLOR, FITTED_COLOR).astype(np.uint8)
    rec.log(f"{path}/image/detected", rr.Points2D.from_fields(radii=-2.5), static=True)
    rec.send_columns(
        f"{path}/image/detected",
        indexes=index,
        columns=rr.Points2D.columns(positions=drawn.detected, colors=colors).partition(
            drawn.counts
        ),
    )
    rec.log(
        f"{path}/image/reprojected",
        rr.Points2D.from_fields(radii=-1.5, colors=[REPROJECTED_COLOR]),
        static=True,
    )
    rec.send_columns(
        f"{path}/image/reprojected",
        indexes=index,
        columns=rr.Points2D.columns(positions=drawn.reprojected).partition(drawn.counts),
    )
    rec.log(f"{path}/image/errors", rr.Arrows2D.from_fields(radii=-1.0), static=True)
    rec.send_columns(
        f"{path}/image/errors",
        indexes=index,
        columns=rr.Arrows2D.columns(
            origins=drawn.detected,
            vectors=k * (drawn.reprojected - drawn.detected),
            colors=colors,
        ).partition(drawn.counts),
    )
    boards = f"world/base/boards/{part}"
    if board.size:
        if _fixed(T_board):
            Tb = T_board[0]
            rec.log(
                boards,
                rr.Points3D(board @ Tb[:3, :3].T + Tb[:3, 3], colors=[BOARD_COLOR], radii=-3.0),
                static=True,
            )
        else:  # on the flange: where each frame puts it, in the base frame
            rec.log(boards, rr.Points3D.from_fields(colors=[BOARD_COLOR], radii=-3.0), static=True)
            placed = np.einsum("fij,nj->fni", T_board[:, :3, :3], board) + T_board[:, None, :3, 3]
            rec.send_columns(
                boards,
                indexes=index,
                columns=rr.Points3D.columns(positions=placed.reshape(-1, 3)).partition(
                    [len(board)] * len(frames)
                ),
            )


def _send_images(
    rec: rr.RecordingStream, entity: str, frames: list[FrameView], t_ns: np.ndarray
) -> None:
    """The frames' images (JPEG or PNG by their bytes; others left out) as columns, sent
    :data:`IMAGE_BATCH_BYTES` at a time: the copy the SDK makes of a batch stays bounded however
    many frames were kept."""
    blobs: list[bytes] = []
    kinds: list[str] = []
    rows: list[int] = []
    size = 0

    def send() -> None:
        rec.send_columns(
            entity,
            indexes=[time_column(t_ns[rows])],
            columns=rr.EncodedImage.columns(blob=blobs, media_type=kinds),
        )

    for i, f in enumerate(frames):
        kind = media_type(f)
        if not f.image or kind is None:
            continue
        blobs.append(f.image)
        kinds.append(kind)
        rows.append(i)
        size += len(f.image)
        if size >= IMAGE_BATCH_BYTES:
            send()
            blobs, kinds, rows, size = [], [], [], 0
    if rows:
        send()


def _summary(view: CameraView, drawn: _Drawn, k: float) -> str:
    cam = view.intrinsics
    held = sum(1 for f in drawn.frames if f.held_out)
    images = sum(1 for f in drawn.frames if f.image)
    lines = [
        f"**Camera `{view.name}`** ({view.setup}), {cam.width}×{cam.height} px, "
        f"fx {cam.K[0, 0]:.1f} px, fy {cam.K[1, 1]:.1f} px, {cam.model}.",
        f"Reprojection RMS of the result: {view.rms_px:.3g} px. "
        f"{len(drawn.frames)} frame(s) drawn of {len(view.frames)} ({images} with an image), "
        f"{held} held out.",
        f"Detected corners: fitted frames blue, held-out frames amber; reprojected magenta; "
        f"error vectors detected → reprojected ×{k:g}.",
    ]
    if drawn.unreadable:
        lines.append(f"{drawn.unreadable} image(s) neither JPEG nor PNG by their bytes: not drawn.")
    lines.extend(view.notes)
    return "\n\n".join(lines)


def _eye(view: CameraView, T_world_base: FloatArray) -> rrb.EyeControls3D | None:
    """An eye behind the camera, above and to its side (0.35 of the median camera–board
    distance each), looking at the board's median place: the frustum and the board both in the
    picture."""
    frames = view.frames
    if not frames:
        return None
    T_cam = T_world_base @ _poses(frames, "T_base_camera")
    T_board = T_world_base @ _poses(frames, "T_base_board")
    board = np.asarray(view.board_points, dtype=np.float64).reshape(-1, 3)
    centre = board.mean(axis=0) if board.size else np.zeros(3)
    target = np.median(T_board[:, :3, 3] + T_board[:, :3, :3] @ centre, axis=0)
    camera = np.median(T_cam[:, :3, 3], axis=0)
    d = float(np.linalg.norm(target - camera))
    if not (np.all(np.isfinite(target)) and np.all(np.isfinite(camera)) and d > 0):
        return None
    back = (camera - target) / d
    side = np.cross([0.0, 0.0, 1.0], back)
    side = side / n if (n := float(np.linalg.norm(side))) > 1e-6 else np.array([1.0, 0.0, 0.0])
    eye = camera + 0.35 * d * (back + side + np.array([0.0, 0.0, 1.0]))
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital, position=eye, look_target=target, eye_up=[0.0, 0.0, 1.0]
    )


def camera_tabs(
    views: Sequence[CameraView], T_world_base: FloatArray | None = None
) -> list[rrb.Container]:
    """One tab per camera: the image with its corners and magnified errors (2D) above the
    camera, its frustum and the board in the robot's base frame (3D, at the time cursor on
    ``sensor_time``; the eye behind the camera, :func:`_eye`), the camera's summary below.
    ``T_world_base`` as for :func:`log_cameras`."""
    tabs: list[rrb.Container] = []
    T = np.eye(4) if T_world_base is None else np.asarray(T_world_base, dtype=np.float64)
    for view, path in zip(views, camera_paths(views), strict=True):
        part = path.rsplit("/", 1)[1]
        k = pixel_magnification(view)
        tabs.append(
            rrb.Vertical(
                rrb.Spatial2DView(
                    name=f"{view.name}: corners detected (blue; held out amber), reprojected "
                    f"(magenta), errors ×{k:g} [px]",
                    origin=f"{path}/image",
                ),
                rrb.Spatial3DView(
                    name=f"{view.name}: camera and board [m, robot base frame]",
                    origin="world",
                    contents=[
                        f"+ $origin/base/cameras/{part}/**",
                        f"+ $origin/base/boards/{part}/**",
                        "+ $origin/m/dh/frame_1/**",
                    ],
                    eye_controls=_eye(view, T),
                ),
                rrb.TextDocumentView(name="Camera", origin=f"report/cameras/{part}"),
                row_shares=[5, 4, 1],
                name=f"Camera {view.name} (time line {TIMELINE})",
            )
        )
    return tabs
