"""Fits of planes, circles and lines to measured points, each returning an oriented joint axis.

Circle fits follow seed 002, Sec. 2.3 (SVD plane, then an algebraic least-squares circle in that
plane, Eq. 8–10), refined by the geometric (orthogonal-distance, maximum-likelihood) fit, or
replaced by the encoder-aided fit when each sample's joint angle is known. Every fit reports the
axis oriented along the joint's positive motion (right-hand rule for increasing encoder value, or
time order without encoder), the per-sample residuals, the swept angle or travel, the noise ``σ``
estimated from the residuals and the first-order covariance of the axis from the fit Jacobian.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dhlog.errors import (
    CollinearPointsError,
    EncoderScaleError,
    NonFiniteError,
    SweepTooSmallError,
    TooFewPointsError,
)
from dhlog.geometry._checks import FloatArray, check_points, perpendicular_basis, rotation_about
from dhlog.geometry.lines import Line, Plane

#: Smallest swept angle a circle fit accepts by default (rad).
MIN_SWEEP = math.radians(5.0)
#: Smallest travel a line fit accepts by default (m).
MIN_TRAVEL = 1e-3

CircleMethod = Literal["auto", "algebraic", "geometric", "encoder"]


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


@dataclass(frozen=True, eq=False)
class AxisFit:
    """An oriented joint axis recovered from one sweep.

    Shapes: ``center`` (3,), ``residuals`` (m, 3) sample minus model point, ``positions`` (m,) the
    per-sample angle about the axis (rad, circles) or position along it (m, lines), ``basis`` (2, 3)
    the unit vectors ``u, v`` perpendicular to the axis in which ``axis_covariance`` (4, 4) is
    expressed, for ``[δe·u, δe·v, δc·u, δc·v]``: the tilt of the direction (rad) and the shift of
    the axis at ``center`` (m).
    """

    axis: Line
    kind: Literal["circle", "line"]
    method: str
    n_points: int
    center: FloatArray
    radius: float
    residuals: FloatArray
    rms: float
    sweep: float
    sigma: float
    positions: FloatArray
    basis: FloatArray
    axis_covariance: FloatArray
    encoder_scale: float | None = None
    warnings: tuple[str, ...] = field(default=())

    @property
    def direction_std(self) -> float:
        """RMS tilt of the axis direction expected from the covariance (rad)."""
        return math.sqrt(float(self.axis_covariance[0, 0] + self.axis_covariance[1, 1]))

    @property
    def position_std(self) -> float:
        """RMS shift of the axis perpendicular to itself at ``center`` (m)."""
        return math.sqrt(float(self.axis_covariance[2, 2] + self.axis_covariance[3, 3]))

    def point_direction_covariance(self) -> FloatArray:
        """Covariance (6, 6) of ``[point, direction]`` of :attr:`axis` in the measurement frame."""
        u, v = self.basis
        B = np.zeros((6, 4))
        B[3:, 0], B[3:, 1], B[:3, 2], B[:3, 3] = u, v, u, v
        return np.asarray(B @ self.axis_covariance @ B.T, dtype=np.float64)


def _check_samples(points: ArrayLike, what: str, needed: int = 3) -> FloatArray:
    pts = check_points(f"{what} points", points)
    bad = int(np.count_nonzero(~np.isfinite(pts).all(axis=1)))
    if bad:
        raise NonFiniteError(what, bad)
    stride = max(1, pts.shape[0] // 1000)  # a strided thousand decides almost always
    n_distinct = int(np.unique(pts[::stride], axis=0).shape[0])
    if n_distinct < needed and stride > 1:
        n_distinct = int(np.unique(pts, axis=0).shape[0])
    if n_distinct < needed:
        raise TooFewPointsError(what, n_distinct, needed)
    return pts


def _check_encoder(encoder: ArrayLike | None, m: int, what: str) -> FloatArray | None:
    if encoder is None:
        return None
    q = np.asarray(encoder, dtype=np.float64).reshape(-1)
    if q.shape != (m,):
        raise TooFewPointsError(f"{what} encoder values ({q.shape[0]} for {m} points)", 0, m)
    bad = int(np.count_nonzero(~np.isfinite(q)))
    if bad:
        raise NonFiniteError(f"{what} encoder values", bad)
    return q


def fit_plane(
    points: ArrayLike, *, what: str = "base plane", sigma: float | None = None
) -> PlaneFit:
    """Least-squares plane by SVD of the centred points (seed 002, Eq. 8–9): ``n = v3``.

    ``points`` (m, 3). The normal's sign is chosen so that it has a non-negative z component.
    The covariance takes the points' σ from their residuals, or ``sigma`` (m) where it is known
    (a plan: a dozen points estimate their own σ only to ±25 %).
    """
    pts = _check_samples(points, what)
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


def _order_key(encoder: FloatArray | None, m: int) -> FloatArray:
    return encoder if encoder is not None else np.arange(m, dtype=np.float64)


def _sense(values: FloatArray, key: FloatArray) -> float:
    """Sign of the least-squares slope of ``values`` against ``key``."""
    kc = key - key.mean()
    return 1.0 if float(kc @ (values - values.mean())) >= 0.0 else -1.0


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


def _circle_residuals(
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
    r = _circle_residuals(pts, center, normal, radius)
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
    if _sense(phases, key) < 0.0:
        normal = -normal
        u, v = perpendicular_basis(normal)
        phases = _unwrapped_phases(pts, center, u, v, key)
    sweep = float(phases.max() - phases.min())
    if sweep < min_sweep:
        raise SweepTooSmallError(what, sweep, min_sweep, "rad")
    sigma, basis, axis_cov = _free_angle_covariance(pts, center, normal, radius)
    residuals = _circle_residuals(pts, center, normal, radius)
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


def _algebraic_circle(pts: FloatArray, what: str) -> tuple[FloatArray, FloatArray, float]:
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
    pts = _check_samples(points, what)
    q = _check_encoder(encoder, pts.shape[0], what)
    center, normal, radius = _algebraic_circle(pts, what)
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
    pts = _check_samples(points, what)
    q = _check_encoder(encoder, pts.shape[0], what)
    c0, n0, r0 = _algebraic_circle(pts, what)
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


def _skew(x: FloatArray) -> FloatArray:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


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
    pts = _check_samples(points, what)
    q = _check_encoder(encoder, pts.shape[0], what)
    assert q is not None
    sweep = float(q.max() - q.min())
    if sweep < min_sweep:
        raise SweepTooSmallError(what, sweep, min_sweep, "rad")
    center, normal, radius = _algebraic_circle(pts, what)
    u, v = perpendicular_basis(normal)
    phases = _unwrapped_phases(pts, center, u, v, q)
    if _sense(phases, q) < 0.0:
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
    pts = _check_samples(points, what)
    m = pts.shape[0]
    q = _check_encoder(encoder, m, what)
    centroid = pts.mean(axis=0)
    centred = pts - centroid
    warnings: list[str] = []
    scale: float | None = None
    if q is None:
        _, _, vt = np.linalg.svd(centred, full_matrices=False)
        direction = vt[0]
        t = centred @ direction
        if _sense(t, np.arange(m, dtype=np.float64)) < 0.0:
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
    pts = _check_samples(points, what)
    line = fit_line(pts, min_travel=0.0, what=what)
    try:
        center, normal, radius = _algebraic_circle(pts, what)
    except CollinearPointsError:
        return "prismatic", "the points are collinear"
    circle_rms = float(
        np.sqrt(np.mean(np.sum(_circle_residuals(pts, center, normal, radius) ** 2, axis=1)))
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
    max_points: int | None = None,
    what: str = "axis fit",
) -> tuple[AxisFit, NDArray[np.bool_]]:
    """A circle or line fit with iterative rejection of gross outliers.

    After each fit, samples whose orthogonal distance from the circle (or line) exceeds
    ``threshold`` times the robust noise scale (median distance / 1.1774, the median of a 2-dof
    chi variable) are set aside and the fit repeated, until nothing changes. Returns the fit on
    the inliers and the inlier mask over the input samples.

    ``max_points``: fit an evenly strided subset of at most this many samples (a start for the
    whole-model fit needs no more); the inlier mask still covers every sample, judged against
    that fit.
    """
    pts_all = check_points(f"{what} points", points)
    q_all = None if encoder is None else np.asarray(encoder, dtype=np.float64).reshape(-1)
    stride = 1
    if max_points is not None and pts_all.shape[0] > max_points:
        stride = -(-pts_all.shape[0] // max_points)
    pts = pts_all[::stride]
    q = None if q_all is None else q_all[::stride]
    keep = np.ones(pts.shape[0], dtype=bool)

    def run(mask: NDArray[np.bool_]) -> AxisFit:
        enc = None if q is None else q[mask]
        if kind == "line":
            return fit_line(pts[mask], encoder=enc, what=what)
        return fit_circle(pts[mask], encoder=enc, method=method, min_sweep=min_sweep, what=what)

    fit = run(keep)
    for _ in range(max_rounds):
        distance = _orthogonal_distances(fit, pts)
        # median of a 2-dof chi variable is sqrt(2 ln 2) = 1.1774 σ
        scale = float(np.median(distance[keep])) / 1.1774
        new_keep = distance <= threshold * max(scale, 1e-12)
        if np.array_equal(new_keep, keep) or np.count_nonzero(new_keep) < 3:
            break
        keep = new_keep
        fit = run(keep)
    if stride > 1:
        scale = float(np.median(_orthogonal_distances(fit, pts[keep]))) / 1.1774
        keep = _orthogonal_distances(fit, pts_all) <= threshold * max(scale, 1e-12)
    return fit, keep


def _orthogonal_distances(fit: AxisFit, pts: FloatArray) -> NDArray[np.float64]:
    """Distance of every sample from the fitted circle or line (the 2-dof orthogonal residual)."""
    if fit.kind == "line":
        rel = pts - fit.center
        d = fit.axis.direction
        return np.asarray(np.linalg.norm(rel - np.outer(rel @ d, d), axis=1), dtype=np.float64)
    residuals = _circle_residuals(pts, fit.center, fit.axis.direction, fit.radius)
    return np.asarray(np.linalg.norm(residuals, axis=1), dtype=np.float64)
