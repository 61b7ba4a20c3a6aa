"""Circle fits of a revolute joint's sweep, each returning its oriented axis (:class:`AxisFit`).

Seed 002, Sec. 2.3 (SVD plane, then an algebraic least-squares circle in that plane, Eq. 8–10),
refined by the geometric (orthogonal-distance, maximum-likelihood) fit, or replaced by the
encoder-aided fit when each sample's joint angle is known. Every fit orients the axis along the
joint's positive motion (right-hand rule for increasing encoder value, or time order without
encoder) and reports the per-sample residuals, the swept angle, the noise ``σ`` estimated from the
residuals and the first-order covariance of the axis from the fit Jacobian.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import CollinearPointsError, SweepTooSmallError, TooFewPointsError
from dhlog.geometry._checks import FloatArray, perpendicular_basis, rotation_about
from dhlog.geometry.axisfit import MIN_SWEEP, AxisFit, check_encoder, check_samples, sense
from dhlog.geometry.lines import Line

CircleMethod = Literal["auto", "algebraic", "geometric", "encoder"]


def _order_key(encoder: FloatArray | None, m: int) -> FloatArray:
    return encoder if encoder is not None else np.arange(m, dtype=np.float64)


def _unwrapped_phases(
    pts: FloatArray, center: FloatArray, u: FloatArray, v: FloatArray, key: FloatArray
) -> FloatArray:
    """Angle of each point about the centre in the (u, v) basis, unwrapped along ``key`` order."""
    w = pts - center
    phase = np.arctan2(w @ v, w @ u)
    order = np.argsort(key, kind="stable")
    out = np.empty_like(phase)
    out[order] = np.unwrap(phase[order])
    return out


def circle_residuals(
    pts: FloatArray, center: FloatArray, normal: FloatArray, radius: float
) -> FloatArray:
    """Vector from the nearest point of the circle to each sample, shape (m, 3)."""
    w = pts - center
    h = w @ normal
    t = w - np.outer(h, normal)
    rho = np.linalg.norm(t, axis=1)
    t_hat = t / np.where(rho > 0.0, rho, 1.0)[:, None]
    return np.asarray(np.outer(h, normal) + (rho - radius)[:, None] * t_hat, dtype=np.float64)


def _free_angle_jacobian(
    pts: FloatArray, center: FloatArray, normal: FloatArray, basis: tuple[FloatArray, FloatArray]
) -> FloatArray:
    """Jacobian (2m, 6) of the orthogonal residuals ``[h; ρ − r]`` w.r.t. ``[c, a, b, r]``.

    The normal is perturbed as ``n + a u + b v``; ``h`` is the out-of-plane and ``ρ − r`` the radial
    distance of each sample from the circle.
    """
    u, v = basis
    w = pts - center
    h = w @ normal
    t = w - np.outer(h, normal)
    t_hat = t / np.linalg.norm(t, axis=1)[:, None]
    m = pts.shape[0]
    J = np.zeros((2 * m, 6))
    J[:m, :3] = -normal
    J[:m, 3] = w @ u
    J[:m, 4] = w @ v
    J[m:, :3] = -t_hat
    J[m:, 3] = -h * (t_hat @ u)
    J[m:, 4] = -h * (t_hat @ v)
    J[m:, 5] = -1.0
    return J


def _free_angle_covariance(
    pts: FloatArray, center: FloatArray, normal: FloatArray, radius: float
) -> tuple[float, FloatArray, FloatArray]:
    """σ estimated from the orthogonal residuals, and the axis covariance in the basis (u, v)."""
    u, v = perpendicular_basis(normal)
    r = circle_residuals(pts, center, normal, radius)
    m = pts.shape[0]
    dof = max(2 * m - 6, 1)
    sigma2 = float(np.sum(r * r)) / dof
    J = _free_angle_jacobian(pts, center, normal, (u, v))
    cov = sigma2 * np.linalg.pinv(J.T @ J)
    G = np.zeros((4, 6))
    G[0, 3] = G[1, 4] = 1.0
    G[2, :3], G[3, :3] = u, v
    return math.sqrt(sigma2), np.stack([u, v]), np.asarray(G @ cov @ G.T, dtype=np.float64)


def _finish_circle(
    pts: FloatArray,
    encoder: FloatArray | None,
    center: FloatArray,
    normal: FloatArray,
    radius: float,
    *,
    method: str,
    what: str,
    min_sweep: float,
) -> AxisFit:
    """Orient the axis, measure the sweep and attach residuals and covariance (free-angle model)."""
    key = _order_key(encoder, pts.shape[0])
    u, v = perpendicular_basis(normal)
    phases = _unwrapped_phases(pts, center, u, v, key)
    if sense(phases, key) < 0.0:
        normal = -normal
        u, v = perpendicular_basis(normal)
        phases = _unwrapped_phases(pts, center, u, v, key)
    sweep = float(phases.max() - phases.min())
    if sweep < min_sweep:
        raise SweepTooSmallError(what, sweep, min_sweep, "rad")
    sigma, basis, axis_cov = _free_angle_covariance(pts, center, normal, radius)
    residuals = circle_residuals(pts, center, normal, radius)
    return AxisFit(
        axis=Line(center, normal),
        kind="circle",
        method=method,
        n_points=pts.shape[0],
        center=center,
        radius=radius,
        residuals=residuals,
        rms=float(np.sqrt(np.mean(np.sum(residuals**2, axis=1)))),
        sweep=sweep,
        sigma=sigma,
        positions=phases,
        basis=basis,
        axis_covariance=axis_cov,
    )


def algebraic_circle(pts: FloatArray, what: str) -> tuple[FloatArray, FloatArray, float]:
    """Seed 002, Sec. 2.3: SVD plane of the centred points (Eq. 8–9), then the linear circle fit
    ``x² + y² = 2x c1 + 2y c2 + k3`` in that plane (Eq. 10), mapped back to 3D."""
    centroid = pts.mean(axis=0)
    N = pts - centroid
    _, s, vt = np.linalg.svd(N, full_matrices=False)
    if s[1] <= 1e-9 * s[0]:
        raise CollinearPointsError(what)
    v1, v2, v3 = vt
    xy = N @ np.stack([v1, v2]).T
    A = np.column_stack([2.0 * xy, np.ones(len(xy))])
    b = np.sum(xy**2, axis=1)
    (c1, c2, k3), *_ = np.linalg.lstsq(A, b, rcond=None)
    radius2 = k3 + c1 * c1 + c2 * c2
    if not radius2 > 0.0:
        raise CollinearPointsError(what)
    center = centroid + c1 * v1 + c2 * v2
    return (
        np.asarray(center, dtype=np.float64),
        np.asarray(v3, dtype=np.float64),
        math.sqrt(radius2),
    )


def fit_circle_algebraic(
    points: ArrayLike,
    *,
    encoder: ArrayLike | None = None,
    min_sweep: float = MIN_SWEEP,
    what: str = "circle fit",
) -> AxisFit:
    """The seed-002 circle fit (Sec. 2.3, Eq. 8–10): SVD plane and algebraic circle.

    ``points`` (m, 3) in time order; ``encoder`` (m,) optional, used only to orient the axis.
    """
    pts = check_samples(points, what)
    q = check_encoder(encoder, pts.shape[0], what)
    center, normal, radius = algebraic_circle(pts, what)
    return _finish_circle(
        pts, q, center, normal, radius, method="seed002-algebraic", what=what, min_sweep=min_sweep
    )


def fit_circle_geometric(
    points: ArrayLike,
    *,
    encoder: ArrayLike | None = None,
    min_sweep: float = MIN_SWEEP,
    what: str = "circle fit",
) -> AxisFit:
    """Orthogonal-distance (maximum-likelihood for isotropic noise, free angles) 3D circle fit.

    Minimises ``Σ h_j² + (ρ_j − r)²`` over centre, normal and radius, started from the seed-002
    algebraic fit (Sec. 2.3). ``points`` (m, 3) in time order; ``encoder`` (m,) orients the axis.
    """
    pts = check_samples(points, what)
    q = check_encoder(encoder, pts.shape[0], what)
    c0, n0, r0 = algebraic_circle(pts, what)
    u0, v0 = perpendicular_basis(n0)

    def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        raw = n0 + x[3] * u0 + x[4] * v0
        return x[:3], raw / np.linalg.norm(raw), float(x[5])

    def residuals(x: FloatArray) -> FloatArray:
        c, n, r = unpack(x)
        w = pts - c
        h = w @ n
        rho = np.linalg.norm(w - np.outer(h, n), axis=1)
        return np.concatenate([h, rho - r])

    def jacobian(x: FloatArray) -> FloatArray:
        c, n, _ = unpack(x)
        raw_norm = float(np.linalg.norm(n0 + x[3] * u0 + x[4] * v0))
        du = (u0 - n * (n @ u0)) / raw_norm
        dv = (v0 - n * (n @ v0)) / raw_norm
        return _free_angle_jacobian(pts, c, n, (du, dv))

    x0 = np.concatenate([c0, [0.0, 0.0, r0]])
    scale = max(r0, 1e-9)
    from scipy.optimize import least_squares  # imported here: 0.3 s the other paths skip

    sol = least_squares(
        residuals, x0, jac=jacobian, method="lm", x_scale=np.r_[[scale] * 3, 1.0, 1.0, scale]
    )
    center, normal, radius = unpack(sol.x)
    return _finish_circle(
        pts, q, center, normal, abs(radius), method="geometric", what=what, min_sweep=min_sweep
    )


def fit_circle_encoder(
    points: ArrayLike,
    encoder: ArrayLike,
    *,
    min_sweep: float = MIN_SWEEP,
    what: str = "circle fit",
    max_iterations: int = 50,
) -> AxisFit:
    """Encoder-aided circle fit: the relative angles of the samples are the encoder differences.

    Model ``p_j = c + R [r cos q_j, r sin q_j, 0]ᵀ`` with the frame ``R = [u v n]`` (the axis
    ``n``, the phase of ``u``), the centre ``c`` and the radius ``r`` unknown — 7 parameters —
    solved by Gauss–Newton from the seed-002 fit (Sec. 2.3). The axis is oriented so that the
    target turns positively about it as ``q`` increases. ``points`` (m, 3), ``encoder`` (m,) rad.
    """
    pts = check_samples(points, what)
    q = check_encoder(encoder, pts.shape[0], what)
    assert q is not None
    sweep = float(q.max() - q.min())
    if sweep < min_sweep:
        raise SweepTooSmallError(what, sweep, min_sweep, "rad")
    center, normal, radius = algebraic_circle(pts, what)
    u, v = perpendicular_basis(normal)
    phases = _unwrapped_phases(pts, center, u, v, q)
    if sense(phases, q) < 0.0:
        normal = -normal
        u, v = perpendicular_basis(normal)
        phases = _unwrapped_phases(pts, center, u, v, q)
    phi0 = float(np.angle(np.mean(np.exp(1j * (phases - q)))))
    R = np.column_stack([u, v, normal]) @ rotation_about(np.array([0.0, 0.0, 1.0]), phi0)
    m = pts.shape[0]
    cos_q, sin_q = np.cos(q), np.sin(q)

    def model(R: FloatArray, c: FloatArray, r: float) -> FloatArray:
        return np.asarray(
            c + r * (np.outer(cos_q, R[:, 0]) + np.outer(sin_q, R[:, 1])), dtype=np.float64
        )

    def jacobian(R: FloatArray, r: float) -> FloatArray:
        J = np.zeros((m, 3, 7))
        J[:, :, :3] = np.eye(3)
        local = np.column_stack([r * cos_q, r * sin_q, np.zeros(m)])
        # d(R exp([ω]) x)/dω at ω = 0 is −R [x]×
        skews = np.zeros((m, 3, 3))
        skews[:, 0, 1], skews[:, 0, 2] = -local[:, 2], local[:, 1]
        skews[:, 1, 0], skews[:, 1, 2] = local[:, 2], -local[:, 0]
        skews[:, 2, 0], skews[:, 2, 1] = -local[:, 1], local[:, 0]
        J[:, :, 3:6] = -np.einsum("ij,mjk->mik", R, skews)
        J[:, :, 6] = np.outer(cos_q, R[:, 0]) + np.outer(sin_q, R[:, 1])
        return J.reshape(3 * m, 7)

    for _ in range(max_iterations):
        res = (pts - model(R, center, radius)).reshape(-1)
        J = jacobian(R, radius)
        step = np.asarray(np.linalg.lstsq(J, res, rcond=None)[0], dtype=np.float64)
        center = center + step[:3]
        if np.any(step[3:6]):
            R = np.asarray(R @ rotation_about(step[3:6], float(np.linalg.norm(step[3:6]))))
        radius = radius + float(step[6])
        if np.linalg.norm(step[:3]) < 1e-13 * max(radius, 1.0) and np.linalg.norm(step[3:]) < 1e-13:
            break
    residuals = pts - model(R, center, radius)
    dof = max(3 * m - 7, 1)
    sigma2 = float(np.sum(residuals**2)) / dof
    J = jacobian(R, radius)
    cov = sigma2 * np.linalg.pinv(J.T @ J)
    # direction change R (ω × e3) = ω2 u − ω1 v; position change (u·δc, v·δc)
    G = np.zeros((4, 7))
    G[0, 4], G[1, 3] = 1.0, -1.0
    G[2, :3], G[3, :3] = R[:, 0], R[:, 1]
    u, v, normal = R[:, 0], R[:, 1], R[:, 2]
    return AxisFit(
        axis=Line(center, normal),
        kind="circle",
        method="encoder",
        n_points=m,
        center=np.asarray(center, dtype=np.float64),
        radius=float(radius),
        residuals=np.asarray(residuals, dtype=np.float64),
        rms=float(np.sqrt(np.mean(np.sum(residuals**2, axis=1)))),
        sweep=sweep,
        sigma=math.sqrt(sigma2),
        positions=np.asarray(q - q.min(), dtype=np.float64),
        basis=np.stack([u, v]),
        axis_covariance=np.asarray(G @ cov @ G.T, dtype=np.float64),
    )


def fit_circle(
    points: ArrayLike,
    *,
    encoder: ArrayLike | None = None,
    method: CircleMethod = "auto",
    min_sweep: float = MIN_SWEEP,
    what: str = "circle fit",
) -> AxisFit:
    """Fit a revolute joint's circle; ``method="auto"`` uses the encoder-aided fit when encoder
    values are given and the geometric fit otherwise (see the individual fits for the models)."""
    if method == "auto":
        method = "encoder" if encoder is not None else "geometric"
    if method == "encoder":
        if encoder is None:
            raise TooFewPointsError(f"{what} (encoder-aided fit without encoder values)", 0, 3)
        return fit_circle_encoder(points, encoder, min_sweep=min_sweep, what=what)
    if method == "geometric":
        return fit_circle_geometric(points, encoder=encoder, min_sweep=min_sweep, what=what)
    return fit_circle_algebraic(points, encoder=encoder, min_sweep=min_sweep, what=what)
