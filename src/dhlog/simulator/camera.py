"""A simulated vision log (issue 32, item 8): a ChArUco board seen by a pinhole camera with
plumb_bob distortion while the robot runs a protocol, in one of two set-ups, written with the
joint states as a ROS 2 camera records it.

- **eye-to-hand**: the board on the flange (:data:`BOARD_ON_FLANGE`), the camera fixed in the
  cell (the preset's ``camera_distance`` from the board or the workspace), looking at it;
- **eye-in-hand**: the camera on the flange (:data:`CAMERA_ON_FLANGE`), the board fixed in the
  cell (the preset's ``board_distance`` away), facing it.

The camera and board come from a preset (:data:`PRESETS`, ``dhlog simulate --camera``):
``default`` (1280×800, f 1800 px, a 7×5 board of 40 mm squares, 1.5 m / 0.55 m away),
``full-hd`` (issue 32's benchmark: 1920×1080, f 1600 px, a 10×7 board of 30 mm squares, 0.3 m
across, 2 m away) and ``small`` (640×400, the default's field of view at half the pixels, a
board of 60 mm squares: quick logs and tests).

What each protocol gives a camera:

- ``random-poses``: one frame in the middle of each still pose. The fixed part is placed along
  the direction (of :func:`_directions`: level or above, never under the floor) from which the
  most of :data:`PLACEMENT_PROBES` random joint vectors see the board; the poses are drawn
  uniformly within the limits and kept only where the board is seen (:func:`camera_poses`).
- ``sweeps`` and ``coupled``: frames at the camera's frame rate (``frame_rate``, 10 Hz by
  default) over the whole session, each rendered at the true pose at its stamp, and only the
  frames where the board is seen written. Without an ``exposure`` a frame is an instant (a
  global shutter, no motion blur); with one it is the mean of the board drawn at poses evenly
  across the exposure, its stamp in the middle (one drawing for each :data:`MOTION_STEP_PX`
  the corners move, at most :data:`MOTION_POSES`): motion blur, the truth the middle pose. The
  sweeps' home pose and the fixed part are chosen together (:func:`place_for_moves`): among the
  robot's zero pose and :data:`HOME_PROBES` random ones, the fixed part placed square to the
  board (the camera on the board's normal, or the board on the camera's axis) and level with or
  above the workspace's centre, the one whose sweeps (each joint alone, and the coupled move)
  keep the board seen over the longest share of the asked sweep. Each sweep is then limited to
  the part of it where the board is seen (a joint's limits narrowed for the session); a sweep
  the board is never seen in keeps its range and is named in a warning
  (:attr:`VisionSession.warnings`), as is one seen over less than :data:`MIN_SWEEP_SEEN` or in
  fewer than :data:`MIN_SWEEP_FRAMES` frames: the seed method cannot fit that joint's circle.
  Each frame is labelled with the move it was taken in (``joint k``, ``joints a+b`` for the
  coupled move, ``transition``, ``still``).

Several cameras (eye-to-hand, ``cameras``; :func:`camera_topics`): for the still poses along the
directions the most probes see the board from, at least :data:`CAMERA_SPREAD` apart, the poses
kept where one camera at least sees the board; for the moving protocols the first placed as
above and the others looking at the same point (the board's centre at the sweeps' home) from
:data:`CAMERA_OFFSETS` about it. Each camera writes the frames where it sees the board.

Still poses and frames are kept only when the board is seen: at least :data:`MIN_IN_VIEW` of
its corners inside the image and its face tilted less than :data:`MAX_TILT` from the line of
sight (:func:`seen`); with the ``full-hd`` and ``small`` presets also every square imaged at
least 20 px a side (markers of 14.7 px and more, which OpenCV decodes: the 0.3 m board 2.8 m
away at 60° has squares of 8 px, and half of such frames were lost).

Each image is rendered by :func:`render`: every camera pixel's ray (undistorted by OpenCV once
per camera) cut with the board's plane (one homography a frame), the board's flat drawing
(``BoardSpec.image`` at :data:`TEXTURE_SCALE` times the image's scale, smoothed) looked up there
(``cv2.remap``, bilinear) on a grey background, an exposure gain drawn per frame, a
Gaussian blur of :data:`BLUR_SIGMA` px (``cv2.GaussianBlur``) and Gaussian pixel noise of
:data:`PIXEL_NOISE` grey levels. The truth is ``Intrinsics.project`` of the board's corners
through the true chain (:meth:`Rig.board_in_camera`); :func:`simulate_detections` gives those
corners with Gaussian pixel noise and no rendering (fast Monte Carlo).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from mcap.writer import CompressionType, Writer
from numpy.typing import NDArray

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.protocols import joints_at, keyframes, protocol_config, swept_joints
from dhlog.simulator.robot import perturbed
from dhlog.simulator.session import START_NS, Session, simulate_session
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics

CameraSetup = Literal["eye-to-hand", "eye-in-hand"]
ImageFormat = Literal["jpeg", "png", "raw"]
CAMERA_SETUPS = ("eye-to-hand", "eye-in-hand")
IMAGE_FORMATS = ("jpeg", "png", "raw")

#: the board: ChArUco, 7×5 squares of 40 mm, markers of 30 mm, DICT_5X5_100
BOARD = BoardSpec(kind="charuco", dictionary="DICT_5X5_100", squares=(7, 5), square_m=0.04)
#: the camera: 1280×800, f 1800 px (39° × 25°), plumb_bob distortion (k1 k2 t1 t2 k3)
CAMERA = Intrinsics(
    1280,
    800,
    np.array([[1800.0, 0.0, 641.5], [0.0, 1797.0, 398.2], [0.0, 0.0, 1.0]]),
    "plumb_bob",
    np.array([-0.12, 0.08, 4e-4, -3e-4, 0.0]),
)
#: the fixed camera's distance from the workspace's centre (eye-to-hand), m
CAMERA_DISTANCE = 1.5
#: the fixed board's distance from the workspace's centre (eye-in-hand), m
BOARD_DISTANCE = 0.55
#: eye-to-hand: the board's frame on the flange, its printed face looking along the flange's z
#: (OpenCV's board z goes into the board), its centre 30 mm out and 10 mm aside
BOARD_ON_FLANGE = np.array(
    [[1.0, 0.0, 0.0, -0.13], [0.0, -1.0, 0.0, 0.10], [0.0, 0.0, -1.0, 0.03], [0.0, 0.0, 0.0, 1.0]]
)
#: eye-in-hand: the camera's frame on the flange, looking along the flange's z, 60 mm aside
#: and 40 mm out, turned 5° about its x
CAMERA_ON_FLANGE = np.array(
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, math.cos(0.0873), -math.sin(0.0873), 0.06],
        [0.0, math.sin(0.0873), math.cos(0.0873), 0.04],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


@dataclass(frozen=True)
class CameraPreset:
    """A camera and its board (``dhlog simulate --camera NAME``): the intrinsics, the board,
    the fixed camera's distance (eye-to-hand) and the fixed board's (eye-in-hand), m."""

    name: str
    camera: Intrinsics
    board: BoardSpec
    camera_distance: float
    board_distance: float
    #: the smallest side (px) of a square as imaged for a pose to be kept: markers OpenCV can
    #: decode (0: the default's test alone)
    min_square_px: float = 0.0


def board_on_flange(board: BoardSpec) -> FloatArray:
    """Eye-to-hand: the board's frame on the flange, its printed face looking along the
    flange's z, its centre 30 mm out and 10 mm aside (:data:`BOARD_ON_FLANGE` for the
    default board)."""
    w, h = board.size_m
    T = BOARD_ON_FLANGE.copy()
    T[:2, 3] = [0.01 - w / 2, h / 2]
    return T


#: the presets: the current camera (the default), issue 32's benchmark camera (1920×1080, f
#: 1600 px, k1 −0.1, a 10×7 ChArUco board of 30 mm squares and 22 mm markers, 0.3 m across,
#: 2 m away in both set-ups) and a small one (640×400, the default's field of view, a board of
#: 60 mm squares and 45 mm markers so that its markers keep the default's size in pixels, the
#: fixed board 0.82 m away)
PRESETS = {
    "default": CameraPreset("default", CAMERA, BOARD, CAMERA_DISTANCE, BOARD_DISTANCE),
    "full-hd": CameraPreset(
        "full-hd",
        Intrinsics(
            1920,
            1080,
            np.array([[1600.0, 0.0, 961.3], [0.0, 1600.0, 538.4], [0.0, 0.0, 1.0]]),
            "plumb_bob",
            np.array([-0.1, 0.05, 2e-4, -1e-4, 0.0]),
        ),
        BoardSpec(
            kind="charuco",
            dictionary="DICT_5X5_100",
            squares=(10, 7),
            square_m=0.03,
            marker_m=0.022,
        ),
        2.0,
        2.0,
        20.0,
    ),
    "small": CameraPreset(
        "small",
        Intrinsics(
            640,
            400,
            np.array([[900.0, 0.0, 320.3], [0.0, 898.5, 199.1], [0.0, 0.0, 1.0]]),
            "plumb_bob",
            np.array([-0.12, 0.08, 4e-4, -3e-4, 0.0]),
        ),
        BoardSpec(
            kind="charuco",
            dictionary="DICT_5X5_100",
            squares=(7, 5),
            square_m=0.06,
            marker_m=0.045,
        ),
        CAMERA_DISTANCE,
        1.5 * BOARD_DISTANCE,
        20.0,
    ),
}
CAMERA_PRESETS = tuple(PRESETS)
#: the share of the board's corners that must be in the image for a pose to be kept
MIN_IN_VIEW = 0.8
#: the largest angle between the board's face and the line of sight for a pose to be kept, rad
MAX_TILT = math.radians(60.0)
#: random joint vectors tried for placing the fixed camera or board
PLACEMENT_PROBES = 600
#: random home poses tried (with the zero pose) for a moving protocol's sweeps
HOME_PROBES = 160
#: a sweep seen over less than this (rad; mm for a prismatic joint's travel) or in fewer frames
#: is named in a warning: too short for the seed method's circle (its least sweep is 5°)
MIN_SWEEP_SEEN = math.radians(10.0)
MIN_SWEEP_TRAVEL = 0.005
MIN_SWEEP_FRAMES = 5
#: the camera's frame rate of the moving protocols, Hz
FRAME_RATE = 10.0
#: motion blur: the poses across an exposure taken (at most), and the image motion (px) each
#: drawing of them stands for
MOTION_POSES = 17
MOTION_STEP_PX = 0.5
#: several cameras (eye-to-hand): at most this many; the least angle between two cameras'
#: directions for the still poses; the others' offsets (azimuth, elevation; degrees) from the
#: first about the board's centre at the sweeps' home
MAX_CAMERAS = 6
CAMERA_SPREAD = math.radians(40.0)
CAMERA_OFFSETS = ((35.0, 0.0), (-35.0, 0.0), (0.0, 30.0), (35.0, 30.0), (-35.0, 30.0))
#: Gaussian pixel noise (σ, grey levels of 255) and blur (σ, px)
PIXEL_NOISE = 2.0
BLUR_SIGMA = 0.6
#: the board's drawing at this many pixels to an image pixel (at the board's distance), smoothed
#: by a Gaussian of σ ``TEXTURE_PREFILTER`` image pixels before it is sampled (``cv2.remap``
#: samples without averaging). A drawing at the image's scale draws the full-hd board's markers
#: at 2.5 px a cell, quantized, and OpenCV found 665 of 1 296 corners in 24 full-hd poses (0.069
#: px RMS from the truth); at 3 and 0.35 px, 1 218 (0.056 px RMS); at 3 without smoothing 1 243
#: but 0.180 px RMS (aliased edges)
TEXTURE_SCALE = 3
TEXTURE_PREFILTER = 0.35
#: the exposure gain of a frame, drawn uniformly in this range
EXPOSURE = (0.8, 1.1)
#: the grey level of the scene behind the board
BACKGROUND = 110
JPEG_QUALITY = 95
TOPICS = {
    "raw": "/camera/image_raw",
    "compressed": "/camera/image_raw/compressed",
    "info": "/camera/camera_info",
    "joints": "/joint_states",
}


@dataclass(frozen=True)
class Rig:
    """The camera set-up: ``T_fixed`` the fixed part in the robot's base frame (the camera for
    eye-to-hand, the board for eye-in-hand), ``T_mounted`` the part on the flange (the board for
    eye-to-hand, the camera for eye-in-hand); the board and the intrinsics."""

    setup: CameraSetup
    T_fixed: FloatArray
    T_mounted: FloatArray
    board: BoardSpec = BOARD
    camera: Intrinsics = CAMERA
    #: the smallest side (px) of the board's squares as imaged for a pose to be kept (0: any)
    min_square_px: float = 0.0

    def board_in_camera(self, T_base_flange: FloatArray) -> FloatArray:
        """The board's frame in the camera's (…, 4, 4) at flange poses (…, 4, 4) in the base."""
        if self.setup == "eye-to-hand":
            return np.linalg.inv(self.T_fixed) @ T_base_flange @ self.T_mounted
        return np.linalg.inv(T_base_flange @ self.T_mounted) @ self.T_fixed

    def document(self) -> dict[str, object]:
        """The truth's ``camera`` block."""
        fixed, mounted = (
            ("T_base_camera", "T_flange_board")
            if self.setup == "eye-to-hand"
            else ("T_base_board", "T_flange_camera")
        )
        b, c = self.board, self.camera
        return {
            "setup": self.setup,
            fixed: self.T_fixed.tolist(),
            mounted: self.T_mounted.tolist(),
            "board": {
                "kind": b.kind,
                "dictionary": b.dictionary,
                "squares": list(b.squares),
                "square_m": b.square_m,
                "marker_m": b.marker_m,
                "first_id": b.first_id,
            },
            "intrinsics": {
                "width": c.width,
                "height": c.height,
                "K": c.K.tolist(),
                "distortion_model": c.model,
                "D": c.coefficients.tolist(),
            },
        }


def flange_poses(robot: Robot, session_table: object, q: FloatArray) -> FloatArray:
    """The flange's frames (m, 4, 4) in the robot's base frame (the table's frame 1)."""
    return np.asarray(fk_frames(session_table, q)[..., -1, :, :])  # type: ignore[arg-type]


def seen(rig: Rig, T_cam_board: FloatArray) -> NDArray[np.bool_]:
    """Which board poses (m, 4, 4) in the camera the pose test keeps: at least
    ``MIN_IN_VIEW`` of the corners inside the image (a pixel's margin) and the face tilted
    less than ``MAX_TILT`` from the line of sight to its centre; for a ChArUco board, every
    square imaged at least ``rig.min_square_px`` a side (where that is set)."""
    P = rig.board.object_points()
    pts = np.einsum("mij,kj->mki", T_cam_board[:, :3, :3], P) + T_cam_board[:, None, :3, 3]
    uv = rig.camera.project(pts.reshape(-1, 3)).reshape(len(pts), -1, 2)
    w, h = rig.camera.size
    inside = (uv[..., 0] > 1) & (uv[..., 0] < w - 2) & (uv[..., 1] > 1) & (uv[..., 1] < h - 2)
    centre = pts.mean(axis=1)
    sight = centre / np.linalg.norm(centre, axis=1, keepdims=True)
    # the printed face looks along the board's −z: towards the camera when z is along the sight
    facing = np.einsum("mi,mi->m", T_cam_board[:, :3, 2], sight)
    ok = (inside.mean(axis=1) >= MIN_IN_VIEW) & (facing > math.cos(MAX_TILT))
    if rig.min_square_px > 0 and rig.board.kind == "charuco":
        cols, rows = rig.board.squares
        grid = uv.reshape(len(pts), rows - 1, cols - 1, 2)  # corner ids run along x first
        along_x = np.linalg.norm(np.diff(grid, axis=2), axis=-1).reshape(len(pts), -1)
        along_y = np.linalg.norm(np.diff(grid, axis=1), axis=-1).reshape(len(pts), -1)
        sides = np.concatenate([along_x, along_y], axis=1)
        with np.errstate(invalid="ignore"):
            ok &= np.all(sides >= rig.min_square_px, axis=1)  # NaN (behind the camera): not
    return np.asarray(ok)


def _directions() -> FloatArray:
    """Candidate directions from the workspace's centre: 16 azimuths at elevations 0°, 30°
    and 60°, and straight up."""
    out = [[0.0, 0.0, 1.0]]
    for el in (0.0, 30.0, 60.0):
        for az in range(0, 360, 360 // 16):
            e, a = math.radians(el), math.radians(az)
            out.append([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    return np.array(out)


def _looking_at(eye: FloatArray, target: FloatArray) -> FloatArray:
    """A frame at ``eye`` whose z looks at ``target``, its x level where it can be."""
    z = (target - eye) / np.linalg.norm(target - eye)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.95 else np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = eye
    return T


def _workspace_centre(robot: Robot, table: object, seed: int) -> FloatArray:
    """The mean flange position (3,) over ``PLACEMENT_PROBES`` random joint vectors."""
    rng = np.random.default_rng([seed, 32])
    probes = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (PLACEMENT_PROBES, robot.n))
    return np.asarray(flange_poses(robot, table, probes)[:, :3, 3].mean(axis=0))


def _rig(setup: CameraSetup, T_fixed: FloatArray, preset: CameraPreset) -> Rig:
    mounted = board_on_flange(preset.board) if setup == "eye-to-hand" else CAMERA_ON_FLANGE
    return Rig(setup, T_fixed, mounted, preset.board, preset.camera, preset.min_square_px)


def place_rig(
    robot: Robot,
    table: object,
    setup: CameraSetup,
    seed: int,
    preset: CameraPreset = PRESETS["default"],
) -> Rig:
    """The rig with its fixed part placed along the direction from the workspace's centre
    (the mean flange position over ``PLACEMENT_PROBES`` random joint vectors) from which the most
    of those vectors see the board."""
    rng = np.random.default_rng([seed, 32])
    probes = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (PLACEMENT_PROBES, robot.n))
    flanges = flange_poses(robot, table, probes)
    centre = flanges[:, :3, 3].mean(axis=0)
    best: tuple[int, Rig] | None = None
    for d in _directions():
        if setup == "eye-to-hand":
            eye = centre + preset.camera_distance * d
            rig = _rig(setup, _looking_at(eye, centre), preset)
        else:  # the board faces the centre: its z (into the board) points away from it
            far = centre + preset.board_distance * d
            T = _looking_at(centre, far)
            w, h = preset.board.size_m
            T[:3, 3] = far - T[:3, :3] @ np.array([w / 2, h / 2, 0.0])
            rig = _rig(setup, T, preset)
        count = int(np.count_nonzero(seen(rig, rig.board_in_camera(flanges))))
        if best is None or count > best[0]:
            best = (count, rig)
    assert best is not None
    return best[1]


def _spread_rigs(
    robot: Robot, table: object, kit: CameraPreset, seed: int, cameras: int
) -> list[Rig]:
    """Eye-to-hand, several cameras for the still poses: along the directions (of
    :func:`_directions`) from which the most random joint vectors see the board, each at least
    :data:`CAMERA_SPREAD` from the others."""
    rng = np.random.default_rng([seed, 32])
    probes = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (PLACEMENT_PROBES, robot.n))
    flanges = flange_poses(robot, table, probes)
    centre = flanges[:, :3, 3].mean(axis=0)
    scored = []
    for d in _directions():
        rig = _rig("eye-to-hand", _looking_at(centre + kit.camera_distance * d, centre), kit)
        scored.append((int(np.count_nonzero(seen(rig, rig.board_in_camera(flanges)))), d, rig))
    scored.sort(key=lambda item: -item[0])  # stable: ties in _directions' order
    chosen: list[tuple[FloatArray, Rig]] = []
    for _, d, rig in scored:
        if all(float(d @ other) < math.cos(CAMERA_SPREAD) for other, _ in chosen):
            chosen.append((d, rig))
        if len(chosen) == cameras:
            break
    return [rig for _, rig in chosen]


def _spread_rigs_about(rig: Rig, kit: CameraPreset, cameras: int) -> list[Rig]:
    """Eye-to-hand, several cameras for a moving protocol: the first ``rig`` and the others
    looking at the same point (the board's centre at the sweeps' home), moved about it by
    :data:`CAMERA_OFFSETS` (azimuth, elevation) from the first, never below level."""
    eye = rig.T_fixed[:3, 3]
    target = eye + kit.camera_distance * rig.T_fixed[:3, 2]
    back = (eye - target) / kit.camera_distance
    az0 = math.atan2(back[1], back[0])
    el0 = math.asin(max(-1.0, min(1.0, back[2])))
    out = [rig]
    for daz, del_ in CAMERA_OFFSETS[: cameras - 1]:
        az, el = az0 + math.radians(daz), min(max(el0 + math.radians(del_), 0.0), 1.4)
        d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        out.append(_rig("eye-to-hand", _looking_at(target + kit.camera_distance * d, target), kit))
    return out


def camera_poses(
    robot: Robot, table: object, rig: Rig | list[Rig], count: int, seed: int
) -> FloatArray:
    """``count`` joint vectors (count, n) drawn uniformly within the limits from their own
    generator, each kept only if the board is seen (:func:`seen`; by one camera at least of
    a list of rigs)."""
    rigs = [rig] if isinstance(rig, Rig) else rig
    rng = np.random.default_rng([seed, 33])
    kept: list[FloatArray] = []
    for _ in range(200):
        q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (max(256, 4 * count), robot.n))
        flanges = flange_poses(robot, table, q)
        ok = np.zeros(len(q), dtype=bool)
        for r in rigs:
            ok |= seen(r, r.board_in_camera(flanges))
        kept.extend(q[ok])
        if len(kept) >= count:
            return np.array(kept[:count])
    raise DhlogError(
        f"{robot.name}: the board was seen at {len(kept)} of {200 * max(256, 4 * count)} random "
        f"joint vectors, fewer than the {count} asked; ask fewer --poses or the other "
        "--camera-setup"
    )


def _rays(camera: Intrinsics) -> FloatArray:
    """Each pixel's ray (h·w, 3) in the camera frame, z = 1, through the lens (undistorted by
    ``cv2.undistortPoints``, iterated to 1e-12)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    xy = cv2.undistortPoints(pixels, camera.K, camera.coefficients, criteria=criteria)
    return np.column_stack([xy.reshape(-1, 2), np.ones(camera.width * camera.height)])


@functools.lru_cache(maxsize=4)
def _rays32(camera: Intrinsics) -> NDArray[np.float32]:
    """:func:`_rays`' x and y (h, w, 2) in single precision (the renderer's)."""
    xy = _rays(camera)[:, :2].reshape(camera.height, camera.width, 2)
    return np.ascontiguousarray(xy, dtype=np.float32)


@functools.lru_cache(maxsize=16)
def _drawing(board: BoardSpec, square_px: int) -> tuple[NDArray[np.uint8], FloatArray]:
    """The board drawn flat with squares of ``square_px``, smoothed by a Gaussian of
    ``TEXTURE_PREFILTER`` image pixels (``TEXTURE_SCALE`` drawing pixels to one)."""
    d = board.image(square_px / board.square_m, margin_px=square_px)
    smooth = cv2.GaussianBlur(d.pixels, (0, 0), TEXTURE_PREFILTER * TEXTURE_SCALE)
    return np.asarray(smooth, dtype=np.uint8), d.image_from_board


def _draw(rig: Rig, T_cam_board: FloatArray) -> NDArray[np.uint8]:
    """The board at ``T_cam_board`` drawn through the lens on the background, before light,
    blur and noise."""
    cam, board = rig.camera, rig.board
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    # the drawing at TEXTURE_SCALE times the camera's scale at the board's distance (cached)
    scale = TEXTURE_SCALE * cam.K[0, 0] * board.square_m / max(t[2], 1e-3)
    pixels, H = _drawing(board, min(max(8, round(scale)), 300))
    # a ray r meets the board's plane at λ·r = R·(x, y, 0) + t = M·(x, y, 1), M = [r1 r2 t]:
    # (x, y, 1)/λ = M⁻¹·r, and the drawing's pixel is H·(x, y, 1), in front where 1/λ > 0
    A = H @ np.linalg.inv(np.column_stack([R[:, 0], R[:, 1], t]))
    xy = _rays32(cam)  # (h, w, 2): the rays' x, y at z = 1
    shape = (cam.height, cam.width)
    maps = cv2.perspectiveTransform(xy.reshape(-1, 1, 2), A).reshape(*shape, 2)
    front = xy[..., 0] * np.float32(A[2, 0]) + xy[..., 1] * np.float32(A[2, 1]) > -A[2, 2]
    maps[~front] = -1e6
    # one CV_32FC2 map and no second one, which some releases' stubs do not allow: called
    # untyped so the check holds for every OpenCV the pins admit
    remap: Any = cv2.remap
    image = remap(pixels, maps, None, cv2.INTER_LINEAR, borderValue=BACKGROUND)
    return np.asarray(image, dtype=np.uint8)


def motion_steps(rig: Rig, T_exposure: FloatArray) -> int:
    """How many of the poses (k, 4, 4) across an exposure to draw: one for each
    ``MOTION_STEP_PX`` the board's corners move in the image between its ends (1 to k)."""
    P = rig.board.object_points()
    ends = T_exposure[[0, -1]]
    pts = np.einsum("mij,kj->mki", ends[:, :3, :3], P) + ends[:, None, :3, 3]
    uv = rig.camera.project(pts.reshape(-1, 3)).reshape(2, -1, 2)
    moved = np.nanmax(np.linalg.norm(uv[1] - uv[0], axis=1), initial=0.0)
    return int(min(len(T_exposure), max(1, math.ceil(moved / MOTION_STEP_PX) + 1)))


def render(
    rig: Rig,
    T_cam_board: FloatArray,
    rng: np.random.Generator,
    T_exposure: FloatArray | None = None,
) -> NDArray[np.uint8]:
    """The camera's grey image (h, w) of the board at ``T_cam_board`` (see the module); with
    ``T_exposure`` (k, 4, 4), the board's poses across the exposure, the mean of its drawings
    at :func:`motion_steps` of them, evenly spread (motion blur)."""
    cam = rig.camera
    shape = (cam.height, cam.width)
    if T_exposure is None or len(T_exposure) < 2:
        image = _draw(rig, T_cam_board).astype(np.float32)
    else:
        k = motion_steps(rig, T_exposure)
        picks = (
            np.rint(np.linspace(0, len(T_exposure) - 1, k)).astype(int)
            if k > 1
            else [len(T_exposure) // 2]
        )
        image = np.mean([_draw(rig, T_exposure[i]).astype(np.float32) for i in picks], axis=0)
    gain = np.float32(rng.uniform(*EXPOSURE))
    lit = np.asarray(cv2.GaussianBlur(image.astype(np.float32) * gain, (0, 0), BLUR_SIGMA))
    lit = lit + rng.normal(0.0, PIXEL_NOISE, shape).astype(np.float32)
    return np.asarray(np.clip(np.rint(lit), 0, 255), dtype=np.uint8)


@dataclass
class CameraFrames:
    """One camera's frames: its rig, each frame's stamp (ns), true board pose in the camera
    (f, 4, 4), true joint values (f, n) and the move it was taken in (``joint k``,
    ``joints a+b``, ``transition``, ``still``)."""

    rig: Rig
    frame_t_ns: NDArray[np.int64]
    T_cam_board: FloatArray
    frame_q: FloatArray
    frame_move: tuple[str, ...]
    #: the board's poses across each frame's exposure (f, k, 4, 4), evenly in time, the frame's
    #: stamp in the middle (None: an instant, no motion blur)
    T_exposure: FloatArray | None = None


@dataclass
class VisionSession:
    """A simulated vision session: the robot's session (its joint states, table and still
    poses), the rig, and each frame's stamp (ns), true board pose in the camera, true joint
    values and move (the first camera's; ``others``: the further cameras' frames).
    ``warnings``: sweeps the board is not seen enough in; ``notes``: sweeps limited to the
    part where it is seen."""

    session: Session
    rig: Rig
    frame_t_ns: NDArray[np.int64]
    T_cam_board: FloatArray
    image_format: ImageFormat
    frame_q: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    frame_move: tuple[str, ...] = ()
    #: the camera's frame rate (Hz) for a moving protocol; None: a frame at each still pose
    frame_rate: float | None = None
    preset: str = "default"
    others: list[CameraFrames] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: the exposure (s) each frame is blurred over by the motion (0: none)
    exposure: float = 0.0
    #: the first camera's board poses across each frame's exposure (see CameraFrames)
    T_exposure: FloatArray | None = None

    @property
    def cameras(self) -> list[CameraFrames]:
        """Every camera's frames, the first camera's first."""
        first = CameraFrames(
            self.rig,
            self.frame_t_ns,
            self.T_cam_board,
            self.frame_q,
            self.frame_move,
            self.T_exposure,
        )
        return [first, *self.others]


def vision_problems(
    setup: str, preset: str, frame_rate: float, cameras: int, exposure: float = 0.0
) -> list[str]:
    """What is wrong with a vision log's camera options (empty when they can be simulated)."""
    out = []
    if not (math.isfinite(exposure) and 0 <= exposure <= 1.0 / max(frame_rate, 1e-9)):
        out.append(
            f"the exposure must be in [0, {1e3 / max(frame_rate, 1e-9):g}] ms, a frame's period "
            f"at {frame_rate:g} Hz (got {exposure * 1e3:g} ms)"
        )
    if preset not in PRESETS:
        out.append(f"the camera must be one of {', '.join(CAMERA_PRESETS)}, not '{preset}'")
    if not (math.isfinite(frame_rate) and 0 < frame_rate <= 1000):
        out.append(f"the frame rate must be in (0, 1000] Hz (got {frame_rate:g})")
    if not 1 <= cameras <= MAX_CAMERAS:
        out.append(f"the cameras must be 1 to {MAX_CAMERAS} (got {cameras})")
    elif cameras > 1 and setup != "eye-to-hand":
        out.append("several cameras are simulated eye-to-hand only (--camera-setup eye-to-hand)")
    return out


def simulate_vision(
    robot: Robot,
    cfg: SimulationConfig,
    setup: CameraSetup,
    image_format: ImageFormat,
    *,
    preset: str = "default",
    frame_rate: float = FRAME_RATE,
    cameras: int = 1,
    exposure: float = 0.0,
) -> VisionSession:
    """The session of ``cfg`` seen by the camera of ``preset`` (see the module): for
    ``random-poses`` one frame in the middle of each still pose where the board is seen, for
    ``sweeps`` and ``coupled`` a frame every ``1 / frame_rate`` s where it is seen; ``cameras``
    fixed cameras (eye-to-hand), each placed differently; ``exposure`` (s): a moving protocol's
    frames blurred by the motion over that time about their stamps."""
    problems = vision_problems(setup, preset, frame_rate, cameras, exposure)
    if problems:
        raise DhlogError(problems[0])
    kit = PRESETS[preset]
    # the still poses and sweeps are chosen on the table as simulated: the session's first draws
    table = (
        perturbed(robot.table, np.random.default_rng(cfg.seed), cfg)
        if (cfg.perturb_length or cfg.perturb_angle)
        else robot.table
    )
    if cfg.protocol == "random-poses":
        return _still_vision(robot, table, cfg, setup, image_format, kit, cameras)
    return _moving_vision(
        robot, table, cfg, setup, image_format, kit, frame_rate, cameras, exposure
    )


def _still_vision(
    robot: Robot,
    table: object,
    cfg: SimulationConfig,
    setup: CameraSetup,
    image_format: ImageFormat,
    kit: CameraPreset,
    cameras: int,
) -> VisionSession:
    """``random-poses``: a frame in the middle of each still pose."""
    rigs = [place_rig(robot, robot.table, setup, cfg.seed, kit)]
    if cameras > 1:
        rigs = _spread_rigs(robot, robot.table, kit, cfg.seed, cameras)
    poses = camera_poses(robot, table, rigs, cfg.poses, cfg.seed)
    session = simulate_session(robot, replace(cfg, pose_list=tuple(map(tuple, poses))))
    t, q = session.joint_t_ns, session.joint_q
    stamps = []
    for pose in session.poses:
        still = np.flatnonzero(np.all(np.abs(q - pose) < 1e-12, axis=1))
        if not still.size:  # every still is sampled: the dwell is longer than a joint period
            raise DhlogError(f"{robot.name}: a still pose has no joint state; raise --joint-rate")
        stamps.append(int(t[still[still.size // 2]]))
    flanges = flange_poses(robot, session.table, session.poses)
    views = []
    for rig in rigs:
        T_cb = rig.board_in_camera(flanges)
        keep = seen(rig, T_cb) if len(rigs) > 1 else np.ones(len(T_cb), dtype=bool)
        views.append(
            CameraFrames(
                rig,
                np.array(stamps, dtype=np.int64)[keep],
                T_cb[keep],
                session.poses[keep],
                ("still",) * int(np.count_nonzero(keep)),
            )
        )
    first = views[0]
    return VisionSession(
        session,
        first.rig,
        first.frame_t_ns,
        first.T_cam_board,
        image_format,
        first.frame_q,
        first.frame_move,
        None,
        kit.name,
        views[1:],
    )


@dataclass(frozen=True)
class Move:
    """A move of a moving protocol: the joints at ``home + s · direction`` with ``s`` within
    ``± extent / 2`` (rad or m), each joint swept alone or the coupled pair together."""

    label: str
    direction: FloatArray
    extent: float
    revolute: bool


def protocol_moves(robot: Robot, cfg: SimulationConfig) -> list[Move]:
    """The moves a session of ``cfg`` makes: each swept joint alone, then the coupled ones."""
    revolute = [jt is JointType.REVOLUTE for jt in robot.table.joint_types]
    out = []
    for j in swept_joints(robot, cfg):
        v = np.zeros(robot.n)
        v[j - 1] = 1.0
        out.append(
            Move(f"joint {j}", v, cfg.sweep if revolute[j - 1] else cfg.travel, revolute[j - 1])
        )
    for a, b, ratio in protocol_config(cfg).coupled:
        v = np.zeros(robot.n)
        v[a - 1] = 1.0
        v[b - 1] += ratio
        extent = cfg.sweep if revolute[a - 1] else cfg.travel
        out.append(Move(f"joints {a}+{b}", v, extent, revolute[a - 1]))
    return out


def _seen_runs(
    robot: Robot,
    table: object,
    rigs: list[Rig],
    homes: FloatArray,
    moves: list[Move],
    grid: int,
) -> FloatArray:
    """For each home (c, n) with its rig and each move: the part ``(s_lo, s_hi)`` (c, m, 2) of
    the move about the home, within the limits, where the board is seen without a break
    (``(0, 0)`` where it is not seen at home)."""
    c, m = len(homes), len(moves)
    frac = np.linspace(-0.5, 0.5, grid)  # grid odd: the home in the middle
    S = frac[None, :] * np.array([mv.extent for mv in moves])[:, None]  # (m, grid)
    V = np.array([mv.direction for mv in moves])  # (m, n)
    q = homes[:, None, None, :] + S[None, :, :, None] * V[None, :, None, :]
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    within = np.all((q >= lo - 1e-12) & (q <= hi + 1e-12), axis=-1)
    F = flange_poses(robot, table, q.reshape(-1, robot.n)).reshape(c, m * grid, 4, 4)
    T_fixed = np.array([rig.T_fixed for rig in rigs])[:, None]
    mounted = rigs[0].T_mounted
    if rigs[0].setup == "eye-to-hand":
        T_cb = np.linalg.inv(T_fixed) @ F @ mounted
    else:
        T_cb = np.linalg.inv(F @ mounted) @ T_fixed
    ok = seen(rigs[0], T_cb.reshape(-1, 4, 4)).reshape(c, m, grid) & within
    mid = grid // 2
    idx = np.arange(grid)
    start = np.where(~ok & (idx <= mid), idx, -1).max(axis=-1) + 1
    end = np.where(~ok & (idx >= mid), idx, grid).min(axis=-1) - 1
    found = ok[..., mid]
    runs = np.zeros((c, m, 2))
    runs[..., 0] = np.where(found, S[np.arange(m), np.clip(start, 0, grid - 1)], 0.0)
    runs[..., 1] = np.where(found, S[np.arange(m), np.clip(end, 0, grid - 1)], 0.0)
    return runs


def _square_rig(
    robot: Robot, table: object, setup: CameraSetup, kit: CameraPreset, homes: FloatArray
) -> tuple[list[Rig], NDArray[np.bool_]]:
    """For each home (c, n): the rig with its fixed part square to the mounted one (the camera
    on the board's normal through its centre, or the board across the camera's axis), and
    whether that fixed part is level with or above the workspace's centre."""
    F = flange_poses(robot, table, homes)
    centre_z = _workspace_centre(robot, table, 0)[2]
    w, h = kit.board.size_m
    rigs, ok = [], []
    for T_flange in F:
        if setup == "eye-to-hand":
            T_b = T_flange @ board_on_flange(kit.board)
            middle = T_b[:3, :3] @ np.array([w / 2, h / 2, 0.0]) + T_b[:3, 3]
            eye = middle - kit.camera_distance * T_b[:3, 2]  # the face looks along the −z
            rigs.append(_rig(setup, _looking_at(eye, middle), kit))
            ok.append(eye[2] >= centre_z)
        else:
            T_c = T_flange @ CAMERA_ON_FLANGE
            far = T_c[:3, 3] + kit.board_distance * T_c[:3, 2]
            T = _looking_at(T_c[:3, 3], far)
            T[:3, 3] = far - T[:3, :3] @ np.array([w / 2, h / 2, 0.0])
            rigs.append(_rig(setup, T, kit))
            ok.append(far[2] >= centre_z)
    return rigs, np.array(ok)


def place_for_moves(
    robot: Robot, table: object, cfg: SimulationConfig, setup: CameraSetup, kit: CameraPreset
) -> tuple[Rig, FloatArray, FloatArray]:
    """The rig, the home pose (n,) of a moving protocol's sweeps and each move's part
    ``(s_lo, s_hi)`` (m, 2) where the board is seen (see the module): among the zero pose and
    ``HOME_PROBES`` random ones, the one whose moves keep the board seen over the largest
    share of the asked sweep (the least share over the moves plus their mean)."""
    moves = protocol_moves(robot, cfg)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    rng = np.random.default_rng([cfg.seed, 36])
    homes = np.vstack(
        [np.clip(np.zeros(robot.n), lo, hi), rng.uniform(lo, hi, (HOME_PROBES, robot.n))]
    )
    rigs, level = _square_rig(robot, table, setup, kit, homes)
    if not np.any(level):
        raise DhlogError(
            f"{robot.name}: no home pose of {HOME_PROBES + 1} tried puts the fixed "
            f"{'camera' if setup == 'eye-to-hand' else 'board'} level with or above the "
            "workspace; try another --seed or --camera-setup"
        )
    keep = np.flatnonzero(level)
    if not moves:
        return rigs[int(keep[0])], homes[int(keep[0])], np.zeros((0, 2))
    runs = _seen_runs(robot, table, [rigs[i] for i in keep], homes[keep], moves, 25)
    share = (runs[..., 1] - runs[..., 0]) / np.array([mv.extent for mv in moves])
    best = int(keep[int(np.argmax(share.min(axis=1) + share.mean(axis=1)))])
    fine = _seen_runs(robot, table, [rigs[best]], homes[best : best + 1], moves, 181)[0]
    return rigs[best], homes[best], fine


def _narrowed_limits(
    robot: Robot, home: FloatArray, moves: list[Move], runs: FloatArray
) -> FloatArray:
    """The joint limits (n, 2) that keep each move within the part of it where the board is
    seen (a move never seen keeps its joints' limits); joints no move sweeps held at home."""
    limits = np.repeat(home[:, None], 2, axis=1)
    moved = np.zeros(robot.n, dtype=bool)
    for mv, (s_lo, s_hi) in zip(moves, runs, strict=True):
        joints = np.flatnonzero(mv.direction)
        if s_hi <= s_lo:
            limits[joints] = robot.limits[joints]
            moved[joints] = True
            continue
        for j in joints:
            ends = sorted((home[j] + s_lo * mv.direction[j], home[j] + s_hi * mv.direction[j]))
            if moved[j]:
                ends = [min(ends[0], limits[j, 0]), max(ends[1], limits[j, 1])]
            limits[j] = ends
            moved[j] = True
    return np.asarray(limits)


def _move_labels(
    frames: list[tuple[float, FloatArray]], t: FloatArray, moves: list[Move]
) -> list[str]:
    """The move each instant ``t`` falls in: the keyframe interval's moving joints matched to a
    move (``joint k``, ``joints a+b``), or ``transition``; a still interval takes the label of
    the move before it."""
    ft = np.array([f[0] for f in frames])
    fq = np.stack([f[1] for f in frames])
    labels: list[str] = []
    previous = "transition"
    for k in range(len(ft) - 1):
        d = fq[k + 1] - fq[k]
        if np.any(np.abs(d) > 1e-12):
            previous = "transition"
            for mv in moves:
                v = mv.direction
                along = (d @ v) / (v @ v) * v
                if np.all(np.abs(d - along) <= 1e-9 * max(1.0, float(np.abs(d).max()))):
                    previous = mv.label
                    break
        labels.append(previous)
    i = np.clip(np.searchsorted(ft, t, side="right") - 1, 0, len(ft) - 2)
    return [labels[int(k)] for k in i]


def _moving_vision(
    robot: Robot,
    table: object,
    cfg: SimulationConfig,
    setup: CameraSetup,
    image_format: ImageFormat,
    kit: CameraPreset,
    frame_rate: float,
    cameras: int,
    exposure: float = 0.0,
) -> VisionSession:
    """``sweeps`` and ``coupled``: a frame every ``1 / frame_rate`` s where the board is seen,
    with the poses across its ``exposure`` when that is > 0."""
    moves = protocol_moves(robot, cfg)
    rig, home, runs = place_for_moves(robot, table, cfg, setup, kit)
    moving = replace(robot, limits=_narrowed_limits(robot, home, moves, runs))
    session = simulate_session(moving, cfg, home=home)
    # the trajectory as the session ran it: its draws replayed (the perturbation, then the lock
    # poses), checked against the joint states it wrote
    rng = np.random.default_rng(cfg.seed)
    if cfg.perturb_length or cfg.perturb_angle:
        perturbed(robot.table, rng, cfg)
    frames, _, _ = keyframes(moving, home, protocol_config(cfg), rng, np.zeros((0, robot.n)))
    duration = frames[-1][0]
    start_ns = START_NS + round(cfg.start_day * 86_400e9)
    base_time = 2.0 if cfg.base_points else 0.0
    t_enc = (session.joint_t_ns - start_ns) / 1e9 - base_time + cfg.clock_offset
    if cfg.encoder_scales is None and session.joint_q.size:
        replayed = joints_at(frames, np.clip(t_enc, 0.0, duration))
        if not np.allclose(replayed, session.joint_q, atol=1e-6, rtol=0.0):
            raise AssertionError("the replayed trajectory differs from the session's")
    phase = np.random.default_rng([cfg.seed, 35]).uniform(0.0, 1.0 / frame_rate)
    t = np.arange(phase, duration, 1.0 / frame_rate)
    q = joints_at(frames, t)
    labels = np.array(_move_labels(frames, t, moves))
    flanges = flange_poses(robot, session.table, q)
    stamps = start_ns + np.rint((t + base_time) * 1e9).astype(np.int64)
    rigs = [rig] if cameras == 1 else _spread_rigs_about(rig, kit, cameras)
    sub = None
    if exposure > 0:  # the flange across each frame's exposure, its stamp in the middle
        offsets = np.linspace(-exposure / 2, exposure / 2, MOTION_POSES)
        t_sub = np.clip(t[:, None] + offsets, 0.0, duration)
        sub = flange_poses(robot, session.table, joints_at(frames, t_sub.ravel()))
    views = []
    for r in rigs:
        T_cb = r.board_in_camera(flanges)
        keep = seen(r, T_cb)
        T_exp = None
        if sub is not None:
            T_exp = r.board_in_camera(sub).reshape(len(t), MOTION_POSES, 4, 4)[keep]
        views.append(
            CameraFrames(r, stamps[keep], T_cb[keep], q[keep], tuple(map(str, labels[keep])), T_exp)
        )
    first = views[0]
    warnings, notes = _sweep_report(moves, runs, home, views)
    return VisionSession(
        session,
        first.rig,
        first.frame_t_ns,
        first.T_cam_board,
        image_format,
        first.frame_q,
        first.frame_move,
        frame_rate,
        kit.name,
        views[1:],
        warnings,
        notes,
        exposure,
        first.T_exposure,
    )


def _sweep_report(
    moves: list[Move],
    runs: FloatArray,
    home: FloatArray,
    views: list[CameraFrames],
) -> tuple[list[str], list[str]]:
    """The warnings (a move the board is seen too little in, by every camera) and notes (a
    move limited to the part where it is seen) of a moving protocol's vision log."""
    warnings, notes = [], []
    for mv, (s_lo, s_hi) in zip(moves, runs, strict=True):
        what = (
            f"the sweep of {mv.label}"
            if len(np.flatnonzero(mv.direction)) == 1
            else (f"the coupled move of {mv.label}")
        )
        unit, scale, least = ("°", math.degrees(1.0), MIN_SWEEP_SEEN)
        if not mv.revolute:
            unit, scale, least = (" mm", 1e3, MIN_SWEEP_TRAVEL)
        count, span = 0, 0.0
        for view in views:  # the camera that sees the move best
            sel = np.array([label == mv.label for label in view.frame_move], dtype=bool)
            v = mv.direction
            s = (view.frame_q[sel] - home) @ v / (v @ v)
            count = max(count, int(s.size))
            span = max(span, float(np.ptp(s)) if s.size else 0.0)
        if count == 0:
            warnings.append(
                f"{what}: the board is never seen (turned edge-on or out of the image over "
                f"the whole {mv.extent * scale:.0f}{unit}); the seed method cannot fit its "
                "axis from this log's frames"
            )
        elif count < MIN_SWEEP_FRAMES or span < least:
            warnings.append(
                f"{what}: the board is seen in {count} frames over {span * scale:.1f}{unit} "
                f"only, too little for the seed method's circle"
            )
        elif s_hi - s_lo < mv.extent * 0.999:
            notes.append(
                f"{what}: {(s_hi - s_lo) * scale:.1f}{unit} of the asked "
                f"{mv.extent * scale:.0f}{unit}, the part where the board is seen"
            )
    return warnings, notes


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
            info = ros2.encode_camera_info(
                t, frame_id, cam.width, cam.height, cam.model, cam.coefficients.tolist(), cam.K
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
