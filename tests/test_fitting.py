"""Fits: exact recovery, orientation, efficiency against the Cramér–Rao bound, degenerate input."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from dhlog.errors import (
    CollinearPointsError,
    EncoderScaleError,
    NonFiniteError,
    SweepTooSmallError,
    TooFewPointsError,
)
from dhlog.geometry.axisfit import AxisFit
from dhlog.geometry.circles import (
    fit_circle,
    fit_circle_algebraic,
    fit_circle_encoder,
    fit_circle_geometric,
)
from dhlog.geometry.fitting import fit_line, fit_plane

CENTER = np.array([0.8, -0.3, 0.45])
NORMAL = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
RADIUS = 0.25


def circle_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


def circle_points(phi: np.ndarray) -> np.ndarray:
    u, v = circle_basis(NORMAL)
    return CENTER + RADIUS * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))


def cramer_rao(phi: np.ndarray, sigma: float, *, known_angles: bool) -> tuple[float, float]:
    """RMS bound on the axis direction (rad) and on its position perpendicular to the axis (m).

    Fisher information of ``p_j = c + r R(a, b) [cos φ_j, sin φ_j, 0]`` with isotropic noise σ:
    parameters centre (3), normal tilt a, b (2), radius, and either one phase per sample (free
    angles) or one common phase (known relative angles).
    """
    u, v = circle_basis(NORMAL)
    m = len(phi)
    J = np.zeros((3 * m, 6 + (1 if known_angles else m)))
    for j, f in enumerate(phi):
        rows = slice(3 * j, 3 * j + 3)
        J[rows, :3] = np.eye(3)
        J[rows, 3] = -RADIUS * np.cos(f) * NORMAL
        J[rows, 4] = -RADIUS * np.sin(f) * NORMAL
        J[rows, 5] = np.cos(f) * u + np.sin(f) * v
        J[rows, 6 if known_angles else 6 + j] = RADIUS * (-np.sin(f) * u + np.cos(f) * v)
    cov = sigma**2 * np.linalg.inv(J.T @ J)
    G = np.zeros((4, J.shape[1]))
    G[0, 3] = G[1, 4] = 1.0
    G[2, :3], G[3, :3] = u, v
    axis_cov = G @ cov @ G.T
    return float(np.sqrt(axis_cov[0, 0] + axis_cov[1, 1])), float(
        np.sqrt(axis_cov[2, 2] + axis_cov[3, 3])
    )


def axis_errors(fit: AxisFit) -> tuple[float, float]:
    e = fit.axis.direction
    angle = float(np.arctan2(np.linalg.norm(np.cross(e, NORMAL)), e @ NORMAL))
    return angle, fit.axis.distance_to(CENTER)


FITS: dict[str, Callable[[np.ndarray, np.ndarray], AxisFit]] = {
    "seed002": lambda p, q: fit_circle_algebraic(p, encoder=q),
    "geometric": lambda p, q: fit_circle_geometric(p, encoder=q),
    "encoder": lambda p, q: fit_circle_encoder(p, q),
}


@pytest.mark.parametrize("method", FITS)
def test_exact_circle_is_recovered_and_oriented(method: str) -> None:
    phi = np.linspace(0.2, 1.4, 12)
    fit = FITS[method](circle_points(phi), phi + 3.0)
    np.testing.assert_allclose(fit.center, CENTER, atol=1e-9)
    np.testing.assert_allclose(fit.axis.direction, NORMAL, atol=1e-9)  # positive sense
    assert fit.radius == pytest.approx(RADIUS, abs=1e-9)
    assert fit.sweep == pytest.approx(1.2, abs=1e-9)
    assert fit.rms < 1e-9
    # decreasing encoder values turn the axis round
    back = FITS[method](circle_points(phi), 3.0 - phi)
    np.testing.assert_allclose(back.axis.direction, -NORMAL, atol=1e-9)


def test_time_order_orients_the_axis_without_encoder() -> None:
    phi = np.linspace(0.2, 1.4, 12)
    assert fit_circle(circle_points(phi)).axis.direction @ NORMAL > 0.999
    assert fit_circle(circle_points(phi[::-1])).axis.direction @ NORMAL < -0.999
    assert fit_circle(circle_points(phi), encoder=phi).method == "encoder"


ARCS = [30, 90, 360]


@pytest.mark.parametrize("arc_deg", ARCS)
def test_fits_reach_the_cramer_rao_bound(arc_deg: int) -> None:
    """Over 500 seeded trials (36 points, σ = 20 µm, r = 250 mm) the RMS axis errors of each fit
    are within 10 % of the bound of its own model; the standard error of an RMS over 500 trials is
    about 3 %, so 10 % is above 3 standard errors. The reported σ must match the bound too."""
    rng = np.random.default_rng(arc_deg)
    sigma, m, trials = 20e-6, 36, 500
    phi = np.linspace(0.0, np.radians(arc_deg), m, endpoint=arc_deg != 360)
    exact = circle_points(phi)
    errors: dict[str, list[tuple[float, float, float, float]]] = {k: [] for k in FITS}
    for _ in range(trials):
        noisy = exact + rng.normal(scale=sigma, size=exact.shape)
        for name, fit_fn in FITS.items():
            fit = fit_fn(noisy, phi + 0.7)
            errors[name].append((*axis_errors(fit), fit.direction_std, fit.position_std))
    for name, values in errors.items():
        bound = cramer_rao(phi, sigma, known_angles=name == "encoder")
        arr = np.array(values)
        rmse = np.sqrt(np.mean(arr[:, :2] ** 2, axis=0))
        reported = np.sqrt(np.mean(arr[:, 2:] ** 2, axis=0))
        ratio = rmse / bound
        assert np.all(np.abs(ratio - 1.0) < 0.10), (name, arc_deg, ratio)
        assert np.all(np.abs(reported / bound - 1.0) < 0.10), (name, arc_deg, reported / bound)


def test_encoder_aided_bound_is_about_ten_times_lower_on_a_30_degree_arc() -> None:
    phi = np.linspace(0.0, np.radians(30), 36)
    free = cramer_rao(phi, 1e-5, known_angles=False)
    known = cramer_rao(phi, 1e-5, known_angles=True)
    assert 8.0 < free[1] / known[1] < 12.0


def test_line_fit_recovers_direction_and_encoder_scale() -> None:
    rng = np.random.default_rng(7)
    e = np.array([0.2, 0.9, -0.3]) / np.linalg.norm([0.2, 0.9, -0.3])
    q = np.linspace(-0.1, 0.2, 40)
    points = np.array([0.1, 0.2, 0.3]) + np.outer(q * 1.002, e)
    fit = fit_line(points, encoder=q)
    np.testing.assert_allclose(fit.axis.direction, e, atol=1e-12)
    assert fit.encoder_scale == pytest.approx(1.002, abs=1e-12)
    assert fit.sweep == pytest.approx(0.3 * 1.002)
    assert fit.warnings and "1.00200" in fit.warnings[0]
    assert fit_line(points[::-1]).axis.direction @ e < -0.999999  # time order
    noisy = points + rng.normal(scale=1e-5, size=points.shape)
    assert fit_line(noisy, encoder=q).sigma == pytest.approx(1e-5, rel=0.2)
    with pytest.raises(EncoderScaleError, match="m vs mm"):
        fit_line(points, encoder=q * 1000.0, what="joint 3")


def test_plane_fit() -> None:
    rng = np.random.default_rng(3)
    xy = rng.uniform(-1, 1, (20, 2))
    points = np.column_stack([xy, 0.5 + 0.1 * xy[:, 0]])
    fit = fit_plane(points)
    np.testing.assert_allclose(
        fit.plane.normal, np.array([-0.1, 0, 1]) / np.hypot(0.1, 1), atol=1e-15
    )
    assert fit.rms < 1e-12


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (
            lambda: fit_circle(np.tile([[0, 0, 0], [1, 0, 0]], (5, 1)), what="joint 2"),
            TooFewPointsError,
            "joint 2: only 2 distinct point",
        ),
        (
            lambda: fit_circle(np.outer(np.linspace(0, 1, 9), [1, 2, 3]), what="joint 2"),
            CollinearPointsError,
            "joint 2: the points are collinear",
        ),
        (
            lambda: fit_circle(circle_points(np.linspace(0, 0.05, 9)), what="joint 4"),
            SweepTooSmallError,
            "joint 4: the sweep covers only 2.86°",
        ),
        (
            lambda: fit_circle_encoder(
                circle_points(np.linspace(0, 0.05, 9)), np.linspace(0, 0.05, 9)
            ),
            SweepTooSmallError,
            "minimum 5°",
        ),
        (
            lambda: fit_circle(
                np.where(
                    np.arange(27).reshape(9, 3) == 4, np.nan, circle_points(np.linspace(0, 1, 9))
                )
            ),
            NonFiniteError,
            "1 non-finite",
        ),
        (
            lambda: fit_circle_encoder(circle_points(np.linspace(0, 1, 9)), np.full(9, np.inf)),
            NonFiniteError,
            "encoder values",
        ),
        (
            lambda: fit_line(np.outer(np.linspace(0, 1e-4, 9), [1, 0, 0]), what="joint 1"),
            SweepTooSmallError,
            "joint 1: the sweep covers only 0.1 mm",
        ),
        (
            lambda: fit_plane(np.outer(np.linspace(0, 1, 9), [1, 2, 3])),
            CollinearPointsError,
            "base plane",
        ),
    ],
)
def test_degenerate_input_raises_its_error(
    call: Callable[[], object], error: type[Exception], message: str
) -> None:
    with pytest.raises(error, match=message):
        call()
