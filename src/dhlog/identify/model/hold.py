"""Hold what the samples cannot see: a parameter of the shown DH table whose σ exceeds a physical
bound (:data:`BOUND_ANGLE`, :data:`BOUND_LENGTH`) is not a measurement.

The samples determine it only in name — its direction of the model lies above the numerical
floor of :class:`~dhlog.identify.fit.whole.Determined` but so weakly that noise and unmodelled error
move it by degrees or centimetres (a position-only target a fraction of a millimetre off the
last axis: that axis's tilt about the target). Such a parameter is held at the nominal: the fit
is constrained, to first order as the pair relations are
(:func:`~dhlog.identify.model.relations.constrain_pairs`), to the nominal's value of it, and its
covariance projected (``C' = C − C Aᵀ (A C Aᵀ)⁻¹ A C``), which moves the parameters correlated
with it too (the weak direction is a combination). The parameters are chosen one at a time, the
least determined first, each held before the next is judged: holding α of a wrist often
determines its d. Without a nominal (or where the samples reject it) the value is left as fitted
and marked fixed, never printed as a measurement.

The shown table is the one the console and the JSON's ``hayati_dh`` give: standard rows, and
rows of nearly parallel pairs in the Hayati–Mirmirani form (β in place of d).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError, Note
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.geometry.lines import Plane
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.model.relations import constrain_pairs
from dhlog.identify.read.extract import Extraction
from dhlog.identify.read.propagate import (
    FIXED_BELOW,
    Extractor,
    mixed_angles,
    mixed_vector,
    state_vector,
    undetermined_rows,
)
from dhlog.model.dh import HayatiDH, StandardDH

#: A shown angle (θ, α, β) whose σ exceeds this (rad) is not determined by the samples.
BOUND_ANGLE = math.radians(1.0)
#: A shown length (d, a) whose σ exceeds this (m) is not determined by the samples.
BOUND_LENGTH = 0.010
#: The hold is met when every held parameter is within this of its value (rad or m).
MET = 1e-10
#: Newton steps onto the held values at most (each one extraction per fitted parameter).
MAX_STEPS = 12


@dataclass(frozen=True)
class Held:
    """One entry of the shown table held: ``index`` (4 per row: θ, d or β, a, α), its name
    (``α5``), its σ before any was held (m or rad), whether it is an angle, and whether it was
    held at the nominal (else left as fitted and marked not determined)."""

    index: int
    name: str
    sigma: float
    angular: bool
    at_nominal: bool

    @property
    def reason(self) -> str:
        unit = (
            f"{math.degrees(self.sigma):.3g}° (bound {math.degrees(BOUND_ANGLE):g}°)"
            if self.angular
            else f"{self.sigma * 1e3:.3g} mm (bound {BOUND_LENGTH * 1e3:g} mm)"
        )
        where = "held at the nominal" if self.at_nominal else "the fitted value is no measurement"
        return f"not determined by these samples: σ {unit} before it was held; {where}"


def shown_vector(
    ex: Extraction, rows: frozenset[int], nominal_rows: StandardDH | None
) -> FloatArray:
    """The shown table as one vector (4n: θ, d or β, a, α per row)."""
    if rows:
        return mixed_vector(ex, rows, nominal_rows)
    return state_vector(ex)[: 4 * ex.standard.n]


def nominal_vector(
    nominal: StandardDH | None, rows: frozenset[int], nominal_rows: StandardDH | None
) -> FloatArray | None:
    """The nominal in the shown form (None without a nominal; NaN on the rows a Hayati form
    touches when the nominal has none there)."""
    if nominal is None:
        return None
    t = nominal_rows if rows and nominal_rows is not None else nominal
    second = t.d_offset
    if isinstance(t, HayatiDH):
        second = np.where(t.hayati, t.beta, t.d_offset)
    out = np.column_stack([t.theta_offset, second, t.a, t.alpha]).ravel().astype(np.float64)
    if rows and nominal_rows is None:
        for i in set(rows) | {i + 1 for i in rows}:
            if i < t.n:
                out[4 * i : 4 * i + 4] = np.nan
    return out


def _names(n: int, rows: frozenset[int]) -> list[str]:
    out = []
    for i in range(n):
        out += [f"θ{i + 1}", f"{'β' if i in rows else 'd'}{i + 1}", f"a{i + 1}", f"α{i + 1}"]
    return out


def _difference(a: FloatArray, b: FloatArray, angular: NDArray[np.bool_]) -> FloatArray:
    out = np.asarray(a - b, dtype=np.float64)
    out[angular] = [wrap_angle(float(v)) for v in out[angular]]
    return out


def shown_jacobian(
    fit: WholeFit,
    model: AxisModel,
    extract: Extractor,
    plane: Plane | None,
    rows: frozenset[int],
    nominal_rows: StandardDH | None,
) -> FloatArray:
    """∂(shown vector)/∂(the fit's local parameters at ``model``), by forward differences of the
    extraction (no sample involved; a step of 10⁻⁷ rad or m, where the table is linear to far
    below the σ this Jacobian carries); a parameter whose step the extraction refuses gives a
    zero column."""
    layout, bases = fit.layout, model.bases()
    n = model.n
    angular = mixed_angles(n, rows)
    h = 1e-7
    J = np.zeros((4 * n, layout.size))
    here = shown_vector(extract(list(model.axes), model.target, plane), rows, nominal_rows)
    for col in range(layout.size):
        delta = np.zeros(layout.size)
        delta[col] = h
        moved = model.moved(delta, layout, bases)
        try:
            ex = extract(list(moved.axes), moved.target, plane)
        except DhlogError:
            continue
        J[:, col] = _difference(shown_vector(ex, rows, nominal_rows), here, angular) / h
    return J


def _project(C: FloatArray, A: FloatArray) -> FloatArray:
    """``C − C Aᵀ (A C Aᵀ)⁻¹ A C``: the covariance under the linear constraints ``A``."""
    CA = C @ A.T
    out = C - CA @ np.linalg.pinv(A @ CA) @ CA.T
    return np.asarray((out + out.T) / 2, dtype=np.float64)


def unseen(
    fit: WholeFit,
    J: FloatArray,
    rows: frozenset[int],
    fixed: NDArray[np.bool_] | None = None,
) -> list[tuple[int, float]]:
    """The entries of the shown table the samples do not determine (index, σ before), chosen
    one at a time: the one whose σ exceeds its bound the most, then the covariance projected as
    if it were held, until none exceeds. Entries fixed by a convention (no sensitivity), by a
    relation, or along an undetermined direction are not candidates; nor are ``fixed``."""
    n = fit.model.n
    angular = mixed_angles(n, rows)
    bound = np.where(angular, BOUND_ANGLE, BOUND_LENGTH)
    free = np.max(np.abs(J), axis=1) >= FIXED_BELOW
    free &= ~undetermined_rows(J, fit)
    if fixed is not None:
        free &= ~fixed
    for i, kind in fit.constrained.items():  # α (and a, collinear) held by a pair relation
        free[4 * i + 3] = False
        if kind == "collinear":
            free[4 * i + 2] = False
    C = fit.covariance
    sigma0 = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", J, C, J), 0.0, None))
    chosen: list[tuple[int, float]] = []
    while True:
        sigma = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", J, C, J), 0.0, None))
        ratio = np.where(free, sigma / bound, 0.0)
        k = int(np.argmax(ratio))
        if ratio[k] <= 1.0:
            return chosen
        chosen.append((k, float(sigma0[k])))
        free[k] = False
        C = _project(C, J[k : k + 1])


def hold_at(
    fit: WholeFit,
    indices: list[int],
    values: FloatArray,
    extract: Extractor,
    plane: Plane | None,
    rows: frozenset[int],
    nominal_rows: StandardDH | None,
) -> WholeFit:
    """The fit with the shown entries ``indices`` held at ``values``: Newton steps on the
    constraints, each the minimum of the fit's quadratic cost (metric: its covariance) that
    meets them to first order, the extraction's Jacobian taken again at every step (the moves
    may be degrees); the covariance projected onto the constraints at the end."""
    n = fit.model.n
    angular = mixed_angles(n, rows)
    idx = np.asarray(indices, dtype=np.int64)
    C = fit.covariance
    model = fit.model
    A = np.zeros((0, fit.layout.size))

    def missed(model: AxisModel) -> FloatArray:
        """How far the held entries are from their values at ``model``."""
        ex = extract(list(model.axes), model.target, plane)
        return _difference(shown_vector(ex, rows, nominal_rows)[idx], values, angular[idx])

    for _ in range(MAX_STEPS):
        c = missed(model)
        if float(np.max(np.abs(c))) <= MET and A.shape[0]:
            break  # the last step's Jacobian: the constraints' rows to first order
        A = shown_jacobian(fit, model, extract, plane, rows, nominal_rows)[idx]
        if float(np.max(np.abs(c))) <= MET:
            break
        CA = C @ A.T
        delta = -CA @ np.linalg.pinv(A @ CA) @ c
        model = model.moved(np.asarray(delta, dtype=np.float64), fit.layout, model.bases())
    else:
        if float(np.max(np.abs(missed(model)))) > MET:
            raise DhlogError("holding the undetermined parameters at the nominal did not converge.")
    return replace(fit, model=model, bases=model.bases(), covariance=_project(C, A))


def free_directions(C: FloatArray) -> FloatArray:
    """The directions (size, r; parameter units) a covariance leaves free: its range."""
    d = np.sqrt(np.clip(np.diag(C), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    lam, V = np.linalg.eigh(C / np.outer(d, d))
    keep = lam > 1e-10 * max(float(lam[-1]), 1e-300)
    return np.asarray(d[:, None] * V[:, keep], dtype=np.float64)


def _refitted(
    held: WholeFit,
    refit: Callable[[AxisModel, FloatArray], AxisModel],
    indices: list[int],
    values: FloatArray,
    extract: Extractor,
    plane: Plane | None,
    rows: frozenset[int],
    nominal_rows: StandardDH | None,
) -> WholeFit:
    """``held`` refitted within the directions its covariance leaves free, the pair relations
    snapped again, the held entries put back on their values (moves of the second order)."""
    model = refit(held.model, free_directions(held.covariance))
    again = replace(held, model=model, bases=model.bases())
    if held.constrained:
        kinds = held.constrained
        again = constrain_pairs(
            again,
            [i for i, k in kinds.items() if k == "parallel"],
            [i for i, k in kinds.items() if k == "collinear"],
        )
    return hold_at(again, indices, values, extract, plane, rows, nominal_rows)


def may_hold(shown_std: FloatArray | None, rows: frozenset[int]) -> bool:
    """Whether any entry of the shown table has a σ (``shown_std``, 4n; NaN where fixed) beyond
    its bound: only then can :func:`hold_unseen` hold something (the same σ, from the whole
    covariance), so the run skips its Jacobian otherwise."""
    if shown_std is None:
        return True
    n = shown_std.size // 4
    angular = mixed_angles(n, rows)
    bound = np.where(angular, BOUND_ANGLE, BOUND_LENGTH)
    return bool(np.any(np.nan_to_num(shown_std, nan=0.0) > bound))


def hold_unseen(
    fit: WholeFit,
    extract: Extractor,
    plane: Plane | None,
    rows: frozenset[int],
    nominal: StandardDH | None,
    nominal_rows: StandardDH | None,
    cost: Callable[[WholeFit], float],
    refit: Callable[[AxisModel, FloatArray], AxisModel] | None = None,
) -> tuple[WholeFit, list[Held], tuple[Note, ...]]:
    """The fit with every shown entry the samples do not determine (:func:`unseen`) held at
    the nominal (:func:`hold_at`), what was held, and one warning (``unseen``) naming each, its
    σ before, and what would determine it. Entries without a nominal value, and all of them
    when holding costs the samples more than the constraints' own χ² allows (the samples
    reject the nominal there), are left as fitted and marked not determined (``at_nominal`` False).

    ``refit(model, within)``: the whole-model fit again from ``model``, moving only along
    ``within`` (the directions the held covariance leaves free: neither the held entries nor
    the pair relations move): the first-order hold is exact for the held entries but leaves
    the rest of the model off its optimum by the second order of the move (a tilt of degrees
    about a point 80 mm up the axis: 0.1 mm), which the refit takes up."""
    n = fit.model.n
    J = shown_jacobian(fit, fit.model, extract, plane, rows, nominal_rows)
    chosen = unseen(fit, J, rows)
    if not chosen:
        return fit, [], ()
    names = _names(n, rows)
    angular = mixed_angles(n, rows)
    target = nominal_vector(nominal, rows, nominal_rows)
    at = [k for k, _ in chosen if target is not None and math.isfinite(float(target[k]))]
    held_fit, why = fit, ""
    if at and target is not None:
        try:
            moved = hold_at(fit, at, target[at], extract, plane, rows, nominal_rows)
            if refit is not None:
                moved = _refitted(moved, refit, at, target[at], extract, plane, rows, nominal_rows)
        except (DhlogError, np.linalg.LinAlgError) as exc:
            moved, why = None, f"the hold failed ({exc})"
        if moved is not None:
            # χ² of len(at) degrees of freedom beyond its mean by 10 of its σ (as the pair
            # relations): only a nominal the samples clearly reject is refused
            allowed = fit.chi2_dof * (len(at) + 10.0 * math.sqrt(2.0 * len(at)))
            grown = cost(moved) - cost(fit)
            if grown <= allowed:
                held_fit = moved
            else:
                why = (
                    f"holding them at the nominal costs the samples χ² {grown:.1f} (the "
                    f"constraints alone allow {allowed:.1f})"
                )
    at_nominal = held_fit is not fit
    held = [Held(k, names[k], s, bool(angular[k]), at_nominal and k in at) for k, s in chosen]
    listed = ", ".join(
        f"{h.name} (σ {math.degrees(h.sigma):.3g}°)"
        if h.angular
        else f"{h.name} (σ {h.sigma * 1e3:.3g} mm)"
        for h in held
    )
    # row i relates axes i and i+1: poses that turn both over more of their range see it
    joints = sorted({j for h in held for j in (h.index // 4 + 1, h.index // 4 + 2) if j <= n})
    determine = (
        "measure the target's orientation (a 6-DoF probe), put the target farther from the "
        f"last axes, or add poses that turn joints {', '.join(map(str, joints))} over more of "
        "their range"
    )
    if at_nominal:
        kept = [h.name for h in held if not h.at_nominal]
        said = (
            f"these samples do not determine {listed} (σ beyond {math.degrees(BOUND_ANGLE):g}° "
            f"or {BOUND_LENGTH * 1e3:g} mm): held at the nominal and marked fixed"
            + (f" ({', '.join(kept)}: no nominal value in this form, not measured)" if kept else "")
            + f"; to determine them, {determine}."
        )
    else:
        cause = (
            "without a nominal to hold them at"
            if target is None
            else (why or "the nominal has no value for them in this form")
        )
        said = (
            f"these samples do not determine {listed} (σ beyond {math.degrees(BOUND_ANGLE):g}° "
            f"or {BOUND_LENGTH * 1e3:g} mm): {cause}, they are left as fitted and marked "
            f"fixed, not measurements; to determine them, {determine}."
        )
    held_fit = replace(held_fit, held={h.index: h.reason for h in held})
    return held_fit, held, (Note.warning(said, "unseen"),)
