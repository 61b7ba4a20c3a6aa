"""The measurement-model interface (identify.fit.measure): the tracker's point as a
``Measurement`` through the generic fit gives the tracker's own whole-model fit (its streamed
fast path, identify.fit.whole) — the same optimum and the same covariance — so a camera's pixels and
a tracker's points are one fit with two measurement models."""

from __future__ import annotations

import math

import numpy as np

from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.measure import PointMeasurement, Points, fit_measured, residuals, rms
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.whole import fit_whole_model
from dhlog.model.fk import fk_point
from dhlog.model.noise import NoiseModel
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.robot import perturbed

SIGMA = 1e-5  # 10 µm, a tracker's


def test_point_measurement_is_the_trackers_fit() -> None:
    """A UR5 0.2 mm / 0.05° off its nominal, 80 random poses, 10 µm noise: from the nominal,
    the generic fit with the point measurement and fit_whole_model agree at random joint
    vectors to 1e-3 σ, and their predicted σ there to 1 %."""
    robot = load_robot("ur5")
    rng = np.random.default_rng(12)
    cfg = SimulationConfig(perturb_length=2e-4, perturb_angle=math.radians(0.05))
    true = perturbed(robot.table, rng, cfg)
    tool = np.array([0.05, -0.02, 0.12])
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (80, robot.n))
    P = fk_point(true, Q, tool) + rng.normal(scale=SIGMA, size=(80, 3))
    ref = np.zeros(robot.n)
    start = AxisModel.of_table(robot.table, ref, tool, np.eye(4))
    generic = fit_measured(start, PointMeasurement(), Points(Q, P))
    tracker = fit_whole_model(start, FitData(Q, P), FitOptions(NoiseModel(), SIGMA))
    Qr = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (200, robot.n))
    a, Ja = predict(generic.whole.model, Qr, generic.whole.layout, generic.whole.model.bases())
    b, Jb = predict(tracker.model, Qr, tracker.layout, tracker.model.bases())
    assert Ja is not None and Jb is not None
    assert float(np.max(np.linalg.norm(a - b, axis=1))) < 1e-3 * SIGMA
    sa = np.sqrt(np.einsum("mik,kl,mil->mi", Ja, generic.whole.covariance, Ja))
    sb = np.sqrt(np.einsum("mik,kl,mil->mi", Jb, tracker.covariance, Jb))
    assert np.allclose(sa, sb, rtol=0.01)
    # the fit reaches the noise: the residual RMS (3-D norm) is about √3 σ
    assert (
        abs(
            rms(residuals(generic.whole.model, PointMeasurement(), Points(Q, P)))
            / (math.sqrt(3) * SIGMA)
            - 1
        )
        < 0.2
    )
    assert abs(generic.sigma / SIGMA - 1.0) < 0.15
