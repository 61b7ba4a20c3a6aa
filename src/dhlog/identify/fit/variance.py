"""What the residuals say beyond the declared noise: a model-error variance component, and the
design effect of several samples a pose.

* :func:`refit_with_model_error`: where the declared uncertainties (per-sample covariances, a
  tracker model) are far below the residuals, the model, not the tracker, limits the fit; an
  isotropic model-error variance is estimated (χ²/dof = 1, the method of moments) and added to
  every sample's covariance (``σᵢ² = σ_meas,ᵢ² + σ_model²``), and the fit done again — so that
  weighting by an export's U95 of a few µm never makes a result worse than no weighting when the
  robot leaves tens of µm.
* :func:`design_effect`: static poses measured with several samples each share their pose's
  error (gravity, gears), so the samples are not independent and ``(JᵀWJ)⁻¹ χ²`` is too small by
  up to √(samples a pose); the factor ``1 + (k̄ − 1) ρ`` (k̄ samples a pose, ρ the share of the
  whitened residual variance common to a pose) restores it.

Pure numpy/scipy.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.leaveout import still_pose_blocks
from dhlog.identify.fit.passes import CHUNK
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.whole import WholeFit, fit_whole_model
from dhlog.identify.segment.persample import SampleArray, blocks
from dhlog.model.noise import NoiseModel, model_error_sigma, whitening_from_std

#: Per-sample uncertainties this far below the residuals (χ²/dof above it) call for a
#: model-error variance component.
MODEL_ERROR_CHI2 = 2.0
#: A design effect below this is not applied (nor said).
SMALL_EFFECT = 1.1
#: What a geometric model leaves that a tracker's stated uncertainty does not explain.
MODEL_ERROR_CAUSES = (
    "likely causes: gravity bending the joints and links (compliance), gear and encoder errors "
    "that vary with the angle, thermal drift during the session, a target that slipped on the "
    "flange, or a declared noise model more optimistic than the tracker"
)


@dataclass(frozen=True)
class ModelError:
    """The fit again with the model error: ``sigma`` (m, per coordinate), the covariances it
    used, and the χ²/dof before."""

    fit: WholeFit
    sigma: float
    sample_cov: FloatArray
    chi2_before: float


def refit_with_model_error(
    whole: WholeFit, data: FitData, declared: FloatArray, options: FitOptions
) -> ModelError | None:
    """The model-error component (module docstring) of ``whole``, fitted to ``data`` with the
    declared covariances ``declared`` (m, 3, 3) and the fit's other ``options`` (noise,
    orientations, …); None when χ²/dof is at most :data:`MODEL_ERROR_CHI2`."""
    if whole.chi2_dof <= MODEL_ERROR_CHI2:
        return None
    before = whole.chi2_dof
    s, cov = 0.0, declared
    for _ in range(2):  # the residuals barely move with the weights: twice is converged
        inl = whole.inliers
        r = residuals(whole.model, data.Q, data.P, inl, which=data.which, rates=data.rates)
        dof = max(3 * int(np.count_nonzero(inl)) - whole.layout.size, 1)
        s = model_error_sigma(r, declared[inl], dof)
        cov = declared + (s * s) * np.eye(3)[None]
        whole = fit_whole_model(
            whole.model, replace(data, sample_cov=cov, keep=None), replace(options, sigma=s)
        )
    return ModelError(whole, s, cov, before)


def residuals(
    model: AxisModel,
    Q: SampleArray,
    P: SampleArray,
    rows: NDArray[np.bool_],
    *,
    which: NDArray[np.int64] | None = None,
    rates: SampleArray | None = None,
) -> FloatArray:
    """The position residuals ``P − model`` (k, 3) of the samples ``rows`` (a mask), predicted
    a block at a time."""
    out = np.empty((int(np.count_nonzero(rows)), 3))
    done = 0
    for sl in blocks(Q.shape[0], CHUNK):
        at = sl.start + np.flatnonzero(rows[sl])
        if at.size:
            out[done : done + at.size] = _residuals_at(model, at, Q, P, which, rates)[0]
            done += at.size
    return out


def _residuals_at(
    model: AxisModel,
    at: NDArray[np.intp] | slice,
    Q: SampleArray,
    P: SampleArray,
    which: NDArray[np.int64] | None,
    rates: SampleArray | None,
    q: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The position residuals ``P − model`` (k, 3) of the samples ``at`` and their points
    (``q``: their joint values where already at hand)."""
    pred, _ = predict(
        model,
        Q[at] if q is None else q,
        which=None if which is None else which[at],
        rates=None if rates is None else rates[at],
    )
    points = P[at]
    return points - pred, points


def residual_norms(
    model: AxisModel,
    Q: SampleArray,
    P: SampleArray,
    *,
    which: NDArray[np.int64] | None = None,
    rates: SampleArray | None = None,
) -> FloatArray:
    """The length of every sample's position residual under ``model`` (m,), a block at a time."""
    out = np.empty(Q.shape[0])
    for sl in blocks(Q.shape[0], CHUNK):
        out[sl] = np.linalg.norm(_residuals_at(model, sl, Q, P, which, rates)[0], axis=1)
    return out


#: The whitening of the samples ``rows`` (a mask) at ``points``: a scalar or (m, 3, 3).
Whiten = Callable[[FloatArray, NDArray[np.intp]], FloatArray | float]


def whitened_residuals(
    fit: WholeFit,
    rows: NDArray[np.bool_] | NDArray[np.intp],
    Q: SampleArray,
    P: SampleArray,
    whiten: Whiten,
    *,
    which: NDArray[np.int64] | None = None,
    rates: SampleArray | None = None,
) -> FloatArray:
    """The whitened position residuals (k, 3) of the samples ``rows`` (a mask or indices) under
    ``fit``, predicted ``CHUNK`` samples at a time: the chain's per-sample motions of every
    sample at once took 0.9 GiB at a million samples."""
    index = np.flatnonzero(rows) if rows.dtype == np.bool_ else np.asarray(rows, dtype=np.intp)
    out = np.empty((index.size, 3))
    for start in range(0, index.size, CHUNK):
        at = index[start : start + CHUNK]
        out[start : start + at.size] = _whitened(fit, at, Q, P, whiten, which, rates)
    return out


def _whitened(
    fit: WholeFit,
    at: NDArray[np.intp],
    Q: SampleArray,
    P: SampleArray,
    whiten: Whiten,
    which: NDArray[np.int64] | None,
    rates: SampleArray | None,
    q: FloatArray | None = None,
) -> FloatArray:
    """The whitened position residuals of the samples ``at`` (indices) under ``fit`` (``q``:
    their joint values where already at hand)."""
    r, points = _residuals_at(fit.model, at, Q, P, which, rates, q)
    W = whiten(points, at)
    return r * W if isinstance(W, float) else np.einsum("mij,mj->mi", W, r)


@dataclass(frozen=True)
class Pass:
    """One pass over every sample under a model: each sample's 3-D residual (``norms``, m) and
    the whitened sum of squares of the samples of a mask (``squares``)."""

    norms: FloatArray
    squares: float


def residual_pass(
    fit: WholeFit,
    rows: NDArray[np.bool_],
    Q: SampleArray,
    P: SampleArray,
    whiten: Whiten,
    *,
    which: NDArray[np.int64] | None = None,
    rates: SampleArray | None = None,
) -> Pass:
    """:func:`residual_norms` and the whitened sum of squares of ``rows`` under ``fit``, in one pass
    a block at a time
    (what the relations' test and the outliers' names both read of the model they keep)."""
    norms = np.empty(Q.shape[0])
    total = 0.0
    for sl in blocks(Q.shape[0], CHUNK):
        r, points = _residuals_at(fit.model, sl, Q, P, which, rates)
        norms[sl] = np.linalg.norm(r, axis=1)
        use = np.flatnonzero(rows[sl])
        if use.size:
            W = whiten(points[use], sl.start + use)
            rw = r[use] * W if isinstance(W, float) else np.einsum("mij,mj->mi", W, r[use])
            total += float(np.sum(rw**2))
    return Pass(norms, total)


@dataclass(frozen=True)
class DesignEffect:
    """``effect`` = 1 + (k̄ − 1) ρ of ``samples`` at ``poses`` (``per_pose`` = k̄), ``rho``;
    ``squares``: the whitened sum of squares of those samples (the fit's inliers)."""

    effect: float
    rho: float
    samples: int
    poses: int
    squares: float

    @property
    def per_pose(self) -> float:
        return self.samples / self.poses


def design_effect(
    whole: WholeFit,
    Q: SampleArray,
    P: SampleArray,
    whiten: Whiten,
    *,
    which: NDArray[np.int64] | None = None,
    rates: SampleArray | None = None,
) -> DesignEffect:
    """The design effect of the fit's inliers grouped by still pose (module docstring;
    :func:`~dhlog.identify.fit.leaveout.still_pose_blocks`: within 1 mrad of the pose's first
    sample, so a slow move under a fast tracker is not one pose), in one pass
    over the samples: a pose's samples are consecutive, so each pose's sum of whitened
    residuals is complete when the next pose starts (only the one open at a block's end is
    carried). ``whiten(points, rows)``: the whitening of the samples ``rows`` (a scalar or
    (m, 3, 3)). The effect is 1 where poses hold fewer than two samples on average (sweeps:
    about a pose a sample, nothing to scale)."""
    m, g, last = 0, 0, -1
    squares = between = 0.0  # Σ|r|², Σ_pose |Σ r|² / n
    carry_sum, carry_n = np.zeros(3), 0
    for sl, poses, q in still_pose_blocks(Q):
        use = np.flatnonzero(whole.inliers[sl])
        if not use.size:
            continue
        mine = poses[use]
        new = np.empty(mine.size, dtype=bool)
        new[0] = mine[0] != last
        new[1:] = mine[1:] != mine[:-1]
        local = np.cumsum(new) - int(new[0])  # 0: the carried pose, where new[0] is False
        size = int(local[-1]) + 1
        rw = np.empty((use.size, 3))
        for part in blocks(use.size, CHUNK):
            at = use[part]
            rw[part] = _whitened(whole, sl.start + at, Q, P, whiten, which, rates, q[at])
        sums = np.column_stack(
            [np.bincount(local, weights=rw[:, k], minlength=size) for k in range(3)]
        )
        count = np.bincount(local, minlength=size).astype(np.float64)
        if not new[0]:
            sums[0] += carry_sum
            count[0] += carry_n
        elif carry_n:
            between += float(carry_sum @ carry_sum) / carry_n
        between += float(np.sum(sums[:-1] ** 2 / count[:-1, None]))
        carry_sum, carry_n = sums[-1], int(count[-1])
        squares += float(np.sum(rw**2))
        g += int(np.count_nonzero(new))
        m, last = m + use.size, int(mine[-1])
    if carry_n:
        between += float(carry_sum @ carry_sum) / carry_n
    if g == 0 or m < 2 * g or m - g < 3:
        return DesignEffect(1.0, 0.0, m, max(g, 1), squares)
    # within-pose Σ|r − r̄|² = Σ|r|² − Σ_pose n |r̄|²
    within = (squares - between) / (3 * (m - g))
    total = squares / max(3 * m - whole.layout.size, 1)
    rho = min(max(1.0 - within / total, 0.0), 1.0) if total > 0 else 0.0
    return DesignEffect(1.0 + (m / g - 1.0) * rho, rho, m, g, squares)


def with_model_error(
    whole: WholeFit,
    Q: SampleArray,
    P: SampleArray,
    sample_cov: FloatArray | None,
    noise: NoiseModel,
    which: NDArray[np.int64] | None,
    rates: SampleArray | None,
    rotations: FloatArray | None,
) -> tuple[WholeFit, FloatArray | None, NoiseModel, tuple[Note, ...]]:
    """The model-error component (:func:`refit_with_model_error`) where the declared
    uncertainties (per-sample covariances, the tracker model ``noise``) are far below the
    residuals, said in a warning (``model-error``). Returns the fit, the covariances it used,
    the noise model (with its model-error σ) and that warning."""
    declared = sample_cov
    if declared is None and noise.model == "tracker":
        declared = noise.covariance(P[:])  # (m, 3, 3): a tracker model's weighing holds them
    if declared is None:
        return whole, sample_cov, noise, ()
    data = FitData(Q, P, which=which, rotations=rotations, rates=rates)
    options = FitOptions(
        noise,
        1.0,  # the model-error σ's, set by the refit
        sigma_rotation=noise.orientation,
        fit_scales=whole.layout.scale_at is not None,
    )
    found = refit_with_model_error(whole, data, declared, options)
    if found is None:
        return whole, sample_cov, noise, ()
    noise = replace(noise, model_error=found.sigma)
    said = (
        f"the residuals are {math.sqrt(found.chi2_before):.1f}x what the declared "
        f"uncertainties ({noise.declared}) explain (χ²/dof {found.chi2_before:.1f}): "
        f"the model (or an optimistic noise model), not the tracker, limits the fit; a "
        f"model-error σ of {found.sigma * 1e3:.4f} mm per coordinate was estimated and added "
        f"to every sample's ({MODEL_ERROR_CAUSES})."
    )
    return found.fit, found.sample_cov, noise, (Note.warning(said, "model-error"),)


def whitening(noise: NoiseModel, sample_cov: FloatArray | None, sigma: float) -> Whiten:
    """The whitening of samples ``rows`` at ``points``: their own covariances when the log
    carries them, else the noise model's (isotropic σ ``sigma`` unless it names its own)."""

    def whiten(points: FloatArray, rows: NDArray[np.intp]) -> FloatArray | float:
        if sample_cov is not None:
            return whitening_from_std(sample_cov[rows])
        return noise.whiten(points, sigma)

    return whiten


def pose_clustered(
    whole: WholeFit,
    Q: SampleArray,
    P: SampleArray,
    whiten: Whiten,
    which: NDArray[np.int64] | None,
    rates: SampleArray | None,
) -> tuple[WholeFit, float, tuple[Note, ...]]:
    """The covariance times the design effect of several samples a pose (:func:`design_effect`)
    where it reaches :data:`SMALL_EFFECT`, said in a note (``pose-clustered``); and the
    whitened sum of squares of the fit's inliers, found on the way."""
    d = design_effect(whole, Q, P, whiten, which=which, rates=rates)
    if d.effect < SMALL_EFFECT:
        return whole, d.squares, ()
    said = (
        f"{d.samples} samples at {d.poses} poses ({d.per_pose:.1f} a pose) share their pose's "
        f"error ({d.rho:.0%} of the residual variance): the uncertainty is scaled by the "
        f"design effect, σ x{math.sqrt(d.effect):.2f}."
    )
    clustered = replace(whole, covariance=whole.covariance * d.effect)
    return clustered, d.squares, (Note.info(said, "pose-clustered"),)
