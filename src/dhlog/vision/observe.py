"""What a vision log holds for the calibration: each frame's detected board corners, the joint
values at its stamp, the camera's intrinsics (issue 32).

:func:`observe` reads a camera log with a camera pipeline: the images a block at a time
(:class:`dhlog.io.images.ImageStream`), the board found in each (:func:`dhlog.vision.detect.detect`,
in ``jobs`` processes), the encoders joined at each frame's stamp, and a few frames kept
compressed for the recording.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics
from dhlog.vision.detect import Tally


@dataclass(frozen=True)
class Observations:
    """One camera's detections over a log.

    ``camera``: the image topic; ``intrinsics``: the camera's (CameraInfo or the pipeline's
    calibration file); ``board``: the pipeline's ``[target]``. Per detected frame ``f`` (in
    time order): ``t_ns`` (f,) its stamp, ``frame`` (f,) its index among the topic's messages,
    ``q`` (f, n) the joint values at the stamp (rad or m, chain order ``joint_names``),
    ``ids[f]`` (k,) int64 the corners' ids and ``uv[f]`` (k, 2) their positions (px).
    ``tally``: every frame's outcome (detected or the reason not); ``kept``: a decimated
    selection of frames kept compressed for the recording, ``(frame index, format, bytes)``
    with format ``"jpeg"`` or ``"png"``; ``warnings``: one line each (frames without joint
    values, the robot moving during exposure, …)."""

    path: str
    camera: str
    intrinsics: Intrinsics
    board: BoardSpec
    t_ns: NDArray[np.int64]
    frame: NDArray[np.int64]
    q: FloatArray
    joint_names: list[str]
    ids: list[NDArray[np.int64]]
    uv: list[FloatArray]
    tally: Tally
    kept: list[tuple[int, str, bytes]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    @property
    def frames(self) -> int:
        """Detected frames with joint values."""
        return int(self.t_ns.size)
