"""A simulated vision session as data: each camera's frames (:class:`CameraFrames`) and the
session with its rig, frames, warnings and notes (:class:`VisionSession`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.simulator.camera.presets import (
    ImageFormat,
)
from dhlog.simulator.camera.rig import (
    Rig,
)
from dhlog.simulator.session import Session


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
