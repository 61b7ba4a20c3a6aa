"""A simulated vision log: a ChArUco board seen by a pinhole camera with plumb_bob distortion
while the robot runs a protocol, in one of two set-ups, written with the joint states as a ROS 2
camera records it.

- :mod:`~dhlog.simulator.camera.presets`: the set-ups (eye-to-hand: the board on the flange,
  the camera fixed in the cell; eye-in-hand: the camera on the flange, the board fixed), the
  image formats and the camera presets (``dhlog simulate --camera``);
- :mod:`~dhlog.simulator.camera.rig`: where the fixed part stands (:class:`Rig`) and which
  poses see the board (:func:`seen`, :func:`camera_poses`);
- :mod:`~dhlog.simulator.camera.render`: a frame rendered (:func:`render`: the board's drawing
  through the lens, exposure, blur, noise, motion blur);
- :mod:`~dhlog.simulator.camera.frames`: the session as data (:class:`VisionSession`,
  :class:`CameraFrames`);
- :mod:`~dhlog.simulator.camera.moving`: the moving protocols' frames, the sweeps' home and
  the fixed part chosen together, sweeps limited to where the board is seen;
- :mod:`~dhlog.simulator.camera.session`: :func:`simulate_vision` (still poses' frames here,
  the moving protocols' there);
- :mod:`~dhlog.simulator.camera.log`: the MCAP log (:func:`write_vision_log`), detections
  without rendering (:func:`simulate_detections`) and the truth block (:func:`vision_truth`).

Every public name of these modules is importable from ``dhlog.simulator.camera``.
"""

from dhlog.simulator.camera.frames import CameraFrames, VisionSession
from dhlog.simulator.camera.log import (
    JPEG_QUALITY,
    TOPICS,
    camera_topics,
    simulate_detections,
    vision_truth,
    write_vision_log,
)
from dhlog.simulator.camera.moving import (
    HOME_PROBES,
    MIN_SWEEP_FRAMES,
    MIN_SWEEP_SEEN,
    MIN_SWEEP_TRAVEL,
    Move,
    place_for_moves,
    protocol_moves,
)
from dhlog.simulator.camera.presets import (
    BOARD,
    BOARD_DISTANCE,
    BOARD_ON_FLANGE,
    CAMERA,
    CAMERA_DISTANCE,
    CAMERA_ON_FLANGE,
    CAMERA_PRESETS,
    CAMERA_SETUPS,
    IMAGE_FORMATS,
    PRESETS,
    CameraPreset,
    CameraSetup,
    ImageFormat,
    board_on_flange,
)
from dhlog.simulator.camera.render import (
    BACKGROUND,
    BLUR_SIGMA,
    EXPOSURE,
    MOTION_POSES,
    MOTION_STEP_PX,
    PIXEL_NOISE,
    TEXTURE_PREFILTER,
    TEXTURE_SCALE,
    motion_steps,
    render,
)
from dhlog.simulator.camera.rig import (
    CAMERA_OFFSETS,
    CAMERA_SPREAD,
    MAX_CAMERAS,
    MAX_TILT,
    MIN_IN_VIEW,
    PLACEMENT_PROBES,
    Rig,
    camera_poses,
    flange_poses,
    place_rig,
    seen,
)
from dhlog.simulator.camera.session import simulate_vision, vision_problems
from dhlog.simulator.config import FRAME_RATE

__all__ = [
    "BACKGROUND",
    "BLUR_SIGMA",
    "BOARD",
    "BOARD_DISTANCE",
    "BOARD_ON_FLANGE",
    "CAMERA",
    "CAMERA_DISTANCE",
    "CAMERA_OFFSETS",
    "CAMERA_ON_FLANGE",
    "CAMERA_PRESETS",
    "CAMERA_SETUPS",
    "CAMERA_SPREAD",
    "EXPOSURE",
    "FRAME_RATE",
    "HOME_PROBES",
    "IMAGE_FORMATS",
    "JPEG_QUALITY",
    "MAX_CAMERAS",
    "MAX_TILT",
    "MIN_IN_VIEW",
    "MIN_SWEEP_FRAMES",
    "MIN_SWEEP_SEEN",
    "MIN_SWEEP_TRAVEL",
    "MOTION_POSES",
    "MOTION_STEP_PX",
    "PIXEL_NOISE",
    "PLACEMENT_PROBES",
    "PRESETS",
    "TEXTURE_PREFILTER",
    "TEXTURE_SCALE",
    "TOPICS",
    "CameraFrames",
    "CameraPreset",
    "CameraSetup",
    "ImageFormat",
    "Move",
    "Rig",
    "VisionSession",
    "board_on_flange",
    "camera_poses",
    "camera_topics",
    "flange_poses",
    "motion_steps",
    "place_for_moves",
    "place_rig",
    "protocol_moves",
    "render",
    "seen",
    "simulate_detections",
    "simulate_vision",
    "vision_problems",
    "vision_truth",
    "write_vision_log",
]
