"""The measurement-model interface (identify.fit.measure): the tracker's point as a
``Measurement`` through the generic fit gives the tracker's own whole-model fit (its streamed
fast path, identify.fit.whole) — the same optimum and the same covariance — so a camera's pixels and
a tracker's points are one fit with two measurement models."""

from __future__ import annotations

import math

import numpy as np

from dhlog.geometry._checks import rotation_from_vector
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.measure import PointMeasurement, Points, fit_measured, residuals, rms
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.register import register_nominal
from dhlog.identify.fit.whole import fit_whole_model
from dhlog.model.fk import fk_frames, fk_point
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


def test_the_trackers_placement_is_its_measurements_place() -> None:
    """``PointMeasurement.place`` is the tracker's one placement (``place_on``, as
    ``register_nominal``): a UR5 measured by a tracker re-stationed 1.2 m away and turned 125°
    about its vertical, with a 12 cm tool point; placed from the identity and a zero tool
    point, the model's FK at random joint vectors meets the truth's within 2 σ of the noise
    (80 poses of 10 µm noise fix the six placement and three tool parameters to about
    σ/√80 each), its residuals are register_nominal's to rounding, and the carried frame's
    orientation given is kept."""
    robot = load_robot("ur5")
    rng = np.random.default_rng(4)
    T = np.eye(4)
    T[:3, :3] = rotation_from_vector(np.array([0.0, 0.0, math.radians(125.0)]))
    T[:3, 3] = [1.2, -0.3, 0.4]
    tool = np.array([0.05, -0.02, 0.12])
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (80, robot.n))
    P = fk_point(robot.table, Q, tool, T_base=T) + rng.normal(scale=SIGMA, size=(80, 3))
    ref = np.zeros(robot.n)
    R_tool = rotation_from_vector(np.array([0.1, 0.2, 0.3]))
    model, meas = PointMeasurement().place(
        robot.table, ref, np.eye(4), np.zeros(3), R_tool, Points(Q, P)
    )
    assert meas == PointMeasurement()
    Qr = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (200, robot.n))
    truth = fk_point(robot.table, Qr, tool, T_base=T)
    got, _ = predict(model, Qr, None, None)
    assert float(np.sqrt(np.mean(np.sum((got - truth) ** 2, axis=1)))) < 2 * SIGMA
    reg = register_nominal(robot.table, Q, P)
    own = np.linalg.norm(residuals(model, PointMeasurement(), Points(Q, P)), axis=1)
    np.testing.assert_allclose(own, reg.residuals, rtol=0, atol=1e-12)
    assert model.tool_rotation is not None
    flange = fk_frames(robot.table, ref, T_base=reg.T_measurement_base)[-1][:3, :3]
    np.testing.assert_allclose(model.tool_rotation, flange @ R_tool, atol=1e-12)
