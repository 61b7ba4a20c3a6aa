"""The pinhole camera and its lens distortion, as ROS's ``CameraInfo`` and OpenCV describe it.

Points in the camera frame are in metres (x right, y down, z along the optical axis); image
coordinates are in pixels, the centre of the top-left pixel at (0, 0), as OpenCV has them.
Every projection goes through OpenCV (``cv2.projectPoints`` for the pinhole models,
``cv2.fisheye.projectPoints`` for the equidistant one), so what dhlog predicts is what OpenCV's
calibration, PnP and undistortion assume.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal, cast

import cv2
import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import FieldError
from dhlog.geometry._checks import FloatArray

DistortionModel = Literal["plumb_bob", "rational_polynomial", "equidistant"]

#: The coefficients each model takes, in ROS's and OpenCV's order.
COEFFICIENTS: dict[str, tuple[str, ...]] = {
    "plumb_bob": ("k1", "k2", "t1", "t2", "k3"),
    "rational_polynomial": ("k1", "k2", "t1", "t2", "k3", "k4", "k5", "k6"),
    "equidistant": ("k1", "k2", "k3", "k4"),
}

#: Other names of the models: Foxglove's ``CameraCalibration`` calls the fisheye model
#: ``kannala_brandt``; ROS's ``camera_calibration_parsers`` writes ``fisheye`` too.
ALIASES: dict[str, str] = {"kannala_brandt": "equidistant", "fisheye": "equidistant"}


class CameraError(FieldError):
    """Intrinsics that cannot describe a camera (a field missing, of the wrong size or value)."""


@dataclass(frozen=True)
class Intrinsics:
    """A camera's intrinsics: image size (px), camera matrix ``K`` (3×3, px) and lens distortion.

    ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` (no skew: OpenCV's projection has none).
    ``coefficients`` are the distortion model's, in its order (:data:`COEFFICIENTS`):
    ``plumb_bob`` (5: k1 k2 t1 t2 k3), ``rational_polynomial`` (8: k1 k2 t1 t2 k3 k4 k5 k6),
    ``equidistant`` (4: the fisheye k1..k4). Checked on construction: finite, ``fx, fy > 0``,
    the principal point inside the image, the model known and its coefficient count right;
    anything else raises :class:`CameraError` naming the field. ``where`` names the source
    (a file, a topic) in those messages and is not compared.
    """

    width: int
    height: int
    K: FloatArray
    model: DistortionModel
    coefficients: FloatArray
    where: str = field(default="intrinsics", compare=False)

    def __post_init__(self) -> None:
        w = self.where
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
                raise CameraError(
                    w,
                    name,
                    f"is {value!r}, not a positive whole number of pixels",
                    "give the image size",
                )
            object.__setattr__(self, name, int(value))
        K = _float_array(w, "K", self.K)
        if K.shape != (3, 3):
            raise CameraError(
                w, "K", f"has shape {K.shape}, not (3, 3)", "give the 3×3 camera matrix"
            )
        if not np.all(np.isfinite(K)):
            raise CameraError(w, "K", "holds NaN or infinite values", "give a finite camera matrix")
        if not np.any(K):
            raise CameraError(
                w,
                "K",
                "is all zeros (the CameraInfo of an uncalibrated camera)",
                "calibrate the camera and give its calibration file",
            )
        if K[0, 0] <= 0 or K[1, 1] <= 0:
            raise CameraError(
                w,
                "K",
                f"has focal lengths fx={K[0, 0]:g}, fy={K[1, 1]:g} px, not both > 0",
                "check the calibration",
            )
        if K[0, 1] != 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1:
            raise CameraError(
                w,
                "K",
                "is not of the form [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] "
                f"(got {K.ravel().tolist()})",
                "give a camera matrix without skew, its last row 0 0 1",
            )
        if not (0 <= K[0, 2] <= self.width and 0 <= K[1, 2] <= self.height):
            raise CameraError(
                w,
                "K",
                f"puts the principal point ({K[0, 2]:g}, {K[1, 2]:g}) px outside the "
                f"{self.width}×{self.height} image",
                "check the calibration belongs to this image size",
            )
        model = ALIASES.get(str(self.model), str(self.model))
        if model not in COEFFICIENTS:
            raise CameraError(
                w,
                "distortion model",
                f"{self.model!r} is not known",
                "use one of " + ", ".join(COEFFICIENTS),
            )
        d = _float_array(w, "distortion coefficients", self.coefficients).ravel()
        names = COEFFICIENTS[model]
        if d.size != len(names):
            raise CameraError(
                w,
                "distortion coefficients",
                f"are {d.size} for the {model} model, which takes {len(names)} ({' '.join(names)})",
                "give them all (zeros where not calibrated)",
            )
        if not np.all(np.isfinite(d)):
            raise CameraError(
                w,
                "distortion coefficients",
                "hold NaN or infinite values",
                "give finite coefficients",
            )
        K = K.copy()
        d = d.copy()
        K.flags.writeable = False
        d.flags.writeable = False
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "coefficients", d)
        object.__setattr__(self, "model", model)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Intrinsics):
            return NotImplemented
        return (
            (self.width, self.height, self.model) == (other.width, other.height, other.model)
            and bool(np.array_equal(self.K, other.K))
            and bool(np.array_equal(self.coefficients, other.coefficients))
        )

    def __hash__(self) -> int:
        return hash(
            (self.width, self.height, self.model, self.K.tobytes(), self.coefficients.tobytes())
        )

    @classmethod
    def from_camera_info(
        cls,
        width: int,
        height: int,
        distortion_model: str,
        d: Sequence[float] | ArrayLike,
        k: Sequence[float] | ArrayLike,
        *,
        where: str = "CameraInfo",
    ) -> Intrinsics:
        """From ROS ``sensor_msgs/msg/CameraInfo`` (or Foxglove ``CameraCalibration``) fields.

        ``k`` is the camera matrix row-major (9 values, px), ``d`` the distortion coefficients.
        An all-zero ``k`` — what an uncalibrated camera's driver publishes — is refused.
        """
        K = _float_array(where, "k", k).ravel()
        if K.size != 9:
            raise CameraError(
                where, "k", f"has {K.size} values, not 9", "give the 3×3 camera matrix row-major"
            )
        return cls(
            width,
            height,
            K.reshape(3, 3),
            cast(DistortionModel, distortion_model),
            _float_array(where, "d", d),
            where,
        )

    @classmethod
    def from_yaml_text(cls, text: str, where: str) -> Intrinsics:
        """From a calibration file's text: ROS's ``camera_info`` YAML or OpenCV's own YAML/XML.

        Read by OpenCV's ``cv2.FileStorage`` from memory (PyYAML is not a dependency of dhlog);
        it reads ROS's ``camera_calibration_parsers`` files (``image_width``, ``image_height``,
        ``camera_matrix: {rows, cols, data}``, ``distortion_model``,
        ``distortion_coefficients: {…, data}``) and OpenCV's (``!!opencv-matrix`` nodes, as
        ``cv2.FileStorage.write`` and OpenCV's calibration sample write them). Without a
        ``distortion_model`` key the count decides, as OpenCV's own meaning of it: 4 or 5
        coefficients are ``plumb_bob`` (k3 = 0 when 4), 8 ``rational_polynomial``; a fisheye
        calibration must say ``distortion_model: equidistant``.
        """
        try:
            fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
            opened = fs.isOpened()
        except (cv2.error, SystemError, ValueError, TypeError) as exc:
            cause = str(exc.__cause__ or exc).strip().splitlines() or [type(exc).__name__]
            why = cause[-1].split("error: ")[-1][:120]
            raise CameraError(
                where,
                "the text",
                f"is not YAML or XML OpenCV can read ({why})",
                "give a camera calibration file",
            ) from None
        if not opened:
            raise CameraError(
                where, "the text", "is empty or unreadable", "give a camera calibration file"
            )
        width = _scalar(fs, where, "image_width")
        height = _scalar(fs, where, "image_height")
        K = _matrix(fs, where, "camera_matrix")
        d = _matrix(fs, where, "distortion_coefficients")
        model_node = fs.getNode("distortion_model")
        if model_node.empty():
            model = {4: "plumb_bob", 5: "plumb_bob", 8: "rational_polynomial"}.get(d.size)
            if model is None:
                raise CameraError(
                    where,
                    "distortion_model",
                    f"is missing and {d.size} coefficients do not say which model",
                    "add distortion_model: plumb_bob, rational_polynomial or equidistant",
                )
            if d.size == 4:
                d = np.append(d, 0.0)
        elif model_node.isString():
            model = model_node.string()
        else:
            raise CameraError(
                where,
                "distortion_model",
                "is not a name",
                "write plumb_bob, rational_polynomial or equidistant",
            )
        if width != int(width) or height != int(height):
            raise CameraError(
                where,
                "image_width/image_height",
                "are not whole numbers",
                "give the image size in pixels",
            )
        return cls.from_camera_info(int(width), int(height), model, d, K, where=where)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels, as OpenCV takes an image size."""
        return (self.width, self.height)

    def project(self, points_cam: ArrayLike) -> FloatArray:
        """Pixels (m, 2) of points (m, 3) in the camera frame (m), through the lens model.

        A point at or behind the camera's plane (z ≤ 0) has no image: its row is NaN.
        """
        return self._project(points_cam, jacobian=False)[0]

    def project_jacobian(self, points_cam: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Pixels (m, 2) with their derivatives, from OpenCV's own Jacobian of the projection.

        Returns ``(uv, d_uv_d_point, d_uv_d_intrinsics)``: ``d_uv_d_point`` (m, 2, 3) in px/m,
        with respect to the point in the camera frame; ``d_uv_d_intrinsics`` (m, 2, 4 + n) with
        respect to ``fx, fy, cx, cy`` and the model's n coefficients in their order. Rows of
        points with z ≤ 0 are NaN.
        """
        uv, jac_p, jac_i = self._project(points_cam, jacobian=True)
        assert jac_p is not None and jac_i is not None
        return uv, jac_p, jac_i

    def _project(
        self, points_cam: ArrayLike, *, jacobian: bool
    ) -> tuple[FloatArray, FloatArray | None, FloatArray | None]:
        P = np.asarray(points_cam, dtype=np.float64)
        if P.ndim != 2 or P.shape[1] != 3:
            raise CameraError(
                self.where,
                "points",
                f"have shape {P.shape}, not (m, 3)",
                "give points in the camera frame",
            )
        m = P.shape[0]
        n = self.coefficients.size
        uv = np.full((m, 2), np.nan)
        jp = np.full((m, 2, 3), np.nan) if jacobian else None
        ji = np.full((m, 2, 4 + n), np.nan) if jacobian else None
        ok = np.isfinite(P).all(axis=1) & (P[:, 2] > 0)
        if not ok.any():
            return uv, jp, ji
        Q = np.ascontiguousarray(P[ok])
        zero = np.zeros(3)
        if self.model == "equidistant":
            # The fisheye projection's Jacobian columns: fx fy, cx cy, k1..k4, rvec, tvec, alpha.
            img, J = cv2.fisheye.projectPoints(
                Q.reshape(1, -1, 3), zero, zero, self.K, self.coefficients
            )
            uv[ok] = img.reshape(-1, 2)
            if jacobian:
                J = np.asarray(J).reshape(-1, 2, 15)
                assert jp is not None and ji is not None
                jp[ok] = J[:, :, 11:14]
                ji[ok] = J[:, :, 0:8]
        else:
            # The pinhole projection's Jacobian columns: rvec, tvec, fx fy, cx cy, coefficients.
            # With the pose at the identity, d(uv)/d(tvec) is d(uv)/d(point).
            img, J = cv2.projectPoints(Q, zero, zero, self.K, self.coefficients)
            uv[ok] = img.reshape(-1, 2)
            if jacobian:
                J = np.asarray(J).reshape(-1, 2, 10 + n)
                assert jp is not None and ji is not None
                jp[ok] = J[:, :, 3:6]
                ji[ok] = J[:, :, 6 : 10 + n]
        return uv, jp, ji


def _float_array(where: str, name: str, value: object) -> FloatArray:
    try:
        return np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CameraError(where, name, "is not an array of numbers", "give numbers") from None


def _scalar(fs: cv2.FileStorage, where: str, key: str) -> float:
    node = fs.getNode(key)
    if node.empty() or not (node.isReal() or node.isInt()):
        raise CameraError(where, key, "is missing or not a number", f"add {key} (pixels)")
    value = float(node.real())
    if not math.isfinite(value) or value <= 0:
        raise CameraError(where, key, f"is {value:g}", "give the image size in pixels")
    return value


def _matrix(fs: cv2.FileStorage, where: str, key: str) -> FloatArray:
    node = fs.getNode(key)
    if node.empty():
        raise CameraError(where, key, "is missing", f"add {key} to the calibration file")
    if node.isMap():
        data = node.getNode("data")  # ROS's {rows, cols, data}; OpenCV's !!opencv-matrix adds dt
        if not node.getNode("dt").empty():
            try:
                return np.asarray(node.mat(), dtype=np.float64).ravel()
            except (cv2.error, SystemError, TypeError, ValueError):
                raise CameraError(
                    where, key, "is a matrix OpenCV cannot read", "check its rows, cols and data"
                ) from None
        node = data
    if not node.isSeq():
        raise CameraError(
            where, key, "has no list of numbers (data: [...])", "write its values under data"
        )
    values = []
    for i in range(node.size()):
        item = node.at(i)
        if not (item.isReal() or item.isInt()):
            raise CameraError(where, f"{key}.data[{i}]", "is not a number", "write numbers only")
        values.append(float(item.real()))
    return np.asarray(values, dtype=np.float64)


def planar_pose(
    obj: FloatArray, img: FloatArray, K: FloatArray, D: FloatArray
) -> tuple[FloatArray, FloatArray] | None:
    """A planar board's pose in the camera from its points ``obj`` (k, 3, m) seen at ``img``
    (k, 1, 2, px) through ``K``, ``D``: OpenCV's IPPE, refined by Levenberg–Marquardt; the
    rotation (3×3) and translation (3,), or None where OpenCV finds none."""
    try:
        ok, rvec, tvec = cv2.solvePnP(obj, img, K, D, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            return None
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, D, rvec, tvec)
    except cv2.error:
        return None
    R = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
    return R, np.asarray(tvec, dtype=np.float64).ravel()
