"""ISO 9283:1998 pose stabilisation time and overshoot (7.4, 7.5) of one arrival on plain arrays,
and over the cycles of a pose; the band and which deviation is the overshoot are the choices
docs/iso9283.md ("The formulas") lists.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import Iso9283Error, NonFiniteError, ShapeError
from dhlog.iso9283.formulas.checks import (
    _finite,
    _points,
    _vector,
)


@dataclass(frozen=True)
class Stabilisation:
    """One arrival's pose stabilisation time (ISO 9283:1998, 7.4) and overshoot (7.5):
    ``time`` (s) from the attained-pose signal until the position stays within ``band`` (m) of
    the attained position (from ``settled_at``, s), ``overshoot`` (m) past the attained
    position along the approach direction (0 when the approach does not go past), and
    ``excursion`` (m), the largest distance from the attained position after the first crossing
    of the band (at ``entered_at``, s; in any direction, not a characteristic of the standard:
    shown beside it)."""

    time: float
    overshoot: float
    excursion: float
    band: float
    settled_at: float
    entered_at: float

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (s, m)."""
        return {
            "time_s": self.time,
            "overshoot_m": self.overshoot,
            "excursion_m": self.excursion,
            "band_m": self.band,
            "settled_at_s": self.settled_at,
            "entered_at_s": self.entered_at,
        }


def stabilisation(
    t: ArrayLike,
    p: ArrayLike,
    final: ArrayLike,
    arrival_t: float,
    *,
    band: float,
) -> Stabilisation:
    """Pose stabilisation time (ISO 9283:1998, 7.4) and pose overshoot (7.5) of one arrival,
    from the measured positions ``p`` (k, 3) at the times ``t`` (k,) (s, increasing) of the
    approach and what follows, the attained (settled) position ``final`` (3,) and the instant
    ``arrival_t`` (s) of the robot's attained-pose signal (the end of the commanded motion).
    The samples must begin on the approach, outside the band.

    With d_i = |p_i − final| and u the approach direction, the unit vector from the first
    sample to ``final``:

    - stabilisation time = t_s − arrival_t (0 if negative), where t_s is the first sample time
      from which every later sample lies within the limit band, d_i ≤ ``band``. The standard
      leaves the band to the manufacturer: the caller states it (m).
    - overshoot OV = max(0, max_i D_i), D_i = (p_i − final) · u: the largest deviation past
      the attained position along the approach, zero when the robot never goes past (the
      standard's OV_j = max D_ij if max D_ij > 0, else 0; "the maximum deviation between the
      approach path and the attained pose after the robot first crosses the limit band": the
      samples before the crossing are behind the band, D_i < −band, so they never set the
      maximum — a crossing between two samples counts, too).
    - excursion = max d_i over the samples from the first crossing on (the first with
      d_i ≤ band or D_i ≥ −band): the largest distance in any direction, shown beside OV.

    The resolution of both times is the sample period (no interpolation between samples). The
    standard measures three cycles per pose; see :func:`stabilisation_over_cycles`.
    """
    what = "pose stabilisation"
    tt = _finite(f"{what}: times", np.asarray(t, dtype=np.float64))
    pts = _points(f"{what}: positions", p, at_least=2, unit="samples")
    if tt.shape != (len(pts),):
        raise ShapeError(f"{what}: times", f"one time per position, ({len(pts)},)", tt.shape)
    if np.any(np.diff(tt) <= 0.0):
        raise Iso9283Error(what, "the sample times do not increase", "sort the samples by time")
    fin = _vector(f"{what}: attained position", final)
    if not np.isfinite(arrival_t):
        raise NonFiniteError(f"{what}: arrival time", 1)
    if not (np.isfinite(band) and band > 0.0):
        raise Iso9283Error(what, f"the limit band {band!r} m is not positive", "give band > 0 m")
    d = np.linalg.norm(pts - fin, axis=1)
    if d[0] <= band:
        raise Iso9283Error(
            what,
            f"the first sample (t = {tt[0]:.6g} s) is already within the band "
            f"({d[0] * 1e3:.4g} mm of the attained position, band {band * 1e3:.4g} mm), so the "
            "approach is not in the samples",
            "give the samples from before the robot reaches the band",
        )
    inside = d <= band
    if not inside[-1]:
        raise Iso9283Error(
            what,
            f"the position is still {d[-1] * 1e3:.4g} mm from the attained position at the last "
            f"sample (t = {tt[-1]:.6g} s; band {band * 1e3:.4g} mm)",
            "give the samples until the robot has settled, or a wider band",
        )
    outside = np.flatnonzero(~inside)
    settled_at = float(tt[int(outside[-1]) + 1])
    u = (fin - pts[0]) / d[0]
    D = (pts - fin) @ u
    crossed = inside | (D >= -band)
    entry = int(np.argmax(crossed))
    return Stabilisation(
        time=max(0.0, settled_at - float(arrival_t)),
        overshoot=max(0.0, float(D.max())),
        excursion=float(d[entry:].max()),
        band=float(band),
        settled_at=settled_at,
        entered_at=float(tt[entry]),
    )


def stabilisation_over_cycles(arrivals: Sequence[Stabilisation]) -> dict[str, float]:
    """The stabilisation time and overshoot of one pose over its measured cycles (ISO 9283
    measures three): their means (``time_mean_s``, ``overshoot_mean_m``) and maxima
    (``time_max_s``, ``overshoot_max_m``)."""
    if not arrivals:
        raise Iso9283Error(
            "pose stabilisation", "no arrival was measured", "record the arrivals at >= 100 Hz"
        )
    times = np.array([a.time for a in arrivals])
    ovs = np.array([a.overshoot for a in arrivals])
    return {
        "cycles": float(len(arrivals)),
        "time_mean_s": float(times.mean()),
        "time_max_s": float(times.max()),
        "overshoot_mean_m": float(ovs.mean()),
        "overshoot_max_m": float(ovs.max()),
    }
