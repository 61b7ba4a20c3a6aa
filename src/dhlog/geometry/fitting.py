"""Fits of planes and lines to measured points, the robust fit of a joint's axis (a circle or a
line, gross outliers set aside) and the guess of a joint's type from its sweep.

A plane by SVD (seed 002, Eq. 8–9); a prismatic joint's line by total least squares or, with
encoder values, by regression on them; circles in :mod:`dhlog.geometry.circles`. Every axis fit
returns an :class:`~dhlog.geometry.axisfit.AxisFit`: the axis oriented along the joint's positive
motion, the per-sample residuals, the travel, the noise ``σ`` estimated from the residuals and the
first-order covariance of the axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dhlog.errors import CollinearPointsError, EncoderScaleError, SweepTooSmallError
from dhlog.geometry._checks import FloatArray, check_points, perpendicular_basis
from dhlog.geometry.axisfit import (
    MIN_SWEEP,
    MIN_TRAVEL,
    AxisFit,
    check_encoder,
    check_samples,
    sense,
)
from dhlog.geometry.circles import CircleMethod, algebraic_circle, circle_residuals, fit_circle
from dhlog.geometry.lines import Line, Plane


@dataclass(frozen=True, eq=False)
class PlaneFit:
    """A plane fitted by SVD, with the signed residual of every point (m) and their RMS.

    ``covariance`` (3, 3) is that of ``[δn·u, δn·v, δ(offset)]``: the tilt of the normal (rad)
    towards the in-plane unit vectors ``basis = (u, v)`` and the shift of the plane along its
    normal at ``plane.point`` (m), with σ from the residuals.
    """

    plane: Plane
    residuals: FloatArray
    rms: float
    basis: FloatArray
    covariance: FloatArray


def fit_plane(
    points: ArrayLike, *, what: str = "base plane", sigma: float | None = None
) -> PlaneFit:
    """Least-squares plane by SVD of the centred points (seed 002, Eq. 8–9): ``n = v3``.

    ``points`` (m, 3). The normal's sign is chosen so that it has a non-negative z component.
    The covariance takes the points' σ from their residuals, or ``sigma`` (m) where it is known
    (a plan: a dozen points estimate their own σ only to ±25 %).
    """
    pts = check_samples(points, what)
    centroid = pts.mean(axis=0)
    _, s, vt = np.linalg.svd(pts - centroid, full_matrices=False)
    if s[1] <= 1e-9 * s[0]:
        raise CollinearPointsError(what)
    normal = vt[2] if vt[2][2] >= 0.0 else -vt[2]
    plane = Plane(centroid, normal)
    residuals = plane.signed_distance(pts)
    m = pts.shape[0]
    sigma2 = float(residuals @ residuals) / max(m - 3, 1) if sigma is None else sigma**2
    u, v = perpendicular_basis(plane.normal)
    A = (pts - centroid) @ np.stack([u, v]).T
    cov = np.zeros((3, 3))
    cov[:2, :2] = sigma2 * np.linalg.inv(A.T @ A)
    cov[2, 2] = sigma2 / m
    return PlaneFit(plane, residuals, float(np.sqrt(np.mean(residuals**2))), np.stack([u, v]), cov)


def fit_line(
    points: ArrayLike,
    *,
    encoder: ArrayLike | None = None,
    min_travel: float = MIN_TRAVEL,
    scale_tol: float = 1e-3,
    max_scale_error: float = 0.1,
    what: str = "line fit",
) -> AxisFit:
    """Fit a prismatic joint's line; the axis direction points along increasing encoder value.

    Without encoder: total least squares (centroid and first right singular vector). With encoder
    values ``q`` (m, metres): the maximum-likelihood regression ``p_j = p0 + q_j w``, whose
    ``|w|`` is the encoder scale (fitted travel per encoder metre). A scale further than
    ``max_scale_error`` from 1 raises :class:`EncoderScaleError`; further than ``scale_tol`` warns.
    """
    pts = check_samples(points, what)
    m = pts.shape[0]
    q = check_encoder(encoder, m, what)
    centroid = pts.mean(axis=0)
    centred = pts - centroid
    warnings: list[str] = []
    scale: float | None = None
    if q is None:
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        direction = vt[0]
        t = centred @ direction
        if sense(t, np.arange(m, dtype=np.float64)) < 0.0:
            direction = -direction
            t = -t
        residuals = centred - np.outer(t, direction)
        dof = max(2 * m - 4, 1)
    else:
        qc = q - q.mean()
        sqq = float(qc @ qc)
        if sqq <= 0.0:
            raise SweepTooSmallError(what, 0.0, min_travel, "m")
        w = (qc @ centred) / sqq
        scale = float(np.linalg.norm(w))
        if scale == 0.0 or abs(scale - 1.0) > max_scale_error:
            raise EncoderScaleError(what, scale)
        if abs(scale - 1.0) > scale_tol:
            warnings.append(
                f"{what}: measured travel is {scale:.5f} times the encoder travel "
                f"({(scale - 1.0) * 100:+.3f} %)."
            )
        direction = w / scale
        t = centred @ direction
        residuals = centred - np.outer(qc, w)
        dof = max(3 * m - 6, 1)
    travel = float(t.max() - t.min())
    tc = t - t.mean()
    spread = float(tc @ tc)
    # a travel of denormals (offsets of 1e-320 m) squares to 0: no direction to speak of
    if travel < min_travel or not spread > 0.0 or not math.isfinite(spread):
        raise SweepTooSmallError(what, travel, min_travel, "m")
    sigma2 = float(np.sum(residuals**2)) / dof
    u, v = perpendicular_basis(direction)
    axis_cov = np.diag([sigma2 / spread] * 2 + [sigma2 / m] * 2)
    return AxisFit(
        axis=Line(centroid, direction),
        kind="line",
        method="line-encoder" if q is not None else "line-svd",
        n_points=m,
        center=centroid,
        radius=0.0,
        residuals=np.asarray(residuals, dtype=np.float64),
        rms=float(np.sqrt(np.mean(np.sum(residuals**2, axis=1)))),
        sweep=travel,
        sigma=math.sqrt(sigma2),
        positions=np.asarray(t - t.min(), dtype=np.float64),
        basis=np.stack([u, v]),
        axis_covariance=axis_cov,
        encoder_scale=scale,
        warnings=tuple(warnings),
    )


def detect_joint_type(points: ArrayLike, *, what: str = "joint") -> tuple[str, str]:
    """Whether a sweep looks prismatic or revolute, and why.

    A sweep is prismatic when a straight line fits it within the noise: the line's residual RMS
    is no more than 1.5 times the circle's (a circle fitted to a straight sweep only absorbs the
    noise), or the points are collinear outright. Returns ``("prismatic" | "revolute", reason)``.
    """
    pts = check_samples(points, what)
    line = fit_line(pts, min_travel=0.0, what=what)
    try:
        center, normal, radius = algebraic_circle(pts, what)
    except CollinearPointsError:
        return "prismatic", "the points are collinear"
    circle_rms = float(
        np.sqrt(np.mean(np.sum(circle_residuals(pts, center, normal, radius) ** 2, axis=1)))
    )
    ratio = line.rms / max(circle_rms, 1e-15)
    if ratio <= 1.5:
        return "prismatic", f"a line fits as well as a circle (RMS {line.rms * 1e6:.1f} µm)"
    return "revolute", f"a circle fits {ratio:.0f}x better than a line"


def fit_axis_robust(
    points: ArrayLike,
    *,
    kind: Literal["circle", "line"],
    encoder: ArrayLike | None = None,
    method: CircleMethod = "auto",
    threshold: float = 5.0,
    max_rounds: int = 5,
    min_sweep: float = MIN_SWEEP,
    what: str = "axis fit",
) -> tuple[AxisFit, NDArray[np.bool_]]:
    """A circle or line fit with iterative rejection of gross outliers.

    After each fit, samples whose orthogonal distance from the circle (or line) exceeds
    ``threshold`` times the robust noise scale (median distance / 1.1774, the median of a 2-dof
    chi variable) are set aside and the fit repeated, until nothing changes. Returns the fit on
    the inliers and the inlier mask over the input samples (a start fit on a subset judges
    the rest with :func:`inlier_limit` and :func:`within`).
    """
    pts = check_points(f"{what} points", points)
    q = None if encoder is None else np.asarray(encoder, dtype=np.float64).reshape(-1)
    keep = np.ones(pts.shape[0], dtype=bool)

    def run(mask: NDArray[np.bool_]) -> AxisFit:
        enc = None if q is None else q[mask]
        if kind == "line":
            return fit_line(pts[mask], encoder=enc, what=what)
        return fit_circle(pts[mask], encoder=enc, method=method, min_sweep=min_sweep, what=what)

    fit = run(keep)
    for _ in range(max_rounds):
        distance = orthogonal_distances(fit, pts)
        # median of a 2-dof chi variable is sqrt(2 ln 2) = 1.1774 σ
        scale = float(np.median(distance[keep])) / 1.1774
        new_keep = distance <= threshold * max(scale, 1e-12)
        if np.array_equal(new_keep, keep) or np.count_nonzero(new_keep) < 3:
            break
        keep = new_keep
        fit = run(keep)
    return fit, keep


def inlier_limit(fit: AxisFit, inliers: FloatArray, threshold: float = 5.0) -> float:
    """The largest orthogonal distance an inlier of ``fit`` may have: ``threshold`` times the
    robust noise scale of its ``inliers`` (their median distance / 1.1774)."""
    scale = float(np.median(orthogonal_distances(fit, inliers))) / 1.1774
    return threshold * max(scale, 1e-12)


def within(fit: AxisFit, pts: FloatArray, limit: float) -> NDArray[np.bool_]:
    """Whether each sample of ``pts`` lies within ``limit`` of ``fit`` (NaN: no)."""
    return np.asarray(orthogonal_distances(fit, pts) <= limit)


def orthogonal_distances(fit: AxisFit, pts: FloatArray) -> NDArray[np.float64]:
    """Distance of every sample from the fitted circle or line (the 2-dof orthogonal residual)."""
    if fit.kind == "line":
        rel = pts - fit.center
        d = fit.axis.direction
        return np.asarray(np.linalg.norm(rel - np.outer(rel @ d, d), axis=1), dtype=np.float64)
    residuals = circle_residuals(pts, fit.center, fit.axis.direction, fit.radius)
    return np.asarray(np.linalg.norm(residuals, axis=1), dtype=np.float64)
