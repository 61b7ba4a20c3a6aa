"""The camera calibration (issue 32): the whole model's maximum likelihood in pixels
(identify.camera.pixels) and the run around it (identify.camera), on corners projected through a
known robot, camera and board (the simulator's rig) with Gaussian noise of a known σ.

The fit is checked by forward kinematics against the truth at random joint vectors, against an
ML fit of the same corners started from the truth, by the spread of repeated realisations
against the σ it reports, and by the camera's pose against the truth read in the same DH
conventions."""

from __future__ import annotations

import dataclasses
import json
import math
from importlib import resources

import jsonschema
import numpy as np
import pytest

import camera_rig as cams
from dhlog.identify.camera.flow import process_observations
from dhlog.identify.camera.pixels import PixelModel, fit_pixels
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.measure import residuals
from dhlog.identify.fit.prediction import predict
from dhlog.identify.options import ProcessOptions
from dhlog.identify.run import process_poses
from dhlog.io.dhfile import DHModel
from dhlog.result.document import result_document
from dhlog.simulator.camera import CAMERA, Rig, camera_poses


def _fk_rms(a: AxisModel, b: AxisModel, Q: np.ndarray) -> float:
    pa, _ = predict(a, Q)
    pb, _ = predict(b, Q)
    return float(np.sqrt(np.mean(np.sum((pa - pb) ** 2, axis=1))))


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
def test_pixel_fit_is_the_maximum_likelihood(setup: str) -> None:
    """From the nominal (its placement true), the fit reaches the ML of an ML fit started
    from the truth (the same optimum: within 1 µm at random joint vectors) and beats the
    nominal by far; σ comes back as the corners' (0.2 px, within 10 %: over 1000+ corners
    the estimate's own spread is under 3 %)."""
    robot, true, rig, Q = cams.session(setup, 3)
    rng = np.random.default_rng(7)
    ids, uv = cams.corners(rig, true, robot, Q, rng)
    data = cams.data(Q, ids, uv)
    measurement = PixelModel(setup, CAMERA)
    truth = cams.model(rig, true, robot.n)
    fit = fit_pixels(cams.model(rig, robot.table, robot.n), measurement, data)
    from_truth = fit_pixels(truth, measurement, data)
    Qr = np.random.default_rng(8).uniform(robot.limits[:, 0], robot.limits[:, 1], (300, robot.n))
    err = _fk_rms(fit.whole.model, truth, Qr)
    nominal_err = _fk_rms(cams.model(rig, robot.table, robot.n), truth, Qr)
    assert _fk_rms(fit.whole.model, from_truth.whole.model, Qr) < 1e-6
    assert err < 0.5 * nominal_err
    assert abs(fit.sigma / cams.SIGMA_PX - 1.0) < 0.1


def test_reported_sigma_matches_the_spread() -> None:
    """Over 24 noise realisations (eye-to-hand, 40 poses) the spread of the fitted target
    point's prediction at a fixed far pose matches the σ the fit reports: their ratio lies
    within the 99.9 % band of a χ² of 23 dof (0.55 … 1.5)."""
    robot, true, rig, Q = cams.session("eye-to-hand", 5, poses=40)
    measurement = PixelModel("eye-to-hand", CAMERA)
    start = cams.model(rig, robot.table, robot.n)
    q_far = np.asarray(robot.limits).mean(axis=1)[None] + 0.3
    values, sigmas = [], []
    for k in range(24):
        ids, uv = cams.corners(rig, true, robot, Q, np.random.default_rng([11, k]))
        fit = fit_pixels(start, measurement, cams.data(Q, ids, uv))
        p, J = predict(fit.whole.model, q_far, fit.whole.layout, fit.whole.model.bases())
        assert J is not None
        values.append(p[0])
        sigmas.append(np.sqrt(np.diag(J[0] @ fit.whole.covariance @ J[0].T)))
    spread = np.std(np.array(values), axis=0, ddof=1)
    reported = np.sqrt(np.mean(np.array(sigmas) ** 2, axis=0))
    ratio = spread / reported
    assert np.all((ratio > 0.55) & (ratio < 1.5)), ratio


def test_nominal_placed_keeps_its_geometry() -> None:
    """Placing the nominal (``PixelModel.place``: the camera's pose and the board's mount from
    a start 10 mm and 1° off) keeps its table and finds the true placement the corners give; it
    fits them far worse than the calibration."""
    from scipy.spatial.transform import Rotation

    robot, true, rig, Q = cams.session("eye-to-hand", 4)
    ids, uv = cams.corners(rig, true, robot, Q, np.random.default_rng(2))
    data = cams.data(Q, ids, uv)
    measurement = PixelModel("eye-to-hand", CAMERA)
    shift = np.eye(4)
    shift[:3, 3] = cams.centre()
    mount = rig.T_mounted @ shift
    T0 = np.linalg.inv(rig.T_fixed)
    off = T0.copy()
    off[:3, :3] = Rotation.from_rotvec([0.0, 0.01, 0.01]).as_matrix() @ off[:3, :3]
    off[:3, 3] += [0.01, -0.01, 0.005]
    ref = np.zeros(robot.n)
    placed, _ = measurement.place(robot.table, ref, off, mount[:3, 3], mount[:3, :3], data)
    exact = AxisModel.of_table(robot.table, ref, mount[:3, 3], T0, tool_rotation=mount[:3, :3])
    Qr = np.random.default_rng(3).uniform(robot.limits[:, 0], robot.limits[:, 1], (200, robot.n))
    calibrated = fit_pixels(exact, measurement, data)
    nominal_rms = float(np.sqrt(np.mean(np.sum(residuals(placed, measurement, data) ** 2, 1))))
    # the placement moves the nominal to where the corners put it: within 2 mm of the true
    # placement at random joint vectors (the nominal's own error is ~1 mm; placement absorbs
    # part of it), far from the 10 mm start
    assert _fk_rms(placed, exact, Qr) < 2e-3
    assert nominal_rms > 1.5 * calibrated.rms


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
def test_process_observations(setup: str) -> None:
    """The run: the set-up decided from the data, the camera's (fixed part's) pose within 4 σ
    of the truth read in the same DH conventions, held-out reprojection close to the noise
    (a 2-D norm of σ 0.2 px per coordinate: 0.28 px, up to the model's own error) and well
    below the nominal's, the PnP noise floor predicted within 25 % of the calibrated mm
    figure."""
    robot, true, rig, Q = cams.session(setup, 6)
    ids, uv = cams.corners(rig, true, robot, Q, np.random.default_rng(9))
    obs = cams.observations(robot, Q, ids, uv)
    nominal = DHModel(robot.table, np.eye(4), np.zeros(3), tuple(obs.joint_names), "library")
    result = process_observations(
        [obs], ProcessOptions(nominal=nominal, holdout=5), start=process_poses
    )
    cam = result.camera
    assert cam.setup == setup and cam.setup_reason.startswith("decided")
    # the truth in the same conventions: the true axes in M, extracted with the same nominal
    T_true = cams.fixed_in_base(rig, true, robot.table, robot.n)
    err = cam.T_base_fixed[:3, 3] - T_true[:3, 3]
    assert np.all(np.abs(err) < 4 * cam.fixed_std[3:] + 1e-6), (err, cam.fixed_std)
    h = cam.holdout
    assert h is not None and h.nominal_px is not None
    assert h.calibrated_px < 0.35 and h.calibrated_px < 0.5 * h.nominal_px
    assert abs(h.calibrated_mm / h.pnp_noise_mm - 1.0) < 0.25
    from dhlog.result.document import result_document

    doc = result_document(result)
    schema = json.loads(resources.files("dhlog").joinpath("schemas/result.schema.json").read_text())
    jsonschema.validate(json.loads(json.dumps(doc, allow_nan=False)), schema)
    assert doc["camera"]["setup"] == setup
    assert doc["camera"][cam.fixed_name] == cam.T_base_fixed.tolist()
    assert len(result.cameras) == 1 and len(result.cameras[0].frames) == len(Q)


def test_a_camera_that_moved_is_named() -> None:
    """Eye-to-hand, 50 poses, the camera knocked by 1.5 mm and 0.05° after the 30th frame: one
    warning names the frames it moved between (within two frames of the truth) and the option;
    the same session with the camera still gives none."""
    from scipy.spatial.transform import Rotation

    robot, true, rig, Q = cams.session("eye-to-hand", 8)
    rng = np.random.default_rng(4)
    ids, uv = cams.corners(rig, true, robot, Q, rng)
    knock = np.eye(4)
    knock[:3, :3] = Rotation.from_rotvec([0.0, math.radians(0.05), 0.0]).as_matrix()
    knock[:3, 3] = [0.0015, 0.0, 0.0]
    moved = Rig(rig.setup, rig.T_fixed @ knock, rig.T_mounted, rig.board, rig.camera)
    ids2, uv2 = cams.corners(moved, true, robot, Q[30:], rng)
    nominal = DHModel(robot.table, np.eye(4), np.zeros(3), tuple(f"j{k}" for k in range(6)), "lib")
    still = process_observations(
        [cams.observations(robot, Q, ids, uv)],
        ProcessOptions(nominal=nominal, camera_setup="eye-to-hand"),
        start=process_poses,
    )
    assert not any("moved during the session" in w for w in still.warnings)
    result = process_observations(
        [cams.observations(robot, Q, ids[:30] + ids2, uv[:30] + uv2)],
        ProcessOptions(nominal=nominal, camera_setup="eye-to-hand"),
        start=process_poses,
    )
    said = [w for w in result.warnings if "moved during the session" in w]
    assert len(said) == 1, result.warnings
    moved_notes = [n for n in result.notes if n.code == "camera-moved"]  # the same, by its code
    assert [(n.level, n.text) for n in moved_notes] == [("warning", said[0])]
    import re

    m = re.search(r"between frames (\d+) and (\d+)", said[0])
    assert m is not None and abs(int(m.group(2)) - 30) <= 2
    assert "--frames" in said[0]
    # the option it names calibrates from the part before the move, which is still
    before = process_observations(
        [cams.observations(robot, Q, ids[:30] + ids2, uv[:30] + uv2)],
        ProcessOptions(nominal=nominal, camera_setup="eye-to-hand", frames=(None, 30)),
        start=process_poses,
    )
    assert not any("moved during the session" in w for w in before.warnings)
    assert before.camera.frames == 30


def test_two_cameras_fitted_together() -> None:
    """Two fixed cameras (the second 0.5 m aside, turned 15°) see the board on the flange at 40
    poses each: fitted together, each camera's pose in the base frame within 4 σ of the truth
    read in the same conventions, and the model's FK closer to the truth than from the first
    camera alone (the second adds its corners)."""
    from scipy.spatial.transform import Rotation

    robot, true, rig, Q = cams.session("eye-to-hand", 9, poses=40)
    aside = np.eye(4)
    aside[:3, :3] = Rotation.from_rotvec([0.0, math.radians(15.0), 0.0]).as_matrix()
    aside[:3, 3] = [-0.5, 0.0, 0.1]
    rig2 = Rig(rig.setup, rig.T_fixed @ aside, rig.T_mounted, rig.board, rig.camera)

    Q2 = camera_poses(robot, true, rig2, 40, 10)
    rng = np.random.default_rng(6)
    ids, uv = cams.corners(rig, true, robot, Q, rng)
    ids2, uv2 = cams.corners(rig2, true, robot, Q2, rng)
    first = cams.observations(robot, Q, ids, uv)
    second = dataclasses.replace(
        cams.observations(robot, Q2, ids2, uv2), camera="/camera_2/image_raw/compressed"
    )
    nominal = DHModel(robot.table, np.eye(4), np.zeros(3), tuple(first.joint_names), "library")
    alone = process_observations(
        [first], ProcessOptions(nominal=nominal, camera_setup="eye-to-hand"), start=process_poses
    )
    both = process_observations(
        [first, second],
        ProcessOptions(nominal=nominal, camera_setup="eye-to-hand", holdout=3),
        start=process_poses,
    )
    assert len(both.camera_results) == 2
    truth = cams.model(rig, true, robot.n)
    T_base_M = cams.fixed_in_base(rig, true, robot.table, robot.n)
    for cam, T_true in zip(both.camera_results, (T_base_M, T_base_M @ aside), strict=True):
        err = cam.T_base_fixed[:3, 3] - T_true[:3, 3]
        assert np.all(np.abs(err) < 4 * cam.fixed_std[3:] + 1e-6), (err, cam.fixed_std)
    Qr = np.random.default_rng(8).uniform(robot.limits[:, 0], robot.limits[:, 1], (300, robot.n))
    assert _fk_rms(both.whole.model, truth, Qr) < _fk_rms(alone.whole.model, truth, Qr)
    # the board's mount is the joint fit's (its centre at the joint fit's target in the last
    # frame), not the first camera's own fit's, whose target lies elsewhere
    assert both.extraction is not None and alone.extraction is not None
    for cam in both.camera_results:
        centre_on_flange = (
            cam.T_flange_mounted[:3, :3] @ cams.centre() + cam.T_flange_mounted[:3, 3]
        )
        assert np.allclose(centre_on_flange, both.extraction.tool_point, atol=1e-9)
    assert not np.allclose(both.extraction.tool_point, alone.extraction.tool_point, atol=1e-9)
    h = both.camera.holdout
    assert h is not None and h.calibrated_px < 0.35
    doc = result_document(both)
    assert [c["topic"] for c in doc["cameras"]] == [first.camera, second.camera]
    # every note coded; the first camera's design effect replaced by the cameras' together
    assert all(n.code for n in both.notes), both.notes
    assert [n.code for n in both.notes].count("frame-clustered") <= 1
    assert [n.code for n in both.notes if n.code.startswith("camera")][:1] == ["camera-start"]
    assert doc["notes"] == list(both.info) and doc["warnings"] == list(both.warnings)
    assert len(both.cameras) == 2


def test_a_wrong_camera_setup_is_said() -> None:
    """Eye-to-hand corners calibrated with --camera-setup eye-in-hand: the run does not end in
    exit 0 silently — either the start fails naming --camera-setup, or a warning says the
    nominal placed in that set-up misses the corners."""
    from dhlog.errors import DhlogError

    robot, true, rig, Q = cams.session("eye-to-hand", 3, poses=40)
    ids, uv = cams.corners(rig, true, robot, Q, np.random.default_rng(5))
    obs = cams.observations(robot, Q, ids, uv)
    nominal = DHModel(robot.table, np.eye(4), np.zeros(3), tuple(obs.joint_names), "library")
    try:
        result = process_observations(
            [obs], ProcessOptions(nominal=nominal, camera_setup="eye-in-hand"), start=process_poses
        )
    except DhlogError as exc:
        assert "--camera-setup" in str(exc)
        return
    assert any("--camera-setup eye-in-hand" in w for w in result.warnings), result.warnings
