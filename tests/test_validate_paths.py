"""``--validate`` of task sessions along a path (issue 39, item 1): real MCAP files from the
simulator's ``line`` and ``curve`` protocols, the tracker re-stationed (0.61 m, turned 125°) and
the 6-DoF probe re-mounted (0.95 mm, 1.6°) since the calibration, the orientation constant
along each path. Scored against the truth, computed here on its own: each model (the nominal as
placed on the calibration session, the result) placed by least squares on the noise-free truth
at every pose of the log (base, tool point and frame: the freedoms the log needs), its 3-D
position error there.

A KR5 off its nominal (0.2 mm, 0.05°) is calibrated from 40 random still poses (σ 10 µm, 0.2
mrad). The validation sessions are quiet (σ 1 µm, 0.02 mrad), so their figures are the models'
own errors: the nominal's ~50-80 µm, the result's ~5-10 µm, against the noise's √3 µm a pose;
a footing stuck far off (what main's local search did after the re-station: 192 mm) or a
re-mount left unplaced (~1 mm) is orders beyond the 10 % asked.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.geometry._checks import rotation_from_vector
from dhlog.identify.check.footing import LogHoldout
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.run import Identification, ProcessOptions, process_log
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import parse_pipeline
from dhlog.io.writer import write_session
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot, load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.exports import leica_export
from dhlog.simulator.session import Session, simulate_session
from dhlog.simulator.tracker import default_measurement_pose

OFF = {"perturb_length": 2e-4, "perturb_angle": math.radians(0.05)}
ROTATION = (0.3, -0.2, 0.5)
SIX_DOF = (
    'name = "six_dof"\nencoding = "cdr"\n[streams.point]\ntopic = "/tracker/point"\n'
    'orientation = true\n[streams.joints]\ntopic = "/joint_states"\n'
)
COMMON: dict[str, object] = {
    "dwell": 0.5,
    "tracker_rate": 2.0,  # one sample a pose
    "joint_rate": 100.0,
    "tool_rotation": ROTATION,
}
QUIET = {"noise": 3e-8, "orientation_noise": 1e-6}
#: the validation's figure against the truth's: within 10 % (issue 39's "done when")
WITHIN = 0.10
Run = tuple[Robot, Identification, dict[str, Session], dict[str, LogHoldout]]


def nominal_of(robot: Robot) -> DHModel:
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    return DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    folder = tmp_path_factory.mktemp("paths")
    robot = load_robot("kr5")
    cfg = SimulationConfig(
        protocol="random-poses", poses=40, seed=5, noise=1e-5, orientation_noise=2e-4,
        **COMMON, **OFF,  # type: ignore[arg-type]
    )  # fmt: skip
    cal = simulate_session(robot, cfg)
    write_session(cal, folder / "cal.mcap")
    same = dataclasses.replace(robot, table=cal.table)  # the robot as calibrated
    moved = {"restation": True, "remount": True}
    plans: dict[str, dict[str, object]] = {
        "line": {"protocol": "line", "poses": 90, **moved},
        "curve": {"protocol": "curve", "poses": 120, **moved},
        "random": {"protocol": "random-poses", "poses": 45, **moved},
    }
    sessions = {}
    for k, (name, plan) in enumerate(plans.items()):
        config = SimulationConfig(seed=30 + k, **{**COMMON, **QUIET, **plan})  # type: ignore[arg-type]
        sessions[name] = simulate_session(same, config)
        write_session(sessions[name], folder / f"{name}.mcap")
    # the line again as the tracker's 6-DoF export (Q0 = w), imported as a user would
    (folder / "line_export.csv").write_text(leica_export(sessions["line"]))
    made = CliRunner().invoke(
        app,
        ["import", str(folder / "line_export.csv"), "--format", "leica", "-o",
         str(folder / "line_export.mcap")],
    )  # fmt: skip
    assert made.exit_code == 0, made.output
    sessions["line_export"] = sessions["line"]
    other = load_robot("ur5")  # another robot of six joints
    config = SimulationConfig(protocol="random-poses", poses=30, seed=40, **COMMON)  # type: ignore[arg-type]
    write_session(simulate_session(other, config), folder / "ur5.mcap")
    config = SimulationConfig(protocol="random-poses", poses=10, seed=41, **COMMON)  # type: ignore[arg-type]
    write_session(simulate_session(load_robot("scara"), config), folder / "scara.mcap")
    result = process_log(
        folder / "cal.mcap",
        ProcessOptions(
            pipeline=parse_pipeline(SIX_DOF, "six_dof.toml"),
            nominal=nominal_of(robot),
            model=ModelRequest("geometric"),
            validate=tuple(
                [folder / f"{name}.mcap" for name in (*plans, "line_export", "ur5", "scara")]
            ),
        ),
    )
    checks = {}
    for check in result.holdout:
        assert isinstance(check, LogHoldout) and check.path is not None
        checks[Path(check.path).stem] = check
    return robot, result, sessions, checks


def truth_error(
    table: StandardDH,
    T: np.ndarray,
    tool: np.ndarray,
    R_tool: np.ndarray,
    session: Session,
) -> float:
    """RMS (m) of the model's 3-D position error against the session's noise-free truth at
    the poses not placed on: the model placed by least squares (its base and the probe's frame,
    1 mrad weighed as 0.1 mm; the tool point too where the flange's orientation varies — at one
    orientation a tool point is a translation of the base) on every third pose, started from
    the placement the truth knows."""
    assert session.tool_rotation is not None
    q = session.poses
    true = fk_frames(session.table, q, T_base=session.T_measurement_base)[:, -1]
    P = np.einsum("kij,j->ki", true[:, :3, :3], session.tool_point) + true[:, :3, 3]
    R = true[:, :3, :3] @ session.tool_rotation
    F = fk_frames(table, q)[:, -1]
    on = np.zeros(q.shape[0], dtype=bool)
    on[::3] = True
    free_tool = session.config.protocol == "random-poses"

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        B = np.eye(4)
        B[:3, :3] = rotation_from_vector(x[:3]) @ T[:3, :3]
        B[:3, 3] = T[:3, 3] + x[3:6]
        return B, tool + (x[9:12] if free_tool else 0.0), R_tool @ rotation_from_vector(x[6:9])

    def position(x: np.ndarray, rows: np.ndarray) -> np.ndarray:
        B, t, _ = unpack(x)
        local = np.einsum("kij,j->ki", F[rows, :3, :3], t) + F[rows, :3, 3]
        return np.asarray(local @ B[:3, :3].T + B[:3, 3])

    def miss(x: np.ndarray) -> np.ndarray:
        B, _, Rt = unpack(x)
        frame = np.einsum("ij,kjl,lm->kim", B[:3, :3], F[on, :3, :3], Rt)
        turn = np.einsum("kji,kjl->kil", R[on], frame)
        skew = 0.5 * np.stack([turn[:, 2, 1] - turn[:, 1, 2], turn[:, 0, 2] - turn[:, 2, 0],
                               turn[:, 1, 0] - turn[:, 0, 1]], axis=1)  # fmt: skip
        return np.concatenate([(position(x, on) - P[on]).ravel(), 0.1 * skew.ravel()])

    x = least_squares(miss, np.zeros(12 if free_tool else 9), x_scale="jac").x
    return float(np.sqrt(np.mean(np.sum((position(x, ~on) - P[~on]) ** 2, axis=1))))


def truth_errors(run: Run, name: str) -> tuple[float, float]:
    """The nominal's and the result's error against the truth at the log ``name``'s poses,
    each started from where the truth says it stands: the nominal at the true base, tool point
    and frame; the result at its calibrated placement carried by the known re-station and
    re-mount."""
    robot, result, sessions, _ = run
    session = sessions[name]
    ex = result.extraction
    assert ex is not None and result.tool_orientation is not None
    assert session.tool_rotation is not None
    move = session.T_measurement_base @ np.linalg.inv(calibration_T())  # M_cal → M of the log
    shift = session.tool_point - robot.tool_point
    turn = rotation_from_vector(-np.asarray(ROTATION)) @ session.tool_rotation
    nominal = truth_error(
        robot.table, session.T_measurement_base, session.tool_point, session.tool_rotation,
        session,
    )  # fmt: skip
    calibrated = truth_error(
        ex.standard, move @ ex.T_measurement_base, ex.tool_point + shift,
        result.tool_orientation @ turn, session,
    )  # fmt: skip
    return nominal, calibrated


def calibration_T() -> np.ndarray:
    """The calibration session's true T_measurement_base (the default tracker's)."""
    return default_measurement_pose() @ load_robot("kr5").T_base


@pytest.mark.parametrize("name", ["line", "curve", "random", "line_export"])
def test_a_path_session_is_scored_as_the_truth_says(run: Run, name: str) -> None:
    """A line (90 poses along 400 mm) and a planar curve (120 poses), the orientation constant,
    the tracker re-stationed and the probe re-mounted, and random poses for comparison: the
    base and the tool are placed for both models alike, and each figure is within 10 % of the
    model's error against the truth (main scored the line at 192.66 → 192.71 mm, the curve's
    footing at 2.1 mm); the line as a Leica export, imported, scores as its MCAP log."""
    _, _, _, checks = run
    check = checks[name]
    assert check.registered and check.tool_replaced and check.components == "3-D"
    assert check.nominal is not None and check.nominal.n_poses == check.calibrated.n_poses
    nominal, calibrated = truth_errors(run, name)
    assert abs(check.nominal.rms / nominal - 1.0) < WITHIN, (check.nominal.rms, nominal)
    assert abs(check.calibrated.rms / calibrated - 1.0) < WITHIN, (check.calibrated.rms, calibrated)
    assert check.calibrated.rms < check.nominal.rms / 3


def test_a_path_at_one_orientation_says_the_tool_point_is_not_determined(run: Run) -> None:
    """Along a path at one orientation the base's translation takes up the tool point: the
    note says so instead of printing a shift the poses cannot measure; random poses measure
    it (0.955 mm)."""
    _, _, _, checks = run
    for name in ("line", "curve"):
        assert any("its point not determined by these poses" in n for n in checks[name].notes)
    note = next(n for n in checks["random"].notes if "re-mounted" in n)
    assert "point moved 0.95" in note and "turned 1.6" in note


def test_a_session_of_another_robot_is_not_scored_and_implausible(run: Run) -> None:
    """A UR5's session given to a KR5's calibration: no footing places it (hundreds of mm at
    best); a SCARA's has four joints. Each is one warning line, no figure, an entry marked not
    scored in the JSON and a reason in ``implausible``; the other logs are scored."""
    from dhlog.result.document import result_document

    _, result, _, checks = run
    assert "ur5" not in checks and "scara" not in checks
    lines = [w for w in result.warnings if w.startswith("held-out log not scored")]
    assert len(lines) == 2
    assert "ur5.mcap" in lines[0] and "no footing" in lines[0]
    assert "scara.mcap: has 4 joints" in lines[1]
    assert len(result.implausible) == 2
    assert "ur5.mcap" in result.implausible[0] and "scara.mcap" in result.implausible[1]
    doc = json.loads(json.dumps(result_document(result)))
    ur5, scara = doc["validation"]["not_scored"]
    assert ur5["path"].endswith("ur5.mcap") and ur5["scored"] is False and ur5["unplaced"]
    assert scara["path"].endswith("scara.mcap") and scara["unplaced"]
    scored = [h["path"] for h in doc["validation"]["holdout"]]
    assert not any(p.endswith(("ur5.mcap", "scara.mcap")) for p in scored)


def test_the_simulated_paths_are_what_they_say(run: Run) -> None:
    """The line's true positions lie within µm of one 400 mm line, the curve's in one plane
    and not on a line, the orientation constant along both; the re-station and the re-mount
    are in each session's truth."""
    robot, _, sessions, _ = run
    for name in ("line", "curve"):
        s = sessions[name]
        true = fk_frames(s.table, s.poses, T_base=s.T_measurement_base)[:, -1]
        P = np.einsum("kij,j->ki", true[:, :3, :3], s.tool_point) + true[:, :3, 3]
        sv = np.linalg.svd(P - P.mean(axis=0), compute_uv=False)
        spread = np.ptp((P - P.mean(axis=0)) @ np.linalg.svd(P - P.mean(axis=0))[2][0])
        if name == "line":
            assert abs(spread - 0.4) < 1e-6 and sv[1] < 1e-4 * sv[0]
        else:  # an S, 400 mm along the line's direction: a little less along its widest
            assert 0.35 < spread < 0.4 and sv[1] > 0.1 * sv[0] and sv[2] < 1e-4 * sv[0]
        turns = np.einsum("ji,kjl->kil", true[0, :3, :3], true[:, :3, :3])
        assert np.max(np.abs(turns - np.eye(3))) < 1e-6
        assert np.linalg.norm(s.tool_point - robot.tool_point) == pytest.approx(0.955e-3, abs=1e-6)
        assert np.linalg.norm(s.T_measurement_base[:3, 3] - calibration_T()[:3, 3]) > 0.3


def test_simulate_writes_a_path_session(tmp_path: Path) -> None:
    """``dhlog simulate --protocol curve --restation --remount --six-dof --leica-export``
    writes the log, its truth and the Leica export; a path the robot cannot reach is one line,
    exit 2."""
    out = tmp_path / "line.mcap"
    r = CliRunner().invoke(
        app,
        ["simulate", "kr5", "-o", str(out), "--protocol", "curve", "--poses", "20",
         "--restation", "--remount", "--six-dof", "--tracker-rate", "10", "--leica-export"],
    )  # fmt: skip
    assert r.exit_code == 0, r.output
    truth = json.loads(out.with_name("line.truth.json").read_text())
    sim = truth["simulation"]
    assert sim["protocol"] == "curve" and sim["restation"] and sim["remount"]
    rows = out.with_name("line.leica.csv").read_text().splitlines()
    assert rows[0].startswith("Point Name,X [mm],Y [mm],Z [mm],U(95)  [mm],Q0,Q1,Q2,Q3,j1")
    assert len(rows) == 21  # a row a stop
    far = CliRunner().invoke(
        app,
        ["simulate", "kr5", "-o", str(tmp_path / "far.mcap"), "--protocol", "line",
         "--path-length-mm", "4000", "--poses", "10"],
    )  # fmt: skip
    assert far.exit_code == 2 and "leaves the reach" in far.output
    assert "Traceback" not in far.output
