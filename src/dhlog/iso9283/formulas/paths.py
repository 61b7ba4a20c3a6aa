"""The ISO 9283:1998 path characteristics on plain arrays: path accuracy and repeatability (8.2: the
attained paths cut by the commanded path's normal planes, the orientation interpolated between
the commanded points) and the path velocity characteristics (8.4).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import Iso9283Error, ShapeError
from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.iso9283.formulas.checks import (
    _finite,
    _floats,
    _points,
    _rotations,
    _sample_std,
)
from dhlog.iso9283.formulas.orientation import (
    _mean_rotation,
    orientation_deviation,
)


@dataclass(frozen=True)
class PathCharacteristics:
    """Path accuracy and repeatability (ISO 9283:1998, 8.2) of n cycles of one path at m
    commanded points: ``crossings`` (m, n, 3), each cycle's attained point in the plane normal
    to the command path at each commanded point; ``barycentres`` (m, 3); ``deviation`` (m,), the
    barycentre's distance from the commanded point; ``repeatability`` (m,), l̄_i + 3 S_li;
    ``AT_P`` = max deviation, ``RT_P`` = max repeatability. With orientations:
    ``deviation_abc`` (m, 3), the mean deviation of the attained orientations from the
    commanded one at each point, ``repeatability_abc`` (m, 3), 3 S_ai …, and ``AT_abc``,
    ``RT_abc`` (3,) their largest absolute values over the points. m, rad."""

    cycles: int
    commanded: FloatArray
    crossings: FloatArray
    barycentres: FloatArray
    deviation: FloatArray
    repeatability: FloatArray
    AT_P: float
    RT_P: float
    deviation_abc: FloatArray | None = None
    repeatability_abc: FloatArray | None = None
    AT_abc: FloatArray | None = None
    RT_abc: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m), with the per-point deviation and repeatability."""
        return {
            "cycles": self.cycles,
            "points": len(self.commanded),
            "AT_P_m": self.AT_P,
            "RT_P_m": self.RT_P,
            "AT_at_point": int(np.argmax(self.deviation)),
            "RT_at_point": int(np.argmax(self.repeatability)),
            "deviation_m": _floats(self.deviation),
            "repeatability_m": _floats(self.repeatability),
            "barycentres_m": _floats(self.barycentres),
            "AT_abc_rad": _floats(self.AT_abc),
            "RT_abc_rad": _floats(self.RT_abc),
            "deviation_abc_rad": _floats(self.deviation_abc),
            "repeatability_abc_rad": _floats(self.repeatability_abc),
        }


def _tangents(commanded: FloatArray) -> FloatArray:
    """Unit tangents of a commanded polyline (m, 3) by central differences (second-order
    one-sided ones at the ends, first-order for two points)."""
    if np.any(np.linalg.norm(np.diff(commanded, axis=0), axis=1) <= 0.0):
        raise Iso9283Error(
            "path accuracy",
            "two consecutive commanded path points coincide, so the path has no direction there",
            "give distinct commanded points, or their tangents",
        )
    g = np.gradient(commanded, axis=0, edge_order=2 if len(commanded) > 2 else 1)
    norm = np.linalg.norm(g, axis=1)
    if np.any(norm <= 0.0):
        raise Iso9283Error(
            "path accuracy",
            "the commanded path turns back on itself, so it has no direction at a point",
            "give the tangents of the commanded path",
        )
    return np.asarray(g / norm[:, None], dtype=np.float64)


def _crossing(
    path: FloatArray, point: FloatArray, normal: FloatArray
) -> tuple[FloatArray, int, float] | None:
    """Where the polyline ``path`` (k, 3) crosses the plane through ``point`` normal to
    ``normal``, nearest ``point`` (linear interpolation between the two bracketing samples):
    the point, the index s of the sample before it and the fraction λ of the way to sample
    s + 1; None when the path never reaches the plane."""
    side = (path - point) @ normal
    on = np.flatnonzero(side == 0.0)
    seg = np.flatnonzero(side[:-1] * side[1:] < 0.0)
    lam = side[seg] / (side[seg] - side[seg + 1])
    cand = path[seg] + lam[:, None] * (path[seg + 1] - path[seg])
    cand = np.concatenate([cand, path[on]])
    if len(cand) == 0:
        return None
    best = int(np.argmin(np.linalg.norm(cand - point, axis=1)))
    if best < len(seg):
        return np.asarray(cand[best], dtype=np.float64), int(seg[best]), float(lam[best])
    return np.asarray(cand[best], dtype=np.float64), int(on[best - len(seg)]), 0.0


def _rotation_vector(R: FloatArray) -> FloatArray:
    """The rotation vector (axis × angle, rad) of a rotation of less than 90°."""
    w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    sin = float(np.linalg.norm(w))
    angle = float(np.arctan2(sin, (np.trace(R) - 1.0) / 2.0))  # not arccos: exact when small
    return w if sin < 1e-15 else w * (angle / sin)


def _interpolated_rotation(Rs: FloatArray, seg: int, lam: float, what: str) -> FloatArray:
    """The rotation a fraction ``lam`` of the way from ``Rs[seg]`` to ``Rs[seg + 1]`` along
    the shortest turn between them (as slerp)."""
    if lam == 0.0:
        return np.asarray(Rs[seg], dtype=np.float64)
    step = Rs[seg].T @ Rs[seg + 1]
    if np.trace(step) < 1.0:  # a turn of more than 90° between two samples
        raise Iso9283Error(
            what,
            f"the orientation turns by more than 90° between samples {seg + 1} and {seg + 2}",
            "record the path's orientations at a higher rate",
        )
    return np.asarray(Rs[seg] @ rotation_from_vector(lam * _rotation_vector(step)))


def path_accuracy(
    attained_paths: Sequence[ArrayLike],
    commanded: ArrayLike,
    tangents: ArrayLike | None = None,
    R_paths: Sequence[ArrayLike] | None = None,
    R_commanded: ArrayLike | None = None,
) -> PathCharacteristics:
    """Path accuracy AT_P and path repeatability RT_P, ISO 9283:1998 clause 8.2, from the n ≥ 2
    attained paths ``attained_paths`` (each (k_j, 3), the measured positions of one cycle in
    time order) of the command path through the commanded points ``commanded`` (m, 3), whose
    unit ``tangents`` (m, 3) give the normal planes (by default central differences of the
    commanded points, second-order one-sided at the ends: give the tangents where the ends
    matter on a coarsely sampled curve).

    For each commanded point i, each cycle's attained point x_ij is where its path crosses the
    plane through the commanded point normal to the command path (linearly interpolated between
    the two samples on either side of the plane; of several crossings, the nearest the
    commanded point), and

        x̄_i = (1/n) Σ_j x_ij, AT_P = max_i √((x̄_i − x_ci)² + (ȳ_i − y_ci)² + (z̄_i − z_ci)²),
        l_ij = |x_ij − x̄_i|, S_li = √(Σ_j (l_ij − l̄_i)² / (n − 1)),
        RT_P = max_i (l̄_i + 3 S_li).

    With the attained orientations ``R_paths`` (each (k_j, 3, 3), one per sample) and the
    commanded ones ``R_commanded`` (m, 3, 3), each cycle's orientation at the crossing is
    interpolated along the shortest turn between the two samples (as slerp), and

        AT_a = max_i |ā_i − a_ci|, RT_a = max_i 3 S_ai (likewise b, c),

    with ā_i − a_ci the mean :func:`orientation_deviation` of the cycles' orientations from the
    commanded one and S_ai the sample standard deviation of their deviations from their mean
    orientation (as in :func:`pose_repeatability`)."""
    what = "path accuracy"
    if len(attained_paths) < 2:
        raise Iso9283Error(
            what,
            f"{len(attained_paths)} attained path(s) given, at least 2 cycles are needed",
            "measure the path in several cycles (the standard prescribes 10)",
        )
    cmd = _points(f"{what}: commanded path points", commanded, at_least=2, unit="points")
    if tangents is None:
        tan = _tangents(cmd)
    else:
        tan = np.asarray(tangents, dtype=np.float64)
        if tan.shape != cmd.shape:
            raise ShapeError(
                f"{what}: tangents", f"one per commanded point, {cmd.shape}", tan.shape
            )
        _finite(f"{what}: tangents", tan)
        norm = np.linalg.norm(tan, axis=1)
        if np.any(norm <= 0.0):
            raise ShapeError(f"{what}: tangents", "non-zero directions", "a zero vector")
        tan = tan / norm[:, None]
    paths = [
        _points(f"{what}: attained path of cycle {j + 1}", p, at_least=2, unit="samples")
        for j, p in enumerate(attained_paths)
    ]
    m, n = len(cmd), len(paths)
    if (R_paths is None) != (R_commanded is None):
        raise Iso9283Error(
            what,
            "attained orientations were given without commanded ones (or the reverse)",
            "give both R_paths and R_commanded, or neither",
        )
    Rp: list[FloatArray] = []
    Rc = None
    if R_paths is not None and R_commanded is not None:
        if len(R_paths) != n:
            raise Iso9283Error(
                what,
                f"{len(R_paths)} cycles of orientations for {n} attained paths",
                "give one array of orientations per attained path",
            )
        Rp = [
            _rotations(f"{what}: orientations of cycle {j + 1}", R, len(paths[j]))
            for j, R in enumerate(R_paths)
        ]
        Rc = _rotations(f"{what}: commanded orientations", R_commanded, m)
    crossings = np.empty((m, n, 3))
    R_cross = np.empty((m, n, 3, 3))
    for i in range(m):
        for j, path in enumerate(paths):
            hit = _crossing(path, cmd[i], tan[i])
            if hit is None:
                raise Iso9283Error(
                    what,
                    f"the attained path of cycle {j + 1} never crosses the plane normal to the "
                    f"command path at commanded point {i + 1} of {m}",
                    "give the whole pass of each cycle, or drop the commanded points it does "
                    "not reach",
                )
            crossings[i, j] = hit[0]
            if Rp:
                R_cross[i, j] = _interpolated_rotation(
                    Rp[j], hit[1], hit[2], f"{what}: cycle {j + 1}"
                )
    bary = crossings.mean(axis=1)
    deviation = np.linalg.norm(bary - cmd, axis=1)
    l_ij = np.linalg.norm(crossings - bary[:, None, :], axis=2)
    rt = l_ij.mean(axis=1) + 3.0 * np.std(l_ij, axis=1, ddof=1)
    dev_abc = rep_abc = at_abc = rt_abc = None
    if Rc is not None:
        dev_abc = np.array(
            [orientation_deviation(R_cross[i], Rc[i]).mean(axis=0) for i in range(m)]
        )
        rep_abc = np.array(
            [
                3.0 * _sample_std(orientation_deviation(R_cross[i], _mean_rotation(R_cross[i])))
                for i in range(m)
            ]
        )
        at_abc = np.abs(dev_abc).max(axis=0)
        rt_abc = rep_abc.max(axis=0)
    return PathCharacteristics(
        n,
        cmd,
        crossings,
        bary,
        deviation,
        rt,
        float(deviation.max()),
        float(rt.max()),
        dev_abc,
        rep_abc,
        at_abc,
        rt_abc,
    )


@dataclass(frozen=True)
class PathVelocity:
    """Path velocity characteristics (ISO 9283:1998, 8.4) of n cycles at the commanded speed
    ``v_c`` (m/s): ``v_mean`` (n,), each cycle's mean speed; ``AV`` = (v̄ − v_c)/v_c and
    ``RV`` = 3 S_v / v_c (ratios; the standard states them in per cent of v_c), and ``FV``
    (m/s) the largest speed range within one cycle."""

    cycles: int
    v_c: float
    v_mean: FloatArray
    AV: float
    RV: float
    FV: float

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m/s; AV and RV in per cent of the commanded speed, as the
        standard states them)."""
        return {
            "cycles": self.cycles,
            "v_c_m_per_s": self.v_c,
            "v_mean_m_per_s": _floats(self.v_mean),
            "AV_percent": 100.0 * self.AV,
            "RV_percent": 100.0 * self.RV,
            "FV_m_per_s": self.FV,
        }


def speeds_from_positions(t: ArrayLike, p: ArrayLike) -> FloatArray:
    """The speeds (m/s) between consecutive samples of positions ``p`` (k, 3) at times ``t``
    (k,): |p_{i+1} − p_i| / (t_{i+1} − t_i), (k − 1,)."""
    pts = _points("path velocity: positions", p, at_least=2, unit="samples")
    tt = _finite("path velocity: times", np.asarray(t, dtype=np.float64))
    if tt.shape != (len(pts),) or np.any(np.diff(tt) <= 0.0):
        raise ShapeError("path velocity: times", f"({len(pts)},) increasing", tt.shape)
    return np.asarray(np.linalg.norm(np.diff(pts, axis=0), axis=1) / np.diff(tt), dtype=np.float64)


def path_velocity(speeds: Sequence[ArrayLike], commanded_speed: float) -> PathVelocity:
    """Path velocity accuracy AV, repeatability RV and fluctuation FV, ISO 9283:1998 clause 8.4,
    from the speeds measured along the steady part of the path in each of n ≥ 2 cycles
    (``speeds``, each (k_j,), m/s) at the commanded speed v_c = ``commanded_speed``:

        v̄_j = mean speed of cycle j, v̄ = (1/n) Σ v̄_j, AV = (v̄ − v_c) / v_c × 100 %,
        S_v = √(Σ (v̄_j − v̄)² / (n − 1)), RV = ±3 S_v / v_c × 100 %,
        FV = max_j (max_i v_ij − min_i v_ij).

    The ratios are returned as fractions (``document()`` gives per cent)."""
    what = "path velocity"
    if len(speeds) < 2:
        raise Iso9283Error(
            what,
            f"{len(speeds)} cycle(s) given, at least 2 are needed",
            "measure the path in several cycles (the standard prescribes 10)",
        )
    if not (np.isfinite(commanded_speed) and commanded_speed > 0.0):
        raise Iso9283Error(
            what, f"the commanded speed {commanded_speed!r} m/s is not positive", "give v_c > 0"
        )
    v = []
    for j, s in enumerate(speeds):
        arr = _finite(f"{what}: speeds of cycle {j + 1}", np.asarray(s, dtype=np.float64))
        if arr.ndim != 1 or len(arr) == 0:
            raise ShapeError(
                f"{what}: speeds of cycle {j + 1}", "a non-empty (k,) array", arr.shape
            )
        v.append(arr)
    v_mean = np.array([a.mean() for a in v])
    vbar = float(v_mean.mean())
    vc = float(commanded_speed)
    fv = float(max(a.max() - a.min() for a in v))
    return PathVelocity(
        len(v), vc, v_mean, (vbar - vc) / vc, 3.0 * float(_sample_std(v_mean)) / vc, fv
    )
