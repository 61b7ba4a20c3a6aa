"""The whole-model fit: its Jacobian, its optimum against the truth, the noise model, the pair
relations it holds, discrete-point protocols and joints never moved alone."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dhlog.identify.check.validate import fk_prediction_std
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.whole import fit_whole_model
from dhlog.identify.model.parked import PARKED_REASON
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import Identification, ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.noise import NoiseModel
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session

from chains import fk_error


def truth_model(session: Session, ref: np.ndarray) -> AxisModel:
    return AxisModel.of_table(session.table, ref, session.tool_point, session.T_measurement_base)


@pytest.mark.parametrize("robot", ["kr5", "stanford", "scara"])
@pytest.mark.parametrize("fit_scales", [False, True])
def test_the_jacobian_is_the_derivative_of_the_prediction(robot: str, fit_scales: bool) -> None:
    """Analytic columns against a first-order step of 1e-6 in every local parameter: the
    difference is second order (≤ 1e-10 m for moves of 1e-6)."""
    rob = load_robot(robot)
    session = simulate_session(rob, SimulationConfig(seed=1))
    model = truth_model(session, session.reference_pose)
    layout = ParameterLayout.of(model.types, fit_scales=fit_scales, clock=True)
    model = dataclasses.replace(model, clock=0.01)
    bases = model.bases()
    Q = np.random.default_rng(0).uniform(rob.limits[:, 0], rob.limits[:, 1], (40, rob.n))
    rates = np.random.default_rng(2).normal(scale=0.5, size=Q.shape)
    step = np.random.default_rng(1).normal(size=layout.size) * 1e-6
    p0, J = predict(model, Q, layout, bases, rates=rates)
    p1, _ = predict(model.moved(step, layout, bases), Q, rates=rates)
    assert J is not None
    assert np.abs(p1 - p0 - J @ step).max() < 1e-10 < np.abs(J @ step).max()


@pytest.mark.parametrize("robot", ["kr5", "stanford", "scara"])
def test_the_position_alone_is_the_forward_kinematics(robot: str) -> None:
    """Without a Jacobian the target is carried inward through the joints (no prefix
    rotations): at random joint vectors within the limits it equals the DH forward kinematics
    of the simulator's table in the measurement frame, and the composed prediction (with the
    Jacobian), to rounding (1e-12 m); with two targets, encoder scales and a clock offset it
    still equals the composed one."""
    rob = load_robot(robot)
    session = simulate_session(rob, SimulationConfig(seed=1))
    model = truth_model(session, session.reference_pose)
    Q = np.random.default_rng(0).uniform(rob.limits[:, 0], rob.limits[:, 1], (300, rob.n))
    alone, _ = predict(model, Q)
    T = session.T_measurement_base
    fk = np.array(
        [T[:3, :3] @ fk_point(session.table, q, session.tool_point) + T[:3, 3] for q in Q]
    )
    assert np.abs(alone - fk).max() < 1e-12
    layout = ParameterLayout.of(model.types, fit_scales=True, clock=True, extra_targets=1)
    model = dataclasses.replace(
        model,
        extra_targets=model.target[None] + np.array([[0.03, -0.02, 0.05]]),
        scales=np.full(rob.n, 1.001),
        clock=0.01,
    )
    which = np.arange(Q.shape[0]) % 2
    rates = np.random.default_rng(2).normal(scale=0.5, size=Q.shape)
    alone, _ = predict(model, Q, which=which, rates=rates)
    composed, J = predict(model, Q, layout, model.bases(), which=which, rates=rates)
    assert J is not None and np.abs(alone - composed).max() < 1e-12


@pytest.mark.parametrize("robot", ["kr5", "stanford", "scara"])
@pytest.mark.parametrize("fit_scales", [False, True])
@pytest.mark.parametrize("noise", ["isotropic", "tracker"])
def test_the_adjoint_gradient_equals_the_jacobian_transpose_times_the_residual(
    robot: str, fit_scales: bool, noise: str
) -> None:
    """The full pass's gradient by the adjoint of the chain (no J formed) against ``JᵀWr`` of
    the explicit columns, with two targets, a clock offset, a tracker's 3x3 whitening, held-out
    samples and samples beyond the truncation: equal to rounding (1e-9 relative)."""
    from dhlog.identify.fit.passes import Samples, accumulate, gradient

    rob = load_robot(robot)
    session = simulate_session(rob, SimulationConfig(seed=1))
    base = truth_model(session, session.reference_pose)
    model = dataclasses.replace(
        base,
        extra_targets=base.target[None] + np.array([[0.03, -0.02, 0.05]]),
        scales=np.full(rob.n, 1.001),
    )
    layout = ParameterLayout.of(model.types, fit_scales=fit_scales, extra_targets=1)
    bases = model.bases()
    rng = np.random.default_rng(2)
    m = 40000  # more than one chunk
    Q = rng.uniform(rob.limits[:, 0], rob.limits[:, 1], (m, rob.n))
    which = rng.integers(0, 2, m)
    P, _ = predict(model, Q, None, None, which)
    P = P + rng.normal(scale=2e-4, size=P.shape)
    P[::97] += 0.05  # beyond the truncation
    nm = (
        NoiseModel()
        if noise == "isotropic"
        else NoiseModel(model="tracker", radial=1e-4, transverse=2e-4, transverse_per_m=5e-5)
    )
    rates = rng.normal(scale=0.5, size=Q.shape)
    model = dataclasses.replace(model, clock=0.003)
    layout = ParameterLayout.of(model.types, fit_scales=fit_scales, extra_targets=1, clock=True)
    data = Samples(
        Q, P, rng.random(m) > 0.1, None, lambda x, W: nm.whiten(x, 1e-4), which, Qd=rates
    )
    n1, n2 = np.zeros(m), np.zeros(m)
    _, g, cost, count, chi2 = accumulate(model, layout, bases, data, 5.0, n1)
    g2, cost2, count2, chi22 = gradient(model, layout, bases, data, 5.0, n2)
    assert count == count2 < 0.95 * m
    assert np.abs(n1 - n2).max() < 1e-8  # in sigma: rounding of metre-sized sums
    assert cost2 == pytest.approx(cost, rel=1e-12)
    assert chi22 == pytest.approx(chi2, rel=1e-12)
    assert np.abs(g2 - g).max() < 1e-9 * np.abs(g).max()


def test_from_a_start_a_millimetre_off_the_fit_reaches_the_truth_within_its_sigma() -> None:
    """Started 1 mm / 1 mrad away from the truth, the fit converges, χ²/dof is 1 within its
    spread, and every parameter is within 4σ of the truth (the start cannot be told apart)."""
    rob = load_robot("puma560")
    session = simulate_session(rob, SimulationConfig(seed=2, noise=2e-5, tracker_rate=50.0))
    seg_log = log_data_from_session(session)
    result = process_data(seg_log, ProcessOptions(analytic_only=True))
    table = result.segmentation.table
    Q = table.select([f"q_{i + 1}" for i in range(rob.n)]).drop_nulls().to_numpy()
    P = table.drop_nulls(subset=[f"q_{i + 1}" for i in range(rob.n)]).select("x", "y", "z")
    truth = truth_model(session, result.reference_pose)
    layout = ParameterLayout.of(truth.types)
    start = truth.moved(
        np.random.default_rng(3).normal(size=layout.size) * 1e-3, layout, truth.bases()
    )
    fit = fit_whole_model(start, FitData(Q, P.to_numpy()), FitOptions(NoiseModel(), 2e-5))
    dof = 3 * fit.n_points - layout.size
    assert abs(fit.chi2_dof - 1.0) < 4 * math.sqrt(2 / dof)
    # the truth in the fit's local coordinates: the first-order step from the fit to the truth
    p_fit, J = predict(fit.model, Q, layout, fit.bases)
    p_true, _ = predict(truth, Q)
    assert J is not None
    delta, *_ = np.linalg.lstsq(J.reshape(-1, layout.size), (p_true - p_fit).ravel(), rcond=None)
    z = delta / np.sqrt(np.diag(fit.covariance))
    assert np.all(np.abs(z) < 4.0), np.abs(z).max()


def test_the_table_equals_the_fitted_model_and_pairs_held_parallel_are_fixed() -> None:
    """KR5 exactly at its nominal, given as the nominal: axes 2 and 3 are parallel within the
    noise (within Akaike's 2σ in this session), the fit holds them parallel, so d2 and α2 are
    fixed (with the reason) and the DH table reproduces the fitted model to rounding at the
    samples' joint vectors."""
    rob = load_robot("kr5")
    nominal = DHModel(rob.table, rob.T_base, rob.tool_point, ("a",) * 6, "kr5")
    session = simulate_session(rob, SimulationConfig(seed=1, noise=2e-5))
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal))
    assert result.whole is not None and 1 in result.whole.constrained
    doc = result_document(result)
    row2 = doc["standard_dh"][1]
    assert set(row2["fixed"]) == {"d", "alpha"} and row2["std"]["alpha"] is None
    assert "parallel" in row2["fixed_reason"]
    assert not any("departs from the fitted model" in w for w in result.warnings)
    Q = result.segmentation.table.select([f"q_{i + 1}" for i in range(6)]).drop_nulls()
    Q = Q.to_numpy()[::50]
    ex = result.extraction
    assert ex is not None
    fitted, _ = predict(result.whole.model, Q)
    table = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    assert np.abs(fitted - table).max() < 1e-9


def test_a_tracker_noise_model_weighs_the_fit_and_is_checked_by_chi2() -> None:
    """Samples with a tracker's anisotropic noise (radial 5 µm, transverse 30 µm + 10 µm/m from
    a station 2.5 m away): under the right model χ²/dof is 1 and the FK error is covered by the
    reported uncertainty; under a model 3x too optimistic χ²/dof is far from 1 and said so."""
    rob = load_robot("kr5")
    session = simulate_session(rob, SimulationConfig(seed=6, noise=1e-9, tracker_rate=50.0))
    rng = np.random.default_rng(7)
    station = np.array([2.5, 0.3, 0.5])
    model = NoiseModel("tracker", radial=5e-6, transverse=30e-6, transverse_per_m=10e-6)
    model = dataclasses.replace(model, station=tuple(station))
    rel = session.point_xyz - station
    dist = np.linalg.norm(rel, axis=1)
    u = rel / dist[:, None]
    noise = rng.normal(size=rel.shape)
    radial = (noise * u).sum(axis=1)
    transverse = noise - radial[:, None] * u
    s_t = 30e-6 + 10e-6 * dist
    session.point_xyz = session.point_xyz + 5e-6 * radial[:, None] * u + s_t[:, None] * transverse
    log = log_data_from_session(session)
    right = process_data(
        dataclasses.replace(log, pipeline=dataclasses.replace(log.pipeline, noise=model))
    )
    assert right.whole is not None and 0.9 < right.whole.chi2_dof < 1.1
    doc = result_document(right)
    assert doc["noise"]["model"] == "tracker" and doc["noise"]["radial"] == 5e-6
    Q = np.random.default_rng(8).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    assert np.all(fk_error(right, session, Q) <= 4.0 * fk_prediction_std(right, Q))
    wrong = dataclasses.replace(model, radial=5e-6 / 3, transverse=10e-6, transverse_per_m=3e-6)
    off = process_data(
        dataclasses.replace(log, pipeline=dataclasses.replace(log.pipeline, noise=wrong))
    )
    # the residuals are 3x what the model explains: a model-error variance is estimated and
    # added (χ²/dof 1 again), said with the ratio
    assert off.whole is not None and 0.9 < off.whole.chi2_dof < 1.1
    assert off.noise.model_error is not None and off.noise.model_error > 10e-6
    assert any("declared uncertainties" in w and "model-error σ" in w for w in off.warnings)


def test_a_discrete_point_protocol_with_six_stops_per_joint_works_with_the_defaults() -> None:
    """Step-and-measure with one tracker point per stop, 6 stops per joint (the common laser
    tracker practice): identified with the shipped defaults, FK within the uncertainty."""
    rob = load_robot("kr5")
    cfg = SimulationConfig(seed=3, motion="step", steps=6, noise=1e-5, tracker_rate=1 / 0.3)
    session = simulate_session(rob, cfg)
    result = process_data(log_data_from_session(session))
    assert result.complete and result.whole is not None
    assert all(j.fit is not None and j.fit.n_points <= 12 for j in result.joints)
    Q = np.random.default_rng(9).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    assert np.all(fk_error(result, session, Q) <= 4.0 * fk_prediction_std(result, Q))


def test_a_joint_never_moved_alone_is_identified_from_coupled_moves() -> None:
    """KR5 off its nominal; joint 3 is only moved together with joint 2 (q3 = −q2, the level
    forearm sweep): with the nominal, the whole-model fit identifies it and the FK error is
    covered by the uncertainty. Without the coupled moves joint 3 never moves at all: parked,
    held at the nominal and said (:mod:`dhlog.identify.model.parked`)."""
    rob = load_robot("kr5")
    nominal = DHModel(
        rob.table, rob.T_base, rob.tool_point, tuple(f"joint_{i}" for i in range(6)), "kr5"
    )
    base = {"seed": 11, "noise": 2e-5, "skip_joints": (3,), "perturb_length": 5e-4}
    coupled = SimulationConfig(**base, coupled=((2, 3, -1.0),))  # type: ignore[arg-type]
    session = simulate_session(rob, coupled)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal))
    assert result.complete and result.whole is not None
    assert any("never moved alone" in w for w in result.warnings)
    Q = np.random.default_rng(10).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    assert np.all(fk_error(result, session, Q) <= 4.0 * fk_prediction_std(result, Q))
    alone = simulate_session(rob, SimulationConfig(**base))  # type: ignore[arg-type]
    partial = process_data(log_data_from_session(alone), ProcessOptions(nominal=nominal))
    assert partial.parked == (2,) and partial.fixed[8] == PARKED_REASON
    assert any("joint 3 (joint_3" in w and "parked" in w for w in partial.warnings)


def test_per_sample_covariance_of_pose_with_covariance_stamped_weighs_the_fit(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A log whose target stream is ``geometry_msgs/msg/PoseWithCovarianceStamped`` (written by
    the real ``mcap_ros2`` writer) with a different anisotropic covariance per sample and noise
    drawn from it: the reader carries the covariance into the measurement table, the fit is
    weighted by it (noise model "per-sample", χ²/dof ≈ 1) and the FK error is covered."""
    from mcap_ros2.writer import Writer

    from dhlog.identify.run import process_log
    from dhlog.io import ros2

    rob = load_robot("kr5")
    session = simulate_session(rob, SimulationConfig(seed=12, noise=1e-9, tracker_rate=50.0))
    rng = np.random.default_rng(13)
    m = session.point_xyz.shape[0]
    scales = np.column_stack([rng.uniform(5e-6, 40e-6, m) for _ in range(3)])
    rotations = [np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(m)]
    covs = np.array([R @ np.diag(s**2) @ R.T for R, s in zip(rotations, scales, strict=True)])
    noisy = session.point_xyz + np.einsum(
        "mij,mj->mi", np.linalg.cholesky(covs), rng.normal(size=(m, 3))
    )
    path = tmp_path / "pose_cov.mcap"
    with path.open("wb") as f:
        writer = Writer(f)
        pose = writer.register_msgdef(
            ros2.POSE_WITH_COVARIANCE, ros2.MSGDEFS[ros2.POSE_WITH_COVARIANCE]
        )
        joint = writer.register_msgdef(ros2.JOINT_STATE, ros2.MSGDEFS[ros2.JOINT_STATE])

        def stamp(t: int) -> dict[str, object]:
            return {"sec": t // 1_000_000_000, "nanosec": t % 1_000_000_000}

        messages = []
        for t, p, c in zip(session.point_t_ns, noisy, covs, strict=True):
            full = np.zeros((6, 6))
            full[:3, :3] = c
            full[3:, 3:] = np.eye(3)
            msg = {
                "header": {"stamp": stamp(int(t)), "frame_id": "tracker"},
                "pose": {
                    "pose": {
                        "position": {"x": p[0], "y": p[1], "z": p[2]},
                        "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                    },
                    "covariance": full.ravel().tolist(),
                },
            }
            messages.append((int(t), "/tracker/point", pose, msg))
        for t, q in zip(session.joint_t_ns, session.joint_q, strict=True):
            msg = {
                "header": {"stamp": stamp(int(t)), "frame_id": ""},
                "name": session.joint_names,
                "position": q.tolist(),
                "velocity": [],
                "effort": [],
            }
            messages.append((int(t), "/joint_states", joint, msg))
        for t, topic, schema, msg in sorted(messages, key=lambda x: x[0]):
            writer.write_message(topic, schema, msg, log_time=t, publish_time=t)
        writer.finish()
    result = process_log(path)
    assert "cxx" in result.segmentation.table.columns
    assert result.noise.model == "per-sample" and result.whole is not None
    dof = 3 * result.whole.n_points
    assert abs(result.whole.chi2_dof - 1.0) < 5 * math.sqrt(2 / dof)
    assert result_document(result)["noise"]["model"] == "per-sample"
    Q = np.random.default_rng(14).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    assert np.all(fk_error(result, session, Q) <= 4.0 * fk_prediction_std(result, Q))
    # the general reader (mcap's own decoders) gives the same covariance
    fast = result.segmentation.table.select("cxx", "cyz").to_numpy()
    general = (
        process_log(path, ProcessOptions(fast=False))
        .segmentation.table.select("cxx", "cyz")
        .to_numpy()
    )
    assert np.allclose(fast, general, equal_nan=True)


def test_several_targets_are_fitted_jointly(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A KR5 whose primary target sits 2 mm off the wrist axis 6 (its circle about axis 6 is
    2 mm across) and a second target 120 mm out, on two topics of a ROS 2 log: read through a
    pipeline with ``extra_topics``, both enter the whole-model fit, the second target's tool
    point comes out within its σ, and axis 6 is far better determined than from the primary
    target alone."""
    from dhlog.identify.run import process_log
    from dhlog.io.pipeline import parse_pipeline

    rob = load_robot("kr5")
    near = (0.002, 0.0, 0.05)
    far = (0.12, 0.03, 0.08)
    session = simulate_session(
        dataclasses.replace(rob, tool_point=np.array(near)),
        SimulationConfig(seed=15, noise=2e-5, tracker_rate=50.0, extra_tools=(far,)),
    )
    path = tmp_path / "two_targets.mcap"
    from dhlog.io.writer import write_session

    write_session(session, path)
    text = (
        'name = "two_smr"\nencoding = "cdr"\n[streams.point]\ntopic = "/tracker/point"\n'
        'extra_topics = ["/tracker/point_2"]\n[streams.joints]\ntopic = "/joint_states"\n'
        '[streams.base]\ntopic = "/tracker/base_plane"\n'
    )
    pipeline = parse_pipeline(text, "two_smr.toml")
    both = process_log(path, ProcessOptions(pipeline=pipeline))
    one = process_log(path)
    # read without the further target, the log says which topic was left and how to read it
    left = [w for w in one.warnings if "extra_topics" in w]
    assert len(left) == 1 and "/tracker/point_2 carries the target's message type" in left[0]
    assert not any("extra_topics" in w for w in both.warnings)
    # mcap's own decoders read the further target into the same table
    general = process_log(path, ProcessOptions(pipeline=pipeline, fast=False)).segmentation.table
    assert general.select("t_ns", "x", "target").equals(
        both.segmentation.table.select("t_ns", "x", "target")
    )
    assert both.whole is not None and one.whole is not None
    assert both.whole.n_points > 1.9 * one.whole.n_points
    doc = result_document(both)
    extra = doc["tool"]["further_targets"][0]
    assert extra["topic"] == "/tracker/point_2"
    ex = both.extraction
    assert ex is not None
    Q = np.random.default_rng(16).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    got = fk_point(ex.standard, Q, np.array(extra["point"]), T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, np.array(far), T_base=session.T_measurement_base)
    err = np.linalg.norm(got - want, axis=1)
    # its error: the chain's (the primary target's predicted FK error) plus its own position's
    # (σ of the further target at the reference pose, from the fit's covariance)
    k = both.whole.layout.names.index("target_2_x")
    own = math.sqrt(float(np.trace(both.whole.covariance[k : k + 3, k : k + 3])))
    chain = math.sqrt(float(np.mean(fk_prediction_std(both, Q) ** 2)))
    assert np.sqrt(np.mean(err**2)) < 2.0 * (chain + own)
    assert np.all(fk_error(both, session, Q) <= 4.0 * fk_prediction_std(both, Q))
    # axis 6's direction: its σ from both targets is far below the one from the primary alone
    assert np.sqrt(np.trace(axis6_cov(both))) < 0.3 * np.sqrt(np.trace(axis6_cov(one)))


def axis6_cov(result: Identification) -> np.ndarray:
    from dhlog.identify.model.relations import axis_covariances

    assert result.whole is not None
    return axis_covariances(result.whole)[5][:2, :2]


def test_a_target_whose_orientation_is_measured_fixes_the_wrist(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A 6-DoF target (PoseStamped with its orientation, 0.2 mrad noise) 2 mm off the wrist
    axis 6, read with ``orientation = true``: the orientation enters the whole-model fit, axis
    6's direction is far better determined than from the 2 mm circle alone, the target frame's
    orientation in the last frame comes out within its σ, and the FK error is covered."""
    from dhlog.identify.run import process_log
    from dhlog.io.pipeline import parse_pipeline
    from dhlog.io.writer import write_session

    rob = dataclasses.replace(load_robot("kr5"), tool_point=np.array([0.002, 0.0, 0.05]))
    cfg = SimulationConfig(
        seed=17,
        noise=2e-5,
        tracker_rate=50.0,
        tool_rotation=(0.3, -0.2, 0.5),
        orientation_noise=2e-4,
    )
    session = simulate_session(rob, cfg)
    path = tmp_path / "six_dof.mcap"
    write_session(session, path)
    text = (
        'name = "six_dof"\nencoding = "cdr"\n[streams.point]\ntopic = "/tracker/point"\n'
        'orientation = true\n[streams.joints]\ntopic = "/joint_states"\n'
        '[streams.base]\ntopic = "/tracker/base_plane"\n'
    )
    with_rot = process_log(path, ProcessOptions(pipeline=parse_pipeline(text, "six_dof.toml")))
    plain = process_log(path)
    assert with_rot.whole is not None and with_rot.whole.sigma_rotation is not None
    assert 1.5e-4 < with_rot.whole.sigma_rotation < 2.5e-4
    assert np.sqrt(np.trace(axis6_cov(with_rot))) < 0.3 * np.sqrt(np.trace(axis6_cov(plain)))
    doc = result_document(with_rot)
    got = np.array(doc["tool"]["orientation"]["matrix"])
    ex = with_rot.extraction
    assert ex is not None and session.tool_rotation is not None
    # the truth's target frame in the result's last frame, at the reference pose
    from dhlog.model.fk import fk_frames

    R_true_world = (
        fk_frames(session.table, session.reference_pose, T_base=session.T_measurement_base)[
            -1, :3, :3
        ]
        @ session.tool_rotation
    )
    want = ex.frames[-1][:3, :3].T @ R_true_world
    E = got.T @ want
    angle = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 2
    assert np.all(np.abs(angle) <= 4 * np.array(doc["tool"]["orientation"]["std"]) + 1e-9)
    Q = np.random.default_rng(18).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    assert np.all(fk_error(with_rot, session, Q) <= 4.0 * fk_prediction_std(with_rot, Q))


def test_scara_gauges_are_fixed_and_the_table_equals_the_model() -> None:
    """The SCARA sample (axes 1–3 parallel, prismatic joint 4 along axis 3): θ3 (a rotation
    about the common axis of 3 and 4) and the prismatic axis' placement are gauges, marked fixed
    with their reasons, never printed as measured; the table reproduces the fitted model."""
    from pathlib import Path

    from dhlog.identify.run import process_log

    result = process_log(Path(__file__).parents[1] / "sample_logs" / "scara.mcap")
    rows = result_document(result)["standard_dh"]
    assert {"theta", "d", "a"} <= set(rows[2]["fixed"])
    assert "prismatic" in rows[2]["fixed_reason"] and "collinear" in rows[2]["fixed_reason"]
    assert not any("departs from the fitted model" in w for w in result.warnings)
    for row in rows:
        for name, sd in row["std"].items():
            assert (name in row.get("fixed", [])) == (sd is None)


def test_encoder_scales_are_fitted_on_request() -> None:
    """Encoders of joints 2 and 5 that count 0.1 % short and 0.05 % long (a gear ratio off):
    with ``fit_scales`` the whole-model fit recovers each scale within 4σ, the table (with its
    ``encoder_scale`` per row: θ = θ_offset + scale · q) meets the samples at the noise and the
    truth within the uncertainty; without it the FK residual shows the error."""
    rob = load_robot("kr5")
    scales = (1.0, 1.001, 1.0, 1.0, 0.9995, 1.0)
    cfg = SimulationConfig(seed=19, noise=1e-5, tracker_rate=50.0, encoder_scales=scales)
    session = simulate_session(rob, cfg)
    log = log_data_from_session(session)
    fitted = process_data(log, ProcessOptions(fit_scales=True))
    # geometric: with --model auto the harmonics (sin q ≈ q) would take up part of a scale error
    plain = process_data(log, ProcessOptions(model=ModelRequest("geometric")))
    assert fitted.whole is not None and plain.whole is not None
    doc = result_document(fitted)["whole_fit"]["encoder_scales"]
    value, std = np.array(doc["value"]), np.array(doc["std"])
    assert np.all(np.abs(value - np.array(scales)) <= 4 * std), (value, std)
    assert fitted.validation is not None and plain.validation is not None
    assert fitted.validation.rms < 1.1 * math.sqrt(3) * 1e-5 < 1.5 * fitted.validation.rms
    assert plain.validation.rms > 1.5 * fitted.validation.rms
    rows = result_document(fitted)["standard_dh"]
    table = fitted.extraction
    assert table is not None
    Q = np.random.default_rng(20).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    offsets = np.array([r["theta_offset"] for r in rows])
    scale = np.array([r["encoder_scale"] for r in rows])
    from dhlog.model.dh import StandardDH

    as_doc = StandardDH(
        table.standard.joint_types,
        offsets,
        table.standard.d_offset,
        table.standard.a,
        table.standard.alpha,
    )
    got = fk_point(as_doc, Q * scale, table.tool_point, T_base=table.T_measurement_base)
    want = fk_point(
        session.table, Q * np.array(scales), session.tool_point, T_base=session.T_measurement_base
    )
    assert np.sqrt(np.mean(np.sum((got - want) ** 2, axis=1))) < 2e-4
