"""Exports checked by real consumers: the URDF through yourdfpy's loader and its forward
kinematics against dhlog's at random joint vectors (to 1e-9 m)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yourdfpy
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.io.dhfile import load_dh
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot

SAMPLES = Path(__file__).parents[1] / "sample_logs"
runner = CliRunner()


@pytest.mark.parametrize(
    ("log", "robot"),
    [("kr5_0.01mm", "kr5"), ("kr5_real", "kr5"), ("scara", "scara")],
    ids=["parallel pair held", "Hayati row", "prismatic joint"],
)
def test_the_urdf_reproduces_the_result_exactly(log: str, robot: str, tmp_path: Path) -> None:
    """``dhlog process`` then ``dhlog export --format urdf``: yourdfpy loads the URDF, and the
    target's position (``tool0`` in ``measurement``) equals the result's FK to 1e-9 m at 200
    random joint vectors within the robot's limits; the joint names and limits are the library
    robot's (``--limits-from``), the names as its ROS 2 driver publishes them where it has them."""
    out = tmp_path / "out"
    done = runner.invoke(
        app, ["process", str(SAMPLES / f"{log}.mcap"), "--no-rrd", "--out", str(out)]
    )
    assert done.exit_code == 0, done.output
    result = out / f"{log}.dh.json"
    urdf = tmp_path / "robot.urdf"
    made = runner.invoke(
        app, ["export", str(result), "-o", str(urdf), "--format", "urdf", "--limits-from", robot]
    )
    assert made.exit_code == 0, made.output
    model = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_scene_graph=True)
    rob = load_robot(robot)
    names = list(rob.joint_names) or [j["name"] for j in json.loads(result.read_text())["joints"]]
    assert list(model.actuated_joint_names) == names and model.robot.name == robot
    for k, name in enumerate(names):
        limit = model.joint_map[name].limit
        assert (limit.lower, limit.upper) == pytest.approx(tuple(rob.limits[k]))
    dh = load_dh(result)
    Q = np.random.default_rng(0).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, rob.n))
    want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
    for q, p in zip(Q, want, strict=True):
        model.update_cfg(q)
        T = model.get_transform("tool0", "measurement")
        assert np.abs(T[:3, 3] - p).max() < 1e-9


def test_a_result_with_encoder_scales_is_not_exported(tmp_path: Path) -> None:
    """An encoder scale has no place in a URDF: one line, exit 2."""
    data = json.loads((SAMPLES / "kr5_0.01mm.truth.json").read_text())
    data["standard_dh"][1]["encoder_scale"] = 1.001
    path = tmp_path / "scaled.dh.json"
    path.write_text(json.dumps(data))
    made = runner.invoke(app, ["export", str(path), "-o", str(tmp_path / "x.urdf")])
    assert made.exit_code == 2 and "encoder scales" in made.output


def test_compare_finds_the_changed_parameter_and_nothing_else(tmp_path: Path) -> None:
    """Two sessions of one robot (a KR5 off its nominal, its truth as a DH file) differ by
    noise only: no parameter beyond 4 combined σ, FK within 50 µm RMS. A third session of the
    same robot with a2 0.5 mm longer: a2 changed by 0.5 mm far beyond its σ, the FK difference
    of that size."""
    base = tmp_path / "robot.mcap"
    assert (
        runner.invoke(
            app,
            ["simulate", "kr5", "-o", str(base), "--perturb-mm", "0.3", "--perturb-deg", "0.02"],
        ).exit_code
        == 0
    )
    robot = tmp_path / "robot.truth.json"
    longer = json.loads(robot.read_text())
    longer["standard_dh"][1]["a"] += 5e-4
    changed = tmp_path / "longer.json"
    changed.write_text(json.dumps(longer))
    results = []
    for k, source in enumerate((robot, robot, changed)):
        log = tmp_path / f"s{k}.mcap"
        made = runner.invoke(app, ["simulate", str(source), "-o", str(log), "--seed", str(k + 1)])
        assert made.exit_code == 0, made.output
        done = runner.invoke(app, ["process", str(log), "--no-rrd", "--out", str(tmp_path)])
        assert done.exit_code == 0, done.output
        results.append(tmp_path / f"s{k}.dh.json")
    from dhlog.fleet.compare import compare

    same = compare(results[0], results[1])
    z = [c.significance for c in same.changes if c.significance is not None]
    assert max(z) < 4.0 and same.fk_rms < 50e-6
    moved = compare(results[0], results[2])
    a2 = next(c for c in moved.changes if c.name == "a_2")
    assert a2.diff == pytest.approx(5e-4, abs=4 * (a2.sigma or 0)) and (a2.significance or 0) > 10
    others = [c for c in moved.changes if c.name != "a_2" and c.significance is not None]
    assert 2e-4 < moved.fk_rms < 1e-3 and moved.fk_max < 1.5e-3
    shown = runner.invoke(app, ["compare", str(results[0]), str(results[2])])
    assert shown.exit_code == 0 and "a_2" in shown.output and "changed beyond 3σ" in shown.output
    assert len(others) > 10 and max(c.significance or 0 for c in others) < 4.0


def _export(result: Path, fmt: str, out: Path) -> str:
    made = runner.invoke(app, ["export", str(result), "-o", str(out), "--format", fmt])
    assert made.exit_code == 0, made.output
    return made.output


def _joint_vectors(robot: str, n: int = 200) -> np.ndarray:
    rob = load_robot(robot)
    return np.random.default_rng(4).uniform(rob.limits[:, 0], rob.limits[:, 1], (n, rob.n))


def test_a_ur_calibration_needs_six_revolute_joints(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = runner.invoke(
        app, ["process", str(SAMPLES / "scara.mcap"), "--no-rrd", "--out", str(out)]
    )
    assert done.exit_code == 0, done.output
    made = runner.invoke(
        app,
        ["export", str(out / "scara.dh.json"), "-o", str(tmp_path / "u.yaml"), "--format", "ur"],
    )
    assert made.exit_code == 2 and "six revolute joints" in made.output


@pytest.mark.parametrize(
    ("log", "robot"), [("ur5", "ur5"), ("kr5_real", "kr5"), ("scara", "scara")]
)
def test_the_roboticstoolbox_robot_reproduces_the_result(
    log: str, robot: str, ur5_result: Path, tmp_path: Path
) -> None:
    """The rtb snippet run by roboticstoolbox-python: ``robot.fkine(q).t`` equals dhlog's FK of
    the target in the measurement frame to 1e-9 m at 200 joint vectors (a Hayati row's result
    and a prismatic joint included)."""
    import runpy

    if log == "ur5":
        result = ur5_result
    else:
        out = tmp_path / "out"
        done = runner.invoke(
            app, ["process", str(SAMPLES / f"{log}.mcap"), "--no-rrd", "--out", str(out)]
        )
        assert done.exit_code == 0, done.output
        result = out / f"{log}.dh.json"
    snippet = tmp_path / "robot.py"
    _export(result, "rtb", snippet)
    rtb_robot = runpy.run_path(str(snippet))["robot"]
    dh = load_dh(result)
    Q = _joint_vectors(robot, 200)
    want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
    for q, p in zip(Q, want, strict=True):
        assert np.abs(rtb_robot.fkine(q).t - p).max() < 1e-9


def test_the_plain_dh_tables_reproduce_the_result(ur5_result: Path, tmp_path: Path) -> None:
    """dh-json's modified table (Craig's ``Rx(α) Tx(a) Rz(θ) Tz(d)`` rows and its tool-end
    transform) and dh-csv's standard rows read back by polars give dhlog's FK to 1e-9 m."""
    import polars as pl

    from dhlog.model.dh import modified_dh_transform, standard_dh_transform

    _export(ur5_result, "dh-json", tmp_path / "dh.json")
    _export(ur5_result, "dh-csv", tmp_path / "dh.csv")
    doc = json.loads((tmp_path / "dh.json").read_text())
    csv = pl.read_csv(tmp_path / "dh.csv").filter(pl.col("convention") == "standard")
    dh = load_dh(ur5_result)
    Q = _joint_vectors("ur5", 50)
    want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
    for q, p in zip(Q, want, strict=True):
        T_mod = np.asarray(doc["T_base"])
        T_std = np.asarray(doc["T_base"])
        for k, (m, s) in enumerate(zip(doc["modified"], csv.iter_rows(named=True), strict=True)):
            T_mod = T_mod @ modified_dh_transform(
                m["alpha_prev"], m["a_prev"], m["theta_offset"] + q[k], m["d"]
            )
            T_std = T_std @ standard_dh_transform(
                s["theta_offset"] + q[k], s["d"], s["a"], s["alpha"]
            )
        T_mod = T_mod @ np.asarray(doc["modified_T_tool_end"])
        tool = np.r_[doc["tool_point"], 1.0]
        assert np.abs((T_mod @ tool)[:3] - p).max() < 1e-9
        assert np.abs((T_std @ tool)[:3] - p).max() < 1e-9
    assert csv["std_a"].is_not_null().all()


UR5_TEMPLATE = """<?xml version="1.0"?>
<robot name="ur5">
  <!-- as the UR description lays it out: base_link turned by pi into base_link_inertia -->
  <link name="world"/>
  <link name="base_link"/>
  <link name="base_link_inertia">
    <visual><geometry><mesh filename="package://ur_description/meshes/ur5/visual/base.dae"/></geometry></visual>
    <inertial><mass value="4.0"/><origin xyz="0 0 0" rpy="0 0 0"/>
      <inertia ixx="0.0044" ixy="0" ixz="0" iyy="0.0044" iyz="0" izz="0.0072"/></inertial>
  </link>
{links}
  <link name="flange"/>
  <link name="tool0"/>
  <joint name="world_joint" type="fixed"><parent link="world"/><child link="base_link"/>
    <origin xyz="0.5 -0.2 0.8" rpy="0 0 0.3"/></joint>
  <joint name="base_link-base_link_inertia" type="fixed"><parent link="base_link"/>
    <child link="base_link_inertia"/><origin xyz="0 0 0" rpy="0 0 3.141592653589793"/></joint>
{joints}
  <joint name="wrist_3-flange" type="fixed"><parent link="wrist_3_link"/><child link="flange"/>
    <origin xyz="0 0 0" rpy="0 -1.5707963267948966 -1.5707963267948966"/></joint>
  <joint name="flange-tool0" type="fixed"><parent link="flange"/><child link="tool0"/>
    <origin xyz="0 0 0" rpy="1.5707963267948966 0 1.5707963267948966"/></joint>
  <transmission name="shoulder_trans"><type>transmission_interface/SimpleTransmission</type>
    <joint name="joint_1"><hardwareInterface>PositionJointInterface</hardwareInterface></joint>
  </transmission>
</robot>
"""
#: UR5 default_kinematics.yaml (x y z roll pitch yaw) per joint, as the UR description ships it.
UR5_KINEMATICS = [
    ("shoulder_link", "base_link_inertia", "0 0 0.089159", "0 0 0"),
    ("upper_arm_link", "shoulder_link", "0 0 0", "1.570796327 0 0"),
    ("forearm_link", "upper_arm_link", "-0.425 0 0", "0 0 0"),
    ("wrist_1_link", "forearm_link", "-0.39225 0 0.10915", "0 0 0"),
    ("wrist_2_link", "wrist_1_link", "0 -0.09465 -1.941e-11", "1.570796327 0 0"),
    (
        "wrist_3_link",
        "wrist_2_link",
        "0 0.0823 -1.688e-11",
        "1.570796326 3.141592653589793 3.141592653589793",
    ),
]


def ur5_template(path: Path) -> None:
    links, joints = [], []
    for k, (child, parent, xyz, rpy) in enumerate(UR5_KINEMATICS):
        links.append(
            f'  <link name="{child}">\n    <visual><geometry><mesh filename="package://'
            f'ur_description/meshes/ur5/visual/{child}.dae"/></geometry></visual>\n'
            f'    <inertial><mass value="{k + 1.5}"/><origin xyz="0 0 0.1" rpy="0 0 0"/>\n'
            '      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.005"/>'
            "</inertial>\n  </link>"
        )
        joints.append(
            f'  <joint name="joint_{k + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{child}"/>\n    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="0 0 1"/>'
            f'<limit lower="-{6.2 - k / 10}" upper="{6.2 - k / 10}" effort="150" velocity="3.15"/>'
            "</joint>"
        )
    path.write_text(UR5_TEMPLATE.format(links="\n".join(links), joints="\n".join(joints)))


def test_a_urdf_template_gets_the_calibrated_origins_and_keeps_the_rest(
    ur5_result: Path, tmp_path: Path
) -> None:
    """A UR5 URDF laid out as the UR description (base_link_inertia turned by π, the link frames
    of default_kinematics.yaml, flange and tool0, meshes, inertials, a transmission): after
    ``--template``, yourdfpy's FK of ``dhlog_target`` in ``dhlog_measurement`` equals the result's
    to 1e-9 m at 200 joint vectors; every link element, limit and the transmission is unchanged;
    each link frame at zero stays within 2 mm and 0.1° of the template's (the robot is 0.2 mm,
    0.02° off its nominal)."""
    import xml.etree.ElementTree as ET

    template = tmp_path / "ur5.urdf"
    ur5_template(template)
    out = tmp_path / "ur5_calibrated.urdf"
    made = runner.invoke(
        app, ["export", str(ur5_result), "-o", str(out), "--template", str(template)]
    )
    assert made.exit_code == 0, made.output
    before = yourdfpy.URDF.load(str(template), load_meshes=False)
    after = yourdfpy.URDF.load(str(out), load_meshes=False)
    dh = load_dh(ur5_result)
    Q = _joint_vectors("ur5")
    want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
    for q, p in zip(Q, want, strict=True):
        after.update_cfg(q)
        T = after.get_transform("dhlog_target", "dhlog_measurement")
        assert np.abs(T[:3, 3] - p).max() < 1e-9
    src, got = ET.parse(template).getroot(), ET.parse(out).getroot()

    def text(e: ET.Element | None) -> bytes:
        assert e is not None
        e.tail = None
        return ET.tostring(e)

    for a, b in zip(src.findall("link"), got.findall("link"), strict=False):
        assert text(a) == text(b)
    assert text(src.find("transmission")) == text(got.find("transmission"))
    for name in [f"joint_{k}" for k in range(1, 7)]:
        assert after.joint_map[name].limit.upper == before.joint_map[name].limit.upper
    after.update_cfg(np.zeros(6))
    before.update_cfg(np.zeros(6))
    for link, *_ in UR5_KINEMATICS:
        T0, T1 = before.get_transform(link, "world"), after.get_transform(link, "world")
        assert np.linalg.norm(T1[:3, 3] - T0[:3, 3]) < 2e-3, link
        turn = np.degrees(np.arccos(np.clip((np.trace(T0[:3, :3].T @ T1[:3, :3]) - 1) / 2, -1, 1)))
        assert turn < 0.1, link


def test_a_template_without_the_results_joints_is_one_line(
    ur5_result: Path, tmp_path: Path
) -> None:
    template = tmp_path / "other.urdf"
    ur5_template(template)
    template.write_text(template.read_text().replace('"joint_3"', '"elbow_joint"'))
    made = runner.invoke(
        app,
        ["export", str(ur5_result), "-o", str(tmp_path / "x.urdf"), "--template", str(template)],
    )
    assert made.exit_code == 2 and "has no joint joint_3 of the result" in made.output
    assert len(made.output.strip().splitlines()) == 1


def test_zero_offsets_in_the_calibration_tags(ur5_result: Path, tmp_path: Path) -> None:
    """``--zero-offsets calibration``: each joint's ``<calibration rising>`` is its zero offset;
    yourdfpy at joint positions encoder + rising gives the result's FK to 1e-9 m."""
    out = tmp_path / "cal.urdf"
    made = runner.invoke(
        app, ["export", str(ur5_result), "-o", str(out), "--zero-offsets", "calibration"]
    )
    assert made.exit_code == 0, made.output
    model = yourdfpy.URDF.load(str(out), load_meshes=False)
    rising = np.array([model.joint_map[n].calibration.rising for n in model.actuated_joint_names])
    dh = load_dh(ur5_result)
    assert np.abs(rising).max() > 1e-5  # the robot is off its nominal: offsets are not zero
    Q = _joint_vectors("ur5", 100)
    want = fk_point(dh.table, Q, dh.tool_point, T_base=dh.T_base)
    for q, p in zip(Q, want, strict=True):
        model.update_cfg(q + rising)
        assert np.abs(model.get_transform("tool0", "measurement")[:3, 3] - p).max() < 1e-9
