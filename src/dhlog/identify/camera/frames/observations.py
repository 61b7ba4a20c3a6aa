"""What a vision log holds for the calibration: each frame's detected board corners, the joint
values at its stamp, the camera's intrinsics.

:func:`observe.observe <dhlog.identify.camera.frames.observe.observe>` reads a camera log with a
camera pipeline into :class:`Observations`: the images a block at a time
(:class:`~dhlog.identify.camera.frames.images.ImageStream`), the board found in each
(:func:`~dhlog.identify.camera.frames.detect.detect`, in ``jobs`` processes), the encoders joined
at each frame's stamp, and a few frames kept compressed for the recording. What needs no log is
here: the encoders at the frames' stamps (:func:`joint_values_at`) and the frames kept evenly over
a log of unknown length (:class:`Decimation`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.camera.frames.detect import Tally
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics


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
    kept: tuple[tuple[int, str, bytes], ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def frames(self) -> int:
        """Detected frames with joint values."""
        return int(self.t_ns.size)


#: A joint moving faster than this (rad/s, or m/s for a prismatic joint) at a frame's stamp
#: smears the frame: over a nominal exposure of 10 ms it turns 1e-4 rad (or moves 0.1 mm),
#: 0.1 mm at a lever of 1 m — 0.09 px for a camera of f 1800 px 2 m away, as much as the
#: detector's own noise (0.1–0.3 px, tests/test_vision.py).
MOVING_SPEED = 0.01
#: The nominal exposure time (s) the smear above is reckoned with.
NOMINAL_EXPOSURE_S = 0.01


@dataclass(frozen=True)
class JointsAt:
    """The encoders at frames' stamps: ``q`` (f, n) interpolated linearly between the samples
    around each stamp, ``speed`` (f, n) the joints' speed there (per second; a central
    difference over the samples strictly before and after the stamp), ``ok`` (f,) whether both
    samples around the stamp lie within the tolerance of it (``q`` and ``speed`` are NaN where
    not)."""

    q: FloatArray
    speed: FloatArray
    ok: NDArray[np.bool_]


def joint_values_at(
    t_ns: NDArray[np.int64], joint_t_ns: NDArray[np.int64], joint_q: FloatArray, tolerance_s: float
) -> JointsAt:
    """The joint values (m, n) sampled at ``joint_t_ns`` (m,), ascending, at the stamps
    ``t_ns`` (f,): see :class:`JointsAt`. A stamp before the first sample or after the last,
    or further than ``tolerance_s`` from either sample around it, is not ``ok``."""
    t = np.asarray(t_ns, dtype=np.int64)
    jt = np.asarray(joint_t_ns, dtype=np.int64)
    jq = np.asarray(joint_q, dtype=np.float64).reshape(jt.size, -1)
    n = jq.shape[1]
    nan = np.full((t.size, n), np.nan)
    if jt.size == 0 or t.size == 0:
        return JointsAt(nan, nan.copy(), np.zeros(t.size, dtype=bool))
    last = jt.size - 1
    i0 = np.searchsorted(jt, t, side="right") - 1  # the last sample at or before the stamp
    i1 = np.searchsorted(jt, t, side="left")  # the first at or after it
    a, b = np.clip(i0, 0, last), np.clip(i1, 0, last)
    tol = round(tolerance_s * 1e9)
    ok = (i0 >= 0) & (i1 <= last) & (t - jt[a] <= tol) & (jt[b] - t <= tol)
    dt = (jt[b] - jt[a]).astype(np.float64)
    w = np.divide((t - jt[a]).astype(np.float64), dt, out=np.zeros(t.size), where=dt > 0)
    q = jq[a] + w[:, None] * (jq[b] - jq[a])
    lo = np.clip(np.searchsorted(jt, t, side="left") - 1, 0, last)  # strictly before
    hi = np.clip(np.searchsorted(jt, t, side="right"), 0, last)  # strictly after
    span = (jt[hi] - jt[lo]).astype(np.float64) * 1e-9
    speed = np.divide(jq[hi] - jq[lo], span[:, None], out=np.zeros((t.size, n)),
                      where=span[:, None] > 0)  # fmt: skip
    q[~ok] = np.nan
    speed[~ok] = np.nan
    return JointsAt(q, speed, ok)


class Decimation:
    """Frames kept evenly over a log whose length is not known in advance: every ``step``-th
    frame (by its index on the topic), ``step`` doubling (and the frames off it dropped)
    whenever more than ``limit`` are held, so between ``limit / 2`` and ``limit`` frames stay,
    spread over the whole log. :meth:`wanted` says whether a frame would be kept now (a frame
    not wanted now never is: the step only grows)."""

    def __init__(self, limit: int) -> None:
        self.limit, self.step = max(int(limit), 0), 1
        self.kept: dict[int, tuple[str, bytes]] = {}

    def wanted(self, index: int) -> bool:
        return self.limit > 0 and index % self.step == 0

    def add(self, index: int, image_format: str, data: bytes) -> None:
        """Keep frame ``index`` (compressed ``data`` of ``image_format``) if still wanted."""
        if not self.wanted(index):
            return
        self.kept[index] = (image_format, data)
        while len(self.kept) > self.limit:
            self.step *= 2
            self.kept = {i: v for i, v in self.kept.items() if i % self.step == 0}

    def frames(self) -> tuple[tuple[int, str, bytes], ...]:
        """The frames kept, ``(index, format, bytes)`` in index order."""
        return tuple((i, *self.kept[i]) for i in sorted(self.kept))
