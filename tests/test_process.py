"""``dhlog process`` end to end: every sample log against its truth, the result files, the
recording, partial results and the command line."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from importlib import resources
from importlib.metadata import version
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.identify.check.validate import fk_prediction_std
from dhlog.identify.run import Identification, ProcessOptions, process_log
from dhlog.io.dhfile import load_dh
from dhlog.io.writer import write_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.present.recording import write_process_recording
from dhlog.result.document import nominal_difference, result_csv, result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

SAMPLES = Path(__file__).parents[1] / "sample_logs"
LOGS = sorted(SAMPLES.glob("*.mcap"))
SCHEMA = json.loads(resources.files("dhlog").joinpath("schemas/result.schema.json").read_text())
RERUN = str(Path(sys.executable).with_name("rerun"))
runner = CliRunner()


def rrd_verify(path: Path) -> None:
    """``rerun rrd verify`` accepts the recording."""
    check = subprocess.run(
        [RERUN, "rrd", "verify", str(path)],
        capture_output=True,
        text=True,
        env={"RERUN_ANALYTICS": "false", "PATH": ""},
    )
    assert check.returncode == 0, check.stderr


def assert_within_3_sigma(result: Identification) -> np.ndarray:
    """Every parameter with an uncertainty is within 3 reported σ of the nominal; the others
    (fixed by a convention or by the nominal) equal it. Returns the mask of free parameters."""
    diff = nominal_difference(result, shown=True)  # the well-conditioned form, when there is one
    std = result.conditioned.std if result.conditioned is not None else result.std
    assert diff is not None and std is not None
    sigma = std[: diff.size].reshape(diff.shape)
    free = sigma > 0
    ratio = np.abs(diff) / np.where(free, sigma, 1)
    assert np.all(ratio[free] <= 3.0), ratio.max()
    assert np.all(np.abs(diff[~free]) < 1e-9)
    return free


def truth_of(path: Path) -> tuple[dict[str, object], object]:
    truth_path = path.with_name(path.stem + ".truth.json")
    return json.loads(truth_path.read_text()), load_dh(truth_path)


@pytest.fixture(scope="module", params=LOGS, ids=lambda p: p.stem)
def processed(request: pytest.FixtureRequest) -> tuple[Path, Identification, Identification]:
    path: Path = request.param
    _, truth = truth_of(path)
    return path, process_log(path), process_log(path, ProcessOptions(nominal=truth))  # type: ignore[arg-type]


def test_fk_of_the_result_matches_the_truth_within_the_noise(processed) -> None:  # type: ignore[no-untyped-def]
    """At 300 random joint vectors within the robot's limits, the FK error against the truth is
    within what the propagated uncertainty predicts: every point within 4 predicted σ (3D) and
    the RMS within 2x the predicted RMS."""
    path, result, _ = processed
    doc, truth = truth_of(path)
    robot = load_robot(doc["simulation"]["robot"])  # type: ignore[index]
    assert result.complete and result.extraction is not None
    Q = np.random.default_rng(0).uniform(robot.limits[:, 0], robot.limits[:, 1], (300, robot.n))
    ex = result.extraction
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(truth.table, Q, truth.tool_point, T_base=truth.T_base)  # type: ignore[attr-defined]
    err = np.linalg.norm(got - want, axis=1)
    pred = fk_prediction_std(result, Q)
    assert np.all(err <= 4.0 * pred), (err / pred).max()
    assert np.sqrt(np.mean(err**2)) <= 2.0 * np.sqrt(np.mean(pred**2))


def test_with_the_truth_as_nominal_every_parameter_is_within_3_sigma(processed) -> None:  # type: ignore[no-untyped-def]
    _path, _, result = processed
    free = assert_within_3_sigma(result)
    n = free.shape[0]
    # the identifiable parameters have an uncertainty: at least n - 1 of the 4n (the SCARA has
    # exactly 3: a1, θ2, a2 — the heights along its parallel axes, the rotation about the
    # collinear pair 3-4 and the prismatic axis' placement are gauges, fixed)
    assert free.sum() >= n - 1


def test_result_documents_follow_the_contract(processed) -> None:  # type: ignore[no-untyped-def]
    path, result, with_nominal = processed
    for r in (result, with_nominal):
        doc = result_document(r)
        jsonschema.validate(doc, SCHEMA)
        assert doc["dhlog_version"] == version("dhlog")  # pyproject's, as CHANGELOG.md's newest
        assert doc["source"]["path"] == path.name
        assert len(doc["standard_dh"]) == len(doc["joints"]) == len(doc["modified_dh"])
        # any consumer can check the result with the contract's FK convention: the JSON alone
        # gives back the FK residuals dhlog reports
        table, T_base, tool = load_dh_from(doc)
        if r.validation is None:
            continue
        seg = r.segmentation.table
        rows = r.validation.rows  # every sample checked: a log far below SHOWN_SAMPLES
        assert rows.size == r.validation.n_points
        Q = seg.select([f"q_{i + 1}" for i in range(table.n)]).to_numpy()[rows]
        P = seg.select(["x", "y", "z"]).to_numpy()[rows]
        residual = np.linalg.norm(fk_point(table, Q, tool, T_base=T_base) - P, axis=1)
        np.testing.assert_allclose(residual, r.validation.residuals, atol=1e-12)
        assert doc["validation"]["fk_rms"] == pytest.approx(np.sqrt(np.mean(residual**2)))


def load_dh_from(doc: dict) -> tuple:  # type: ignore[type-arg]
    from dhlog.io.dhfile import parse_dh

    model = parse_dh(doc, "result")
    return model.table, model.T_base, model.tool_point


def test_csv_has_one_row_per_joint(processed) -> None:  # type: ignore[no-untyped-def]
    _, result, _ = processed
    rows = list(csv.DictReader(result_csv(result).splitlines()))
    assert len(rows) == len(result.joints)
    assert set(rows[0]) >= {"joint", "a_mm", "alpha_deg", "std_a_mm"}


def test_the_recording_verifies_and_holds_the_entities(processed, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from rerun.chunk import RrdReader

    _, result, _ = processed
    path = tmp_path / "run.rrd"
    write_process_recording(result, path)
    rrd_verify(path)
    rows: dict[str, int] = {}
    for chunk in RrdReader(path).stream():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    n = len(result.joints)
    seg = result.segmentation
    for sid, count in zip(seg.segments["segment"], seg.segments["n"], strict=True):
        outliers = sum(
            int(np.count_nonzero(~j.inliers)) for j in result.joints if sid in j.segments
        )
        assert rows[f"/world/m/samples/segment_{sid}"] == count - outliers + 1  # + style row
    for k in range(1, n + 1):
        assert f"/world/m/joints/j{k}/axis" in rows and f"/world/m/joints/j{k}/fit" in rows
        assert f"/residuals/fit/j{k}/radial" in rows  # and axial (circle) or tangential (line)
        assert f"/residuals/fit/j{k}/axial" in rows or f"/residuals/fit/j{k}/tangential" in rows
    assert all(f"/world/m/dh/frame_{i}" in rows for i in range(1, n + 2))
    assert "/world/m/robot/links" in rows and "/report/dh_table" in rows
    assert ("/residuals/fk/j1/tangential" in rows) == seg.has_encoders
    assert ("/world/m/magnified/j1" in rows) == seg.has_encoders


def test_each_run_is_its_own_recording(processed, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """Two recordings of the same result have different recording ids (they no longer merge
    when opened together); the log's hash is a property, the name says the log."""
    from rerun.chunk import RrdReader

    _, result, _ = processed
    ids = set()
    for k in range(2):
        path = tmp_path / f"run_{k}.rrd"
        write_process_recording(result, path)
        (entry,) = RrdReader(path).recordings()
        assert entry.application_id == "dhlog process"
        ids.add(entry.recording_id)
        (props,) = [
            c.to_record_batch().to_pydict()
            for c in RrdReader(path).stream()
            if c.entity_path == "/__properties/dhlog"
        ]
        assert props["log_sha256"] == [[result.sha256]] and props["log"] == [[str(result.path)]]
        names = [
            c.to_record_batch().to_pydict()["RecordingInfo:name"]
            for c in RrdReader(path).stream()
            if c.entity_path == "/__properties"
            and "RecordingInfo:name" in c.to_record_batch().schema.names
        ]
        assert names and names[0][0][0].startswith(Path(result.path).name)
    assert len(ids) == 2


def test_the_residual_components_match_the_validation(processed) -> None:  # type: ignore[no-untyped-def]
    """The FK residual components plotted per joint (radial, axial, tangential) are the FK
    residual the result reports, split along orthonormal directions: their norm equals the
    validation's residual at each sample."""
    from dhlog.present.recording import residual_parts

    _, result, _ = processed
    found = [r for r in residual_parts(result) if r.kind == "fk"]
    assert bool(found) == result.segmentation.has_encoders  # no encoders: no FK per sample
    for res in found:
        assert result.validation is not None
        norm = np.sqrt(sum(v**2 for v in res.parts.values()))
        want = np.linalg.norm(result.validation.at(res.rows), axis=1)
        checked = np.isfinite(want)  # samples the validation left out (its own inliers)
        assert checked.mean() > 0.9
        # the components split the validation's own residual vectors: the norm is kept
        np.testing.assert_allclose(norm[checked], want[checked], rtol=1e-9, atol=1e-15)


def test_gross_outliers_are_rejected(tmp_path: Path) -> None:
    cfg = SimulationConfig(seed=21, noise=1e-5, outliers=0.05, sweep=math.radians(60))
    session = simulate_session(load_robot("puma560"), cfg)
    path = tmp_path / "outliers.mcap"
    write_session(session, path)
    result = process_log(path)
    found = sum(j.n_outliers for j in result.joints)
    assert found >= 0.8 * session.n_outliers * (
        result.segmentation.table["segment"].is_not_null().mean()
    )  # type: ignore[operator]
    assert result.validation is not None and result.validation.rms < 3e-5


# ---- the command line ----------------------------------------------------------------------


def test_process_command_writes_three_files_and_keeps_them(tmp_path: Path) -> None:
    log = SAMPLES / "kr5_0.01mm.mcap"
    result = runner.invoke(
        app,
        [
            "process",
            str(log),
            "--out",
            str(tmp_path),
            "--nominal",
            str(SAMPLES / "kr5_0.01mm.truth.json"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "Standard DH" in result.output and "Δa" in result.output and "FK check" in result.output
    for suffix in (".dh.json", ".dh.csv", ".rrd"):
        assert (tmp_path / f"kr5_0.01mm{suffix}").exists()
    jsonschema.validate(json.loads((tmp_path / "kr5_0.01mm.dh.json").read_text()), SCHEMA)
    again = runner.invoke(app, ["process", str(log), "--out", str(tmp_path)])
    assert again.exit_code == 1 and "--force" in again.output
    forced = runner.invoke(
        app, ["process", str(log), "--out", str(tmp_path), "--force", "--no-rrd", "--units", "m"]
    )
    assert forced.exit_code == 0 and "a [m]" in forced.output


def test_partial_result_names_the_joint_and_exits_3(tmp_path: Path) -> None:
    session = simulate_session(
        load_robot("ur5"), SimulationConfig(seed=9, skip_joints=(4,), sweep=math.radians(60))
    )
    log = tmp_path / "partial.mcap"
    write_session(session, log)
    result = runner.invoke(app, ["process", str(log), "--no-rrd"])
    assert result.exit_code == 3
    assert "joint 4 (joint_4) not identified" in result.output
    doc = json.loads((tmp_path / "partial.dh.json").read_text())
    jsonschema.validate(doc, SCHEMA)
    assert doc["joints"][3]["error"].startswith("it was parked in the session")
    assert "give --nominal" in doc["joints"][3]["error"]
    assert doc["joints"][2]["axis"] is not None and len(doc["standard_dh"]) == 2


def test_unusable_input_exits_2_with_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "notes.mcap"
    bad.write_text("not a log")
    result = runner.invoke(app, ["process", str(bad)])
    assert result.exit_code == 2
    assert "not an MCAP file" in result.output and "Traceback" not in result.output


def test_usage_errors_exit_1() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "dhlog", "process", "--bogus"], capture_output=True, text=True
    )
    assert proc.returncode == 1 and "error:" in proc.stderr
    proc = subprocess.run(
        [sys.executable, "-m", "dhlog", "--version"], capture_output=True, text=True
    )
    assert proc.returncode == 0 and "dhlog" in proc.stdout


def test_fk_command_prints_pose_and_jacobian() -> None:
    result = runner.invoke(app, ["fk", "scara", "--q", "0,0,0,0"])
    assert result.exit_code == 0, result.output
    assert "0.15" in result.output and "spatial Jacobian" in result.output
    wrong = runner.invoke(app, ["fk", "scara", "--q", "0,0"])
    assert wrong.exit_code == 1


def test_fk_command_reads_a_result_json(tmp_path: Path) -> None:
    log = SAMPLES / "scara.mcap"
    assert (
        runner.invoke(app, ["process", str(log), "--out", str(tmp_path), "--no-rrd"]).exit_code == 0
    )
    result = runner.invoke(app, ["fk", str(tmp_path / "scara.dh.json"), "--q", "0.1,0.2,0.3,-0.01"])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("robot", ["elbow", "scara", "stanford"])
def test_show_writes_a_valid_recording(robot: str, tmp_path: Path) -> None:
    out = tmp_path / f"{robot}.rrd"
    result = runner.invoke(app, ["show", robot, "-o", str(out), "--steps", "10"])
    assert result.exit_code == 0, result.output
    rrd_verify(out)


@pytest.mark.parametrize("robot", ["kr5", "puma560"])
def test_sweeps_from_anywhere_are_carried_to_the_reference_pose(robot: str) -> None:
    """Every joint swept from its own random locked pose: the axes are carried to the reference
    pose through the upstream axes, and the result still agrees with the truth within the
    propagated uncertainty (with the truth as nominal: every parameter within 3σ)."""
    from dhlog.identify.run import process_data
    from dhlog.io.dhfile import DHModel
    from dhlog.io.memory import log_data_from_session

    rob = load_robot(robot)
    session = simulate_session(
        rob, SimulationConfig(seed=3, noise=2e-5, lock_poses="random", sweep=math.radians(60))
    )
    nominal = DHModel(
        rob.table, rob.T_base, rob.tool_point, tuple(f"joint_{i + 1}" for i in range(rob.n)), robot
    )
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=nominal))
    assert result.complete and sum(j.carried for j in result.joints) >= rob.n - 1
    ex = result.extraction
    assert ex is not None and result.std is not None
    Q = np.random.default_rng(1).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, rob.n))
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    assert np.all(np.linalg.norm(got - want, axis=1) <= 4.0 * fk_prediction_std(result, Q))
    assert_within_3_sigma(result)


def test_nearly_parallel_axes_get_hayati_parameters_and_a_note() -> None:
    """UR5 axes 2, 3, 4 are parallel. Exactly parallel in the truth: the data cannot tell them
    from parallel, so d = 0 by convention. Tilted by about 1 mrad (a real misalignment, far
    beyond the noise): the DH d explodes, which is said, and the Hayati–Mirmirani parameters
    (β in place of d) describe the pair."""
    from dhlog.identify.run import process_data
    from dhlog.io.memory import log_data_from_session

    rob = load_robot("ur5")
    exact = process_data(log_data_from_session(simulate_session(rob, SimulationConfig(seed=5))))
    doc = result_document(exact)
    assert doc["relations"][1]["kind"] == "parallel" and doc["relations"][2]["kind"] == "parallel"
    assert [h["joints"] for h in doc["hayati"]] == [[2, 3], [3, 4]]
    assert not any("ill-conditioned" in w for w in exact.warnings + exact.info)
    assert exact.conditioned is None  # parallel pairs have d by convention: no Hayati rows
    tilted_cfg = SimulationConfig(seed=5, perturb_angle=2e-3, perturb_length=1e-4)
    session = simulate_session(rob, tilted_cfg)
    tilted = process_data(log_data_from_session(session))
    doc = result_document(tilted)
    assert doc["relations"][1]["kind"] == "skew"
    assert any(
        "joints 2 and 3 are nearly parallel" in w and "ill-conditioned" in w for w in tilted.info
    )
    assert tilted.conditioned is not None and doc["hayati_dh"]["rows"][1]["form"] == "hayati"
    hayati = {tuple(h["joints"]): h for h in doc["hayati"]}
    # the tilt about the common normal is the DH twist of the truth
    assert abs(abs(hayati[(2, 3)]["alpha"]) - abs(session.table.alpha[1])) < 5e-5
    assert abs(hayati[(2, 3)]["a"] - abs(session.table.a[1])) < 1e-3
    # and the FK of the (ill-conditioned) DH table is still right
    Q = np.random.default_rng(2).uniform(-1, 1, (100, 6))
    ex = tilted.extraction
    assert ex is not None
    err = np.linalg.norm(
        fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
        - fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base),
        axis=1,
    )
    assert np.all(err <= 4.0 * fk_prediction_std(tilted, Q))


def test_the_whole_model_fit_is_closer_to_the_truth_than_the_seed_method() -> None:
    """KR5 with 60° sweeps: the analytic model (seed method) is already near the noise on the
    samples, but the maximum-likelihood fit of the whole model to every sample (the default)
    brings the model closer to the truth over the whole workspace, its uncertainty covers the
    error, and the result carries the analytic table, the covariance and the noise model."""
    from dhlog.identify.run import process_data
    from dhlog.io.memory import log_data_from_session

    rob = load_robot("kr5")
    session = simulate_session(rob, SimulationConfig(seed=5, noise=2e-5, sweep=math.radians(60)))
    log = log_data_from_session(session)
    analytic = process_data(log, ProcessOptions(analytic_only=True))
    whole = process_data(log)
    assert analytic.method == "analytic" and whole.method.startswith("whole-model")
    assert whole.validation is not None and analytic.validation is not None
    # σ per coordinate is 20 µm, so the 3-D residual RMS is √3 · 20 µm at the optimum
    assert whole.validation.rms < 1.05 * math.sqrt(3) * 2e-5
    doc = result_document(whole)
    jsonschema.validate(doc, SCHEMA)
    assert doc["method"] == "whole-model maximum likelihood"
    assert 0.9 < doc["noise"]["chi2_dof"] < 1.1
    assert doc["analytic"]["max_deviation_sigma"] > 0.0
    names = doc["covariance"]["parameters"]
    matrix = np.array(doc["covariance"]["matrix"])
    assert matrix.shape == (len(names), len(names)) and np.allclose(matrix, matrix.T)
    assert np.all(np.linalg.eigvalsh(matrix) > -1e-18)
    # conventions are marked fixed, with a reason, and have no σ: θ1 (x1), d2 (parallel 2-3)
    assert (
        "theta" in doc["standard_dh"][0]["fixed"] and doc["standard_dh"][0]["std"]["theta"] is None
    )
    assert (
        "d" in doc["standard_dh"][1]["fixed"]
        and "parallel" in doc["standard_dh"][1]["fixed_reason"]
    )
    assert "theta_offset_1" not in names and "d_2" not in names
    Q = np.random.default_rng(3).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, rob.n))
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)

    def err(r: Identification) -> np.ndarray:
        ex = r.extraction
        assert ex is not None
        got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
        return np.linalg.norm(got - want, axis=1)

    assert np.sqrt(np.mean(err(whole) ** 2)) < 0.5 * np.sqrt(np.mean(err(analytic) ** 2))
    assert np.all(err(whole) <= 4.0 * fk_prediction_std(whole, Q))


def test_with_log_imports_the_logs_own_channels(tmp_path: Path) -> None:
    """``--with-log``: the MCAP's own topics are in the recording beside dhlog's entities."""
    from rerun.chunk import RrdReader

    done = runner.invoke(
        app,
        ["process", str(SAMPLES / "scara.mcap"), "--out", str(tmp_path), "--with-log"],
    )
    assert done.exit_code == 0, done.output
    rrd_verify(tmp_path / "scara.rrd")
    entities = {chunk.entity_path for chunk in RrdReader(tmp_path / "scara.rrd").stream()}
    assert "/world/m/robot/links" in entities
    assert any(e.startswith("/tracker/point") for e in entities), sorted(entities)[:20]
