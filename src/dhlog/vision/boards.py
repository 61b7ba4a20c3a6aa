"""Calibration targets: ChArUco boards (the default), ArUco marker grids and checkerboards.

The board frame (m) is OpenCV's: the origin at the board's top-left outer corner as printed,
x along its columns, y down its rows, z into the board (so a camera in front of it sees x right,
y down). Each kind's corners carry ids:

- ``charuco``: the chessboard's inner corners, ids ``0 … (cols−1)(rows−1)−1`` row by row, as
  ``cv2.aruco.CharucoBoard.getChessboardCorners`` numbers them;
- ``aruco_grid``: the markers' four corners, id ``4·i + k`` for the i-th marker of the board
  (its ``ids`` order) and its k-th corner (OpenCV's clockwise order from the top-left);
- ``checkerboard``: the inner corners row by row from the corner next to the black corner square
  at the origin; the board needs an odd number of squares in total (one side even, the other
  odd) so that its orientation in the image is unambiguous.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from dhlog.errors import FieldError
from dhlog.geometry._checks import FloatArray

BoardKind = Literal["charuco", "aruco_grid", "checkerboard"]
KINDS: tuple[str, ...] = ("charuco", "aruco_grid", "checkerboard")

#: OpenCV's predefined marker dictionaries, by name (``DICT_5X5_100`` …; the AprilTag ones in
#: OpenCV's spelling, ``DICT_APRILTAG_36h11``).
DICTIONARIES: dict[str, int] = {
    name: int(getattr(cv2.aruco, name))
    for name in dir(cv2.aruco)
    if name.startswith("DICT_") and isinstance(getattr(cv2.aruco, name), int)
}

#: The keys of a ``[target]`` table, with what each holds.
TABLE_KEYS: dict[str, str] = {
    "kind": "charuco, aruco_grid or checkerboard",
    "dictionary": "an OpenCV dictionary name such as DICT_5X5_100",
    "squares": "[cols, rows] of the board (markers for aruco_grid)",
    "square_m": "the square side in metres (the marker pitch for aruco_grid)",
    "marker_m": "the marker side in metres",
    "first_id": "the id of the board's first marker",
    "ids": "the board's marker ids, in order",
    "legacy_pattern": "true for a ChArUco board made before OpenCV 4.6",
}


class BoardError(FieldError):
    """A target description that does not describe a board OpenCV can detect."""


@dataclass(frozen=True)
class BoardImage:
    """A board rendered flat: ``pixels`` (h, w) uint8, and ``image_from_board`` (3, 3), the
    homography taking board-frame points (x, y, 1) in metres to pixels in ``pixels``."""

    pixels: NDArray[np.uint8]
    image_from_board: FloatArray


@dataclass(frozen=True)
class BoardSpec:
    """A calibration target: its kind, marker dictionary, squares (cols, rows) and sizes (m).

    For ``aruco_grid`` ``squares`` counts markers and ``square_m`` is their pitch (marker side
    plus the gap). ``ids`` are the board's marker ids in order (default ``first_id, first_id+1,
    …``); ``legacy_pattern`` selects the ChArUco layout of OpenCV before 4.6 for boards with an
    even number of rows. Checked on construction (:class:`BoardError` names ``where`` and the
    field); ``BoardSpec.from_table`` reads a pipeline's ``[target]`` table.
    """

    kind: BoardKind = "charuco"
    dictionary: str = "DICT_5X5_100"
    squares: tuple[int, int] = (7, 5)
    square_m: float = 0.04
    marker_m: float = 0.03
    first_id: int = 0
    ids: tuple[int, ...] | None = None
    legacy_pattern: bool = False
    where: str = field(default="target", compare=False)

    def __post_init__(self) -> None:
        w = self.where
        if self.kind not in KINDS:
            raise BoardError(w, "kind", f"is {self.kind!r}", "use " + ", ".join(KINDS))
        if self.kind != "checkerboard" and self.dictionary not in DICTIONARIES:
            raise BoardError(
                w,
                "dictionary",
                f"{self.dictionary!r} is not one of OpenCV's",
                "use a name such as DICT_5X5_100, DICT_4X4_50 or DICT_APRILTAG_36h11",
            )
        sq = self.squares
        if (
            not isinstance(sq, tuple)
            or len(sq) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in sq)
        ):
            raise BoardError(w, "squares", f"is {sq!r}", "give [cols, rows], two whole numbers")
        least = 1 if self.kind == "aruco_grid" else (3 if self.kind == "checkerboard" else 2)
        if min(sq) < least or max(sq) > 200:
            raise BoardError(
                w, "squares", f"is {list(sq)}", f"give [cols, rows] from {least} to 200 each"
            )
        if self.kind == "checkerboard" and (sq[0] + sq[1]) % 2 == 0:
            raise BoardError(
                w,
                "squares",
                f"is {list(sq)}, a checkerboard that looks the same turned half a turn",
                "use a board with one side even and the other odd (e.g. [9, 6])",
            )
        for name in ("square_m", "marker_m"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise BoardError(w, name, f"is {value!r}", "give a length in metres")
            if not (math.isfinite(value) and 0 < value <= 10):
                raise BoardError(w, name, f"is {value!r}", "give a length in metres (0 to 10 m)")
        if self.kind != "checkerboard" and self.marker_m >= self.square_m:
            raise BoardError(
                w,
                "marker_m",
                f"is {self.marker_m:g} m, not below square_m {self.square_m:g} m",
                "give the marker's side, smaller than the square (the pitch for aruco_grid)",
            )
        if not isinstance(self.legacy_pattern, bool):
            raise BoardError(
                w, "legacy_pattern", f"is {self.legacy_pattern!r}", "give true or false"
            )
        n = self.marker_count
        size = self.dictionary_size
        if isinstance(self.first_id, bool) or not isinstance(self.first_id, int):
            raise BoardError(w, "first_id", f"is {self.first_id!r}", "give a whole number")
        if self.ids is not None:
            ids = self.ids
            if not isinstance(ids, tuple) or not all(
                isinstance(i, int) and not isinstance(i, bool) for i in ids
            ):
                raise BoardError(w, "ids", f"is {ids!r}", "give a list of whole numbers")
            if len(ids) != n:
                raise BoardError(
                    w, "ids", f"has {len(ids)} ids for a board of {n} markers", f"give {n} ids"
                )
            if len(set(ids)) != len(ids):
                raise BoardError(w, "ids", "repeats an id", "give each marker's id once")
        else:
            ids = tuple(range(self.first_id, self.first_id + n))
        if ids and (min(ids) < 0 or max(ids) >= size):
            raise BoardError(
                w,
                "ids" if self.ids is not None else "first_id",
                f"puts ids from {min(ids)} to {max(ids)} on the board, beyond {self.dictionary}'s "
                f"0 to {size - 1}",
                "check the dictionary and the ids",
            )

    @classmethod
    def from_table(cls, table: object, where: str) -> BoardSpec:
        """From an untrusted TOML table (a pipeline's ``[target]``): every key checked.

        Keys (:data:`TABLE_KEYS`): ``kind`` (default ``charuco``), ``dictionary``
        (``DICT_5X5_100``), ``squares`` ([cols, rows]), ``square_m``, ``marker_m`` (m),
        ``first_id`` or ``ids``, ``legacy_pattern``. An unknown key is refused (a typo would
        otherwise silently keep a default).
        """
        if not isinstance(table, dict):
            raise BoardError(where, "the target", f"is a {type(table).__name__}", "give a table")
        unknown = sorted(str(k) for k in table if k not in TABLE_KEYS)
        if unknown:
            raise BoardError(
                where,
                "key " + unknown[0],
                "is not a target key",
                "use " + ", ".join(TABLE_KEYS),
            )
        t: dict[str, Any] = dict(table)
        kwargs: dict[str, Any] = {"where": where}
        for key in ("kind", "dictionary"):
            if key in t:
                if not isinstance(t[key], str):
                    raise BoardError(where, key, f"is {t[key]!r}", f"give {TABLE_KEYS[key]}")
                kwargs[key] = t[key]
        for key in ("square_m", "marker_m"):
            if key in t:
                kwargs[key] = t[key] if isinstance(t[key], (int, float)) else str(t[key])
        if "squares" in t:
            sq = t["squares"]
            kwargs["squares"] = tuple(sq) if isinstance(sq, list) else sq
        if "first_id" in t and "ids" in t:
            raise BoardError(where, "ids", "and first_id are both given", "give one of them")
        if "first_id" in t:
            kwargs["first_id"] = t["first_id"]
        if "ids" in t:
            ids = t["ids"]
            kwargs["ids"] = tuple(ids) if isinstance(ids, list) else ids
        if "legacy_pattern" in t:
            kwargs["legacy_pattern"] = t["legacy_pattern"]
        needed = ["squares", "square_m"]
        if kwargs.get("kind", "charuco") != "checkerboard":
            needed.append("marker_m")
        for key in needed:
            if key not in t:
                raise BoardError(where, key, "is missing", f"give {TABLE_KEYS[key]}")
        return cls(**kwargs)

    @property
    def marker_count(self) -> int:
        """How many markers the board carries (0 for a checkerboard)."""
        cols, rows = self.squares
        if self.kind == "charuco":
            return cols * rows // 2
        return cols * rows if self.kind == "aruco_grid" else 0

    @property
    def dictionary_size(self) -> int:
        """How many markers the dictionary holds (0 for a checkerboard)."""
        if self.kind == "checkerboard":
            return 0
        return int(
            cv2.aruco.getPredefinedDictionary(DICTIONARIES[self.dictionary]).bytesList.shape[0]
        )

    @property
    def marker_ids(self) -> NDArray[np.int32]:
        """The board's marker ids in order (n,)."""
        if self.ids is not None:
            return np.asarray(self.ids, dtype=np.int32)
        return np.arange(self.first_id, self.first_id + self.marker_count, dtype=np.int32)

    @property
    def size_m(self) -> tuple[float, float]:
        """The board's outer width and height in metres (the markers' extent for a grid)."""
        cols, rows = self.squares
        if self.kind == "aruco_grid":
            gap = self.square_m - self.marker_m
            return (cols * self.square_m - gap, rows * self.square_m - gap)
        return (cols * self.square_m, rows * self.square_m)

    def cv_board(self) -> cv2.aruco.Board:
        """The OpenCV board (``CharucoBoard`` or ``GridBoard``); a checkerboard has none."""
        if self.kind == "checkerboard":
            raise BoardError(
                self.where,
                "kind",
                "is checkerboard, which has no OpenCV board object",
                "use object_points",
            )
        dictionary = cv2.aruco.getPredefinedDictionary(DICTIONARIES[self.dictionary])
        ids = self.marker_ids.reshape(-1, 1)
        if self.kind == "charuco":
            board = cv2.aruco.CharucoBoard(
                self.squares, self.square_m, self.marker_m, dictionary, ids
            )
            board.setLegacyPattern(self.legacy_pattern)
            return board
        gap = self.square_m - self.marker_m
        return cv2.aruco.GridBoard(self.squares, self.marker_m, gap, dictionary, ids)

    def object_points(self) -> FloatArray:
        """The corners' positions (N, 3) in the board frame (m), row i the corner of id i."""
        cols, rows = self.squares
        if self.kind == "charuco":
            board = cast(cv2.aruco.CharucoBoard, self.cv_board())
            return np.asarray(board.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
        if self.kind == "aruco_grid":
            corners = self.cv_board().getObjPoints()
            return np.asarray(corners, dtype=np.float64).reshape(-1, 3)
        j, i = np.mgrid[1:rows, 1:cols]
        xy = np.stack([i.ravel(), j.ravel()], axis=1) * self.square_m
        return np.column_stack([xy, np.zeros(len(xy))])

    def image(
        self, px_per_m: float | None = None, *, width_px: int | None = None, margin_px: int = 20
    ) -> BoardImage:
        """The board drawn flat at ``px_per_m`` pixels a metre, or ``width_px`` pixels wide in
        all, with a white margin of ``margin_px`` on every side.

        ChArUco and ArUco boards are drawn by OpenCV (``Board.generateImage``); a
        checkerboard, which OpenCV does not draw, by filling its squares. The scale is rounded
        so that each square spans a whole number of pixels; ``image_from_board`` holds the one
        used (a board point (x, y) m lands at pixel ``margin + x·scale − ½``: pixel centres
        are whole numbers).
        """
        if (px_per_m is None) == (width_px is None):
            raise BoardError(self.where, "image", "needs px_per_m or width_px", "give one of them")
        if not isinstance(margin_px, int) or not 0 <= margin_px <= 10_000:
            raise BoardError(self.where, "margin_px", f"is {margin_px!r}", "give whole pixels")
        if width_px is not None:
            px_per_m = (width_px - 2 * margin_px) / self.size_m[0]
        assert px_per_m is not None
        if not (math.isfinite(px_per_m) and px_per_m > 0):
            raise BoardError(self.where, "px_per_m", f"is {px_per_m!r}", "give a positive scale")
        square_px = max(1, round(self.square_m * px_per_m))
        scale = square_px / self.square_m
        width_m, height_m = self.size_m
        w = round(width_m * scale)
        h = round(height_m * scale)
        if (w + 2 * margin_px) * (h + 2 * margin_px) > 100_000_000:
            raise BoardError(
                self.where, "px_per_m", f"{px_per_m:g} draws a huge image", "draw it smaller"
            )
        pixels: NDArray[np.uint8]
        if self.kind == "checkerboard":
            cols, rows = self.squares
            pixels = np.full((h + 2 * margin_px, w + 2 * margin_px), 255, dtype=np.uint8)
            cells = np.kron(
                (np.add.outer(np.arange(rows), np.arange(cols)) % 2).astype(np.uint8) * 255,
                np.ones((square_px, square_px), dtype=np.uint8),
            )
            pixels[margin_px : margin_px + h, margin_px : margin_px + w] = cells
        else:
            drawn = self.cv_board().generateImage(
                (w + 2 * margin_px, h + 2 * margin_px), marginSize=margin_px
            )
            pixels = np.asarray(drawn, dtype=np.uint8)
        H = np.array(
            [[scale, 0.0, margin_px - 0.5], [0.0, scale, margin_px - 0.5], [0.0, 0.0, 1.0]]
        )
        return BoardImage(np.ascontiguousarray(pixels, dtype=np.uint8), H)
