"""``dhlog export --format urdf`` of a library robot's result, checked by yourdfpy: the robot's
name, the joint names its ROS 2 driver publishes, its position, velocity and effort limits (the
velocity and effort of the UR entries checked against ur_description's joint_limits.yaml, copied
in tests/data/ur_description.toml), and yourdfpy's FK equal to ``Calibration.fk`` to 1e-9 m."""

from __future__ import annotations

import math
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yourdfpy  # type: ignore[import-untyped]
from typer.testing import CliRunner

import dhlog
from dhlog.cli.app import app
from dhlog.model.robots import library_robots, load_robot

DATA = Path(__file__).parent / "data"
UR = tomllib.loads((DATA / "ur_description.toml").read_text(encoding="utf-8"))
runner = CliRunner()


def worst_fk_difference(urdf: Path, result: Path, names: list[str], tip: str = "tool0") -> float:
    """The largest distance (m) between yourdfpy's ``tip`` in ``measurement`` and the result's
    ``Calibration.fk`` at 200 random joint vectors within ±π (joints set by ``names``)."""
    model = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_scene_graph=True)
    calibration = dhlog.load(result)
    Q = np.random.default_rng(11).uniform(-math.pi, math.pi, (200, len(names)))
    want = calibration.fk(Q)
    worst = 0.0
    for q, p in zip(Q, want, strict=True):
        model.update_cfg(dict(zip(names, q, strict=True)))
        T = model.get_transform(tip, "measurement")
        worst = max(worst, float(np.abs(T[:3, 3] - p).max()))
    return worst


def test_the_library_entries_carry_ur_descriptions_velocity_and_effort() -> None:
    """Each UR entry's velocity (rad/s) and effort (N·m) limits are joint_limits.yaml's."""
    for name, entry in UR.items():
        robot = load_robot(name)
        assert robot.velocity_limits == pytest.approx(np.radians(entry["velocity_deg_s"]), abs=0)
        assert robot.effort_limits == pytest.approx(entry["effort_nm"], abs=0)


def test_a_library_robots_urdf_is_that_robots(ur5e_result: Path, tmp_path: Path) -> None:
    """``--nominal ur5e``: robot ur5e, the UR driver's joint names, the library's position
    limits, ur_description's velocity and effort; no joint says its dynamics are unknown; FK
    equal to Calibration.fk to 1e-9 m."""
    out = tmp_path / "ur5e.urdf"
    made = runner.invoke(app, ["export", str(ur5e_result), "-o", str(out), "--nominal", "ur5e"])
    assert made.exit_code == 0, made.output
    robot = load_robot("ur5e")
    model = yourdfpy.URDF.load(str(out), load_meshes=False)
    assert model.robot.name == "ur5e"
    assert list(model.actuated_joint_names) == list(robot.joint_names)
    for k, name in enumerate(robot.joint_names):
        limit = model.joint_map[name].limit
        assert (limit.lower, limit.upper) == tuple(robot.limits[k])
        assert limit.velocity == pytest.approx(math.radians(UR["ur5e"]["velocity_deg_s"][k]))
        assert limit.effort == UR["ur5e"]["effort_nm"][k]
    assert "not known" not in out.read_text()
    worst = worst_fk_difference(out, ur5e_result, list(robot.joint_names))
    assert worst < 1e-9, worst


def test_unknown_dynamics_are_said_on_each_joint(ur5e_result: Path, tmp_path: Path) -> None:
    """Without a library robot, or with one the library has no velocity for, each moving joint
    carries a comment that its velocity and effort are 0 because they are not known."""
    for extra, why in (([], "no library robot given"), (["--limits-from", "ur5"], None)):
        out = tmp_path / f"x{len(extra)}.urdf"
        made = runner.invoke(app, ["export", str(ur5e_result), "-o", str(out), *extra])
        assert made.exit_code == 0, made.output
        parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
        root = ET.parse(out, parser=parser).getroot()
        joints = [j for j in root.iter("joint") if j.get("type") != "fixed"]
        assert len(joints) == 6
        for joint in joints:
            limit = joint.find("limit")
            assert limit is not None
            if why is None:  # ur5 has them
                assert float(limit.get("velocity", "0")) > 0
                continue
            assert (limit.get("effort"), limit.get("velocity")) == ("0", "0")
            comments = [c.text or "" for c in joint if c.tag is ET.Comment]  # type: ignore[comparison-overlap]
            assert any("not known" in c and why in c for c in comments), comments


def test_the_library_carries_each_vendor_descriptions_velocity_and_effort() -> None:
    """Every entry with a vendor description in tests/data/vendor has that description's
    velocity limits (rad/s, written in °/s: 1e-12 relative) and its efforts where they are
    given; where every effort there is 0 (the ROS-Industrial descriptions' "not given") the
    library has none, and the URDF export says so instead of inventing one."""
    from vendor_urdf import VENDOR, load_vendor_urdf

    checked = 0
    for robot in library_robots():
        if not (VENDOR / f"{robot.name}.urdf").exists():
            continue
        joints = [load_vendor_urdf(robot.name).joint_map[n] for n in robot.joint_names]
        velocity = [j.limit.velocity for j in joints]
        effort = [j.limit.effort for j in joints]
        assert robot.velocity_limits == pytest.approx(velocity, rel=1e-11), robot.name
        if all(e > 0 for e in effort):
            assert robot.effort_limits == pytest.approx(effort, rel=1e-12), robot.name
        else:
            assert len(robot.effort_limits) == 0 and not any(effort), robot.name
        checked += 1
    assert checked == 21  # the 22 fixtures less kr6r900sixx_kuka_experimental (a second KR 6)


def test_known_velocity_and_unknown_effort_are_told_apart(tmp_path: Path) -> None:
    """An ABB IRB 120 (its description gives velocities, not efforts): each joint's velocity
    is the library's, its effort 0 with a comment that names the effort only."""
    result = tmp_path / "irb120.dh.json"
    made = runner.invoke(app, ["simulate", "irb120", "-o", str(tmp_path / "irb120.mcap")])
    assert made.exit_code == 0, made.output
    truth = tmp_path / "irb120.truth.json"
    result.write_text(truth.read_text())
    out = tmp_path / "irb120.urdf"
    made = runner.invoke(app, ["export", str(result), "-o", str(out), "--nominal", "irb120"])
    assert made.exit_code == 0, made.output
    robot = load_robot("irb120")
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    root = ET.parse(out, parser=parser).getroot()
    joints = [j for j in root.iter("joint") if j.get("type") != "fixed"]
    for joint, velocity in zip(joints, robot.velocity_limits, strict=True):
        limit = joint.find("limit")
        assert limit is not None
        assert float(limit.get("velocity", "nan")) == velocity and limit.get("effort") == "0"
        told = [c.text or "" for c in joint if c.tag is ET.Comment]  # type: ignore[comparison-overlap]
        assert len(told) == 1 and told[0].startswith(" effort limit not known"), told
