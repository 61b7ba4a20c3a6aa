"""A simulated vision log (issue 32, item 8, first slice): a ChArUco board seen by a pinhole
camera with plumb_bob distortion at each still pose of the ``random-poses`` protocol, in one of
two set-ups, written with the joint states as a ROS 2 camera records it.

- **eye-to-hand**: the board on the flange (:data:`BOARD_ON_FLANGE`), the camera fixed in the
  cell :data:`CAMERA_DISTANCE` from the workspace's centre, looking at it;
- **eye-in-hand**: the camera on the flange (:data:`CAMERA_ON_FLANGE`), the board fixed in the
  cell :data:`BOARD_DISTANCE` from the workspace's centre, facing it.

The fixed one is placed along the direction (of :func:`_directions`: level or above, never under
the floor) from which the most of :data:`PLACEMENT_PROBES` random joint vectors see the board.
The still poses are then drawn uniformly within the limits and kept only when the board is
seen: at least :data:`MIN_IN_VIEW` of its corners inside the image and its face tilted less than
:data:`MAX_TILT` from the line of sight (:func:`camera_poses`). Poses that fail are never drawn.

Each image is rendered by :func:`render`: every camera pixel's ray (undistorted by OpenCV once
per camera) cut with the board's plane, the board's flat drawing (``BoardSpec.image``) looked up
there (``cv2.remap``, bilinear) on a grey background, an exposure gain drawn per frame, a
Gaussian blur of :data:`BLUR_SIGMA` px (``cv2.GaussianBlur``) and Gaussian pixel noise of
:data:`PIXEL_NOISE` grey levels. The truth is ``Intrinsics.project`` of the board's corners
through the true chain (:func:`board_in_camera`).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from mcap.writer import CompressionType, Writer
from numpy.typing import NDArray

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot
from dhlog.simulate.config import SimulationConfig
from dhlog.simulate.robot import perturbed
from dhlog.simulate.session import Session, simulate_session
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
#: the share of the board's corners that must be in the image for a pose to be kept
MIN_IN_VIEW = 0.8
#: the largest angle between the board's face and the line of sight for a pose to be kept, rad
MAX_TILT = math.radians(60.0)
#: random joint vectors tried for placing the fixed camera or board
PLACEMENT_PROBES = 600
#: Gaussian pixel noise (σ, grey levels of 255) and blur (σ, px)
PIXEL_NOISE = 2.0
BLUR_SIGMA = 0.6
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
    less than ``MAX_TILT`` from the line of sight to its centre."""
    P = rig.board.object_points()
    pts = np.einsum("mij,kj->mki", T_cam_board[:, :3, :3], P) + T_cam_board[:, None, :3, 3]
    uv = rig.camera.project(pts.reshape(-1, 3)).reshape(len(pts), -1, 2)
    w, h = rig.camera.size
    inside = (uv[..., 0] > 1) & (uv[..., 0] < w - 2) & (uv[..., 1] > 1) & (uv[..., 1] < h - 2)
    centre = pts.mean(axis=1)
    sight = centre / np.linalg.norm(centre, axis=1, keepdims=True)
    # the printed face looks along the board's −z: towards the camera when z is along the sight
    facing = np.einsum("mi,mi->m", T_cam_board[:, :3, 2], sight)
    return np.asarray((inside.mean(axis=1) >= MIN_IN_VIEW) & (facing > math.cos(MAX_TILT)))


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


def place_rig(robot: Robot, table: object, setup: CameraSetup, seed: int) -> Rig:
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
            rig = Rig(setup, _looking_at(centre + CAMERA_DISTANCE * d, centre), BOARD_ON_FLANGE)
        else:  # the board faces the centre: its z (into the board) points away from it
            T = _looking_at(centre, centre + BOARD_DISTANCE * d)
            w, h = BOARD.size_m
            T[:3, 3] = centre + BOARD_DISTANCE * d - T[:3, :3] @ np.array([w / 2, h / 2, 0.0])
            rig = Rig(setup, T, CAMERA_ON_FLANGE)
        count = int(np.count_nonzero(seen(rig, rig.board_in_camera(flanges))))
        if best is None or count > best[0]:
            best = (count, rig)
    assert best is not None
    return best[1]


def camera_poses(robot: Robot, table: object, rig: Rig, count: int, seed: int) -> FloatArray:
    """``count`` joint vectors (count, n) drawn uniformly within the limits from their own
    generator, each kept only if the board is seen (:func:`seen`)."""
    rng = np.random.default_rng([seed, 33])
    kept: list[FloatArray] = []
    for _ in range(200):
        q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (max(256, 4 * count), robot.n))
        ok = seen(rig, rig.board_in_camera(flange_poses(robot, table, q)))
        kept.extend(q[ok])
        if len(kept) >= count:
            return np.array(kept[:count])
    raise DhlogError(
        f"{robot.name}: the board was seen at {len(kept)} of {200 * max(256, 4 * count)} random "
        f"joint vectors, fewer than the {count} asked; ask fewer --poses or the other "
        "--camera-setup"
    )


@functools.lru_cache(maxsize=4)
def _rays(camera: Intrinsics) -> FloatArray:
    """Each pixel's ray (h·w, 3) in the camera frame, z = 1, through the lens (undistorted by
    ``cv2.undistortPoints``, iterated to 1e-12)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    xy = cv2.undistortPoints(pixels, camera.K, camera.coefficients, criteria=criteria)
    return np.column_stack([xy.reshape(-1, 2), np.ones(camera.width * camera.height)])


@functools.lru_cache(maxsize=16)
def _drawing(board: BoardSpec, square_px: int) -> tuple[NDArray[np.uint8], FloatArray]:
    d = board.image(square_px / board.square_m, margin_px=square_px)
    return d.pixels, d.image_from_board


def render(rig: Rig, T_cam_board: FloatArray, rng: np.random.Generator) -> NDArray[np.uint8]:
    """The camera's grey image (h, w) of the board at ``T_cam_board`` (see the module)."""
    cam, board = rig.camera, rig.board
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    # the drawing at about the camera's scale at the board's distance (cached by square size)
    square_px = max(8, round(cam.K[0, 0] * board.square_m / max(t[2], 1e-3)))
    pixels, H = _drawing(board, min(square_px, 200))
    rays = _rays(cam)
    n = R[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (n @ t) / (rays @ n)  # each ray meets the board's plane at s·ray
        local = (s[:, None] * rays - t) @ R  # the board-frame point there
    q = local[:, :2] @ H[:2, :2].T + H[:2, 2]
    shape = (cam.height, cam.width)
    behind = ~(s > 0)
    map_x = np.where(behind, -1e6, q[:, 0]).reshape(shape).astype(np.float32)
    map_y = np.where(behind, -1e6, q[:, 1]).reshape(shape).astype(np.float32)
    image = cv2.remap(pixels, map_x, map_y, cv2.INTER_LINEAR, borderValue=BACKGROUND)
    gain = np.float32(rng.uniform(*EXPOSURE))
    lit = np.asarray(cv2.GaussianBlur(image.astype(np.float32) * gain, (0, 0), BLUR_SIGMA))
    lit = lit + rng.normal(0.0, PIXEL_NOISE, shape).astype(np.float32)
    return np.asarray(np.clip(np.rint(lit), 0, 255), dtype=np.uint8)


@dataclass
class VisionSession:
    """A simulated vision session: the robot's session (its joint states, table and still
    poses), the rig, and each frame's stamp (ns) and true board pose in the camera."""

    session: Session
    rig: Rig
    frame_t_ns: NDArray[np.int64]
    T_cam_board: FloatArray
    image_format: ImageFormat


def simulate_vision(
    robot: Robot, cfg: SimulationConfig, setup: CameraSetup, image_format: ImageFormat
) -> VisionSession:
    """The session of ``cfg`` (``random-poses``) at still poses where the board is seen, one
    frame in the middle of each still."""
    rig = place_rig(robot, robot.table, setup, cfg.seed)
    # the still poses are chosen on the table as simulated: the session's first draws
    table = (
        perturbed(robot.table, np.random.default_rng(cfg.seed), cfg)
        if (cfg.perturb_length or cfg.perturb_angle)
        else robot.table
    )
    poses = camera_poses(robot, table, rig, cfg.poses, cfg.seed)
    session = simulate_session(robot, replace(cfg, pose_list=tuple(map(tuple, poses))))
    t, q = session.joint_t_ns, session.joint_q
    stamps = []
    for pose in session.poses:
        still = np.flatnonzero(np.all(np.abs(q - pose) < 1e-12, axis=1))
        if not still.size:  # every still is sampled: the dwell is longer than a joint period
            raise DhlogError(f"{robot.name}: a still pose has no joint state; raise --joint-rate")
        stamps.append(int(t[still[still.size // 2]]))
    T_cb = rig.board_in_camera(flange_poses(robot, session.table, session.poses))
    return VisionSession(session, rig, np.array(stamps, dtype=np.int64), T_cb, image_format)


def write_vision_log(vision: VisionSession, path: str | Path, seed: int) -> None:
    """Write ``vision`` to ``path`` (atomically) as rosbag2 records it: ``/joint_states``, the
    images (raw mono8, or JPEG / PNG compressed) and ``/camera/camera_info`` with each."""
    from dhlog.io import ros2
    from dhlog.io.writer import atomic_output

    s, rig, fmt = vision.session, vision.rig, vision.image_format
    rng = np.random.default_rng([seed, 34])
    image_schema = ros2.IMAGE if fmt == "raw" else ros2.COMPRESSED_IMAGE
    image_topic = TOPICS["raw" if fmt == "raw" else "compressed"]
    cam = rig.camera
    with atomic_output(path) as f:
        writer = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD, enable_crcs=False)
        writer.start(profile="ros2", library="rosbag2 (simulated by dhlog)")
        ids = {
            name: writer.register_schema(name, "ros2msg", ros2.MSGDEFS[name].encode())
            for name in (ros2.JOINT_STATE, image_schema, ros2.CAMERA_INFO)
        }
        qos = {"offered_qos_profiles": ""}
        ch_joints = writer.register_channel(TOPICS["joints"], "cdr", ids[ros2.JOINT_STATE], qos)
        ch_image = writer.register_channel(image_topic, "cdr", ids[image_schema], qos)
        ch_info = writer.register_channel(TOPICS["info"], "cdr", ids[ros2.CAMERA_INFO], qos)
        joints = ros2.encode_joint_state(s.joint_t_ns, s.joint_names, s.joint_q)
        events = [(int(t), 0, i) for i, t in enumerate(s.joint_t_ns)]
        events += [(int(t), 1, i) for i, t in enumerate(vision.frame_t_ns)]
        for t, kind, i in sorted(events):
            if kind == 0:
                writer.add_message(ch_joints, t, joints[i], t)
                continue
            pixels = render(rig, vision.T_cam_board[i], rng)
            if fmt == "raw":
                payload = ros2.encode_image(t, "camera", pixels, "mono8")
            else:
                ext = ".jpg" if fmt == "jpeg" else ".png"
                params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if fmt == "jpeg" else []
                ok, data = cv2.imencode(ext, pixels, params)
                assert ok
                payload = ros2.encode_compressed_image(t, "camera", data.tobytes(), fmt)
            writer.add_message(ch_image, t, payload, t)
            info = ros2.encode_camera_info(
                t, "camera", cam.width, cam.height, cam.model, cam.coefficients.tolist(), cam.K
            )
            writer.add_message(ch_info, t, info, t)
        counts = {
            TOPICS["joints"]: len(joints),
            image_topic: len(vision.frame_t_ns),
            TOPICS["info"]: len(vision.frame_t_ns),
        }
        writer.add_metadata(
            "rosbag2",
            {
                "serialized_metadata": json.dumps(
                    {"version": 9, "storage_identifier": "mcap", "message_counts": counts}
                )
            },
        )
        writer.finish()  # type: ignore[no-untyped-call]


def vision_truth(vision: VisionSession, **source: str) -> dict[str, object]:
    """The truth document of a vision log: the session's (:func:`truth_document`; its tracker
    samples were not written) with a ``camera`` block: the rig (the camera's pose in the base
    frame for eye-to-hand or on the flange for eye-in-hand, the board's mount, the board and
    the intrinsics), the images' format, count, noise and blur."""
    from dhlog.simulate.truth import truth_document

    doc = truth_document(vision.session, **source)
    doc["camera"] = {
        **vision.rig.document(),
        "image_format": vision.image_format,
        "frames": int(vision.frame_t_ns.size),
        "pixel_noise": PIXEL_NOISE,
        "blur_sigma_px": BLUR_SIGMA,
        "exposure_gain": list(EXPOSURE),
        "image_topic": TOPICS["raw" if vision.image_format == "raw" else "compressed"],
        "info_topic": TOPICS["info"],
    }
    simulation = doc["simulation"]
    assert isinstance(simulation, dict)
    simulation["instrument"] = "camera"
    return doc
