"""Noise models of the measured target positions, as per-sample whitening.

The whole-model fit weighs each residual ``r = p_measured − p_model`` (m, 3) by ``W`` with
``WᵀW = C⁻¹`` for the sample's covariance ``C``:

* ``isotropic``: ``C = σ² I`` (the default; σ estimated from the per-joint fits);
* ``tracker``: a laser tracker's specification: a radial (ranging) standard deviation along the
  line of sight from the tracker station and a transverse (angular) one perpendicular to it that
  grows with the distance, ``σ_t = transverse + transverse_per_m · distance``, so
  ``C = σ_r² ûûᵀ + σ_t² (I − ûûᵀ)`` with ``û`` the unit line of sight;
* per-sample covariances carried by the log (three standard deviations or full 3×3 matrices).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray


@dataclass(frozen=True)
class NoiseModel:
    """How the target positions scatter: ``model`` is ``isotropic`` or ``tracker`` (metres)."""

    model: str = "isotropic"
    sigma: float | None = None
    radial: float = 10e-6
    transverse: float = 15e-6
    transverse_per_m: float = 6e-6
    station: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: float | None = None
    #: the isotropic σ (m) of what the model leaves beyond the declared uncertainties (gravity,
    #: gears), estimated and added to every sample's covariance; None when not needed
    model_error: float | None = None

    def __post_init__(self) -> None:
        if self.model not in ("isotropic", "tracker", "per-sample"):
            raise InputError(
                f"noise model '{self.model}' is not known; use 'isotropic' or 'tracker'."
            )
        values = [self.radial, self.transverse, self.transverse_per_m]
        if self.sigma is not None:
            values.append(self.sigma)
        if self.orientation is not None:
            values.append(self.orientation)
        if not all(np.isfinite(v) and v >= 0 for v in values) or (
            self.model == "tracker" and (self.radial <= 0 or self.transverse <= 0)
        ):
            raise InputError(
                "the [noise] section needs positive standard deviations (m): radial, "
                "transverse, and transverse_per_m >= 0."
            )

    @property
    def described(self) -> str:
        """One line for the console and the result."""
        base = self.declared
        if self.model_error is None:
            return base
        return f"{base} + model error σ {self.model_error * 1e3:.4f} mm per coordinate"

    @property
    def declared(self) -> str:
        """The declared model alone, without the estimated model error."""
        if self.model == "per-sample":
            return "per-sample covariance from the log"
        if self.model == "tracker":
            return (
                f"tracker (radial {self.radial * 1e6:.1f} µm, transverse "
                f"{self.transverse * 1e6:.1f} µm + {self.transverse_per_m * 1e6:.1f} µm/m, "
                f"station {list(self.station)})"
            )
        return "isotropic"

    def whiten(self, points: FloatArray, sigma: float) -> FloatArray | float:
        """The whitening of samples at ``points`` (m, 3): a scalar ``1/σ`` for the isotropic model
        (``σ`` given), else ``W`` (m, 3, 3) with ``WᵀW = C⁻¹``."""
        if self.model == "isotropic":
            s = self.sigma if self.sigma is not None else sigma
            if not (s > 0.0 and math.isfinite(s)):  # NaN too
                raise InputError(
                    f"the isotropic noise σ is {s:g} m, so the samples cannot be weighed by it "
                    "(the data scatter by nothing, or the noise was given as 0); give a "
                    "positive [noise] sigma (m) in the pipeline."
                )
            return 1.0 / s
        uu, s_t = self._line_of_sight(points)
        eye = np.eye(3)[None]
        return np.asarray(uu / self.radial + (eye - uu) / s_t[:, None, None], dtype=np.float64)

    def covariance(self, points: FloatArray) -> FloatArray:
        """The tracker model's covariance (m, 3, 3) of samples at ``points`` (m, 3)."""
        uu, s_t = self._line_of_sight(points)
        eye = np.eye(3)[None]
        return np.asarray(
            uu * self.radial**2 + (eye - uu) * (s_t**2)[:, None, None], dtype=np.float64
        )

    def _line_of_sight(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Per sample, ``ûûᵀ`` (m, 3, 3) of the unit line of sight from the station and the
        transverse σ at its distance (m,)."""
        rel = points - np.asarray(self.station)
        dist = np.linalg.norm(rel, axis=1)
        u = rel / np.maximum(dist, 1e-9)[:, None]
        return u[:, :, None] * u[:, None, :], self.transverse + self.transverse_per_m * dist

    def document(self) -> dict[str, object]:
        """The noise model's parameters for the result JSON."""
        doc: dict[str, object] = {}
        if self.model == "tracker":
            doc = {
                "radial": self.radial,
                "transverse": self.transverse,
                "transverse_per_m": self.transverse_per_m,
                "station": list(self.station),
            }
        if self.model_error is not None:
            doc["model_error_sigma"] = self.model_error
        return doc


def whitening_from_std(std: FloatArray) -> FloatArray:
    """Whitening (m, 3, 3) of per-sample covariances given as standard deviations (m, 3) along
    the measurement axes, or as full matrices (m, 3, 3)."""
    if std.ndim == 2:
        W = np.zeros((std.shape[0], 3, 3))
        idx = np.arange(3)
        W[:, idx, idx] = 1.0 / std
        return W
    L = np.linalg.cholesky(std)  # C = L Lᵀ → W = L⁻¹
    return np.asarray(np.linalg.inv(L), dtype=np.float64)


def model_error_sigma(residuals: FloatArray, cov: FloatArray, dof: int) -> float:
    """The isotropic model-error σ (m) that, added to every sample's covariance
    (``C_i + σ² I``), makes the weighted residuals' χ² equal ``dof`` (the method of moments of a
    variance component): ``residuals`` (m, 3), ``cov`` (m, 3, 3). 0 when χ² is already at most
    ``dof``."""
    from scipy.optimize import brentq

    e, U = np.linalg.eigh(cov)
    z2 = np.einsum("mij,mi->mj", U, residuals) ** 2  # the residual along each eigenvector

    def excess(s2: float) -> float:
        return float(np.sum(z2 / (e + s2))) - dof

    if excess(0.0) <= 0:
        return 0.0
    hi = float(np.max(np.sum(residuals**2, axis=1))) + float(np.max(e))
    while excess(hi) > 0:
        hi *= 4.0
    return float(np.sqrt(brentq(excess, 0.0, hi, xtol=1e-30, rtol=1e-10)))
