"""A calibration target found in one image, by OpenCV, or the reason it was not.

``detect`` never raises on what an image holds: a frame without the board, with too few of its
corners, with markers of another dictionary, blurred beyond use or not an image at all comes
back as :class:`Rejected` with one of :data:`REASONS` and a detail, and :func:`tally` counts them
over a log. Image coordinates are pixels, the centre of the top-left pixel at (0, 0).
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.vision.boards import DICTIONARIES, BoardSpec
from dhlog.vision.camera import Intrinsics

Reason = Literal["no target", "too few corners", "wrong dictionary", "blurred", "unreadable image"]
REASONS: tuple[Reason, ...] = (
    "no target",
    "too few corners",
    "wrong dictionary",
    "blurred",
    "unreadable image",
)

#: The fewest corners a detection keeps by default: a planar target's pose (a homography) needs
#: 4; 6 leave two to check it by.
MIN_CORNERS = 6

#: A frame where nothing was found is named "blurred" when its edges rise from 10 % to 90 %
#: over more than this many pixels, as :func:`edge_rise_px` measures them (a sharp edge gives
#: 2–2.8 px, pure noise 3.3 px, a Gaussian blur of σ px about 2.5 σ to 3.5 σ). OpenCV's
#: ``estimateChessboardSharpness`` documents that the rise "should be below ~3.0 pixels" for
#: an accurate calibration; 5 px lies above what noise alone measures and well beyond that.
BLUR_RISE_PX = 5.0

#: Below this spread of grey levels (1st to 99th percentile, of 255) an image is blank.
MIN_CONTRAST = 16.0

#: The dictionaries tried, in this order, when the board's own finds no marker, to tell "wrong
#: dictionary" from "no target": each family's of 100 markers (their first markers are the
#: smaller ones'; the 1000-marker ones cost 6–8 times as much to search), then the others.
#: The search stops at the first that finds markers; on a full-HD frame each costs 15–110 ms.
OTHER_DICTIONARIES: tuple[str, ...] = (
    "DICT_4X4_100",
    "DICT_5X5_100",
    "DICT_6X6_100",
    "DICT_7X7_100",
    "DICT_APRILTAG_36h11",
    "DICT_APRILTAG_25h9",
    "DICT_ARUCO_ORIGINAL",
)

#: The fewest marker-like squares the board's dictionary could not decode that make the search
#: above worth its cost (a board of another dictionary shows one for each marker).
MIN_CANDIDATES = 4

#: How many markers of another dictionary make a frame "wrong dictionary" rather than
#: "no target" (one can be a pattern in the scene that happens to decode).
WRONG_DICTIONARY_MARKERS = 2

#: The smallest marker side OpenCV looks for (px) on a large image. OpenCV's default
#: (``minMarkerPerimeterRate`` 0.03 of the image's larger side) asks for 14.4 px on a full-HD
#: frame, which the camera benchmark's board (0.3 m at 2 m: 22 mm markers of about 17 px,
#: foreshortened by its tilt) fails in 2 frames of 6 (benchmarks/vision_detect.py), and a flat
#: board of 14 px markers entirely (tests/test_vision.py). 10 px lies below the 13.5 px (2 px a
#: cell) at which OpenCV decodes a 5×5 marker at all, so the decoding decides, at the same cost.
#: Smaller images keep OpenCV's default, and no smaller marker is looked for: on a frame of
#: noise every speck is a candidate (2 479 on 320×240 at a rate of 0.01, 0.5 s a dictionary).
MIN_MARKER_SIDE_PX = 10.0

#: Beyond this many undecoded candidates a frame is noise or clutter, not a board of another
#: dictionary, and the other dictionaries are not searched.
MAX_CANDIDATES = 1000

#: The largest image side accepted (px); beyond it the image is "unreadable".
MAX_SIDE = 20_000


@dataclass(frozen=True)
class Detection:
    """The board's corners found in one image.

    ``ids`` (N,) int64: the corners' ids (see :mod:`dhlog.vision.boards`), ascending;
    ``corners_px`` (N, 2) float64: their sub-pixel positions (px); ``object_points`` (N, 3)
    float64: the same corners in the board frame (m).
    """

    ids: NDArray[np.int64]
    corners_px: FloatArray
    object_points: FloatArray

    def __len__(self) -> int:
        return int(self.ids.size)


@dataclass(frozen=True)
class Rejected:
    """A frame without a usable detection: ``reason`` one of :data:`REASONS`, ``detail`` a
    phrase saying what was seen."""

    reason: Reason
    detail: str


def detect(
    image: object,
    board: BoardSpec,
    *,
    camera: Intrinsics | None = None,
    min_corners: int = MIN_CORNERS,
    blur_rise_px: float = BLUR_RISE_PX,
) -> Detection | Rejected:
    """Find ``board`` in ``image`` ((h, w) uint8 or uint16, or (h, w, 3|4) uint8 BGR(A)).

    ChArUco boards by ``cv2.aruco.CharucoDetector.detectBoard`` (markers, then the chessboard
    corners between them interpolated and refined to sub-pixel by OpenCV), ArUco grids by
    ``cv2.aruco.ArucoDetector`` (``detectMarkers`` with OpenCV's sub-pixel corner refinement,
    then ``refineDetectedMarkers`` against the board to recover missed markers), checkerboards
    by ``cv2.findChessboardCornersSB`` (sub-pixel by construction).

    Give the ``camera`` where its intrinsics are known (pinhole models; a fisheye's are not
    OpenCV's board model and are not used): OpenCV then places each ChArUco corner from the
    board's pose before refining it, instead of from the homography of its two neighbouring
    markers, and recovers missed grid markers by projection. Without them, at Gaussian noise of
    a tenth of the board's contrast, 3 frames of 10 had one corner settled 5.3 px off on a
    neighbouring edge; with them no corner was over 0.4 px off (tests/test_vision.py).

    Fewer than ``min_corners`` corners is a rejection; when nothing is found the image is
    looked at to name why (blank, another dictionary's markers, edges wider than
    ``blur_rise_px``). Never raises on the image's content.
    """
    gray = _gray(image)
    if isinstance(gray, Rejected):
        return gray
    try:
        lens = None if camera is None or camera.model == "equidistant" else camera
        if board.kind == "charuco":
            found = _charuco(gray, board, lens)
        elif board.kind == "aruco_grid":
            found = _aruco_grid(gray, board, lens)
        else:
            found = _checkerboard(gray, board)
    except cv2.error as exc:  # OpenCV refused this image: say so, never a traceback
        last = str(exc).strip().splitlines()[-1:] or ["OpenCV error"]
        return Rejected("unreadable image", f"OpenCV could not read it ({last[0][:100]})")
    if isinstance(found, Detection):
        if len(found) >= min_corners:
            return found
        few = f"{len(found)} corner(s) of {len(board.object_points())}, fewer than {min_corners}"
        rise, _ = edge_rise_px(gray)
        if rise > blur_rise_px:
            return Rejected(
                "blurred",
                f"edges rise over {rise:.1f} px (blurred beyond {blur_rise_px:g} px); {few}",
            )
        return Rejected("too few corners", few)
    markers = found.markers
    contrast = _contrast(gray)
    if contrast < MIN_CONTRAST:
        return Rejected("no target", f"a blank image (grey levels spread over {contrast:.0f})")
    if markers == 0 and MIN_CANDIDATES <= found.candidates <= MAX_CANDIDATES:
        other = _other_dictionary(gray, board)
        if other is not None:
            return other
    rise, _ = edge_rise_px(gray)
    if rise > blur_rise_px:
        return Rejected(
            "blurred",
            f"edges rise over {rise:.1f} px (blurred beyond {blur_rise_px:g} px)"
            + (f"; {markers} marker(s) but too few corners" if markers else ""),
        )
    if markers:
        return Rejected("too few corners", f"{markers} marker(s) found but no corner between them")
    return Rejected("no target", f"no {_what(board)} in the image")


def edge_rise_px(gray: NDArray[np.uint8]) -> tuple[float, float]:
    """How wide the image's sharpest edges are (px), in the direction where they are widest,
    and its contrast (grey levels).

    The 10–90 % rise of an edge of contrast C blurred by a Gaussian of σ px is 2.56 σ; its
    steepest slope is C / (√(2π) σ), so C / slope = 2.51 σ estimates the rise. C is the spread
    from the 1st to the 99th percentile of grey, the slope the 99.9th percentile of the Sobel
    gradient's component along each of four directions (0°, 45°, 90°, 135°: motion blur widens
    the edges across its direction only), the steepest 0.1 % of pixels being the board's edges
    (a few thousandths of a frame). The widest direction's rise is returned. Noise only
    steepens slopes, so a noisy image is never called blurred for its noise.
    """
    contrast = _contrast(gray)
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3, scale=1 / 8)  # the 3×3 Sobel weighs by 8
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3, scale=1 / 8)
    slopes = []
    for c, s in ((1.0, 0.0), (0.5**0.5, 0.5**0.5), (0.0, 1.0), (-(0.5**0.5), 0.5**0.5)):
        along = np.abs(cv2.addWeighted(gx, c, gy, s, 0.0))
        slopes.append(_percentile(along, 0.999, 256.0))
    slope = min(slopes)
    return (contrast / slope if slope > 0 else float("inf")), contrast


def _contrast(gray: NDArray[np.uint8]) -> float:
    """The spread of grey levels from the 1st to the 99th percentile."""
    return _percentile(gray, 0.99, 256.0) - _percentile(gray, 0.01, 256.0)


def _percentile(values: NDArray[Any], q: float, top: float) -> float:
    """The q-quantile of an image's values in [0, top), to top/1024 (a histogram: no sort)."""
    bins = 256 if values.dtype == np.uint8 else 1024
    hist = cv2.calcHist([values], [0], None, [bins], [0.0, top]).ravel()
    cdf = np.cumsum(hist) / max(float(hist.sum()), 1.0)
    return float(np.searchsorted(cdf, q)) * top / bins


@dataclass(frozen=True)
class Tally:
    """Detections and rejections counted over frames (by their index), with the first three
    frames of each reason (:meth:`of`)."""

    frames: int = 0
    detected: int = 0
    counts: Mapping[str, int] = field(default_factory=dict)
    examples: Mapping[str, tuple[int, ...]] = field(default_factory=dict)

    @staticmethod
    def of(outcomes: Iterable[tuple[int, str | None]]) -> Tally:
        """The tally of frames ``(index, reason)``: the reason it was rejected, or None where
        the board was found."""
        frames = detected = 0
        counts: dict[str, int] = {}
        examples: dict[str, tuple[int, ...]] = {}
        for index, reason in outcomes:
            frames += 1
            if reason is None:
                detected += 1
                continue
            counts[reason] = counts.get(reason, 0) + 1
            shown = examples.get(reason, ())
            if len(shown) < 3:
                examples[reason] = (*shown, index)
        return Tally(frames, detected, counts, examples)

    def summary(self) -> str:
        """One line: ``412 of 500 frame(s) with the target; 60 no target (frames 3, 4, 9, …)``."""
        line = f"{self.detected} of {self.frames} frame(s) with the target"
        parts = []
        for reason in REASONS:
            n = self.counts.get(reason, 0)
            if n:
                frames = ", ".join(str(i) for i in self.examples[reason])
                more = ", …" if n > len(self.examples[reason]) else ""
                parts.append(f"{n} {reason} (frame{'s' if n > 1 else ''} {frames}{more})")
        return line + ("; " + ", ".join(parts) if parts else "")


def tally(outcomes: Iterable[Detection | Rejected], *, first_index: int = 0) -> Tally:
    """Count the outcomes of consecutive frames numbered from ``first_index``."""
    return Tally.of((i, reason_of(o)) for i, o in enumerate(outcomes, start=first_index))


def reason_of(outcome: Detection | Rejected) -> str | None:
    """Why a frame was rejected, or None where the board was found."""
    return None if isinstance(outcome, Detection) else outcome.reason


def _gray(image: object) -> NDArray[np.uint8] | Rejected:
    if not isinstance(image, np.ndarray):
        return Rejected("unreadable image", f"a {type(image).__name__}, not an array of pixels")
    if image.dtype not in (np.uint8, np.uint16):
        return Rejected("unreadable image", f"pixels of type {image.dtype}, not uint8 or uint16")
    shape = image.shape
    channels = shape[2] if image.ndim == 3 else 1
    if image.ndim not in (2, 3) or channels not in (1, 3, 4):
        return Rejected("unreadable image", f"an array of shape {shape}, not (h, w) or (h, w, 3)")
    if min(shape[:2]) < 8 or max(shape[:2]) > MAX_SIDE:
        return Rejected("unreadable image", f"an image of {shape[1]}×{shape[0]} px")
    img = np.ascontiguousarray(image)
    if img.dtype == np.uint16:
        stretched = np.empty(img.shape, dtype=np.uint8)  # mono16: min..max onto 0..255
        cv2.normalize(img, stretched, 0, 255, cv2.NORM_MINMAX, cv2.CV_8U)
        img = stretched
    if channels == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif channels == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2GRAY)
    elif img.ndim == 3:
        img = img[:, :, 0]
    return np.ascontiguousarray(img, dtype=np.uint8)


def _what(board: BoardSpec) -> str:
    cols, rows = board.squares
    if board.kind == "checkerboard":
        return f"{cols}×{rows} checkerboard"
    return f"{board.kind} board of {board.dictionary} ({cols}×{rows})"


class _Seen(NamedTuple):
    """What a search that found no corners saw: markers of the board, and marker-like squares
    its dictionary did not decode."""

    markers: int
    candidates: int


def _marker_detector(
    dictionary: str, gray: NDArray[np.uint8], *, refine: bool = False
) -> cv2.aruco.ArucoDetector:
    """OpenCV's marker detector for ``dictionary``, looking for markers down to
    :data:`MIN_MARKER_SIDE_PX` on an image of ``gray``'s size."""
    rate = min(0.03, round(4 * MIN_MARKER_SIDE_PX / max(gray.shape), 4))
    return _marker_detector_at(dictionary, rate, refine)


@functools.lru_cache(maxsize=64)
def _marker_detector_at(dictionary: str, rate: float, refine: bool) -> cv2.aruco.ArucoDetector:
    params = cv2.aruco.DetectorParameters()
    params.minMarkerPerimeterRate = rate
    if refine:
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(DICTIONARIES[dictionary]), params
    )


@functools.lru_cache(maxsize=16)
def _charuco_detector(
    board: BoardSpec, camera: Intrinsics | None
) -> tuple[cv2.aruco.CharucoDetector, FloatArray]:
    cv_board = board.cv_board()
    assert isinstance(cv_board, cv2.aruco.CharucoBoard)
    params = cv2.aruco.CharucoParameters()
    if camera is not None:
        params.cameraMatrix = np.array(camera.K)
        params.distCoeffs = np.array(camera.coefficients)
    return cv2.aruco.CharucoDetector(cv_board, params), board.object_points()


@functools.lru_cache(maxsize=16)
def _grid(board: BoardSpec) -> tuple[cv2.aruco.Board, dict[int, int], FloatArray]:
    index = {int(marker): i for i, marker in enumerate(board.marker_ids)}
    return board.cv_board(), index, board.object_points()


def _charuco(
    gray: NDArray[np.uint8], board: BoardSpec, camera: Intrinsics | None
) -> Detection | _Seen:
    # The markers first (their undecoded candidates tell "wrong dictionary" apart), then
    # OpenCV's ChArUco step on them: the chessboard corners between, refined to sub-pixel.
    marker_corners, marker_ids, rejected = _marker_detector(board.dictionary, gray).detectMarkers(
        gray
    )
    if marker_ids is None or len(marker_ids) == 0:
        return _Seen(0, 0 if rejected is None else len(rejected))
    detector, points = _charuco_detector(board, camera)
    corners, ids, _, _ = detector.detectBoard(
        gray, markerCorners=marker_corners, markerIds=marker_ids
    )
    if ids is None or len(ids) == 0:
        return _Seen(len(marker_ids), 0)
    ids = np.asarray(ids, dtype=np.int64).ravel()
    uv = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    order = np.argsort(ids)
    return Detection(ids[order], uv[order], points[ids[order]])


def _aruco_grid(
    gray: NDArray[np.uint8], board: BoardSpec, camera: Intrinsics | None
) -> Detection | _Seen:
    cv_board, index, points = _grid(board)
    detector = _marker_detector(board.dictionary, gray, refine=True)
    corners, ids, rejected = detector.detectMarkers(gray)
    if ids is not None and len(ids):
        if camera is None:
            corners, ids, _, _ = detector.refineDetectedMarkers(
                gray, cv_board, corners, ids, rejected
            )
        else:
            corners, ids, _, _ = detector.refineDetectedMarkers(
                gray, cv_board, corners, ids, rejected, camera.K, camera.coefficients
            )
    if ids is None or len(ids) == 0:
        return _Seen(0, 0 if rejected is None else len(rejected))
    found = np.asarray(ids, dtype=np.int64).ravel()
    unique, counts = np.unique(found, return_counts=True)
    once = set(unique[counts == 1].tolist()) & index.keys()  # a marker seen twice is ambiguous
    rows = [i for i, marker in enumerate(found) if int(marker) in once]
    if not rows:
        return _Seen(0, len(found))
    corner_ids = np.concatenate([4 * index[int(found[i])] + np.arange(4) for i in rows])
    uv = np.concatenate([np.asarray(corners[i], dtype=np.float64).reshape(4, 2) for i in rows])
    order = np.argsort(corner_ids)
    return Detection(corner_ids[order], uv[order], points[corner_ids[order]])


def _checkerboard(gray: NDArray[np.uint8], board: BoardSpec) -> Detection | _Seen:
    cols, rows = board.squares
    flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_ACCURACY
    ok, corners = cv2.findChessboardCornersSB(gray, (cols - 1, rows - 1), flags=flags)
    if not ok or corners is None:
        return _Seen(0, 0)
    grid = np.asarray(corners, dtype=np.float64).reshape(rows - 1, cols - 1, 2)
    # OpenCV's order may start at any corner of the grid: put the rows the board's way round.
    ex = grid[0, 1] - grid[0, 0]
    ey = grid[1, 0] - grid[0, 0]
    if ex[0] * ey[1] - ex[1] * ey[0] < 0:  # x × y must point into the board, as seen
        grid = grid[:, ::-1]
    if not _dark_first(gray, grid):
        grid = grid[::-1, ::-1]
    uv = grid.reshape(-1, 2)
    ids = np.arange(len(uv), dtype=np.int64)
    return Detection(ids, uv, board.object_points())


def _dark_first(gray: NDArray[np.uint8], grid: FloatArray) -> bool:
    """Whether the square between the first four corners is darker than its neighbour: the
    board's square (1, 1), black as the board is defined (:mod:`dhlog.vision.boards`)."""
    if grid.shape[1] >= 3:
        a = grid[:2, :2].reshape(-1, 2).mean(axis=0)
        b = grid[:2, 1:3].reshape(-1, 2).mean(axis=0)
    else:
        a = grid[:2, :2].reshape(-1, 2).mean(axis=0)
        b = grid[1:3, :2].reshape(-1, 2).mean(axis=0)
    h, w = gray.shape

    def grey(p: FloatArray) -> float:
        x = int(np.clip(round(float(p[0])), 0, w - 1))
        y = int(np.clip(round(float(p[1])), 0, h - 1))
        return float(gray[y, x])

    return grey(a) < grey(b)


def _other_dictionary(gray: NDArray[np.uint8], board: BoardSpec) -> Rejected | None:
    """Markers of another dictionary (called when the image holds square candidates the
    board's own dictionary could not decode: a frame without them costs no more passes)."""
    for name in OTHER_DICTIONARIES:
        if name == board.dictionary or name not in DICTIONARIES:
            continue
        _, ids, _ = _marker_detector(name, gray).detectMarkers(gray)
        if ids is not None and len(ids) >= WRONG_DICTIONARY_MARKERS:
            break
    else:
        return None
    seen = sorted(int(i) for i in np.asarray(ids).ravel())
    n = len(seen)
    shown = ", ".join(str(i) for i in seen[:5]) + (", …" if n > 5 else "")
    return Rejected(
        "wrong dictionary",
        f"{n} markers of {name} (ids {shown}), none of {board.dictionary}: "
        "set the target's dictionary to the board's",
    )
