"""``dhlog plan`` (issue 19, part 1): what a protocol will give, before the session."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cell.plan import plan_session, select_poses
from dhlog.cli.app import app
from dhlog.errors import InputError
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig

runner = CliRunner()


def test_a_plan_predicts_sigma_that_shrinks_with_more_poses() -> None:
    """40 random poses (σ 10 µm): every free parameter has a σ, the FK σ over the workspace is
    a few µm; 160 poses give about half of it (σ ∝ 1/√N: 0.5, allowed 0.4–0.65)."""
    robot = load_robot("kr5")
    few = plan_session(robot, SimulationConfig(protocol="random-poses", poses=40, noise=1e-5))
    many = plan_session(robot, SimulationConfig(protocol="random-poses", poses=160, noise=1e-5))
    free = np.isfinite(few.rows_std)
    assert free.sum() >= 15 and np.all(few.rows_std[free] > 0)
    rms_few = math.sqrt(float(np.mean(few.fk_sd**2)))
    rms_many = math.sqrt(float(np.mean(many.fk_sd**2)))
    assert 1e-7 < rms_few < 1e-5
    assert 0.4 < rms_many / rms_few < 0.65, rms_many / rms_few
    assert few.poses == 40 and any("nominal" in line for line in few.fixed)


def test_a_plan_that_never_moves_a_joint_says_so() -> None:
    cfg = SimulationConfig(motion="step", skip_joints=(4,), noise=1e-5)
    with pytest.raises(InputError, match="joint 4"):
        plan_session(load_robot("kr5"), cfg)


def test_the_plan_command() -> None:
    done = runner.invoke(app, ["plan", "kr5", "--poses", "30"])
    assert done.exit_code == 0, done.output
    assert "Predicted σ of kr5's parameters" in done.output and "Predicted FK σ" in done.output
    bad = runner.invoke(app, ["plan", "kr5", "--protocol", "dance"])
    assert bad.exit_code == 1 and "protocol" in bad.output


def test_select_chooses_more_informative_poses(tmp_path: Path) -> None:
    """--select 40 of 500 random candidates (degrees): the chosen poses' predicted FK σ over the
    workspace is below that of 40 drawn at random; the CSV keeps the candidates' header and
    row numbers; near-singular candidates are counted."""
    rob = load_robot("kr5")
    C = np.degrees(np.random.default_rng(3).uniform(rob.limits[:, 0], rob.limits[:, 1], (500, 6)))
    C[0, 4] = 0.0  # the wrist stretched: axes 4 and 6 in line
    C[0, 2] = math.degrees(math.atan2(0.62, 0.12))  # and the elbow too
    path = tmp_path / "candidates.csv"
    path.write_text("a1,a2,a3,a4,a5,a6\n" + "\n".join(",".join(map(str, q)) for q in C) + "\n")
    out = tmp_path / "chosen.csv"
    args = ["plan", "kr5", "--candidates", str(path), "--select", "40", "--angle-unit", "deg"]
    done = runner.invoke(app, [*args, "-o", str(out)])
    assert done.exit_code == 0, done.output
    lines = out.read_text().splitlines()
    assert lines[0] == "row,a1,a2,a3,a4,a5,a6" and len(lines) == 41
    rows = [int(line.split(",")[0]) for line in lines[1:]]
    assert 1 not in rows and len(set(rows)) == 40  # the singular candidate is never chosen
    found = select_poses(rob, np.radians(C), 40, 1e-5)
    assert found.singular >= 1 and found.fk_sd_chosen < 0.95 * found.fk_sd_random
    # the chosen poses replayed by the simulator, in their order, in the candidates' unit
    log = tmp_path / "chosen.mcap"
    sim = ["simulate", "kr5", "-o", str(log), "--protocol", "random-poses", "--poses", str(out)]
    done = runner.invoke(app, [*sim, "--angle-unit", "deg"])
    assert done.exit_code == 0, done.output
    truth = json.loads(log.with_name("chosen.truth.json").read_text())
    assert truth["simulation"]["poses"] == 40
    from dhlog.simulator.protocols import random_poses

    listed = tuple(tuple(np.radians(C[r - 1])) for r in rows)
    replayed = random_poses(rob, SimulationConfig(pose_list=listed), np.zeros(6))
    assert np.array_equal(replayed, np.radians(C[np.array(rows) - 1]))
    bad = runner.invoke(app, [*sim, "--force"])  # degrees read as radians: out of the limits
    assert bad.exit_code == 1 and "leaves the limits" in bad.output


def test_simulate_replays_a_pose_list() -> None:
    """A pose list is visited in order: the session's still poses are the list's, and each is
    where the robot stands while the tracker measures (the encoders read it)."""
    from dhlog.simulator.session import simulate_session

    rob = load_robot("kr5")
    Q = np.random.default_rng(4).uniform(rob.limits[:, 0], rob.limits[:, 1], (6, 6))
    cfg = SimulationConfig(protocol="random-poses", pose_list=tuple(map(tuple, Q)), noise=0.0)
    session = simulate_session(rob, cfg)
    assert np.array_equal(session.poses, Q)
    encoders = session.joint_q
    for q in Q:  # every pose is held: some joint state reads it to the encoder's resolution
        assert np.min(np.max(np.abs(encoders - q), axis=1)) < 1e-6


def test_a_plan_with_the_tracker_model_and_its_range(tmp_path: Path) -> None:
    """A tracker 2.5 m away with its noise model (radial 10 µm, transverse 15 µm + 6 µm/m):
    poses beyond its range are left out and counted; the transverse σ (≈ 30 µm at that
    distance) dominates, so the FK σ is well above that of an isotropic 10 µm; the JSON says
    what the console says."""
    from dhlog.cell.plan import Tracker

    robot = load_robot("kr5")
    cfg = SimulationConfig(protocol="random-poses", poses=30, noise=1e-5)
    near = Tracker((2.5, 0.0, 0.5), (0.5, 3.2))
    cut = plan_session(robot, cfg, near)
    whole = plan_session(robot, cfg)
    assert cut.out_of_range > 0 and cut.poses == 30 - cut.out_of_range
    modelled = plan_session(robot, cfg, Tracker((2.5, 0.0, 0.5), model=(1e-5, 1.5e-5, 6e-6)))
    rms = [math.sqrt(float(np.mean(p.fk_sd**2))) for p in (whole, modelled)]
    assert 1.5 < rms[1] / rms[0] < 6, rms
    out = tmp_path / "plan.json"
    args = ["plan", "kr5", "--poses", "30", "--station", "2500,0,500", "--range-m", "0.5,3.2"]
    done = runner.invoke(app, [*args, "-o", str(out)])
    assert done.exit_code == 0, done.output
    doc = json.loads(out.read_text())
    assert doc["poses_out_of_range"] == cut.out_of_range and doc["poses"] == cut.poses
    assert doc["rows"][0]["std"]["theta_rad"] is None  # θ1 fixed: the base's gauge
    assert doc["fk_std_m"]["rms"] == pytest.approx(math.sqrt(float(np.mean(cut.fk_sd**2))))
    for bad in (["--station", "1,2"], ["--tracker-um", "1,2,3"], ["--station", "nan,0,0"]):
        refused = runner.invoke(app, ["plan", "kr5", *bad])
        assert refused.exit_code == 1 and "Traceback" not in refused.output


def test_the_simulated_tracker_scatters_along_its_line_of_sight() -> None:
    """simulate's tracker model: the residuals' spread along the line of sight is the radial
    σ, across it the transverse σ at that distance (30 000 samples: ±1 % each)."""
    from dhlog.model.fk import fk_point
    from dhlog.simulator.session import simulate_session

    robot = load_robot("kr5")
    cfg = SimulationConfig(
        protocol="random-poses", poses=100, tracker_rate=1000.0, tracker_model=(1e-5, 2e-5, 0.0)
    )
    s = simulate_session(robot, cfg)
    joint = np.array(
        [np.interp(s.point_t_ns, s.joint_t_ns, s.joint_q[:, j]) for j in range(robot.n)]
    ).T
    e = s.point_xyz - fk_point(s.table, joint, s.tool_point, T_base=s.T_measurement_base)
    u = s.point_xyz / np.linalg.norm(s.point_xyz, axis=1, keepdims=True)
    along = np.sum(e * u, axis=1)
    across = e - along[:, None] * u
    assert e.shape[0] > 20_000
    assert abs(np.std(along) / 1e-5 - 1) < 0.03
    assert abs(np.sqrt(np.mean(np.sum(across**2, axis=1)) / 2) / 2e-5 - 1) < 0.03
