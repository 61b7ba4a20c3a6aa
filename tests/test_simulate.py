"""The simulator's protocols (sweeps, random static poses, coupled moves), its unmodelled model
error, and the default session kept byte for byte."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.model.fk import fk_frames, fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig, config_problems
from dhlog.simulator.protocols import MIN_POSE_CHANGE, swept_joints
from dhlog.simulator.session import Session, simulate_session
from dhlog.simulator.truth import truth_document

#: SHA-256 of point_xyz and joint_q of ``simulate_session(kr5, SimulationConfig())``, computed
#: before the protocols and the model error were added: the default path draws nothing new
DEFAULT_POINT_XYZ = "927ea1c41cc9b71ec7725a836136c17ba9ec71332136850a8512f0059b18d04f"
DEFAULT_JOINT_Q = "73842742f1b4223924d9fb8e43342afb850e1d3e54c89d6aa5c9f530125b4c34"

runner = CliRunner()


def still_poses(session: Session, least: int = 10) -> np.ndarray:
    """Joint vectors the encoders report at least ``least`` times in a row: the stops."""
    values, counts = np.unique(session.joint_q, axis=0, return_counts=True)
    return values[counts >= least]


def nearest(points: np.ndarray, candidates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the nearest candidate to each point and its distance."""
    d = np.linalg.norm(points[:, None, :] - candidates[None, :, :], axis=2)
    index = np.argmin(d, axis=1)
    return index, d[np.arange(points.shape[0]), index]


def test_the_default_session_is_unchanged() -> None:
    session = simulate_session(load_robot("kr5"), SimulationConfig())
    assert hashlib.sha256(session.point_xyz.tobytes()).hexdigest() == DEFAULT_POINT_XYZ
    assert hashlib.sha256(session.joint_q.tobytes()).hexdigest() == DEFAULT_JOINT_Q
    assert not session.model_error_xyz.any() and session.poses.size == 0


def test_random_poses_are_still_distinct_within_the_limits_and_only_measured_still() -> None:
    """15 random poses of a KR5 with a 6-DoF target and a further SMR, no noise: every joint
    changes from one pose to the next, every pose lies within the limits, the encoders stop at
    exactly these poses, and every tracker sample (and orientation, and further target) is the
    FK of one of them, a dwell's worth of samples each."""
    rob = load_robot("kr5")
    far = (0.12, 0.03, 0.08)
    cfg = SimulationConfig(
        seed=5,
        noise=0.0,
        protocol="random-poses",
        poses=15,
        tool_rotation=(0.3, -0.2, 0.5),
        extra_tools=(far,),
    )
    assert not config_problems(rob, cfg) and swept_joints(rob, cfg) == []
    session = simulate_session(rob, cfg)
    poses = session.poses
    assert poses.shape == (15, 6)
    lo, hi = rob.limits[:, 0], rob.limits[:, 1]
    assert np.all((poses >= lo) & (poses <= hi))
    steps = np.abs(np.diff(np.vstack([session.reference_pose, poses]), axis=0))
    assert np.all(steps >= MIN_POSE_CHANGE * (hi - lo))  # every joint changes, home → 1st too
    assert np.unique(poses, axis=0).shape[0] == 15
    assert np.array_equal(session.reference_pose, np.zeros(6)) and not session.sweeps.any()
    stops = still_poses(session)
    assert stops.shape[0] == 15 and np.all(nearest(stops, poses)[1] == 0.0)
    # every tracker sample: the FK of a pose (taken while still), 30 ± 1 per pose (0.3 s × 100 Hz)
    T_mb = session.T_measurement_base
    at_poses = fk_point(session.table, poses, session.tool_point, T_base=T_mb)
    which, gap = nearest(session.point_xyz, at_poses)
    assert np.all(gap < 1e-12)
    assert np.all(np.abs(np.bincount(which, minlength=15) - 30) <= 1)
    rotations = fk_frames(session.table, poses, T_base=T_mb)[:, -1, :3, :3]
    assert session.point_rotation is not None and session.tool_rotation is not None
    assert np.allclose(session.point_rotation, rotations[which] @ session.tool_rotation)
    far_at = fk_point(session.table, poses, np.array(far), T_base=T_mb)[which]
    assert np.allclose(session.extra_point_xyz[0], far_at, atol=1e-12)


@pytest.mark.parametrize("lock_poses", ["home", "random"])
def test_coupled_joints_move_only_together_and_every_joint_stops_eight_times(
    lock_poses: str,
) -> None:
    """The coupled protocol with 8 stops per joint (continuous motion asked, stops given): joint
    2 only ever moves together with joint 3, q3 = −q2 (in stops, within the limits), never
    alone; every other joint (3 too) is swept alone in 8 stops; the tracker measures only at
    stops."""
    rob = load_robot("kr5")
    cfg = SimulationConfig(
        seed=7,
        noise=0.0,
        protocol="coupled",
        steps=8,
        lock_poses=lock_poses,  # type: ignore[arg-type]
    )
    assert not config_problems(rob, cfg) and swept_joints(rob, cfg) == [1, 3, 4, 5, 6]
    session = simulate_session(rob, cfg)
    q = session.joint_q
    moving_2 = q[:, 1] != 0.0
    assert np.max(np.abs(q[moving_2, 1] + q[moving_2, 2])) < 1e-12  # home is 0: q3 = −q2
    assert np.isclose(np.ptp(q[:, 1]), math.radians(90)) and np.all(q >= rob.limits[:, 0])
    assert np.all(q <= rob.limits[:, 1])
    assert session.sweeps[1] == 0.0
    assert np.all(session.sweeps[[0, 2, 3, 4, 5]] > 0)
    stops = still_poses(session)
    coupled = stops[stops[:, 1] != 0.0]
    assert np.unique(coupled[:, 1]).size == 8 and np.allclose(coupled[:, [0, 3, 4, 5]], 0.0)
    if lock_poses == "home":  # each other joint: 8 stops with the rest at home
        for k in (0, 2, 3, 4, 5):
            others = np.delete(stops, k, axis=1)
            alone = stops[np.all(others == 0.0, axis=1) & (stops[:, k] != 0.0), k]
            assert np.unique(alone).size == 8
    at_stops = fk_point(session.table, stops, session.tool_point, T_base=session.T_measurement_base)
    assert np.all(nearest(session.point_xyz, at_stops)[1] < 1e-12)


def test_the_model_error_has_the_asked_rms_and_is_smooth() -> None:
    """σ = 0.1 mm over 100 random poses: the session's error (the only difference to the same
    session without it) has an RMS within 20 % of σ, moves every target alike, and is zero
    when not asked; along continuous sweeps it changes smoothly."""
    rob = load_robot("kr5")
    base = {"seed": 9, "noise": 0.0, "protocol": "random-poses", "poses": 100}
    base["extra_tools"] = ((0.1, 0.0, 0.05),)
    plain = simulate_session(rob, SimulationConfig(**base))  # type: ignore[arg-type]
    session = simulate_session(rob, SimulationConfig(**base, model_error=1e-4))  # type: ignore[arg-type]
    assert not plain.model_error_xyz.any()
    assert np.array_equal(session.point_t_ns, plain.point_t_ns)
    assert np.array_equal(session.joint_q, plain.joint_q)
    error = session.point_xyz - plain.point_xyz
    assert np.allclose(error, session.model_error_xyz, rtol=0, atol=1e-15)
    rms = float(np.sqrt(np.mean(error**2)))
    assert 0.8e-4 < rms < 1.2e-4
    extra = session.extra_point_xyz[0] - plain.extra_point_xyz[0]
    assert np.allclose(extra, error, rtol=0, atol=1e-15)  # the robot's error: every target alike
    sweeps = simulate_session(rob, SimulationConfig(seed=9, noise=0.0, model_error=1e-4))
    step = np.linalg.norm(np.diff(sweeps.model_error_xyz, axis=0), axis=1)
    assert sweeps.model_error_xyz.any() and np.max(step) < 0.05 * 1e-4


def test_the_truth_records_protocol_poses_and_model_error() -> None:
    rob = load_robot("scara")
    cfg = SimulationConfig(seed=2, protocol="random-poses", poses=5, model_error=5e-5)
    doc = truth_document(
        simulate_session(rob, cfg), source_path="x.mcap", sha256="0", pipeline="p", version="0"
    )
    sim = doc["simulation"]
    assert isinstance(sim, dict)
    assert (sim["protocol"], sim["poses"], sim["model_error_m"]) == ("random-poses", 5, 5e-5)
    assert sim["motion"] == "step"


@pytest.mark.parametrize(
    ("robot", "changes", "problem"),
    [
        ("stanford", {"protocol": "coupled"}, "both must be revolute"),
        ("kr5", {"protocol": "random-poses", "poses": 0}, "number of poses"),
        ("kr5", {"protocol": "random-poses", "skip_joints": (2,)}, "sweeps no joint"),
        ("kr5", {"protocol": "coupled", "tracker_rate": 2.0}, "without a sample"),
        ("kr5", {"model_error": -1e-4}, "model error"),
        ("kr5", {"orientation_noise": 1e-3}, "needs a 6-DoF target"),
        ("kr5", {"coupled": ((2, 9, -1.0),)}, "coupled moves name joint(s) [9]"),
    ],
)
def test_config_problems_of_the_protocols(
    robot: str, changes: dict[str, object], problem: str
) -> None:
    problems = config_problems(load_robot(robot), SimulationConfig(**changes))  # type: ignore[arg-type]
    assert len(problems) == 1 and problem in problems[0]


def test_simulate_random_poses_through_the_cli_and_read_them_back(tmp_path: Path) -> None:
    """``dhlog simulate --protocol random-poses`` writes a log the reader takes: 6 clusters of
    target samples (one per still pose), the encoders, and the truth's protocol."""
    from dhlog.io.reader import read_log

    out = tmp_path / "poses.mcap"
    args = ["simulate", "kr5", "-o", str(out), "--protocol", "random-poses", "--poses", "6"]
    args += ["--seed", "4", "--joint-rate", "50", "--model-error-mm", "0.05"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    log = read_log(out)
    xyz = log.points.select("x", "y", "z").to_numpy()
    assert 6 * 29 <= xyz.shape[0] <= 6 * 31  # 0.3 s at 100 Hz per pose
    assert log.joints is not None and log.joints.height > 100
    gaps = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    assert np.count_nonzero(gaps > 1e-3) == 5  # six stops; 10 µm noise within each
    truth = json.loads((tmp_path / "poses.truth.json").read_text())
    sim = truth["simulation"]
    assert (sim["protocol"], sim["poses"], sim["model_error_m"]) == ("random-poses", 6, 5e-5)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--protocol", "spiral"], "--protocol must be one of"),
        (["--orientation-noise-deg", "0.1"], "needs a 6-DoF target"),
        (["--extra-targets", "1,2;3,4,5"], "x,y,z triples"),
        (["--model-error-mm", "-1"], "model error must be in"),
        (["--protocol", "random-poses", "--poses", "0"], "number of poses"),
    ],
)
def test_simulate_checks_the_new_options_with_one_line_and_exit_1(
    args: list[str], message: str, tmp_path: Path
) -> None:
    result = runner.invoke(app, ["simulate", "kr5", "-o", str(tmp_path / "x.mcap"), *args])
    assert result.exit_code == 1, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0]
    assert not list(tmp_path.iterdir())
