"""What the recording shows of a camera calibration: the frames kept, each
with its detected corners and where the result reprojects them, and the camera and the board
placed in the robot's base frame by the result. Filled by the calibration
(:mod:`dhlog.identify`), drawn by :mod:`dhlog.present.recording`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.vision.camera import Intrinsics


@dataclass(frozen=True)
class FrameView:
    """One frame: its stamp (ns), index among the topic's messages, the image kept (``image``
    compressed bytes of ``image_format`` "jpeg" / "png", or None when the frame was not kept),
    the corners' ``ids`` (k,), where they were detected ``detected_px`` (k, 2) and where the
    result reprojects them ``reprojected_px`` (k, 2); ``held_out``: the frame scored the result
    but did not fit it; ``T_base_camera``, ``T_base_board`` (4, 4): the camera's and the board's
    frames in the robot's base frame at this frame (by the result's model)."""

    t_ns: int
    index: int
    image: bytes | None
    image_format: str
    ids: NDArray[np.int64]
    detected_px: FloatArray
    reprojected_px: FloatArray
    held_out: bool
    T_base_camera: FloatArray
    T_base_board: FloatArray


@dataclass(frozen=True)
class CameraView:
    """One camera: ``name`` (its image topic), ``setup`` ("eye-to-hand": fixed in the cell,
    the board on the flange; "eye-in-hand": on the flange, the board fixed), its
    ``intrinsics``, the board's corners in the board frame ``board_points`` (N, 3, m), the
    reprojection RMS of the result (px), the frames and ``notes`` (the held-out check)."""

    name: str
    setup: str
    intrinsics: Intrinsics
    board_points: FloatArray
    rms_px: float
    frames: list[FrameView]
    #: lines the recording shows beside the camera: the held-out check's figures and notes
    notes: tuple[str, ...] = ()
