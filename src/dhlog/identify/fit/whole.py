"""Maximum-likelihood fit of the whole kinematic model (:mod:`dhlog.identify.fit.axismodel`) to
every sample.

The normal equations ``JᵀWJ δ = −JᵀWr`` are accumulated over chunks of samples
(:mod:`dhlog.identify.fit.passes`, the analytic Jacobian of :mod:`dhlog.identify.fit.prediction`)
and solved by Levenberg–Marquardt within the directions the samples determine (:class:`Determined`),
first on an evenly strided subset, then finished on every sample. Gross outliers are held out by a
truncated quadratic at ``threshold`` times the noise scale. The covariance of the parameters is
``(JᵀWJ)⁻¹ · χ²/dof``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.lm import levenberg_marquardt
from dhlog.identify.fit.passes import Samples, accumulate, gradient
from dhlog.identify.fit.prediction import orientation_residual, predict_orientation
from dhlog.identify.segment.persample import blocks
from dhlog.io import scratch
from dhlog.model.dh import JointType

#: Median of a 3-dof chi variable (|r|/σ of an isotropic 3-D residual).
CHI3_MEDIAN = 1.5382
#: Expected decrease of the weighted cost below which the fit has converged (a step of about
#: 1 % of σ in every parameter).
CONVERGED = 1e-3
#: A direction of the column-scaled normal matrix ``JᵀWJ`` whose eigenvalue is below this
#: fraction of the largest (a singular value of the scaled Jacobian below 10⁻⁶ of the largest)
#: is not determined by the samples: held at the start (the nominal) and reported.
UNDETERMINED = 1e-12


@dataclass(frozen=True)
class Determined:
    """What the samples determine of the model (as in base-parameter identification: the
    eigen-decomposition of the column-scaled ``JᵀWJ``, i.e. the SVD of the scaled Jacobian).

    ``scale`` (size,): the column scales (√ of the diagonal); ``basis`` (size, r): the
    determined directions in scaled coordinates (orthonormal); ``values`` (r,) their
    eigenvalues; ``null`` (size, k): the undetermined directions (scaled, orthonormal);
    ``condition``: √(largest / smallest determined eigenvalue), the scaled Jacobian's
    condition number; ``weakest`` (size,): the least determined of the determined directions."""

    scale: FloatArray
    basis: FloatArray
    values: FloatArray
    null: FloatArray
    condition: float
    weakest: FloatArray

    @classmethod
    def of(cls, H: FloatArray, within: FloatArray | None = None) -> Determined:
        """``within`` (size, r; parameter units): the directions the fit may move along (a
        constrained fit: :mod:`dhlog.identify.model.hold`); the others are neither determined nor
        undetermined but held, in neither ``basis`` nor ``null``."""
        diag = np.diag(H)
        scale = np.where(diag > 0, np.sqrt(np.abs(diag)), 1.0)
        Hs = H / np.outer(scale, scale)
        if within is None:
            lam, V = np.linalg.eigh((Hs + Hs.T) / 2)
        else:
            U, sv, _ = np.linalg.svd(within * scale[:, None], full_matrices=False)
            N = U[:, sv > 1e-9 * max(float(sv[0]), 1e-300)] if sv.size else U[:, :0]
            lam, Vn = np.linalg.eigh(N.T @ ((Hs + Hs.T) / 2) @ N)
            V = N @ Vn
        top = max(float(lam[-1]), 1e-300)
        keep = lam > UNDETERMINED * top
        kept = lam[keep]
        return cls(
            scale,
            V[:, keep],
            kept,
            V[:, ~keep],
            float(np.sqrt(top / kept[0])) if kept.size else math.inf,
            V[:, keep][:, 0] if kept.size else V[:, 0],
        )

    def weakest_terms(self, names: Sequence[str], count: int = 4) -> list[tuple[str, float]]:
        """The weakest determined direction's largest components (name, coefficient), in the
        scaled parameters (unit length), largest first."""
        w = self.weakest / np.linalg.norm(self.weakest)
        order = np.argsort(-np.abs(w))[:count]
        return [(names[int(k)], float(w[k])) for k in order if abs(w[k]) >= 0.05]

    def document(self, names: Sequence[str]) -> dict[str, object]:
        """For the result JSON: the parameter counts, the condition number and the weakest
        direction (the fit's own parameters: axis tilts and shifts, target, …)."""
        return {
            "parameters": int(self.scale.size),
            "determined": int(self.basis.shape[1]),
            "condition_number": self.condition,
            "weakest_direction": {k: v for k, v in self.weakest_terms(names, 6)},
            "undetermined_directions": [
                {names[int(k)]: float(c) for k, c in enumerate(col) if abs(c) >= 0.05}
                for col in self.null.T
            ],
        }

    def solve(self, H: FloatArray, g: FloatArray, damping: float = 0.0) -> FloatArray:
        """The step ``δ`` minimising ``½ δᵀ(H + damping·diag H)δ + gᵀδ`` within the determined
        directions (none along the undetermined ones)."""
        B = self.basis / self.scale[:, None]  # back to parameter units
        A = B.T @ H @ B
        A = A + damping * np.diag(np.maximum(np.diag(A), 1e-30))
        return np.asarray(B @ np.linalg.solve(A, -(B.T @ g)), dtype=np.float64)

    def inverse(self, H: FloatArray) -> FloatArray:
        """``H``'s inverse within the determined directions (zero along the others)."""
        B = self.basis / self.scale[:, None]
        return np.asarray(B @ np.linalg.solve(B.T @ H @ B, B.T), dtype=np.float64)


@dataclass(frozen=True)
class WholeFit:
    """The fitted model, its covariance (``layout`` order), and what the fit saw.

    ``inliers`` is over the samples given; ``chi2_dof`` is the weighted residual variance per
    degree of freedom (1 when the noise model is right).
    """

    model: AxisModel
    layout: ParameterLayout
    covariance: FloatArray
    inliers: NDArray[np.bool_]
    chi2_dof: float
    n_points: int
    iterations: int
    bases: list[tuple[FloatArray, FloatArray]] = field(default_factory=list)
    constrained: dict[int, str] = field(default_factory=dict)
    sigma_rotation: float | None = None
    #: what the samples determine (None: not computed)
    determined: Determined | None = None
    #: entries of the shown DH table (4 per row: θ, d or β, a, α) the samples do not determine
    #: within a physical bound, held at the nominal or marked so (:mod:`dhlog.identify.model.hold`):
    #: index → the reason
    held: dict[int, str] = field(default_factory=dict)
    #: the whitened residual norm beyond which a sample was an outlier of the fit (inf: none)
    limit: float = math.inf


@dataclass(frozen=True)
class _State:
    """A point of the fit: the model, its bases, the normal equations, the truncated cost, the
    inliers' count and χ², every sample's residual norm, the iterations that led to it."""

    model: AxisModel
    bases: list[tuple[FloatArray, FloatArray]]
    H: FloatArray
    g: FloatArray
    cost: float
    count: int
    chi2: float
    norms: FloatArray
    iterations: int = 0


def _levenberg_marquardt(
    model: AxisModel,
    layout: ParameterLayout,
    data: Samples,
    limit: float,
    max_iterations: int,
    progress: Callable[[float], None] | None = None,
    within: FloatArray | None = None,
) -> _State:
    """Levenberg–Marquardt from ``model`` over ``data`` with the truncation ``limit`` (steps
    along ``within`` only, when given)."""
    m = data.Q.shape[0]
    bases = model.bases()
    norms = scratch.zeros(m)
    st = _State(model, bases, *accumulate(model, layout, bases, data, limit, norms), norms)
    if data.per_sample * st.count <= layout.size:
        raise DegenerateGeometryError(
            f"the whole-model fit has {st.count} usable samples ({data.per_sample} residuals "
            "each) for "
            f"{layout.size} parameters."
        )
    determined = Determined.of(st.H, within)  # the samples' symmetries: the same along the way

    def trial(state: _State, delta: FloatArray) -> _State:
        moved = state.model.moved(delta, layout, state.bases)
        moved_bases = moved.bases()
        tnorms = scratch.zeros(m)
        return _State(
            moved, moved_bases, *accumulate(moved, layout, moved_bases, data, limit, tnorms), tnorms
        )

    def settle(state: _State, delta: FloatArray) -> _State:
        """A step far below σ: taken, H kept (the same to first order)."""
        moved = state.model.moved(delta, layout, state.bases)
        return replace(state, model=moved, bases=moved.bases())

    final, iterations = levenberg_marquardt(
        st,
        solve=determined.solve,
        trial=trial,
        settle=settle,
        small=CONVERGED,
        floor=1.0,
        max_iterations=max_iterations,
        progress=None if progress is None else (lambda it: progress(min(it / 3.0, 0.95))),
    )
    return replace(final, iterations=iterations)


def _orientation_scale(
    start: AxisModel, layout: ParameterLayout, data: Samples, stride: int
) -> float:
    """A robust σ (rad, per component) of the measured orientations about the start model."""
    assert data.R is not None
    R_pred, _ = predict_orientation(start, data.Q[::stride], layout, start.bases())
    r = orientation_residual(R_pred, np.moveaxis(data.R[::stride], 0, 2))
    norm = np.sqrt(np.sum(r**2, axis=0))
    return max(float(np.median(norm)) / CHI3_MEDIAN, 1e-9)


def _finish_on_all(
    sub: _State,
    layout: ParameterLayout,
    data: Samples,
    limit: float,
    max_iterations: int,
    progress: Callable[[float], None] | None = None,
    within: FloatArray | None = None,
) -> tuple[_State, float]:
    """From the optimum ``sub`` of a strided subset to the optimum of every sample.

    One pass over every sample gives ``JᵀWr`` by the adjoint of the chain (:func:`gradient`)
    and the inliers; ``JᵀWJ`` is the subset's, scaled by the ratio of inlier counts (an evenly
    strided subset of smooth sweeps integrates the information like a quadrature rule: every σ
    within 0.03 % of the full sum's, the result within 0.001 µm, on the 1 M-sample benchmark
    log). The subset's optimum lies within a few of
    its own σ of the full optimum, where the model is linear to far below the noise (lengths of
    metres against residuals of micrometres), so the Gauss–Newton step from it is the optimum.
    With orientations, or should the step be larger than the subset's uncertainty explains,
    the full ``JᵀWJ`` is accumulated (and, for the latter, the fit goes on by
    Levenberg–Marquardt over every sample). Returns the state and the χ² at the optimum.
    """
    norms = scratch.zeros(data.Q.shape[0])
    if data.R is None and layout.terms_at is None:
        g, cost, count, chi2 = gradient(sub.model, layout, sub.bases, data, limit, norms, progress)
        H = sub.H * (count / max(sub.count, 1))
    else:
        H, g, cost, count, chi2 = accumulate(
            sub.model, layout, sub.bases, data, limit, norms, progress
        )
    try:
        delta = Determined.of(H, within).solve(H, g)
    except np.linalg.LinAlgError:
        delta = None
    if delta is not None and float(delta @ sub.H @ delta) <= 100.0 * layout.size:
        model = sub.model.moved(delta, layout, sub.bases)
        decrease = float(-(g @ delta))  # the quadratic model's decrease: exact to first order
        state = _State(model, model.bases(), H, g, cost - decrease, count, chi2, norms, 1)
        return state, max(chi2 - decrease, 0.0)
    st = _levenberg_marquardt(sub.model, layout, data, limit, max_iterations, within=within)
    return st, st.chi2


def fit_whole_model(
    start: AxisModel,
    data: FitData,
    options: FitOptions,
    *,
    progress: Callable[[float], None] | None = None,
    within: FloatArray | None = None,
) -> WholeFit:
    """Levenberg–Marquardt fit of ``start`` to ``data``'s samples (:class:`FitData`: points ``P``
    at encoder values ``Q``; each sample's covariance, target, orientation and the joints' speeds
    where given; the samples ``keep`` that may enter), weighted and judged as ``options`` says
    (:class:`FitOptions`). With the joints' speeds the residual clock offset is fitted too
    (``model.clock``).

    With more than ``options.subsample`` samples the fit first converges on an evenly strided
    subset and then finishes on every sample (usually one pass: the step left is far below σ).
    With ``within`` (size, r) the fit moves along those directions only (parameter units): the
    constrained fit of :mod:`dhlog.identify.model.hold`."""
    from dhlog.model.noise import whitening_from_std

    Q, P, keep, which, rotations = data.Q, data.P, data.keep, data.which, data.rotations
    sample_cov, rates, noise, sigma = data.sample_cov, data.rates, options.noise, options.sigma
    sigma_rotation, threshold = options.sigma_rotation, options.threshold
    max_iterations, subsample = options.max_iterations, options.subsample
    m = Q.shape[0]
    layout = ParameterLayout.of(
        start.types,
        fit_scales=options.fit_scales,
        extra_targets=len(start.extra_targets),
        rotation=rotations is not None,
        clock=rates is not None,
        terms=() if start.terms is None else start.terms.names(),
    )

    if start.held_axes:  # held axes (parked joints): held, neither determined nor undetermined
        within = _without_held(start, layout, within)

    def whiten(points: FloatArray, W: FloatArray | None) -> FloatArray | float:
        return W if W is not None else noise.whiten(points, sigma)

    samples = Samples(
        Q,
        P,
        scratch.full(m, True, np.bool_) if keep is None else scratch.moved(keep, copy=True),
        None if sample_cov is None else whitening_from_std(sample_cov),
        whiten,
        which,
        rotations,
        1.0 if sigma_rotation is None else sigma_rotation,
        rates,
    )
    stride = -(-m // subsample) if m > subsample else 1
    if rotations is not None and sigma_rotation is None:
        samples = replace(samples, sigma_rot=_orientation_scale(start, layout, samples, stride))
    first = samples.strided(stride) if stride > 1 else samples
    probe = np.zeros(first.Q.shape[0])
    accumulate(start, layout, start.bases(), first, threshold, probe)
    kept = probe[first.keep]
    scale = float(np.median(kept)) / CHI3_MEDIAN if kept.size else 1.0
    # the noise model is off by more than 2x: judge outliers on the data's own scale
    limit = threshold * scale if not 0.5 < scale < 2.0 else threshold
    on_subset = None if progress is None else (lambda f: progress(0.3 * f))
    st = _levenberg_marquardt(start, layout, first, limit, max_iterations, on_subset, within)
    if samples.R is not None and sigma_rotation is None:
        # the start's orientation scale includes the start's own error: judge it again at the
        # optimum of the subset and fit once more with it
        samples = replace(samples, sigma_rot=_orientation_scale(st.model, layout, samples, stride))
        first = samples.strided(stride) if stride > 1 else samples
        st = _levenberg_marquardt(st.model, layout, first, limit, max_iterations, on_subset, within)
    iterations = st.iterations
    chi2 = st.chi2
    if stride > 1:
        on_all = None if progress is None else (lambda f: progress(0.3 + 0.7 * f))
        st, chi2 = _finish_on_all(st, layout, samples, limit, max_iterations, on_all, within)
        iterations += st.iterations
    determined = Determined.of(st.H, within)
    if determined.basis.shape[1] == 0:
        raise DegenerateGeometryError(
            f"the samples determine none of the whole model's {layout.size} parameters: "
            "measure more poses, moving every joint."
        )
    inliers = scratch.empty(samples.keep.size, np.bool_)
    for sl in blocks(inliers.size):
        inliers[sl] = samples.keep[sl] & (st.norms[sl] <= limit)
    dof = max(samples.per_sample * st.count - determined.basis.shape[1], 1)
    chi2_dof = chi2 / dof
    covariance = determined.inverse(st.H) * chi2_dof
    return WholeFit(
        model=st.model,
        layout=layout,
        covariance=np.asarray(covariance, dtype=np.float64),
        inliers=inliers,
        chi2_dof=float(chi2_dof),
        n_points=int(st.count),
        iterations=iterations,
        bases=st.bases,
        sigma_rotation=None if samples.R is None else samples.sigma_rot * math.sqrt(chi2_dof),
        determined=determined,
        limit=float(limit),
    )


def _without_held(
    model: AxisModel, layout: ParameterLayout, within: FloatArray | None
) -> FloatArray:
    """The directions (size, r) the fit may move along with the parameters of ``model``'s held
    axes taken out of ``within`` (default: every direction)."""
    free = np.ones(layout.size, dtype=bool)
    for i in model.held_axes:
        k = layout.axis_at[i]
        free[k : k + (4 if model.types[i] is JointType.REVOLUTE else 2)] = False
    if within is None:
        return np.asarray(np.eye(layout.size)[:, free], dtype=np.float64)
    return np.asarray(within * free[:, None], dtype=np.float64)
