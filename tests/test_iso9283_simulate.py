"""The ISO 9283 test simulated (protocol ``iso9283``, :mod:`dhlog.simulator.iso9283`): the log's
three streams, and each of the robot's known faults — repeatability, drift, overshoot, path error —
found in the truth (and the log) at the asked size. Most tests run a small stand-in program (five
poses near a KR5 pose, one line) so they take a fraction of a second; one runs the planned
program through the command line."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from scipy.spatial.transform import Rotation
from scipy.stats import chi2
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.io.writer import write_session
from dhlog.iso9283 import program as iso
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot, load_robot
from dhlog.simulator.config import SimulationConfig, config_problems
from dhlog.simulator.iso9283 import (
    motion_at,
    overshoot_shape,
    plan_run,
    simulate_iso9283,
    stabilisation_truth,
)
from dhlog.simulator.session import Session, simulate_session

KR5 = load_robot("kr5")
#: the stand-in's centre pose: the tool point about 0.6 m out and 0.5 m up, tool turned down
CENTRE = np.array([0.0, -1.9, 1.9, 0.0, 1.2, 0.0])
STEPS = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.15, 0.1, -0.1],
        [-0.15, 0.1, -0.1],
        [-0.15, -0.1, 0.1],
        [0.15, -0.1, 0.1],
    ]
)
QUIET: dict[str, Any] = {
    "repeatability": 0.0,
    "orientation_repeatability": 0.0,
    "drift": 0.0,
    "overshoot": 0.0,
    "path_error": 0.0,
    "path_repeatability": 0.0,
}


def _tool(robot: Robot, q: np.ndarray) -> np.ndarray:
    F = fk_frames(robot.table, np.atleast_2d(q), T_base=robot.T_base)[:, -1]
    return np.asarray(F[:, :3, :3] @ robot.tool_point + F[:, :3, 3])


def standin_program(robot: Robot = KR5) -> iso.TestProgram:
    """Five poses near ``CENTRE`` (joints 1–3 moved), their commanded poses the nominal's FK,
    and a line from P2 to P4 in joint space, its points the nominal's FK."""
    poses = []
    for k, step in enumerate(STEPS):
        q = CENTRE.copy()
        q[:3] += step
        T = fk_frames(robot.table, q, T_base=robot.T_base)[-1].copy()
        T[:3, 3] = _tool(robot, q)[0]
        poses.append(iso.TestPose(f"P{k + 1}", T, q))
    Q = poses[1].q + (poses[3].q - poses[1].q) * np.linspace(0.0, 1.0, 60)[:, None]
    centre = poses[0].T[:3, 3]
    cube = iso.TestCube(centre, 0.2, "C1-C2-C7-C8", centre + np.zeros((8, 3)))
    line = iso.TestPath("line", _tool(robot, Q), Q, 0.25)
    return iso.TestProgram(robot.name, cube, poses, [line], robot.tool_point.copy())


def run(cycles: int = 30, path_cycles: int = 0, **settings: Any) -> Session:
    cfg = SimulationConfig(
        protocol="iso9283", iso_cycles=cycles, iso_path_cycles=path_cycles, **settings
    )
    assert config_problems(KR5, cfg) == []
    session: Session = simulate_iso9283(KR5, cfg, program=standin_program())
    return session


def visits(session: Session) -> dict[str, list[dict[str, Any]]]:
    """The truth's visits by pose, in cycle order."""
    assert session.iso9283 is not None
    out: dict[str, list[dict[str, Any]]] = {}
    for v in session.iso9283["visits"]:
        out.setdefault(v["pose"], []).append(v)
    return out


def test_the_log_has_the_tracker_the_encoders_and_the_commanded_joints(tmp_path: Path) -> None:
    session = run(cycles=3, path_cycles=2, seed=4)
    program = standin_program()
    path = tmp_path / "iso.mcap"
    write_session(session, path, "ros2")
    with open(path, "rb") as f:
        reader = make_reader(f)
        counts: dict[str, int] = {}
        first: dict[str, Any] = {}
        for _, channel, message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            first.setdefault(channel.topic, message)
    duration = (session.point_t_ns[-1] - session.point_t_ns[0]) * 1e-9
    assert counts["/tracker/point"] == session.point_xyz.shape[0]
    assert counts["/tracker/point"] >= 0.99 * 100.0 * duration  # the tracker at 100 Hz
    assert counts["/joint_states"] == session.joint_q.shape[0] > 2 * counts["/tracker/point"]
    # a command per pose visit (3 cycles × 5), per move to a path's start and per path point
    assert counts["/joint_command"] == 3 * 5 + 2 * (1 + 60)
    # the first command is P1's joints (the cycle P1, P5, P4, P3, P2), as a JointState
    from dhlog.io.ros2 import _parse_joint_layout

    body = first["/joint_command"].data[4:]  # after the CDR encapsulation header
    names, n_pos, offset = _parse_joint_layout(body)
    q = np.frombuffer(body, "<f8", n_pos, offset)
    assert list(names) == session.joint_names
    assert np.allclose(q, program.poses[0].q, atol=0)
    cycle = [v["pose"] for v in session.iso9283["visits"][:5]] if session.iso9283 else []
    assert cycle == ["P1", "P5", "P4", "P3", "P2"]
    # the commanded joints at each command are a program target, stamped at the move's start
    assert np.all(np.diff(session.command_t_ns) > 0)
    targets = np.vstack([[p.q for p in program.poses], program.paths[0].q])
    d = np.min(np.linalg.norm(session.command_q[:, None] - targets[None], axis=2), axis=1)
    assert np.max(d) == 0.0


def test_a_calibration_session_writes_no_commanded_stream(tmp_path: Path) -> None:
    session = simulate_session(KR5, SimulationConfig(seed=1))
    assert session.iso9283 is None and session.command_q.size == 0
    path = tmp_path / "cal.mcap"
    write_session(session, path, "ros2")
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert "/joint_command" not in {c.topic for c in summary.channels.values()}


def test_attained_positions_scatter_with_the_asked_repeatability() -> None:
    sigma, sigma_rot = 20e-6, 5e-5
    session = run(
        cycles=30,
        seed=2,
        **{**QUIET, "repeatability": sigma, "orientation_repeatability": sigma_rot},
    )
    by_pose = visits(session)
    assert sorted(by_pose) == ["P1", "P2", "P3", "P4", "P5"]
    for pose, vs in by_pose.items():
        x = np.array([v["attained"] for v in vs])
        assert x.shape == (30, 3)
        # Σ|x − x̄|² / σ² is χ² with 3 (30 − 1) degrees of freedom: within its 0.1–99.9 % band
        dof = 3 * (x.shape[0] - 1)
        s2 = np.sum((x - x.mean(axis=0)) ** 2) / sigma**2
        assert chi2.ppf(0.001, dof) < s2 < chi2.ppf(0.999, dof), (pose, s2, dof)
        # the commanded position is the program's (the nominal's FK), not where the robot went
        assert np.allclose(vs[0]["commanded"], standin_program().poses[int(pose[1]) - 1].T[:3, 3])
        # the attained orientation: rotations about the pose's mean of σ per axis
        R = np.array([v["attained_R"] for v in vs])
        w = Rotation.from_matrix(R @ R[0].T).as_rotvec()
        s2 = np.sum((w - w.mean(axis=0)) ** 2) / sigma_rot**2
        assert chi2.ppf(0.001, dof) < s2 < chi2.ppf(0.999, dof), (pose, s2, dof)


def test_the_accuracy_is_the_robot_off_its_nominal() -> None:
    session = run(cycles=2, seed=5, perturb_length=2e-4, perturb_angle=2e-4, **QUIET)
    for vs in visits(session).values():
        a = np.array(vs[0]["attained"])
        c = np.array(vs[0]["commanded"])
        # without repeatability or drift the attained pose is the true robot's, mm-ish off
        assert np.allclose(vs[0]["attained"], vs[1]["attained"], atol=1e-12)
        assert 2e-5 < np.linalg.norm(a - c) < 5e-3
        assert np.allclose(a, vs[0]["true_fk"], atol=1e-12)


def test_the_drift_moves_the_barycentre_by_the_asked_amount() -> None:
    drift = 150e-6
    session = run(cycles=12, seed=6, noise=1e-6, **{**QUIET, "drift": drift})
    assert session.iso9283 is not None
    u = np.array(session.iso9283["settings"]["drift_direction"])
    by_cycle = np.array([v["attained"] for v in session.iso9283["visits"]]).reshape(12, 5, 3)
    moved = by_cycle[-1].mean(axis=0) - by_cycle[0].mean(axis=0)
    assert np.linalg.norm(moved) == pytest.approx(drift, rel=1e-6)
    assert np.allclose(moved / drift, u, atol=1e-6)
    # slow and smooth: monotone warm-up, most of it early (τ a third of the test)
    along = (by_cycle.mean(axis=1) - by_cycle[0].mean(axis=0)) @ u
    assert np.all(np.diff(along) > 0) and along[4] > 0.5 * drift
    # the log: the tracker's samples in the settled dwell move with it (σ 1 µm, 150 samples)
    T = session.T_measurement_base
    base = (session.point_xyz - T[:3, 3]) @ T[:3, :3]
    t = session.point_t_ns
    vs = visits(session)["P3"]
    ends = []
    for v in (vs[0], vs[-1]):
        settled = (t > v["t_arrival_ns"] + 0.5e9) & (t < v["t_leave_ns"])
        ends.append(base[settled].mean(axis=0))
    expected = np.array(vs[-1]["attained"]) - np.array(vs[0]["attained"])
    assert np.linalg.norm(ends[1] - ends[0] - expected) < 1e-6


def test_each_arrival_overshoots_by_the_asked_amount_and_settles() -> None:
    overshoot = 200e-6
    session = run(cycles=2, seed=7, noise=1e-6, **{**QUIET, "overshoot": overshoot})
    T = session.T_measurement_base
    base = (session.point_xyz - T[:3, 3]) @ T[:3, :3]
    t = session.point_t_ns
    for vs in visits(session).values():
        for v in vs:
            after = (t >= v["t_arrival_ns"]) & (t < v["t_leave_ns"])
            d = np.linalg.norm(base[after] - np.array(v["attained"]), axis=1)
            # the largest distance from the final position after arrival: the overshoot (the
            # 100 Hz samples miss the peak by ≤ 1.3 %, the noise adds ≈ 1 %)
            assert np.max(d) == pytest.approx(overshoot, rel=0.05)
            late = t[after] > v["t_arrival_ns"] + 1e9
            assert np.max(d[late]) < 0.02 * overshoot  # e^(−ζω·1 s) ≈ 0.2 % + the noise
            # along the approach: the first swing goes beyond the target
            k = int(np.argmax(d))
            swing = base[after][k] - np.array(v["attained"])
            assert swing @ np.array(v["approach"]) > 0.95 * np.linalg.norm(swing)
    # the shape itself: peak 1 at atan(1/ζ)/ω
    w, zeta = 2 * math.pi * 5.0, 0.2
    t_peak = math.atan(1 / zeta) / w
    grid = np.linspace(0, 2, 200_001)
    assert np.max(overshoot_shape(grid, 5.0, zeta)) == pytest.approx(1.0, abs=1e-6)
    assert grid[np.argmax(overshoot_shape(grid, 5.0, zeta))] == pytest.approx(t_peak, abs=1e-5)


def test_the_path_deviates_by_the_asked_path_error() -> None:
    error, random = 300e-6, 30e-6
    session = run(
        cycles=1,
        path_cycles=10,
        seed=8,
        **{**QUIET, "path_error": error},
    )
    assert session.iso9283 is not None

    def tangents(p: dict[str, Any]) -> np.ndarray:
        c = np.gradient(np.array(p["commanded"]), axis=0)
        return np.asarray(c / np.linalg.norm(c, axis=1, keepdims=True))

    for p in session.iso9283["paths"]:
        dev = np.array(p["attained"]) - np.array(p["true_fk"])
        # the systematic deviation: normal to the path, its peak the path error
        assert np.max(np.linalg.norm(dev, axis=1)) == pytest.approx(error, rel=0.01)
        assert np.max(np.abs(np.sum(dev * tangents(p), axis=1))) < 0.01 * error
        assert len(p["t_ns"]) == len(p["attained"]) >= 0.9 * 100 * p["duration_s"]
    # the random part, one offset per cycle: σ per coordinate in the plane normal to the path
    session = run(cycles=1, path_cycles=30, seed=9, **{**QUIET, "path_repeatability": random})
    assert session.iso9283 is not None
    offsets = []
    for p in session.iso9283["paths"]:
        dev = np.array(p["attained"]) - np.array(p["true_fk"])
        size = np.max(np.linalg.norm(dev, axis=1))  # normal to the path, within its bend
        assert np.max(np.abs(np.sum(dev * tangents(p), axis=1))) < 0.02 * size
        offsets.append(dev[len(dev) // 2])  # at the middle of the path: its normal plane there
    o = np.array(offsets)
    dof = 2 * (o.shape[0] - 1)
    s2 = np.sum((o - o.mean(axis=0)) ** 2) / random**2
    assert chi2.ppf(0.001, dof) < s2 < chi2.ppf(0.999, dof)


def test_the_protocols_settings_are_checked() -> None:
    base = SimulationConfig(protocol="iso9283")
    cases = {
        "tracker rate": replace(base, tracker_rate=50.0),
        "damping": replace(base, overshoot_damping=1.0),
        "pose cycles": replace(base, iso_cycles=0),
        "10] mm": replace(base, repeatability=-1e-6),
        "finite": replace(base, drift=math.nan),
        "not simulated": replace(base, instrument="camera"),
    }
    for words, cfg in cases.items():
        problems = config_problems(KR5, cfg)
        assert problems and words in problems[0], (words, problems)


def test_simulate_iso9283_through_the_command_line(tmp_path: Path) -> None:
    """The planned program (dhlog.iso9283.program.test_program) end to end."""
    out = tmp_path / "iso.mcap"
    result = CliRunner().invoke(
        app,
        [
            *("simulate", "kr5", "--protocol", "iso9283", "-o", str(out), "--cycles", "2"),
            *("--path-cycles", "1", "--repeatability-mm", "0.03", "--perturb-mm", "0.1"),
        ],
    )
    assert result.exit_code == 0, result.output
    truth = json.loads(out.with_name("iso.truth.json").read_text())
    block = truth["iso9283"]
    assert truth["simulation"]["protocol"] == "iso9283"
    assert block["settings"]["cycles"] == 2 and block["settings"]["repeatability_m"] == 3e-5
    assert len(block["visits"]) == 10
    assert [p["path"] for p in block["paths"]] == ["line", "circle_large", "circle_small"]
    assert [p["name"] for p in block["program"]["poses"]] == ["P1", "P2", "P3", "P4", "P5"]
    with open(out, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    topics = {c.topic for c in summary.channels.values()}
    assert {"/tracker/point", "/joint_states", "/joint_command"} <= topics


@pytest.mark.parametrize("encoding", ["json", "protobuf"])
def test_the_commanded_joints_in_json_and_protobuf(tmp_path: Path, encoding: str) -> None:
    session = run(cycles=1, path_cycles=1, seed=3)
    path = tmp_path / f"iso_{encoding}.mcap"
    write_session(session, path, encoding)  # type: ignore[arg-type]
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    counts = {
        c.topic: summary.statistics.channel_message_counts[i] for i, c in summary.channels.items()
    }
    assert counts["/joint_command"] == 5 + 1 + 60
    assert counts["/joint_states"] == session.joint_q.shape[0]


def test_a_six_dof_target_turns_with_the_attained_orientation() -> None:
    session = run(cycles=2, seed=10, tool_rotation=(0.3, -0.2, 0.5))
    assert session.point_rotation is not None and session.tool_rotation is not None
    T = session.T_measurement_base
    for vs in visits(session).values():
        for v in vs:
            mid = (v["t_arrival_ns"] + v["t_leave_ns"]) // 2
            k = int(np.searchsorted(session.point_t_ns, mid))
            expected = T[:3, :3] @ np.array(v["attained_R"]) @ session.tool_rotation
            assert np.allclose(session.point_rotation[k], expected, atol=1e-12)


def test_the_protocols_options_are_refused_with_another_protocol(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        app, ["simulate", "kr5", "-o", str(tmp_path / "x.mcap"), "--cycles", "3"]
    )
    assert result.exit_code == 1
    assert "are for --protocol iso9283" in result.output
    assert not (tmp_path / "x.mcap").exists()


def test_simulate_iso9283_through_the_api(tmp_path: Path) -> None:
    import dhlog

    sim = dhlog.simulate(
        "kr5",
        tmp_path / "api.mcap",
        protocol="iso9283",
        iso_cycles=2,
        iso_path_cycles=1,
        drift=1e-4,
        perturb_length=1e-4,
    )
    assert "commanded joint targets" in sim.described
    block = json.loads(sim.truth.read_text())["iso9283"]
    assert block["settings"]["drift_m"] == 1e-4 and len(block["visits"]) == 10
    truth = sim.truth_model()  # the truth still reads as a result document
    q = np.array(block["visits"][0]["q"])
    expected = np.array(block["visits"][0]["true_fk"])
    T = np.array(block["T_measurement_base"])  # the block's frame → M
    assert np.allclose(truth.fk(q[None])[0], T[:3, :3] @ expected + T[:3, 3], atol=1e-9)


def test_the_robot_never_jumps() -> None:
    """Every offset (a visit's repeatability, a path cycle's random offset, the path error, the
    overshoot) comes in and goes out smoothly: the noise-free position is continuous across
    every segment's boundary (1 µm over 2 µs; the robot moves < 1 m/s)."""
    cfg = SimulationConfig(
        protocol="iso9283",
        iso_cycles=2,
        iso_path_cycles=2,
        repeatability=1e-4,
        path_repeatability=1e-4,
        path_error=3e-4,
        overshoot=3e-4,
        drift=1e-4,
    )
    program = standin_program()
    run_ = plan_run(KR5, cfg, program, np.zeros(KR5.n))
    from dhlog.simulator.iso9283 import approach_directions

    approach_directions(KR5, run_, KR5.table, program.tool_point)
    edges = np.array([s.t0 for s in run_.segments[1:]])
    before = motion_at(KR5, cfg, run_, KR5.table, edges - 1e-6).position
    after = motion_at(KR5, cfg, run_, KR5.table, edges + 1e-6).position
    assert np.max(np.linalg.norm(after - before, axis=1)) < 1e-6


def test_the_logs_stabilisation_by_the_formulas_is_the_truths() -> None:
    """formulas.stabilisation on the tracker's samples of each arrival (1 µm noise, 100 Hz)
    against the truth: the stabilisation time of the noise-free oscillation within two sample
    periods (the formula's resolution is one; the noise moves the last sample outside the band
    by about one more, where the swing's peak grazes it) and the overshoot within 5 %."""
    from dhlog.iso9283.formulas import stabilisation

    overshoot, band = 200e-6, 20e-6
    session = run(cycles=2, seed=11, noise=1e-6, **{**QUIET, "overshoot": overshoot})
    expected = stabilisation_truth(overshoot, 5.0, 0.2, band)
    assert 0.2 < expected < 0.5  # e^(−ζωt) / peak = 0.1: ≈ 0.33 s, on a swing's peak before
    T = session.T_measurement_base
    base = (session.point_xyz - T[:3, 3]) @ T[:3, :3]
    t = session.point_t_ns
    for vs in visits(session).values():
        for v in vs:
            window = (t > v["t_arrival_ns"] - 0.3e9) & (t < v["t_leave_ns"])
            found = stabilisation(
                (t[window] - v["t_arrival_ns"]) * 1e-9,
                base[window],
                v["attained"],
                0.0,
                band=band,
            )
            assert abs(found.time - expected) <= 0.0201
            assert found.overshoot == pytest.approx(overshoot, rel=0.05)
