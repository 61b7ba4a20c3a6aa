"""The path characteristics of an ISO 9283 test from its passes (clause 8: AT, RT, the velocity
characteristics), the commanded points left out at a path's ends tried in turn
(:data:`PATH_TRIMS`); the tracker's σ from the settled dwells (:func:`tracker_sigma`) and the RT
that noise alone gives (:func:`noise_rt`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel
from dhlog.iso9283.baseframe import _moved
from dhlog.iso9283.cycles import Segmented
from dhlog.iso9283.dwells import Visit
from dhlog.iso9283.report import (
    PathReport,
)
from dhlog.model.fk import fk_point

#: The commanded points left out at a path's start and end, tried in turn, when a pass does
#: not cross their normal planes (a robot stopping short of the end).
PATH_TRIMS = ((0, 0), (0, 1), (1, 0), (1, 1), (0, 2), (2, 0), (2, 2), (3, 3))


def tracker_sigma(visits: Sequence[Visit]) -> float | None:
    """The tracker's σ per coordinate (m) from the settled dwells' scatter (each visit's 3-D RMS
    about its mean, pooled; isotropic noise assumed); None without settled visits."""
    scatter = [v.scatter for v in visits if v.settled and v.n_settled > 1]
    return math.sqrt(float(np.mean(np.square(scatter))) / 3.0) if scatter else None


def noise_rt(sigma: float, cycles: int, points: int, draws: int = 200) -> float:
    """The path repeatability RT (clause 8.2: max over points of l̄ + 3 S_l) that isotropic
    tracker noise of σ per coordinate alone gives when each of ``points`` crossings is one
    sample in ``cycles`` passes: its two components in each normal plane, ``draws`` seeded
    draws averaged. What RT reads above the robot's own repeatability comes to about this, added
    in quadrature to first order."""
    rng = np.random.default_rng(0)
    d = rng.normal(0.0, sigma, (draws, cycles, points, 2))
    d -= d.mean(axis=1, keepdims=True)
    lengths = np.linalg.norm(d, axis=3)
    rt = lengths.mean(axis=1) + 3.0 * lengths.std(axis=1, ddof=1)
    return float(np.mean(rt.max(axis=1)))


def _paths(
    seg: Segmented,
    T: FloatArray | None,
    nominal: DHModel | None,
    calibrated: DHModel | None,
    notes: list[str],
) -> list[PathReport]:
    """Clause 8.2 for each of the program's paths (:func:`dhlog.iso9283.formulas.path_accuracy`
    on the passes in the base frame, the commanded points the nominal's FK of the path's joint
    targets); after: the crossings' barycentres less the part in each normal plane of the
    calibrated model's correction at the commanded point (what compensated commands would move
    the crossing by, to first order)."""
    from dhlog.iso9283.formulas.paths import path_accuracy

    if not seg.paths:
        notes.append(
            "paths (AT, RT): the commanded paths come from the test program: give --commanded "
            "with the program dhlog plan --iso9283 wrote; not computed."
        )
        return []
    out = []
    for name, q in seg.paths:
        passes = [p for p in seg.passes if p.path == name]
        if not passes:
            continue  # named by the segmentation
        if len(passes) < 2:
            notes.append(f"path {name}: 1 pass: AT and RT need 2 or more; not computed.")
            continue
        if T is None or nominal is None:
            notes.append(
                f"path {name}: AT and RT need the base frame (--nominal, or --result); not "
                "computed."
            )
            continue
        commanded = np.asarray(
            fk_point(nominal.table, q, nominal.tool_point, T_base=nominal.T_base)
        )
        attained = [_moved(T, p.xyz) for p in passes]
        got = None
        first = 0
        problem = ""
        for a, b in PATH_TRIMS:  # the ends a pass may stop short of (the robot stops there)
            try:
                got = path_accuracy(attained, commanded[a : len(q) - b])
            except DhlogError as exc:
                problem = problem or str(exc)
                continue
            if a or b:
                notes.append(
                    f"path {name}: the first {a} and last {b} commanded point(s) are not crossed "
                    "by every pass (the robot stops at the path's ends, short of their normal "
                    "planes): left out of AT and RT."
                )
            commanded, q, first = commanded[a : len(q) - b], q[a : len(q) - b], a
            break
        if got is None:
            notes.append(f"path {name}: {problem}")
            continue
        after = None
        if calibrated is not None:
            predicted = _moved(
                T,
                np.asarray(
                    fk_point(
                        calibrated.table,
                        calibrated.joint_values(q),
                        calibrated.tool_point,
                        T_base=calibrated.T_base,
                    )
                ),
            )
            # the compensated commands move the path by −(predicted − commanded): its crossing
            # of each normal plane moves by that correction's part in the plane
            tangent = np.gradient(commanded, axis=0, edge_order=2)
            tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
            correction = predicted - commanded
            correction -= np.sum(correction * tangent, axis=1, keepdims=True) * tangent
            left = got.barycentres - correction - commanded
            after = float(np.max(np.linalg.norm(left, axis=1)))
        sigma = tracker_sigma(seg.visits)
        floor = None if sigma is None else noise_rt(sigma, int(got.cycles), len(q))
        if sigma is not None and floor is not None and floor > 0.25 * float(got.RT_P):
            notes.append(
                f"path {name}: the tracker's noise ({sigma * 1e6:.1f} µm per coordinate, from "
                f"the dwells) alone gives RT {floor * 1e3:.3f} mm, "
                f"{100 * floor / float(got.RT_P):.0f} % of the {float(got.RT_P) * 1e3:.3f} mm "
                "measured (each crossing is one sample): the robot's own RT is about "
                f"{math.sqrt(max(float(got.RT_P) ** 2 - floor**2, 0.0)) * 1e3:.3f} mm "
                "(√(RT² − noise's²))."
            )
        out.append(
            PathReport(
                name,
                int(got.cycles),
                len(q),
                first,
                float(got.AT_P),
                after,
                float(got.RT_P),
                int(np.argmax(got.deviation)),
                int(np.argmax(got.repeatability)),
                commanded,
                attained,
                RT_noise=floor,
            )
        )
    return out
