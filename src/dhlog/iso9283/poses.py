"""The pose characteristics of an ISO 9283 test from its visits, through
:mod:`dhlog.iso9283.formulas`: accuracy with its σ (clause 7.2.1), repeatability of position
and orientation (7.2.2), multi-directional variation (7.2.3), distance accuracy and
repeatability between :data:`DISTANCE_POSES` (7.3), stabilisation time and overshoot judged on
positions averaged over :data:`STABILISATION_PERIOD` (7.4, 7.5) and drift at :data:`DRIFT_POSE`
(7.6).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.baseframe import _moved
from dhlog.iso9283.cycles import SAME_DIRECTION, Segmented
from dhlog.iso9283.dwells import Visit
from dhlog.iso9283.report import (
    Accuracy,
    DistanceReport,
    DriftReport,
)

#: Stabilisation and overshoot are judged on the tracker's positions averaged over this period
#: (s) where it samples faster: the 100 Hz the standard asks for, so a faster tracker's noise
#: does not leave the band more often (a 1 kHz log read 60 ms long without it).
STABILISATION_PERIOD = 0.01


#: The pair of poses for distance accuracy and repeatability (clause 7.3).
DISTANCE_POSES = ("P2", "P4")


#: The pose drift is measured at (clause 7.6: P1).
DRIFT_POSE = "P1"


def _accuracy(attained: FloatArray, commanded: FloatArray) -> Accuracy:
    """Clause 7.2.1 (:func:`dhlog.iso9283.formulas.pose_accuracy`)."""
    from dhlog.iso9283.formulas.poses import pose_accuracy

    got = pose_accuracy(attained, commanded)
    d = np.asarray(got.AP_xyz, dtype=np.float64)
    sigma = None
    n = attained.shape[0]
    if n >= 2:  # σ(x̄_c) = S_c / √n; AP's along d/AP (all of it where AP is 0)
        var = np.var(attained, axis=0, ddof=1) / n
        u = d / got.AP_P if got.AP_P > 0 else np.full(3, 1 / math.sqrt(3))
        sigma = float(math.sqrt(float(np.sum(u**2 * var))))
    return Accuracy(float(got.AP_P), d, sigma)


def _repeatability(attained: FloatArray) -> tuple[float, float, float]:
    """Clause 7.2.2 (:func:`dhlog.iso9283.formulas.pose_repeatability`): RP_l, l̄, S_l."""
    from dhlog.iso9283.formulas.poses import pose_repeatability

    got = pose_repeatability(attained)
    return float(got.RP_l), float(got.l_mean), float(got.S_l)


def _orientation_repeatability(attained: FloatArray, rotations: Sequence[FloatArray]) -> FloatArray:
    """Clause 7.2.2's RP_a, RP_b, RP_c (±3 S about the frame's x, y, z)."""
    from dhlog.iso9283.formulas.poses import pose_repeatability

    got = pose_repeatability(attained, np.asarray(rotations))
    assert got.RP_abc is not None
    return np.asarray(got.RP_abc, dtype=np.float64)


def _stabilisation(visit: Visit) -> tuple[float, float] | None:
    """Clauses 7.4, 7.5 of one arrival (:func:`dhlog.iso9283.formulas.stabilisation`) in the
    visit's band around its attained position, on the positions averaged over
    ``STABILISATION_PERIOD`` where the tracker samples faster. The controller's attained-pose
    signal is not in
    the log: the encoders' stop stands in for it (:func:`dhlog.iso9283.cycles._encoders_stop`),
    without encoders the first sample within the band. None when the arrival's samples do not
    begin outside the band or never settle."""
    from dhlog.iso9283.formulas.settling import stabilisation

    t, xyz = _binned(visit.arrival_t, visit.arrival_xyz, STABILISATION_PERIOD)
    d = np.linalg.norm(xyz - visit.position, axis=1)
    inside = np.flatnonzero(d <= visit.band)
    if inside.size == 0 or inside[0] == 0:
        return None
    try:
        got = stabilisation(
            t,
            xyz,
            visit.position,
            float(t[inside[0]]) if visit.arrival is None else visit.arrival,
            band=visit.band,
        )
    except DhlogError:
        return None
    return float(got.time), float(got.overshoot)


def _binned(t: FloatArray, xyz: FloatArray, period: float) -> tuple[FloatArray, FloatArray]:
    """Samples faster than ``period`` (s) averaged over consecutive bins of ``period``: each
    bin's mean time and position (slower samples as they are)."""
    steps = np.diff(t)
    if steps.size == 0 or float(np.median(steps)) >= 0.75 * period:
        return t, xyz
    bins = np.floor((t - t[0]) / period).astype(np.int64)
    edges = np.flatnonzero(np.diff(bins)) + 1
    counts = np.diff(np.r_[0, edges, t.size])
    mean_t = np.add.reduceat(t, np.r_[0, edges]) / counts
    mean_xyz = np.add.reduceat(xyz, np.r_[0, edges], axis=0) / counts[:, None]
    return mean_t, mean_xyz


def _multi_directional(vs: list[Visit], X: FloatArray) -> tuple[float | None, int]:
    """Clause 7.2.3: the visits grouped by approach direction (within ``SAME_DIRECTION``, two
    visits at least); vAP (:func:`dhlog.iso9283.formulas.multi_directional`) from the groups'
    barycentres (None with one direction), and the number of directions."""
    from dhlog.iso9283.formulas.poses import multi_directional

    groups: list[tuple[FloatArray, list[int]]] = []
    for i, v in enumerate(vs):
        if not np.any(v.direction):
            continue
        for d, members in groups:
            if float(np.dot(d, v.direction)) >= math.cos(SAME_DIRECTION):
                members.append(i)
                break
        else:
            groups.append((v.direction, [i]))
    groups = [g for g in groups if len(g[1]) >= 2]
    if len(groups) < 2:
        return None, len(groups)
    bary = np.array([X[m].mean(axis=0) for _, m in groups])
    return float(multi_directional(bary).vAP_P), len(groups)


def _distance(
    seg: Segmented,
    T: FloatArray | None,
    commanded_at: Any,
    correction_at: Any,
    notes: list[str],
) -> DistanceReport | None:
    """Clause 7.3 between P2 and P4 (:func:`dhlog.iso9283.formulas.distance_accuracy` with a
    model): D_j = |P4_j − P2_j| per cycle, AD = D̄ − D_c, RD = 3 S_D."""
    from dhlog.iso9283.formulas.poses import distance_accuracy

    a, b = DISTANCE_POSES
    if a not in seg.poses or b not in seg.poses:
        notes.append(f"AD/RD: {a} or {b} not in this log; not computed.")
        return None
    pa = {v.cycle: v.position for v in seg.of_pose(a)}
    pb = {v.cycle: v.position for v in seg.of_pose(b)}
    both = sorted(set(pa) & set(pb))
    if not both:
        notes.append(f"AD/RD: no cycle visits both {a} and {b}; not computed.")
        return None
    Xa = _moved(T, np.array([pa[c] for c in both]))
    Xb = _moved(T, np.array([pb[c] for c in both]))
    D = np.linalg.norm(Xb - Xa, axis=1)
    ka, kb = seg.poses.index(a), seg.poses.index(b)
    Dc = AD = AD_after = None
    RD = float(3.0 * D.std(ddof=1)) if D.size >= 2 else None
    if commanded_at is not None:
        ca, cb = commanded_at(ka), commanded_at(kb)
        Dc = float(np.linalg.norm(cb - ca))
        AD = float(D.mean() - Dc)
        if D.size >= 2:
            got = distance_accuracy(Xa, Xb, ca, cb)
            AD, RD = float(got.AD_P), float(got.RD)
        if correction_at is not None:
            Da = np.linalg.norm((Xb - correction_at(kb)) - (Xa - correction_at(ka)), axis=1)
            AD_after = float(Da.mean() - Dc)
    if RD is None:
        notes.append(f"RD: {D.size} cycle with both {a} and {b}: needs 2 or more; not computed.")
    return DistanceReport((a, b), int(D.size), float(D.mean()), Dc, AD, AD_after, RD)


#: A test shorter than this (h) between its first and last P1 cycles is not a drift test.
DRIFT_HOURS = 0.5


def _drift(
    seg: Segmented, T: FloatArray | None, commanded_at: Any, notes: list[str]
) -> DriftReport | None:
    """Clause 7.6 at P1 between the first and the last ``min(10, n // 2)`` cycles
    (:func:`dhlog.iso9283.formulas.drift` with a model; without one, dRP and the shift)."""
    from dhlog.iso9283.formulas.poses import drift

    vs = seg.of_pose(DRIFT_POSE)
    if len(vs) < 4:
        notes.append(
            f"drift: {len(vs)} visit(s) to {DRIFT_POSE}: needs 4 or more (two groups of two); "
            "not computed."
        )
        return None
    g = min(10, len(vs) // 2)
    X = _moved(T, np.array([v.position for v in vs]))
    t_h = np.array([(v.t_start_ns - vs[0].t_start_ns) * 1e-9 / 3600.0 for v in vs])
    first, last = X[:g], X[-g:]
    hours = float(t_h[-g:].mean() - t_h[:g].mean())
    dAP = None
    dRP = abs(_repeatability(first)[0] - _repeatability(last)[0])
    if commanded_at is not None:
        got = drift([first, last], commanded_at(seg.poses.index(DRIFT_POSE)))
        dAP, dRP = float(got.dAP), float(got.dRP)
    shift = float(np.linalg.norm(last.mean(axis=0) - first.mean(axis=0)))
    rate = 0.0
    if np.ptp(t_h) > 0:
        slope = np.polyfit(t_h, X, 1)[0]
        rate = float(np.linalg.norm(slope))
    if hours < DRIFT_HOURS:
        notes.append(
            f"drift: the first and last cycles at {DRIFT_POSE} are {hours * 60:.1f} min apart: "
            "clause 7.6's drift test runs over hours (from a cold start); these figures are the "
            "change over this test only (rate_per_hour: a line through these minutes, not shown)."
        )
    return DriftReport(DRIFT_POSE, g, hours, dAP, dRP, shift, rate)
