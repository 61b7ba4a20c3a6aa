"""A session seen by simulated cameras (:func:`simulate_vision`): the options checked
(:func:`vision_problems`), then for ``random-poses`` one frame in the middle of each still pose
where the board is seen (several cameras: the poses kept where one camera at least sees it), for
the moving protocols frames at the camera's rate (:mod:`dhlog.simulator.camera.moving`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from dhlog.errors import DhlogError
from dhlog.model.robots import Robot
from dhlog.simulator.camera.frames import CameraFrames, VisionSession
from dhlog.simulator.camera.moving import _moving_vision
from dhlog.simulator.camera.presets import (
    CAMERA_PRESETS,
    PRESETS,
    CameraPreset,
    CameraSetup,
    ImageFormat,
)
from dhlog.simulator.camera.rig import (
    MAX_CAMERAS,
    _spread_rigs,
    camera_poses,
    flange_poses,
    place_rig,
    seen,
)
from dhlog.simulator.config import FRAME_RATE, CameraOptions, SimulationConfig
from dhlog.simulator.robot import perturbed
from dhlog.simulator.session import simulate_session


def vision_problems(setup: str, options: CameraOptions) -> list[str]:
    """What is wrong with a vision log's camera ``options`` for the camera set-up ``setup``
    (empty when they can be simulated)."""
    preset, frame_rate = options.preset, options.frame_rate
    cameras, exposure = options.cameras, options.exposure
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
    """The session of ``cfg`` seen by the camera of ``preset`` (:mod:`dhlog.simulator.camera`):
    for ``random-poses`` one frame in the middle of each still pose where the board is seen,
    for ``sweeps`` and ``coupled`` a frame every ``1 / frame_rate`` s where it is seen;
    ``cameras`` fixed cameras (eye-to-hand), each placed differently; ``exposure`` (s): a
    moving protocol's frames blurred by the motion over that time about their stamps."""
    options = CameraOptions(preset, frame_rate, cameras, exposure)
    problems = vision_problems(setup, options)
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
    return _moving_vision(robot, table, cfg, setup, image_format, options)


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
