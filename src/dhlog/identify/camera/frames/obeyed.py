"""Which of a camera info's two readings a log's images obey: the raw images' ``K`` and ``D``, or
the rectified images' projection ``P`` with no distortion (ROS's ``CameraInfo`` carries both).

The image topic's name decides which is read (:func:`~.camerafind.rectified_topic`, or the
pipeline's ``[camera] rectified``), but a driver may undistort on board and publish on
``image_raw``, or a republisher name its output freely. Read with the wrong one, the fit misses
its corners several fold and puts the camera centimetres off with nothing else to say so. So the
board is placed by PnP in the frames that hold the most corners, under each reading, and the
reprojection RMS of each is compared (:func:`board_fit_rms`): where the other reading's is
:data:`CLEARLY` times lower, the name's choice is overruled and the user's own choice warned
of (:func:`judged`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics

#: Frames (those with the most corners) the board is placed in under each reading.
CHECK_FRAMES = 50
#: Fewest corners a frame checked holds.
MIN_CORNERS = 8
#: Fewest residuals beyond the boards' poses (2 a corner, less 6 a frame) the readings are
#: compared on: the RMS then known to about 5 %.
MIN_DOF = 200
#: How many times lower the other reading's RMS must be. Read right, the board's RMS is the
#: corners' noise; read wrong, the lens's unmodelled part adds to it in every frame: on the
#: simulator's small camera 0.062 against 0.098 px (raw images), 0.061 against 0.107 px
#: (rectified), each frame's board pose absorbing what it can of the difference.
CLEARLY = 1.25

#: One frame's detection: its corners' ids and their pixel positions (k, 2).
Corners = tuple[NDArray[np.int64], NDArray[np.float64]]


@dataclass(frozen=True)
class Reading:
    """One reading of the camera info: its intrinsics, where they come from, and whether it is
    the rectified images' (``P``, no distortion)."""

    intrinsics: Intrinsics
    source: str
    rectified: bool

    @property
    def short(self) -> str:
        return "P, no distortion" if self.rectified else "K and D"


def board_fit_rms(board: BoardSpec, frames: Sequence[Corners], camera: Intrinsics) -> float:
    """The board's reprojection RMS (px) over the corners of ``frames`` after PnP in each
    (IPPE, refined by Levenberg–Marquardt) under ``camera`` (a pinhole model); NaN where no
    frame is fitted."""
    points = board.object_points()
    squares, count = 0.0, 0
    for ids, uv in frames:
        obj = points[ids].astype(np.float64)
        img = np.asarray(uv, dtype=np.float64).reshape(-1, 1, 2)
        K, D = camera.K, camera.coefficients
        try:
            ok, rvec, tvec = cv2.solvePnP(obj, img, K, D, flags=cv2.SOLVEPNP_IPPE)
            if not ok:
                continue
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, D, rvec, tvec)
        except cv2.error:
            continue
        R = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
        pred = camera.project(obj @ R.T + np.asarray(tvec, dtype=np.float64).ravel())
        squares += float(np.sum((pred - uv) ** 2))
        count += int(ids.size)
    return math.sqrt(squares / count) if count else math.nan


def judged(
    name: str,
    board: BoardSpec,
    found: Sequence[Corners],
    used: Reading,
    other: Reading,
    told: bool,
) -> tuple[Reading, tuple[str, ...]]:
    """The reading the images obey, and what to say: ``used`` unless ``other`` places the
    board to a :data:`CLEARLY` times lower RMS in the frames with the most corners; then
    ``other`` where the topic's name chose ``used`` (said), or ``used`` still with a warning
    where the pipeline's ``[camera] rectified`` did (``told``)."""
    if "equidistant" in (used.intrinsics.model, other.intrinsics.model):
        return used, ()  # a fisheye's rectified reading is not P's pinhole: not compared
    rich = sorted((f for f in found if f[0].size >= MIN_CORNERS), key=lambda f: -f[0].size)
    frames = rich[:CHECK_FRAMES]
    if sum(2 * ids.size - 6 for ids, _ in frames) < MIN_DOF:
        return used, ()
    mine = board_fit_rms(board, frames, used.intrinsics)
    theirs = board_fit_rms(board, frames, other.intrinsics)
    if not (np.isfinite(mine) and np.isfinite(theirs)) or theirs * CLEARLY > mine:
        return used, ()
    state = "rectified" if other.rectified else "not rectified"
    fits = (
        f"in the {len(frames)} frames with the most corners the board is placed to "
        f"{theirs:.3g} px RMS with {other.source}, {mine:.3g} px with {used.source}"
    )
    if told:
        key = f"[camera] rectified = {'true' if other.rectified else 'false'}"
        said = (
            f"{name}: the images look {state}, though the pipeline's [camera] rectified says "
            f"otherwise: {fits}; they were read as the pipeline says: set {key} if they are "
            f"{state}."
        )
        return used, (said,)
    said = (
        f"{name}: the images are {state}, whatever their topic's name says: {fits}; they were "
        f"read with {other.short} (set [camera] rectified in the pipeline to decide)."
    )
    return other, (said,)
