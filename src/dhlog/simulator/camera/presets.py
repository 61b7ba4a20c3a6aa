"""The cameras and boards of a simulated vision log: the set-ups (eye-to-hand: the board on the
flange, :data:`BOARD_ON_FLANGE`, the camera fixed in the cell; eye-in-hand: the camera on the
flange, :data:`CAMERA_ON_FLANGE`, the board fixed in the cell), the image formats, and the
presets (:data:`PRESETS`, ``dhlog simulate --camera``): ``default`` (1280×800, f 1800 px, a 7×5
board of 40 mm squares, 1.5 m / 0.55 m away), ``full-hd`` (1920×1080, f 1600 px, a 10×7 board
of 30 mm squares, 0.3 m across, 2 m away) and ``small`` (640×400, the default's field of view
at half the pixels, a board of 60 mm squares: quick logs and tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from dhlog.geometry._checks import FloatArray
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


#: the presets: the current camera (the default), the benchmark camera (1920×1080, f
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
