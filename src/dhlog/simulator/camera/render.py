"""A simulated camera image (:func:`render`): every camera pixel's ray (undistorted by OpenCV once
per camera) cut with the board's plane (one homography a frame), the board's flat drawing
(``BoardSpec.image`` at :data:`TEXTURE_SCALE` times the image's scale, smoothed) looked up there
(``cv2.remap``, bilinear) on a grey background, an exposure gain drawn per frame, a Gaussian blur
of :data:`BLUR_SIGMA` px (``cv2.GaussianBlur``) and Gaussian pixel noise of :data:`PIXEL_NOISE`
grey levels. With an exposure the frame is the mean of the board drawn at poses evenly across it
(one drawing for each :data:`MOTION_STEP_PX` the corners move, at most :data:`MOTION_POSES`):
motion blur.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.simulator.camera.rig import (
    Rig,
)
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics

#: motion blur: the poses across an exposure taken (at most), and the image motion (px) each
#: drawing of them stands for
MOTION_POSES = 17


MOTION_STEP_PX = 0.5


#: Gaussian pixel noise (σ, grey levels of 255) and blur (σ, px)
PIXEL_NOISE = 2.0


BLUR_SIGMA = 0.6


#: the board's drawing at this many pixels to an image pixel (at the board's distance), smoothed
#: by a Gaussian of σ ``TEXTURE_PREFILTER`` image pixels before it is sampled (``cv2.remap``
#: samples without averaging). A drawing at the image's scale draws the full-hd board's markers
#: at 2.5 px a cell, quantized, and OpenCV found 665 of 1 296 corners in 24 full-hd poses (0.069
#: px RMS from the truth); at 3 and 0.35 px, 1 218 (0.056 px RMS); at 3 without smoothing 1 243
#: but 0.180 px RMS (aliased edges)
TEXTURE_SCALE = 3


TEXTURE_PREFILTER = 0.35


#: the exposure gain of a frame, drawn uniformly in this range
EXPOSURE = (0.8, 1.1)


#: the grey level of the scene behind the board
BACKGROUND = 110


def _rays(camera: Intrinsics) -> FloatArray:
    """Each pixel's ray (h·w, 3) in the camera frame, z = 1, through the lens (undistorted by
    ``cv2.undistortPoints``, iterated to 1e-12)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    xy = cv2.undistortPoints(pixels, camera.K, camera.coefficients, criteria=criteria)
    return np.column_stack([xy.reshape(-1, 2), np.ones(camera.width * camera.height)])


@functools.lru_cache(maxsize=4)
def _rays32(camera: Intrinsics) -> NDArray[np.float32]:
    """:func:`_rays`' x and y (h, w, 2) in single precision (the renderer's)."""
    xy = _rays(camera)[:, :2].reshape(camera.height, camera.width, 2)
    return np.ascontiguousarray(xy, dtype=np.float32)


@functools.lru_cache(maxsize=16)
def _drawing(board: BoardSpec, square_px: int) -> tuple[NDArray[np.uint8], FloatArray]:
    """The board drawn flat with squares of ``square_px``, smoothed by a Gaussian of
    ``TEXTURE_PREFILTER`` image pixels (``TEXTURE_SCALE`` drawing pixels to one)."""
    d = board.image(square_px / board.square_m, margin_px=square_px)
    smooth = cv2.GaussianBlur(d.pixels, (0, 0), TEXTURE_PREFILTER * TEXTURE_SCALE)
    return np.asarray(smooth, dtype=np.uint8), d.image_from_board


def _draw(rig: Rig, T_cam_board: FloatArray) -> NDArray[np.uint8]:
    """The board at ``T_cam_board`` drawn through the lens on the background, before light,
    blur and noise."""
    cam, board = rig.camera, rig.board
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    # the drawing at TEXTURE_SCALE times the camera's scale at the board's distance (cached)
    scale = TEXTURE_SCALE * cam.K[0, 0] * board.square_m / max(t[2], 1e-3)
    pixels, H = _drawing(board, min(max(8, round(scale)), 300))
    # a ray r meets the board's plane at λ·r = R·(x, y, 0) + t = M·(x, y, 1), M = [r1 r2 t]:
    # (x, y, 1)/λ = M⁻¹·r, and the drawing's pixel is H·(x, y, 1), in front where 1/λ > 0
    A = H @ np.linalg.inv(np.column_stack([R[:, 0], R[:, 1], t]))
    xy = _rays32(cam)  # (h, w, 2): the rays' x, y at z = 1
    shape = (cam.height, cam.width)
    maps = cv2.perspectiveTransform(xy.reshape(-1, 1, 2), A).reshape(*shape, 2)
    front = xy[..., 0] * np.float32(A[2, 0]) + xy[..., 1] * np.float32(A[2, 1]) > -A[2, 2]
    maps[~front] = -1e6
    # one CV_32FC2 map and no second one, which some releases' stubs do not allow: called
    # untyped so the check holds for every OpenCV the pins admit
    remap: Any = cv2.remap
    image = remap(pixels, maps, None, cv2.INTER_LINEAR, borderValue=BACKGROUND)
    return np.asarray(image, dtype=np.uint8)


def motion_steps(rig: Rig, T_exposure: FloatArray) -> int:
    """How many of the poses (k, 4, 4) across an exposure to draw: one for each
    ``MOTION_STEP_PX`` the board's corners move in the image between its ends (1 to k)."""
    P = rig.board.object_points()
    ends = T_exposure[[0, -1]]
    pts = np.einsum("mij,kj->mki", ends[:, :3, :3], P) + ends[:, None, :3, 3]
    uv = rig.camera.project(pts.reshape(-1, 3)).reshape(2, -1, 2)
    moved = np.nanmax(np.linalg.norm(uv[1] - uv[0], axis=1), initial=0.0)
    return int(min(len(T_exposure), max(1, math.ceil(moved / MOTION_STEP_PX) + 1)))


def render(
    rig: Rig,
    T_cam_board: FloatArray,
    rng: np.random.Generator,
    T_exposure: FloatArray | None = None,
) -> NDArray[np.uint8]:
    """The camera's grey image (h, w) of the board at ``T_cam_board`` (see the module); with
    ``T_exposure`` (k, 4, 4), the board's poses across the exposure, the mean of its drawings
    at :func:`motion_steps` of them, evenly spread (motion blur)."""
    cam = rig.camera
    shape = (cam.height, cam.width)
    if T_exposure is None or len(T_exposure) < 2:
        image = _draw(rig, T_cam_board).astype(np.float32)
    else:
        k = motion_steps(rig, T_exposure)
        picks = (
            np.rint(np.linspace(0, len(T_exposure) - 1, k)).astype(int)
            if k > 1
            else [len(T_exposure) // 2]
        )
        image = np.mean([_draw(rig, T_exposure[i]).astype(np.float32) for i in picks], axis=0)
    gain = np.float32(rng.uniform(*EXPOSURE))
    lit = np.asarray(cv2.GaussianBlur(image.astype(np.float32) * gain, (0, 0), BLUR_SIGMA))
    lit = lit + rng.normal(0.0, PIXEL_NOISE, shape).astype(np.float32)
    return np.asarray(np.clip(np.rint(lit), 0, 255), dtype=np.uint8)
