"""The pair relations of the whole-model fit: each axis's covariance and the variance of the
angle between consecutive axes (the pairs' tolerances), the relations' linearised constraints
(:func:`pair_constraints`), and the fit held to the relations the data cannot reject (parallel,
collinear: :func:`with_fixed_relations`; which pairs, the held-out poses decide:
:mod:`dhlog.identify.model.pairs`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from dhlog.errors import Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line, RelationKind, classify_lines
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.read.analytic import pair_tolerances
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import JointType


def axis_covariances(fit: WholeFit) -> list[FloatArray]:
    """Per axis, the 4×4 covariance of ``[δe·u, δe·v, δc·u, δc·v]`` (the form of
    ``AxisFit.axis_covariance``): a tilt ``a`` about u moves the direction by ``−a v``, a tilt
    ``b`` about v by ``+b u``."""
    out = []
    layout = fit.layout
    for i, jt in enumerate(fit.model.types):
        k = layout.axis_at[i]
        width = 4 if jt is JointType.REVOLUTE else 2
        C = fit.covariance[k : k + width, k : k + width]
        B = np.zeros((4, width))
        B[0, 1], B[1, 0] = 1.0, -1.0
        if width == 4:
            B[2, 2], B[3, 3] = 1.0, 1.0
        out.append(np.asarray(B @ C @ B.T, dtype=np.float64))
    return out


def _relative_tilt_rows(fit: WholeFit, i: int) -> list[FloatArray]:
    """The two rows (``layout.size``,) giving ``e · (δd_{i+1} − sign δd_i)`` for ``e`` in axis
    i's perpendicular basis: the linearised change of the angle between axes i and i+1."""
    model, layout, bases = fit.model, fit.layout, fit.bases
    d1, d2 = model.axes[i].direction, model.axes[i + 1].direction
    sign = 1.0 if d1 @ d2 >= 0 else -1.0
    (u1, v1), (u2, v2) = bases[i], bases[i + 1]
    k1, k2 = layout.axis_at[i], layout.axis_at[i + 1]
    rows = []
    for e in (u1, v1):  # δd = −a v + b u for tilts (a about u, b about v)
        row = np.zeros(layout.size)
        row[k2], row[k2 + 1] = -(e @ v2), e @ u2
        row[k1], row[k1 + 1] = sign * (e @ v1), -sign * (e @ u1)
        rows.append(row)
    return rows


def relative_tilt_variances(fit: WholeFit) -> list[float]:
    """Per consecutive pair of axes, the variance (rad², per component) of the angle between
    them, from the fit's whole covariance: the two axes' own variances less what they share —
    axes that only ever moved together (a coupled move) are determined far better relative to
    each other than each alone."""
    out = []
    for i in range(fit.model.n - 1):
        rows = np.array(_relative_tilt_rows(fit, i))
        out.append(float(np.trace(rows @ fit.covariance @ rows.T)) / 2.0)
    return out


def relation_tolerances(
    fit: WholeFit,
    nominal: DHModel | None,
    angle_tol: float,
    distance_tol: float,
    *,
    parallel_sigma: float,
) -> list[tuple[float, float]] | None:
    """The pairs' tolerances (:func:`pair_tolerances`) from the fit's axis covariances: a pair
    within ``parallel_sigma`` σ (2-D) of the angle between its axes counts as parallel."""
    covs = axis_covariances(fit)
    return pair_tolerances(
        [(c, a.point) for c, a in zip(covs, fit.model.axes, strict=True)],
        nominal,
        angle_tol,
        distance_tol,
        k_parallel=parallel_sigma,
        # the whole-model fit judges a pair by its σ (the candidates of dhlog.identify.model.pairs,
        # or the K σ rule) also where the nominal says parallel, not by the nominal's 5σ: a
        # held pair's tilt is a bias the FK error carries in full. With random static poses and
        # 60 µm unmodelled error, 5σ held KR5's axes 2–3 (0.05° apart) parallel at 1.5–1.9x the
        # FK error; with per-joint sweeps (UR5 0.05° off, 100 Hz tracker, σ 15–20 µm) it held
        # axes 2–3 or 3–4 in 2 of 10 sessions at 1.2–3.1x
        direction_variances=relative_tilt_variances(fit),
    )


def pair_constraints(
    fit: WholeFit, parallel: list[int], collinear: list[int]
) -> tuple[FloatArray, FloatArray]:
    """The linearised constraints ``c₀ + A x = 0`` (``A`` (k, ``layout.size``), ``c₀`` (k,)) in
    ``fit``'s local parameters ``x`` that axes ``i, i+1`` are parallel (``parallel``: two rows,
    the relative tilt) or the same line (``collinear``: two more, the offset between them)."""
    model, layout, bases = fit.model, fit.layout, fit.bases
    rows: list[FloatArray] = []
    c0: list[float] = []
    for i in sorted(set(parallel) | set(collinear)):
        d1, d2 = model.axes[i].direction, model.axes[i + 1].direction
        sign = 1.0 if d1 @ d2 >= 0 else -1.0
        (u1, v1), (u2, v2) = bases[i], bases[i + 1]
        k1, k2 = layout.axis_at[i], layout.axis_at[i + 1]
        rows += _relative_tilt_rows(fit, i)
        c0 += [float(e @ (d2 - sign * d1)) for e in (u1, v1)]
        if i in collinear:
            c1, c2 = model.axes[i].point, model.axes[i + 1].point
            for e in (u1, v1):
                row = np.zeros(layout.size)
                row[k2 + 2], row[k2 + 3] = e @ u2, e @ v2
                row[k1 + 2], row[k1 + 3] = -(e @ u1), -(e @ v1)
                rows.append(row)
                c0.append(float(e @ (c2 - c1)))
    return np.array(rows).reshape(len(rows), layout.size), np.array(c0)


def pairs_within(
    fit: WholeFit, tolerances: list[tuple[float, float]]
) -> tuple[list[int], list[int]]:
    """The consecutive pairs (0-based ``i`` for axes i, i+1) within their ``tolerances`` of
    parallel and of the same line: (parallel, collinear); a pair with a prismatic axis is only
    ever parallel (it has only a direction to hold)."""
    axes, types = fit.model.axes, fit.model.types
    parallel, collinear = [], []
    for i, (a_tol, d_tol) in enumerate(tolerances):
        kind = classify_lines(axes[i], axes[i + 1], angle_tol=a_tol, distance_tol=d_tol).kind
        if JointType.PRISMATIC in (types[i], types[i + 1]):
            if kind.is_parallel:
                parallel.append(i)
        elif kind is RelationKind.COLLINEAR:
            collinear.append(i)
        elif kind.is_parallel:
            parallel.append(i)
    return parallel, collinear


def constrain_pairs(fit: WholeFit, parallel: list[int], collinear: list[int]) -> WholeFit:
    """The fit under the constraint that axes ``i, i+1`` (0-based ``i``) are exactly parallel
    (``parallel``) or the same line (``collinear``): the relations a classification fixes when
    the data cannot reject them.

    To first order the constrained optimum and its covariance follow from the unconstrained
    ones without another pass over the samples (the model is linear far beyond these moves):
    ``x = −C Aᵀ (A C Aᵀ)⁻¹ c₀`` and ``C' = C − C Aᵀ (A C Aᵀ)⁻¹ A C`` for the linearised
    constraints ``c₀ + A x = 0``; then the constrained axes are made exactly parallel (or
    coincident), a change of second order."""
    model, layout, bases = fit.model, fit.layout, fit.bases
    A, c = pair_constraints(fit, parallel, collinear)
    if not A.shape[0]:
        return fit
    C = fit.covariance
    CA = C @ A.T
    S = A @ CA
    K = CA @ np.linalg.pinv(S)
    delta = -K @ c
    cov = C - K @ CA.T
    moved = model.moved(np.asarray(delta, dtype=np.float64), layout, bases)
    axes = list(moved.axes)
    for i in range(len(axes) - 1):
        if i in parallel or i in collinear:
            d1 = axes[i].direction
            sign = 1.0 if d1 @ axes[i + 1].direction >= 0 else -1.0
            point = axes[i].project(axes[i + 1].point) if i in collinear else axes[i + 1].point
            axes[i + 1] = Line(point, sign * d1)
    snapped = replace(moved, axes=tuple(axes))
    return replace(
        fit,
        model=snapped,
        covariance=np.asarray((cov + cov.T) / 2, dtype=np.float64),
        bases=snapped.bases(),
        constrained={
            **{i: "parallel" for i in parallel},
            **{i: "collinear" for i in collinear},
        },
    )


def with_fixed_relations(
    whole: WholeFit,
    tolerances: list[tuple[float, float]] | None,
    cost: Callable[[WholeFit], float],
) -> tuple[WholeFit, list[tuple[float, float]] | None, tuple[Note, ...]]:
    """The fit constrained to the pair relations the data cannot reject: consecutive revolute
    axes within their tolerance of parallel are made parallel (collinear: the same line), so
    that the DH conventions of those pairs hold exactly and the table equals the model.

    The constraint is applied to first order (:func:`constrain_pairs`); where the samples'
    cost then grows by more than the relations' own χ² allows (the first order does not hold:
    parameters that only moved together, as in a coupled move, compensate far), the pairs are
    left free and their tolerances narrowed so that the extraction does not call them parallel
    either (said in a note, ``pairs-free``). Returns the fit, the tolerances and that note."""
    if tolerances is None:
        return whole, tolerances, ()
    parallel, collinear = pairs_within(whole, tolerances)
    held = constrain_pairs(whole, parallel, collinear)
    if held is whole:
        return whole, tolerances, ()
    rows = 2 * len(parallel) + 4 * len(collinear)
    # χ² of `rows` degrees of freedom beyond its mean by 10 of its σ (P < 2e-5 for one pair):
    # only a hold the first order gets badly wrong, never a truly parallel pair's noise (at
    # 4σ, 0.7 % of such sessions were left free, their d and θ far from first order)
    allowed = whole.chi2_dof * (rows + 10.0 * math.sqrt(2.0 * rows))
    grown = cost(held) - cost(whole)
    if grown <= allowed:
        return held, tolerances, ()
    pairs = sorted(set(parallel) | set(collinear))
    narrowed = [
        (min(a, 1e-7), min(d, 1e-7)) if i in pairs else (a, d)
        for i, (a, d) in enumerate(tolerances)
    ]
    names = ", ".join(f"{i + 1}–{i + 2}" for i in pairs)
    said = (
        f"axes {names}: within their tolerance of parallel, but holding them so costs the "
        f"samples χ² {grown:.1f} (the relation alone allows {allowed:.1f}): left free."
    )
    return whole, narrowed, (Note.info(said, "pairs-free"),)
