"""Which of a camera info's two readings a log's images obey: the raw images' ``K`` and ``D``, or
the rectified images' projection ``P`` with no distortion (ROS's ``CameraInfo`` carries both).

The image topic's name decides which is read (:func:`~.camerafind.rectified_topic`, or the
pipeline's ``[camera] rectified``), but a driver may undistort on board and publish on
``image_raw``, or a republisher name its output freely. Read with the wrong one, the fit misses
its corners several fold and puts the camera centimetres off. So the
board is placed by PnP in the frames that hold the most corners, under each reading, and the
reprojection RMS of each is compared (:func:`board_fits`): where the other reading's is
:data:`CLEARLY` times lower, the name's choice is overruled and the user's own choice warned
of (:func:`judged`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics, planar_pose

#: Frames (those with the most corners) the board is placed in under each reading.
CHECK_FRAMES = 50
#: Fewest corners a frame checked holds.
MIN_CORNERS = 8
#: Fewest residuals beyond the boards' poses (2 a corner, less 6 a frame) the readings are
#: compared on: the RMS then known to about 5 %.
MIN_DOF = 200
#: How many times lower the other reading's RMS must be. Both readings place the board on the
#: same corners, so they share the corners' noise; read wrong, the lens's unmodelled part adds
#: to it in every frame, less what each frame's board pose absorbs of it: on the simulator's
#: small camera (boards 130 px across) 0.061 against 0.095 px raw, 0.062 against 0.105 px
#: rectified; a milder lens or noisier corners bring the two closer, and the camera's fit
#: (identify.camera.flow) then warns where it misses the corners far beyond the boards' own RMS.
CLEARLY = 1.1

#: One frame's detection: its corners' ids and their pixel positions (k, 2).
Corners = tuple[NDArray[np.int64], NDArray[np.float64]]


@dataclass(frozen=True)
class Reading:
    """One reading of the camera info: its intrinsics, and whether it is the rectified
    images' (``P``, no distortion) or the raw images' (``K`` and ``D``)."""

    intrinsics: Intrinsics
    rectified: bool

    @property
    def source(self) -> str:
        return f"the camera info's {self.short}"

    @property
    def short(self) -> str:
        return "P (no distortion)" if self.rectified else "K and D"

    @property
    def state(self) -> str:
        return "rectified" if self.rectified else "not rectified"


def board_fits(
    board: BoardSpec, frames: Sequence[Corners], camera: Intrinsics
) -> tuple[FloatArray, NDArray[np.int64]]:
    """Per frame of ``frames``, the board's squared reprojection residuals summed (px²) after
    PnP (IPPE, refined by Levenberg–Marquardt) under ``camera`` (a pinhole model; NaN where it
    failed), and its corner count."""
    points = board.object_points()
    squares = np.full(len(frames), np.nan)
    counts = np.array([ids.size for ids, _ in frames], dtype=np.int64)
    for k, (ids, uv) in enumerate(frames):
        obj = points[ids].astype(np.float64)
        img = np.asarray(uv, dtype=np.float64).reshape(-1, 1, 2)
        pose = planar_pose(obj, img, camera.K, camera.coefficients)
        if pose is None:
            continue
        R, t = pose
        squares[k] = float(np.sum((camera.project(obj @ R.T + t) - uv) ** 2))
    return squares, counts


def judged(
    name: str,
    board: BoardSpec,
    found: Sequence[Corners],
    used: Reading,
    other: Reading,
    *,
    told: bool,
) -> tuple[Reading, tuple[str, ...]]:
    """The reading the images obey, and what to say: ``used`` unless ``other`` places the
    board to a :data:`CLEARLY` times lower RMS in the frames with the most corners (those both
    place); then ``other`` where the topic's name chose ``used`` (said), or ``used`` still with
    a warning where the pipeline's ``[camera] rectified`` did (``told``)."""
    if "equidistant" in (used.intrinsics.model, other.intrinsics.model):
        return used, ()  # a fisheye's rectified reading is not P's pinhole: not compared
    rich = sorted((f for f in found if f[0].size >= MIN_CORNERS), key=lambda f: -f[0].size)
    frames = rich[:CHECK_FRAMES]
    mine, counts = board_fits(board, frames, used.intrinsics)
    theirs, _ = board_fits(board, frames, other.intrinsics)
    both = np.isfinite(mine) & np.isfinite(theirs)
    if int(np.sum(2 * counts[both] - 6)) < MIN_DOF:
        return used, ()
    corners = int(np.sum(counts[both]))
    mine_rms = math.sqrt(float(np.sum(mine[both])) / corners)
    theirs_rms = math.sqrt(float(np.sum(theirs[both])) / corners)
    if theirs_rms * CLEARLY > mine_rms:
        return used, ()
    fits = (
        f"in the {int(np.count_nonzero(both))} frames with the most corners the board is placed "
        f"to {theirs_rms:.3g} px RMS with {other.source}, {mine_rms:.3g} px with {used.source}"
    )
    key = f"[camera] rectified = {'true' if other.rectified else 'false'}"
    if told:
        said = (
            f"{name}: the images fit {other.short} better than {used.short}, though the "
            f"pipeline's [camera] rectified chose {used.short}: {fits}; they were read as the "
            f"pipeline says: set {key} if they are {other.state}."
        )
        return used, (said,)
    said = (
        f"{name}: the images fit {other.short} better than {used.short}, whatever their "
        f"topic's name says: {fits}; they were read with {other.short} (they look "
        f"{other.state}; set [camera] rectified in the pipeline to decide)."
    )
    return other, (said,)
