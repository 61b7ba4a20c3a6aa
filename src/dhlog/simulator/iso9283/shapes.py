"""The simulated robot's performance in time: the arrival's damped oscillation (the overshoot,
:func:`overshoot_shape`) and the stabilisation time it gives (:func:`stabilisation_truth`), and
the drift's warm-up (:func:`drift_shape`).
"""

from __future__ import annotations

import math

import numpy as np

from dhlog.geometry._checks import FloatArray


def overshoot_shape(t: FloatArray, frequency: float, damping: float) -> FloatArray:
    """The arrival's oscillation e^(−ζωt) sin(ωt) (0 before arrival, t < 0), divided by its
    peak: its largest value is 1, at t = atan(1/ζ)/ω."""
    w = 2.0 * math.pi * frequency
    t_peak = math.atan(1.0 / damping) / w
    peak = math.exp(-damping * w * t_peak) * math.sin(w * t_peak)
    shape = np.exp(-damping * w * np.maximum(t, 0.0)) * np.sin(w * np.maximum(t, 0.0)) / peak
    return np.asarray(np.where(t > 0, shape, 0.0), dtype=np.float64)


def stabilisation_truth(
    overshoot: float, frequency: float, damping: float, band: float, horizon: float = 60.0
) -> float:
    """The truth's stabilisation time (s after arrival) of the noise-free arrival of an
    ``overshoot`` (m) with this oscillation: the last instant its distance from the final
    position exceeds ``band`` (m), to 1 µs (0 when it never does)."""
    if overshoot <= band:
        return 0.0
    w = 2.0 * math.pi * frequency
    # beyond the envelope's crossing the oscillation stays within the band
    t_peak = math.atan(1.0 / damping) / w
    peak = math.exp(-damping * w * t_peak) * math.sin(w * t_peak)
    end = min(horizon, math.log(overshoot / (band * peak)) / (damping * w) + 1e-3)
    grid = np.arange(0.0, end, 1e-6)
    outside = np.flatnonzero(overshoot * np.abs(overshoot_shape(grid, frequency, damping)) > band)
    return float(grid[outside[-1]]) if outside.size else 0.0


def drift_shape(t: FloatArray, t0: float, tau: float, scale: float) -> FloatArray:
    """The drift's warm-up ``scale`` · (1 − e^(−(t − t₀)/τ)), 0 until t₀."""
    return np.asarray(-np.expm1(-np.maximum(t - t0, 0.0) / tau) * scale, dtype=np.float64)
