"""The certificate's camera section: a camera calibration's ``camera`` block read
untrusted (:func:`read_camera`, through the report's :class:`~dhlog.result.fields.FieldReader`:
a fault a :class:`~dhlog.present.certificate.read.ResultFileError` naming the field) and shown
(:func:`camera_section`: the set-up, the detections, the hand-eye poses ±1σ, the intrinsics and
the corners' σ; :func:`camera_accuracy`: the held-out check in pixels and mm). SI units inside
except where the JSON is in px or mm; mm and degrees on the page, as the console shows them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dhlog.geometry._checks import roll_pitch_yaw
from dhlog.result.fields import FieldReader

#: The poses a set-up writes: (the fixed part's in the base frame, the mounted part's on the
#: flange), and what each is.
POSES = {
    "eye-to-hand": (
        ("T_base_camera", "the camera in the robot's base frame"),
        ("T_flange_board", "the board on the flange"),
    ),
    "eye-in-hand": (
        ("T_base_board", "the board in the robot's base frame"),
        ("T_flange_camera", "the camera on the flange"),
    ),
}
SETUPS = {
    "eye-to-hand": "eye-to-hand: the camera fixed in the cell, the board on the flange",
    "eye-in-hand": "eye-in-hand: the camera on the flange, the board fixed in the cell",
}
#: The lens coefficients' names in ``D``, by distortion model (OpenCV's order).
LENS = {
    "plumb_bob": ("k1", "k2", "p1", "p2", "k3"),
    "rational_polynomial": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
    "equidistant": ("k1", "k2", "k3", "k4"),
}
#: How far from a rotation the 3×3 part of a pose may be (rounding of the JSON's digits).
ROTATION_TOLERANCE = 1e-6


@dataclass(frozen=True)
class CameraPose:
    """A pose of the hand-eye product: ``name`` (``T_base_camera``, …), what it is, its
    translation (m) and roll, pitch, yaw (rad; ``R = Rz(yaw) Ry(pitch) Rx(roll)``), and the
    σ of the translation (m) and of a small rotation about the parent frame's x, y, z (rad;
    None: unknown)."""

    name: str
    what: str
    translation: list[float]
    rpy: list[float]
    translation_std: list[float | None]
    rotation_std: list[float | None]


@dataclass(frozen=True)
class CameraHoldout:
    """The held-out check of ``camera.holdout``: reprojection RMS (px) and the board's corners'
    3-D RMS (mm, as the JSON has them) of the nominal (None: none given) and the result, the
    in-sample figures, the PnP noise, the calibrated figure beyond it, and the notes."""

    folds: int
    frames: int
    nominal_px: float | None
    calibrated_px: float
    in_sample_px: float
    nominal_mm: float | None
    calibrated_mm: float
    pnp_noise_mm: float | None
    in_sample_mm: float | None
    beyond_noise_mm: float | None
    notes: list[str]


@dataclass(frozen=True)
class CameraShown:
    """What the certificate shows of a result's ``camera`` block, every field checked."""

    topic: str
    setup: str
    setup_reason: str
    fixed: CameraPose
    mounted: CameraPose
    width: int
    height: int
    K: list[list[float]]
    distortion_model: str
    D: list[float]
    refined: bool
    intrinsics_std: list[float | None] | None
    corner_sigma_px: float
    reprojection_rms_px: float
    frames: int
    corners: int
    inlier_corners: int
    detections: str
    holdout: CameraHoldout | None


# ---------------------------------------------------------------------------------------------
# reading


def _pose(f: FieldReader, block: dict[str, Any], name: str, what: str) -> CameraPose:
    """``camera.<name>`` (a rigid 4×4, m) and ``camera.<name>_std`` (``rotation_rad``,
    ``translation_m``; entries may be null)."""
    at = f"camera.{name}"
    rows = f.array(f.get(block, name, "camera", null=True), at)
    if len(rows) != 4:
        f.fail(at, f"must be a 4×4 matrix, not {len(rows)} rows")
    T = np.array([f.vector(r, f"{at}[{k}]", 4) for k, r in enumerate(rows)], dtype=np.float64)
    R = T[:3, :3]
    if (
        np.max(np.abs(R.T @ R - np.eye(3))) > ROTATION_TOLERANCE
        or np.linalg.det(R) <= 0
        or np.max(np.abs(T[3] - [0.0, 0.0, 0.0, 1.0])) > ROTATION_TOLERANCE
    ):
        f.fail(at, "must be a rigid transform (a rotation, a translation, last row 0 0 0 1)")
    for k in range(3):
        f.number(T[k, 3], f"{at}[{k}][3]", "length")
    std_at = f"{at}_std"
    std = f.get_obj(block, f"{name}_std", "camera")
    assert std is not None
    rot = f.vector(
        f.get(std, "rotation_rad", std_at, null=True), f"{std_at}.rotation_rad", 3, null=True
    )
    tr = f.vector(
        f.get(std, "translation_m", std_at, null=True), f"{std_at}.translation_m", 3, null=True
    )
    for key, values in (("rotation_rad", rot), ("translation_m", tr)):
        for k, v in enumerate(values):
            if v is not None and v < 0:
                f.fail(f"{std_at}.{key}[{k}]", f"is {v:.6g}; a standard deviation is not negative")
    return CameraPose(name, what, [float(v) for v in T[:3, 3]], list(roll_pitch_yaw(R)), tr, rot)


def _boolean(f: FieldReader, parent: dict[str, Any], key: str, at: str) -> bool:
    value = f.get(parent, key, at, null=True)
    if not isinstance(value, bool):
        f.mismatch(value, f"{at}.{key}", "true or false")
    return value


def _holdout(f: FieldReader, block: dict[str, Any]) -> CameraHoldout | None:
    raw = f.get(block, "holdout", "camera", null=True)
    if raw is None:
        return None
    at = "camera.holdout"
    h = f.obj(raw, at)
    folds = f.integer(f.get(h, "folds", at, null=True), f"{at}.folds", minimum=2)
    frames = f.integer(f.get(h, "frames", at, null=True), f"{at}.frames", minimum=1)
    px = f.get_obj(h, "reprojection_rms_px", at)
    mm_ = f.get_obj(h, "target_rms_mm", at)
    assert px is not None and mm_ is not None
    px_at, mm_at = f"{at}.reprojection_rms_px", f"{at}.target_rms_mm"

    def optional(parent: dict[str, Any], key: str, where: str) -> float | None:
        # written as null where not computed (no nominal, NaN): present, may be null
        return f.get_number(parent, key, where, null=True, minimum=0.0)

    def required(parent: dict[str, Any], key: str, where: str) -> float:
        value = f.get_number(parent, key, where, minimum=0.0)
        assert value is not None
        return value

    notes = f.get(h, "notes", at, null=True)
    return CameraHoldout(
        folds,
        frames,
        optional(px, "nominal", px_at),
        required(px, "calibrated", px_at),
        required(h, "in_sample_rms_px", at),
        optional(mm_, "nominal", mm_at),
        required(mm_, "calibrated", mm_at),
        optional(mm_, "pnp_noise", mm_at),
        optional(mm_, "in_sample", mm_at),
        f.get_number(mm_, "calibrated_beyond_noise", mm_at, required=False, minimum=0.0),
        [] if notes is None else f.texts(notes, f"{at}.notes"),
    )


def read_camera(f: FieldReader, doc: dict[str, Any]) -> CameraShown | None:
    """The result's ``camera`` block checked field by field (None: a tracker's result)."""
    block = f.get_obj(doc, "camera", required=False)
    if block is None:
        return None
    at = "camera"
    topic = f.get_text(block, "topic", at)
    setup = f.get_text(block, "setup", at)
    assert topic is not None and setup is not None
    if setup not in POSES:
        f.fail(f"{at}.setup", f"must be eye-to-hand or eye-in-hand, not {setup[:40]!r}")
    reason = f.get_text(block, "setup_reason", at) or ""
    (fixed_name, fixed_what), (mounted_name, mounted_what) = POSES[setup]
    fixed = _pose(f, block, fixed_name, fixed_what)
    mounted = _pose(f, block, mounted_name, mounted_what)
    ia = f"{at}.intrinsics"
    intr = f.get_obj(block, "intrinsics", at)
    assert intr is not None
    width = f.integer(f.get(intr, "width", ia, null=True), f"{ia}.width", minimum=1)
    height = f.integer(f.get(intr, "height", ia, null=True), f"{ia}.height", minimum=1)
    k_rows = f.array(f.get(intr, "K", ia, null=True), f"{ia}.K")
    if len(k_rows) != 3:
        f.fail(f"{ia}.K", f"must be a 3×3 matrix, not {len(k_rows)} rows")
    K = [[float(v or 0.0) for v in f.vector(r, f"{ia}.K[{k}]", 3)] for k, r in enumerate(k_rows)]
    if K[0][0] <= 0 or K[1][1] <= 0:
        f.fail(f"{ia}.K", "must have positive focal lengths K[0][0] and K[1][1]")
    model = f.get_text(intr, "distortion_model", ia) or ""
    if model not in LENS:
        f.fail(f"{ia}.distortion_model", f"must be one of {', '.join(LENS)}, not {model[:40]!r}")
    D = [
        f.number(v, f"{ia}.D[{k}]")
        for k, v in enumerate(f.array(f.get(intr, "D", ia, null=True), f"{ia}.D", most=16))
    ]
    refined = _boolean(f, intr, "refined", ia)
    std_raw = f.get(intr, "std", ia, required=False)
    std = None
    if std_raw is not None:
        std = f.vector(std_raw, f"{ia}.std", 4 + len(D), null=True)
        for k, v in enumerate(std):
            if v is not None and v < 0:
                f.fail(f"{ia}.std[{k}]", f"is {v:.6g}; a standard deviation is not negative")
    sigma = f.get_number(block, "corner_sigma_px", at, minimum=0.0)
    rms = f.get_number(block, "reprojection_rms_px", at, minimum=0.0)
    counts = [
        f.integer(f.get(block, key, at, null=True), f"{at}.{key}", minimum=0)
        for key in ("frames", "corners", "inlier_corners")
    ]
    if counts[2] > counts[1]:
        f.fail(f"{at}.inlier_corners", f"is {counts[2]}, more than the {counts[1]} corners")
    detections = f.get_text(block, "detections", at) or ""
    assert sigma is not None and rms is not None
    return CameraShown(
        topic,
        setup,
        reason,
        fixed,
        mounted,
        width,
        height,
        K,
        model,
        D,
        refined,
        std,
        sigma,
        rms,
        counts[0],
        counts[1],
        counts[2],
        detections,
        _holdout(f, block),
    )
