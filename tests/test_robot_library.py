"""The robot library against the vendors' descriptions: each checked entry's FK equals the
vendor's own composition of its joints at random joint vectors within the limits, to 1e-9 m.

Universal Robots: ur_description's default_kinematics.yaml values (tests/data/ur_description.toml,
copied with the source commit) composed as urdf/ur_macro.xacro does — each joint's origin
Translation(x, y, z)·RPY(roll, pitch, yaw), then the rotation about the joint's z — from
base_link_inertia (the controller's Base) to tool0, against dhlog's FK of the library entry to its
last frame. The yaml's roll of 1.570796327 (π/2 + 3e-10) and its z of −2e-11 m are the file's own:
they move tool0 by under 1e-9 m on the largest arm, the tolerance.
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHFileError, dh_model_from, load_dh, robot_or_dh_file
from dhlog.model.fk import fk_frames, fk_point
from dhlog.model.robots import load_robot, merge_library, robot_names

DATA = Path(__file__).parent / "data"
UR = tomllib.loads((DATA / "ur_description.toml").read_text(encoding="utf-8"))
UR_JOINTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
UR_JOINT_NAMES = (  # urdf/ur_macro.xacro's revolute joints, as the UR ROS 2 driver publishes them
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)


def _origin(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> np.ndarray:
    """A URDF origin: Translation(x, y, z)·RPY (fixed axes x, then y, then z)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()
    T[:3, 3] = x, y, z
    return T


def _rot_z(q: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.0, 0.0, q]).as_matrix()
    return T


def ur_description_tool0(model: dict[str, Any], q: np.ndarray) -> FloatArray:
    """base_link_inertia → tool0 as ur_macro.xacro composes it at joint values q."""
    T = np.eye(4)
    for name, value in zip(UR_JOINTS, q, strict=True):
        T = T @ _origin(*model[name]) @ _rot_z(value)
    T = T @ _origin(0, 0, 0, 0, -np.pi / 2, -np.pi / 2)  # wrist_3-flange
    return np.asarray(T @ _origin(0, 0, 0, np.pi / 2, 0, np.pi / 2), dtype=np.float64)  # tool0


@pytest.mark.parametrize("name", sorted(UR))
def test_a_ur_entry_is_ur_descriptions_arm_to_tool0(name: str) -> None:
    robot = load_robot(name)
    vendor = UR[name]
    assert robot.joint_names == UR_JOINT_NAMES
    assert "ur_description" in robot.checked
    # the library's limits hold ur_description's (its elbow is halved artificially; a joint
    # without a position limit turns without end, one turn either way in the library)
    for (lo, hi), yaml_limits in zip(np.degrees(robot.limits), vendor["limits_deg"], strict=True):
        ylo, yhi = yaml_limits if yaml_limits else (-360.0, 360.0)
        assert lo <= ylo + 1e-9 and yhi - 1e-9 <= hi
    rng = np.random.default_rng(40)
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (200, robot.n))
    for q in Q:
        ours = fk_frames(robot.table, q, T_base=robot.T_base)[-1]
        theirs = ur_description_tool0(vendor, q)
        assert np.abs(ours[:3, 3] - theirs[:3, 3]).max() < 1e-9  # m
        assert np.abs(ours[:3, :3] - theirs[:3, :3]).max() < 1e-9  # rad, about
    # and at the zero pose, UR's stretched arm: tool0 at (a2 + a3, -(d4 + d6), d1 - d5)
    zero = ur_description_tool0(vendor, np.zeros(6))[:3, 3]
    t = robot.table
    expected = [t.a[1] + t.a[2], -(t.d_offset[3] + t.d_offset[5]), t.d_offset[0] - t.d_offset[4]]
    np.testing.assert_allclose(zero, expected, atol=1e-9)


def test_the_checked_entries_are_the_described_ones() -> None:
    """An entry says it is checked exactly when a test checks it: its ``checked`` text names the
    test file (this one for the UR arms, ``tests/test_library_*.py`` for the other makers), and
    that file names the entry."""
    tests = Path(__file__).parent
    checked = {n for n in robot_names() if load_robot(n).checked}
    assert set(UR) <= checked
    assert {"ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur16e", "ur20", "ur30"} <= checked
    for name in checked - set(UR):
        files = re.findall(r"tests/(test_library_\w+\.py)", load_robot(name).checked)
        assert files, f"{name}: its checked text names no tests/test_library_*.py"
        assert f'"{name}"' in (tests / files[0]).read_text(encoding="utf-8"), name


def test_a_name_in_two_makers_files_is_refused() -> None:
    """The library's files are read together; a robot named twice is an error, not the later
    file's table silently winning."""
    names = robot_names()
    assert len(names) == len(set(names)) and {"kr5", "ur5e", "panda"} <= set(names)
    with pytest.raises(DhlogError, match=r"names 'kr5' twice \(library/b.toml\)"):
        merge_library([("a.toml", "[kr5]\ntitle = 'x'\n"), ("b.toml", "[kr5]\ntitle = 'y'\n")])


@pytest.mark.parametrize(
    ("spelling", "name"),
    [
        *((s, "ur5e") for s in ("UR5e", "ur5e", "UR-5e", "ur_5e", "Universal Robots UR5e")),
        ("R-2000iC/165F", "r2000ic165f"),
        ("FANUC R-2000iC/165F", "r2000ic165f"),
        ("IRB 1200-5/0.9", "irb1200"),
        ("ABB IRB 120", "irb120"),
        ("LR Mate 200iD", "lrmate200id"),
        ("Yaskawa Motoman GP7", "gp7"),
    ],
)
def test_a_robot_is_found_as_users_write_it(spelling: str, name: str) -> None:
    """Case, spaces and punctuation aside, a maker's name before the model's, or the entry's
    title (a variant's full name)."""
    assert load_robot(spelling).name == name


def test_an_unknown_robot_is_one_line_listing_the_library() -> None:
    with pytest.raises(DhlogError, match=r"Unknown robot 'IRB 9999'; the library has .*irb120"):
        load_robot("IRB 9999")


def test_dhlog_robots_lists_the_library_with_sources_and_checks() -> None:
    """``dhlog robots``: every library robot, its joints, source and whether its FK is checked
    against a vendor description; ``--json`` the same as data."""
    run = CliRunner().invoke(app, ["robots", "--json"])
    assert run.exit_code == 0, run.output
    listed = {e["name"]: e for e in json.loads(run.stdout)}
    assert sorted(listed) == robot_names()
    ur5e = listed["ur5e"]
    assert ur5e["joints"] == 6 and ur5e["joint_types"] == "RRRRRR"
    assert ur5e["joint_names"] == list(UR_JOINT_NAMES)
    assert "ur_description config/ur5e" in ur5e["checked"]
    assert "published DH parameters" in ur5e["source"]
    assert listed["kr5rail"]["joint_types"] == "PRRRRRR" and listed["kr5rail"]["checked"] is None
    assert listed["scara"]["joints"] == 4
    text = CliRunner().invoke(app, ["robots"], env={"COLUMNS": "200"})
    assert text.exit_code == 0, text.output
    lines = text.stdout.splitlines()
    for name in robot_names():  # one row per robot, its name first
        assert any(line.split()[:1] == [name] for line in lines), name
    # the console's width is the one it started with (another test's, in one worker): the words
    # as printed, whatever the wrapping
    words = " ".join(text.stdout.split())
    assert "Universal Robots UR16e 6 RRRRRR ur_description" in words
    assert "Elbow manipulator 6 RRRRRR -" in words
    whole = CliRunner().invoke(app, ["robots", "UR16e", "scara"], env={"COLUMNS": "200"})
    assert whole.exit_code == 0, whole.output
    words = " ".join(whole.stdout.split())
    assert "FK checked: ur_description config/ur16e" in words
    assert "FK checked: not checked against a vendor description" in words
    assert "Universal Robots UR16e: 6 joints (RRRRRR), the driver's joint names" in words
    unknown = CliRunner().invoke(app, ["robots", "IRB 9999"])
    assert unknown.exit_code == 2 and "Unknown robot 'IRB 9999'" in unknown.output


PERTURBED = ("--perturb-mm", "0.5", "--perturb-deg", "0.05")


def test_a_ur5e_session_processes_with_its_nominal_and_its_driver_names(tmp_path: Path) -> None:
    """``dhlog simulate ur5e --driver-joints`` of a UR5e off its nominal (σ 0.5 mm, 0.05°), then
    ``dhlog process --nominal ur5e``: the result names the joints as the UR driver does and its
    FK is the simulated robot's at random joint vectors within the limits. Tracker noise σ 10 µm
    per coordinate over 3008 samples: the held-out error is about 8 µm mean, 19 µm max (seed 1);
    50 µm is beyond that, and the nominal's own error (its table at the true placement, the
    perturbation) is several times larger."""
    log = tmp_path / "ur5e.mcap"
    simulated = CliRunner().invoke(
        app,
        ["simulate", "ur5e", "-o", str(log), "--seed", "1", "--driver-joints", *PERTURBED],
    )
    assert simulated.exit_code == 0, simulated.output
    out = tmp_path / "out"
    run = CliRunner().invoke(
        app, ["process", str(log), "--nominal", "ur5e", "--out", str(out), "--no-rrd"]
    )
    assert run.exit_code == 0, run.output
    document = json.loads((out / "ur5e.dh.json").read_text())
    assert document["plausible"] is True
    assert [j["name"] for j in document["joints"]] == list(UR_JOINT_NAMES)
    truth = dh_model_from(str(tmp_path / "ur5e.truth.json"))
    result = dh_model_from(str(out / "ur5e.dh.json"))
    robot = load_robot("ur5e")
    Q = np.random.default_rng(5).uniform(robot.limits[:, 0], robot.limits[:, 1], (500, 6))
    want = fk_point(truth.table, Q, truth.tool_point, T_base=truth.T_base)
    got = fk_point(result.table, Q, result.tool_point, T_base=result.T_base)
    error = np.linalg.norm(got - want, axis=1)
    assert error.max() < 50e-6
    nominal = fk_point(robot.table, Q, truth.tool_point, T_base=truth.T_base)
    assert np.linalg.norm(nominal - want, axis=1).mean() > 5 * error.mean()


def docs_example(tmp_path: Path) -> Path:
    """docs/dh-files.md's example DH file, as the page shows it."""
    page = (Path(__file__).parents[1] / "docs" / "dh-files.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```toml\n(.*?)^```$", page, re.S | re.M)
    assert len(blocks) == 1
    path = tmp_path / "ur5e.toml"
    path.write_text(blocks[0], encoding="utf-8")
    return path


def test_the_docs_example_is_the_library_ur5e_with_limits_and_names(tmp_path: Path) -> None:
    """The DH-file page's example (mm, degrees, names, limits) is ``--nominal ur5e``: the same
    FK to rounding at random joint vectors, the driver's names, its limits in rad."""
    model = load_dh(docs_example(tmp_path))
    robot = load_robot("ur5e")
    assert model.joint_names == UR_JOINT_NAMES
    assert model.limits is not None
    np.testing.assert_allclose(
        np.degrees(model.limits), [[-360, 360]] * 2 + [[-180, 180]] + [[-360, 360]] * 3
    )
    Q = np.random.default_rng(3).uniform(model.limits[:, 0], model.limits[:, 1], (200, 6))
    ours = fk_frames(model.table, Q, T_base=model.T_base)[..., -1, :, :]
    library = fk_frames(robot.table, Q, T_base=robot.T_base)[..., -1, :, :]
    assert np.abs(ours - library).max() < 1e-12
    np.testing.assert_allclose(model.tool_point, [0, 0, 0.05])
    # the file's limits are the robot dhlog simulate builds from it
    assert np.array_equal(robot_or_dh_file(str(docs_example(tmp_path))).limits, model.limits)


@pytest.mark.parametrize(
    ("limits", "message"),
    [
        ("[10, -10]", r"joints\[1\]\.limits is \[10, -10\]; the lower limit must be below"),
        ("[0]", r"joints\[1\]\.limits is \[0\]; give two numbers \[lower, upper\]"),
        ('["a", 1]', r"joints\[1\]\.limits is \"a\", not a number"),
        ("[-1000, 1000]", r"joints\[1\]\.limits is -1000, beyond"),
    ],
)
def test_a_dh_files_bad_limits_are_one_error_naming_the_joint(
    tmp_path: Path, limits: str, message: str
) -> None:
    path = tmp_path / "arm.toml"
    path.write_text(
        'units = { length = "mm", angle = "deg" }\n'
        f'joints = [{{ name = "j1" }}, {{ name = "j2", limits = {limits} }}]\n'
        "standard_dh = [{ d = 300, a = 0, alpha = 90 }, { a = 250, alpha = 0 }]\n",
        encoding="utf-8",
    )
    with pytest.raises(DHFileError, match=message):
        load_dh(path)


def test_a_dh_file_without_limits_has_none_and_one_limit_is_completed(tmp_path: Path) -> None:
    """No ``limits``: ``DHModel.limits`` is None and a robot built from it takes ±π, ±0.1 m; one
    joint's limits given: the others take those defaults."""
    path = tmp_path / "arm.toml"
    rows = (
        "standard_dh = [{ d = 0.3, a = 0, alpha = 1.5708 }, "
        "{ type = 'prismatic', a = 0.2, alpha = 0 }]\n"
    )
    path.write_text(rows, encoding="utf-8")
    assert load_dh(path).limits is None
    np.testing.assert_allclose(robot_or_dh_file(str(path)).limits, [[-np.pi, np.pi], [-0.1, 0.1]])
    path.write_text("joints = [{}, { limits = [0, 0.5] }]\n" + rows, encoding="utf-8")
    limits = load_dh(path).limits
    assert limits is not None
    np.testing.assert_allclose(limits, [[-np.pi, np.pi], [0.0, 0.5]])
