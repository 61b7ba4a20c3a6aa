"""A camera calibration's product as the result carries it: :class:`CameraResult` (the set-up, the
fixed and mounted parts' poses with σ, the corners' σ) and :class:`PixelHoldout` (the held-out
check in pixels and mm), each with its JSON block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dhlog.geometry._checks import FloatArray
from dhlog.vision.camera import Intrinsics


@dataclass(frozen=True)
class PixelHoldout:
    """The error at frames not used to fit (K-fold over the frames' poses): reprojection RMS
    (px, per corner: the 2-D norm) of the nominal placed on the training frames and of the
    result; and the 3-D RMS (mm) of the board's corners in the camera between the model and
    the held-out frame's own PnP pose (the result's triangulation)."""

    folds: int
    frames: int
    nominal_px: float | None
    calibrated_px: float
    nominal_mm: float | None
    calibrated_mm: float
    fit_px: float
    #: the RMS the held-out frames' own PnP poses are expected to miss the corners by (their
    #: noise at the corners' σ, independent corners; mm): the floor of the mm figures
    pnp_noise_mm: float = math.nan
    #: the same mm figure in sample: the model fitted to every frame against the frames' PnP
    #: poses (what the PnP poses' own errors give when the model is not held out, correlated
    #: corner errors included)
    fit_mm: float = math.nan
    notes: tuple[str, ...] = ()

    @property
    def model_mm(self) -> float:
        """The calibrated mm figure with the PnP noise taken out (quadrature; 0 when within it)."""
        return math.sqrt(max(self.calibrated_mm**2 - self.pnp_noise_mm**2, 0.0))

    def document(self) -> dict[str, object]:
        return {
            "folds": self.folds,
            "frames": self.frames,
            "reprojection_rms_px": {"nominal": self.nominal_px, "calibrated": self.calibrated_px},
            "target_rms_mm": {
                "nominal": self.nominal_mm,
                "calibrated": self.calibrated_mm,
                "pnp_noise": _finite(self.pnp_noise_mm),
                "in_sample": _finite(self.fit_mm),
                "calibrated_beyond_noise": _finite(self.model_mm),
            },
            "in_sample_rms_px": self.fit_px,
            "notes": list(self.notes),
        }


@dataclass(frozen=True)
class CameraResult:
    """One camera's product: the set-up, the intrinsics (held or refined, with σ), the fixed
    part's pose in the robot's base frame and the mounted part's on the flange (4×4, m) with
    their σ (rotation vector rad, translation m; 6 each), the corners' σ and RMS (px), the
    frames' tally, and the held-out check."""

    name: str
    setup: str
    intrinsics: Intrinsics
    intrinsics_refined: bool
    intrinsics_std: FloatArray | None
    T_base_fixed: FloatArray
    fixed_std: FloatArray
    T_flange_mounted: FloatArray
    mounted_std: FloatArray
    sigma_px: float
    rms_px: float
    frames: int
    corners: int
    inlier_corners: int
    tally: str
    setup_reason: str
    holdout: PixelHoldout | None = None

    @property
    def fixed_name(self) -> str:
        return "T_base_camera" if self.setup == "eye-to-hand" else "T_base_board"

    @property
    def mounted_name(self) -> str:
        return "T_flange_board" if self.setup == "eye-to-hand" else "T_flange_camera"

    def document(self) -> dict[str, object]:
        c = self.intrinsics
        return {
            "topic": self.name,
            "setup": self.setup,
            "setup_reason": self.setup_reason,
            self.fixed_name: self.T_base_fixed.tolist(),
            f"{self.fixed_name}_std": _std_doc(self.fixed_std),
            self.mounted_name: self.T_flange_mounted.tolist(),
            f"{self.mounted_name}_std": _std_doc(self.mounted_std),
            "intrinsics": {
                "width": c.width,
                "height": c.height,
                "K": c.K.tolist(),
                "distortion_model": c.model,
                "D": c.coefficients.tolist(),
                "refined": self.intrinsics_refined,
                "std": None if self.intrinsics_std is None else self.intrinsics_std.tolist(),
            },
            "corner_sigma_px": self.sigma_px,
            "reprojection_rms_px": self.rms_px,
            "frames": self.frames,
            "corners": self.corners,
            "inlier_corners": self.inlier_corners,
            "detections": self.tally,
            "holdout": None if self.holdout is None else self.holdout.document(),
        }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _std_doc(std: FloatArray) -> dict[str, list[float]]:
    return {"rotation_rad": std[:3].tolist(), "translation_m": std[3:].tolist()}
