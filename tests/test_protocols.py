"""Any protocol a cell records: random static poses and coupled moves identified by the
whole-model fit from the nominal (registered onto the points), what the poses determine, the
model-error variance component, and the held-out proof (K-fold cross-validation, other logs)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.identify.check.validate import fk_prediction_std
from dhlog.identify.fit.leaveout import pose_groups
from dhlog.identify.fit.register import register_nominal
from dhlog.identify.read.propagate import NOT_DETERMINED
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.decode.frames import COVARIANCE_COLUMNS
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.io.writer import write_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import Robot, load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import Session, simulate_session
from dhlog.simulator.tracker import default_measurement_pose

from chains import fk_error

OFF = {"perturb_length": 2e-4, "perturb_angle": math.radians(0.05)}


def nominal_of(robot: Robot) -> DHModel:
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    return DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)


def random_poses(seed: int, **extra: object) -> tuple[Robot, Session]:
    """A KR5 off its nominal at 40 random still poses, one tracker point per pose (as a
    tracker's export has), σ 10 µm."""
    robot = load_robot("kr5")
    settings: dict[str, object] = {
        "protocol": "random-poses",
        "poses": 40,
        "noise": 1e-5,
        "dwell": 0.5,
        "tracker_rate": 2.0,
        **OFF,
        **extra,
    }
    cfg = SimulationConfig(seed=seed, **settings)  # type: ignore[arg-type]
    return robot, simulate_session(robot, cfg)


def test_the_nominal_registered_onto_the_points_finds_base_and_tool() -> None:
    """The registration of an exact nominal onto noiseless points at random poses recovers the
    tracker → base transform and the tool point to rounding, and survives 10 % gross outliers
    (they are named as outliers, the rest fit)."""
    robot = load_robot("kr5")
    rng = np.random.default_rng(3)
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (60, robot.n))
    T = default_measurement_pose()
    tool = np.array([0.06, 0.04, 0.1])
    P = fk_point(robot.table, Q, tool, T_base=T)
    reg = register_nominal(robot.table, Q, P)
    assert np.abs(reg.T_measurement_base - T).max() < 1e-9
    assert np.abs(reg.tool_point - tool).max() < 1e-9
    bad = rng.choice(60, 6, replace=False)
    P[bad] += rng.normal(scale=0.05, size=(6, 3))
    reg = register_nominal(robot.table, Q, P)
    assert set(np.flatnonzero(~reg.inliers)) == set(bad)
    assert reg.rms < 1e-9 and np.abs(reg.tool_point - tool).max() < 1e-6


def test_random_static_poses_are_identified_from_the_nominal() -> None:
    """40 random static poses (every joint changes between poses), no sweep: with the nominal
    the whole model is fitted from the registered nominal; the FK error against the truth at
    random joint vectors is within 4σ of its predicted uncertainty everywhere. Without a
    nominal the result is partial with one line naming --nominal."""
    robot, session = random_poses(1)
    log = log_data_from_session(session)
    result = process_data(log, ProcessOptions(nominal=nominal_of(robot)))
    assert result.complete and result.whole is not None and result.registration is not None
    assert any("no joint was swept alone" in note for note in result.info)
    Q = np.random.default_rng(4).uniform(robot.limits[:, 0], robot.limits[:, 1], (200, 6))
    err = fk_error(result, session, Q)
    assert np.all(err <= 4.0 * fk_prediction_std(result, Q))
    assert float(np.sqrt(np.mean(err**2))) < 0.05e-3  # the nominal is ~1 mm off
    alone = process_data(log)
    assert not alone.complete
    assert any("pass --nominal" in w for w in alone.warnings)


def test_cross_validation_holds_out_poses_and_the_calibration_beats_the_nominal() -> None:
    """--holdout 5 on 40 random poses: every pose is held out once (the poses, not samples:
    three samples a pose never straddle the folds); the nominal's held-out error is about its
    millimetre of error, the calibrated model's a few times the noise (σ 10 µm: 3-D ≈ 17 µm),
    and above the in-sample FK RMS."""
    robot, session = random_poses(2, tracker_rate=6.0)
    result = process_data(
        log_data_from_session(session), ProcessOptions(nominal=nominal_of(robot), holdout=5)
    )
    (h,) = result.holdout
    assert h.kind == "cross-validation" and h.folds == 5 and h.calibrated.n_poses == 40
    assert h.nominal is not None and 0.3e-3 < h.nominal.rms < 5e-3
    assert h.calibrated.rms < 60e-6 and h.calibrated.rms < h.nominal.rms / 10
    assert result.validation is not None
    in_sample_pose = result.validation.rms / math.sqrt(3)  # three samples averaged per pose
    assert h.calibrated.rms > in_sample_pose
    s = h.calibrated
    assert s.mean <= s.rms <= s.max and s.p95 <= s.max
    doc = result_document(result)
    assert doc["validation"]["holdout"][0]["calibrated"]["n_poses"] == 40


def test_pose_groups_split_at_every_move() -> None:
    Q = np.array([[0.0, 0], [0, 0.0005], [0.2, 0], [0.2, 0], [0.2, 0.5]])
    assert pose_groups(Q).tolist() == [0, 0, 1, 1, 2]


def test_a_model_error_component_keeps_u95_weighting_from_hurting() -> None:
    """Per-point uncertainties of 1–10 µm (an export's U95) on a robot leaving 60 µm of
    unmodelled error: the residuals are far beyond the declared σ, so a model-error σ is
    estimated (within 40 % of the simulated one: the calibration absorbs part of it) and added;
    the FK error is then within 5 % of the unweighted fit's (weighting by U95 alone made it up
    to 1.5x worse), and a warning names the ratio."""
    robot, session = random_poses(3, model_error=6e-5, noise=5e-6)
    log = log_data_from_session(session)
    sd = np.random.default_rng(5).uniform(1e-6, 1e-5, log.points.height)
    cov = {
        c: sd**2 if c in ("cxx", "cyy", "czz") else np.zeros_like(sd) for c in COVARIANCE_COLUMNS
    }
    weighted = dataclasses.replace(
        log, points=log.points.with_columns(pl.Series(k, v) for k, v in cov.items())
    )
    nominal = nominal_of(robot)
    plain = process_data(log, ProcessOptions(nominal=nominal))
    u95 = process_data(weighted, ProcessOptions(nominal=nominal))
    assert u95.noise.model == "per-sample" and u95.noise.model_error is not None
    assert 0.6 * 6e-5 < u95.noise.model_error < 1.4 * 6e-5
    assert any("model-error σ" in w for w in u95.warnings)
    assert u95.whole is not None and 0.8 < u95.whole.chi2_dof < 1.25
    Q = np.random.default_rng(6).uniform(robot.limits[:, 0], robot.limits[:, 1], (300, 6))
    e_plain = float(np.sqrt(np.mean(fk_error(plain, session, Q) ** 2)))
    e_u95 = float(np.sqrt(np.mean(fk_error(u95, session, Q) ** 2)))
    assert e_u95 <= 1.05 * e_plain
    assert result_document(u95)["noise"]["model_error_sigma"] == u95.noise.model_error


def test_what_the_poses_do_not_determine_is_held_at_the_nominal_and_marked() -> None:
    """Joints 2 and 3 only ever move together (q3 = −q2), so how far each of them turned
    (their offsets' split, and what follows from it) is not determined: those directions are
    held at the nominal, the parameters they move are fixed with the reason, and the fit still
    reproduces every sample (FK RMS at the noise)."""
    robot = load_robot("kr5")
    cfg = SimulationConfig(
        seed=4,
        protocol="coupled",
        skip_joints=(3,),  # joint 3 not swept alone either
        steps=8,
        noise=1e-5,
        **OFF,  # type: ignore[arg-type]
    )
    session = simulate_session(robot, cfg)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal_of(robot)))
    assert result.complete and result.whole is not None
    d = result.whole.determined
    assert d is not None and d.null.shape[1] >= 1
    assert any(NOT_DETERMINED in why for why in result.fixed.values())
    assert result.validation is not None and result.validation.rms < 3.0 * math.sqrt(3) * 1e-5
    ident = result_document(result)["whole_fit"]["identifiability"]
    assert ident["determined"] == ident["parameters"] - d.null.shape[1]


def test_process_cli_with_holdout_and_a_log_measured_after_the_tracker_moved(
    tmp_path: Path,
) -> None:
    """Through the CLI on real MCAP files: a random-pose session and a second session of the
    same robot measured after the tracker moved (other poses): --holdout 5 and --validate give
    two held-out checks (the second says the base was placed again), the held-out CSV has one
    row per scored pose, the JSON validates against the schema, and --validate naming an output
    is refused."""
    import jsonschema

    from dhlog.io.writer import write_truth  # noqa: F401  (the writer module is what we test)

    robot = load_robot("kr5")
    cfg = SimulationConfig(
        seed=5,
        protocol="random-poses",
        poses=30,
        noise=1e-5,
        dwell=0.5,
        tracker_rate=2.0,
        **OFF,  # type: ignore[arg-type]
    )
    cal = simulate_session(robot, cfg)
    moved = default_measurement_pose()
    moved[:3, 3] += [0.4, 0.3, 0.05]
    same = dataclasses.replace(robot, table=cal.table)  # the robot as simulated, other poses
    val = simulate_session(
        same,
        dataclasses.replace(cfg, seed=6, perturb_length=0.0, perturb_angle=0.0),
        T_measurement_robot=moved,
    )
    assert not np.allclose(val.poses, cal.poses)
    write_session(cal, tmp_path / "cal.mcap")
    write_session(val, tmp_path / "val.mcap")
    out = tmp_path / "out"
    runner = CliRunner()
    args = ["process", str(tmp_path / "cal.mcap"), "--nominal", "kr5", "--out", str(out)]
    r = runner.invoke(app, [*args, "--holdout", "5", "--validate", str(tmp_path / "val.mcap")])
    assert r.exit_code == 0, r.output
    assert "Held-out error" in r.output and "val.mcap (placed)" in r.output
    doc = json.loads((out / "cal.dh.json").read_text())
    schema = json.loads(
        (Path(__file__).parents[1] / "src/dhlog/schemas/result.schema.json").read_text()
    )
    jsonschema.validate(doc, schema)
    cv, other = doc["validation"]["holdout"]
    assert cv["kind"] == "cross-validation" and other["registered"] is True
    assert other["calibrated"]["rms"] < other["nominal"]["rms"] / 5
    rows = (out / "cal.holdout.csv").read_text().splitlines()
    assert len(rows) == 1 + cv["n_poses"] + other["n_poses"]
    clash = runner.invoke(
        app, [*args, "--force", "--holdout", "5", "--validate", str(out / "cal.dh.json")]
    )
    assert clash.exit_code != 0 and "is an input" in clash.output
    bad = runner.invoke(app, [*args, "--force", "--holdout", "1"])
    assert bad.exit_code != 0 and "--holdout" in bad.output


@pytest.mark.parametrize("seed", [6])
def test_a_coupled_joint_is_identified_without_a_nominal(seed: int) -> None:
    """Joint 2 only moved together with joint 3 (q3 = −q2: the target runs on a circle whose
    centre places axis 2 beside the parallel axis 3), every other joint swept alone: without a
    nominal, joint 2 is started from that circle and the whole-model fit identifies it; the FK
    error is within 4σ of the predicted uncertainty at random joint vectors."""
    robot = load_robot("kr5")
    cfg = SimulationConfig(
        seed=seed,
        skip_joints=(2,),
        coupled=((2, 3, -1.0),),
        noise=1e-5,
        tracker_rate=20.0,
        **OFF,  # type: ignore[arg-type]
    )
    session = simulate_session(robot, cfg)
    result = process_data(log_data_from_session(session))
    assert result.complete and result.whole is not None
    assert any("coupled move" in w for w in result.warnings)
    Q = np.random.default_rng(7).uniform(robot.limits[:, 0], robot.limits[:, 1], (200, 6))
    assert np.all(fk_error(result, session, Q) <= 4.0 * fk_prediction_std(result, Q))


def test_samples_of_one_pose_share_its_error_and_the_uncertainty_says_so() -> None:
    """Five tracker samples at each of 40 still poses of a robot leaving 60 µm of unmodelled
    error: the samples of a pose are not independent, so the σ is scaled by the design effect
    (about √5 here: the pose's error dominates the 10 µm noise) and covers the FK error at
    random joint vectors (4σ); with one sample a pose nothing is scaled."""
    robot, session = random_poses(7, model_error=6e-5, tracker_rate=10.0)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal_of(robot)))
    notes = [n for n in result.info if "design effect" in n]
    assert len(notes) == 1 and "5.0 a pose" in notes[0]
    Q = np.random.default_rng(8).uniform(robot.limits[:, 0], robot.limits[:, 1], (200, 6))
    assert np.all(fk_error(result, session, Q) <= 4.0 * fk_prediction_std(result, Q))
    robot, single = random_poses(7, model_error=6e-5)
    once = process_data(log_data_from_session(single), ProcessOptions(nominal=nominal_of(robot)))
    assert not any("design effect" in n for n in once.info)


def test_the_design_effect_in_one_pass_is_the_direct_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """The design effect is found in one pass, each pose's sums carried across blocks until
    the next pose starts: with blocks of 7 and 3 samples (every pose of 5 straddles one) it is
    the same as with whole blocks, and both equal the direct computation from every inlier's
    whitened residual grouped by :func:`pose_groups`."""
    import dhlog.identify.fit.leaveout as leaveout
    import dhlog.identify.fit.variance as variance
    from dhlog.identify.joints.sweeps import samples_with_encoders

    robot, session = random_poses(7, model_error=6e-5, tracker_rate=10.0)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal_of(robot)))
    assert result.whole is not None
    _, Q, P = samples_with_encoders(result.segmentation)
    inliers = result.whole.inliers

    def whiten(points: np.ndarray, rows: np.ndarray) -> float:
        return 1.0 / 1e-5

    rw = variance.whitened_residuals(result.whole, inliers, Q, P, whiten)
    groups = pose_groups(Q)[inliers]
    _, pose = np.unique(groups, return_inverse=True)
    m, g = rw.shape[0], int(pose.max()) + 1
    sums = np.stack([np.bincount(pose, weights=rw[:, k]) for k in range(3)], axis=1)
    squares = float(np.sum(rw**2))
    within = (squares - float(np.sum(sums**2 / np.bincount(pose)[:, None]))) / (3 * (m - g))
    rho = 1.0 - within / (squares / (3 * m - result.whole.layout.size))
    whole = variance.design_effect(result.whole, Q, P, whiten)
    monkeypatch.setattr(leaveout, "POSE_CHUNK", 7)
    monkeypatch.setattr(variance, "CHUNK", 3)
    small = variance.design_effect(result.whole, Q, P, whiten)
    assert (whole.samples, whole.poses) == (small.samples, small.poses) == (m, g) == (200, 40)
    for d in (whole, small):
        assert d.squares == pytest.approx(squares, rel=1e-12)
        assert d.rho == pytest.approx(rho, rel=1e-9)
        assert d.effect == pytest.approx(1.0 + (m / g - 1.0) * rho, rel=1e-9)
    assert whole.effect > 2.0  # the pose's error dominates: the case the effect is for


def test_the_readme_random_poses_walkthrough(tmp_path: Path) -> None:
    """docs/random-poses.md: the bundled tracker export (6-DoF probe, U95 rounded, one read
    0.000) imported unchanged and processed with --nominal kr5 --holdout 5: exit 0, the
    probe's orientation used, a model-error σ estimated, the held-out table as the page
    shows it, and the FK within 4σ of the truth beside the export at 200 joint vectors."""
    from dhlog.identify.run import process_log
    from dhlog.io.dhfile import dh_model_from, load_dh

    samples = Path(__file__).parents[1] / "sample_logs"
    runner = CliRunner()
    made = runner.invoke(
        app, ["import", str(samples / "kr5_random_poses.csv"), "-o", str(tmp_path / "poses.mcap")]
    )
    assert made.exit_code == 0, made.output
    assert "σ was read from U(95)" in made.output and "Q0, Q1, Q2, Q3" in made.output
    args = ["process", str(tmp_path / "poses.mcap"), "--nominal", "kr5", "--holdout", "5"]
    done = runner.invoke(app, [*args, "--out", str(tmp_path / "results"), "--no-rrd"])
    assert done.exit_code == 0, done.output
    section = (Path(__file__).parents[1] / "docs" / "random-poses.md").read_text()
    (table,) = [b for b in section.split("```") if "Held-out error" in b]
    printed = {line.rstrip() for line in done.output.splitlines()}
    for line in table.strip("\n").splitlines():
        assert line.rstrip() in printed, line
    result = process_log(tmp_path / "poses.mcap", ProcessOptions(nominal=dh_model_from("kr5")))
    assert result.tool_orientation is not None and result.noise.model_error is not None
    truth = load_dh(samples / "kr5_random_poses.truth.json")
    rob = load_robot("kr5")
    Q = np.random.default_rng(2).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    ex = result.extraction
    assert ex is not None and result.complete
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(truth.table, Q, truth.tool_point, T_base=truth.T_base)
    err = np.linalg.norm(got - want, axis=1)
    assert np.all(err <= 4.0 * fk_prediction_std(result, Q))


def test_several_targets_at_random_poses_are_fitted_together() -> None:
    """Three SMRs on the flange measured at each of 40 random poses (no sweep): the nominal is
    placed on the primary target's points and the whole model fits all three; at 200 random
    joint vectors each further target's FK is within 4σ of the truth (σ: the FK's predicted σ
    and its tool point's, together)."""
    extra = ((0.05, 0.0, 0.08), (-0.04, 0.03, 0.09))
    robot, session = random_poses(8, extra_tools=extra)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal_of(robot)))
    assert result.complete and result.whole is not None and result.extraction is not None
    assert result.extra_tool_points.shape == (2, 3)
    ex = result.extraction
    Q = np.random.default_rng(9).uniform(robot.limits[:, 0], robot.limits[:, 1], (200, 6))
    sd = fk_prediction_std(result, Q)
    T = session.T_measurement_base
    for k, true_point in enumerate(extra):
        got = fk_point(ex.standard, Q, result.extra_tool_points[k], T_base=ex.T_measurement_base)
        want = fk_point(session.table, Q, np.array(true_point), T_base=T)
        err = np.linalg.norm(got - want, axis=1)
        bound = 4.0 * np.sqrt(sd**2 + float(np.sum(result.extra_tool_std[k] ** 2)))
        assert np.all(err <= bound), (err / bound).max()


def test_the_batch_summary_carries_the_cross_validation(tmp_path: Path) -> None:
    """dhlog batch --holdout 5: one log's summary row has the held-out statistics of the nominal
    and of the calibrated model (m, named so), the calibrated far below the nominal."""
    from dhlog.fleet.batch import BatchJob, process_job

    _, session = random_poses(9)
    write_session(session, tmp_path / "poses.mcap")
    job = BatchJob(
        str(tmp_path / "poses.mcap"), str(tmp_path), nominal="kr5", no_rrd=True, holdout=5
    )
    row = process_job(job)
    assert row["status"] == "ok", row
    assert (tmp_path / "poses.holdout.csv").exists()
    assert 0 < row["holdout_calibrated_rms_m"] < row["holdout_nominal_rms_m"] / 5
    assert row["holdout_calibrated_max_m"] >= row["holdout_calibrated_p95_m"]
