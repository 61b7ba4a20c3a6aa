"""The ISO 9283 test program (issue 34, item 3): the test cube, the poses P1–P5, the test paths
and the cycle program (``dhlog plan ROBOT --iso9283``), checked on the nominal model by forward
kinematics written out here (not the planner's inverse kinematics)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.errors import InputError, UsageError
from dhlog.iso9283 import program as iso
from dhlog.model import ik
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot, load_robot

runner = CliRunner()


@pytest.fixture(scope="module", params=["kr5", "ur5"])
def planned(request: pytest.FixtureRequest) -> tuple[Robot, iso.TestProgram]:
    robot = load_robot(request.param)
    return robot, iso.test_program(robot)


def tool_frame(robot: Robot, q: np.ndarray, tool: np.ndarray) -> np.ndarray:
    """The tool frame (..., 4, 4): the last link frame moved to the tool point."""
    T = np.array(fk_frames(robot.table, q, T_base=robot.T_base)[..., -1, :, :])
    T[..., :3, 3] = T[..., :3, :3] @ tool + T[..., :3, 3]
    return T


def angle(R: np.ndarray) -> np.ndarray:
    """The rotation angle (rad) of rotation matrices (..., 3, 3), accurate near zero."""
    skew = np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1
    )
    return np.asarray(
        np.arctan2(np.linalg.norm(skew, axis=-1) / 2, (np.trace(R, axis1=-2, axis2=-1) - 1) / 2)
    )


def within(robot: Robot, q: np.ndarray) -> bool:
    return bool(np.all((q >= robot.limits[:, 0]) & (q <= robot.limits[:, 1])))


def test_every_pose_is_reached_by_its_joint_targets(planned: tuple[Robot, iso.TestProgram]) -> None:
    """The nominal FK of each pose's joint targets is its commanded pose (1e-9 m, 1e-9 rad: the
    solver stops at 1e-12), within the limits; one orientation throughout (tool z down)."""
    robot, program = planned
    assert [p.name for p in program.poses] == ["P1", "P2", "P3", "P4", "P5"]
    for pose in program.poses:
        T = tool_frame(robot, pose.q, program.tool_point)
        assert np.max(np.abs(T[:3, 3] - pose.T[:3, 3])) < 1e-9, pose.name
        assert angle(T[:3, :3] @ pose.T[:3, :3].T) < 1e-9, pose.name
        assert np.allclose(pose.T[:3, :3], np.diag([1.0, -1.0, -1.0]))
        assert within(robot, pose.q), pose.name
        kappa = ik.condition(
            robot.table, pose.q, program.tool_point, T_base=robot.T_base, length=1.0
        )
        assert np.isfinite(kappa)


def test_the_poses_lie_where_the_standard_puts_them(planned: tuple[Robot, iso.TestProgram]) -> None:
    """P1 at the cube's centre; P2, P3, P4, P5 on the diagonals of the plane C1-C2-C7-C8 at 10 %
    of the diagonal (√3 · edge) from C1, C2, C7, C8; C1 the corner at the lowest x, y, z."""
    _, program = planned
    cube = program.cube
    c, s = cube.centre, cube.size
    assert cube.plane == "C1-C2-C7-C8" and s > 0.2  # both robots fit a cube over 200 mm
    h = s / 2
    signs = {1: (-1, -1, -1), 2: (1, -1, -1), 7: (1, 1, 1), 8: (-1, 1, 1)}
    C = {k: c + h * np.array(v) for k, v in signs.items()}
    assert np.allclose(cube.corners[[0, 1, 6, 7]], [C[1], C[2], C[7], C[8]], atol=1e-15)
    P = {p.name: p.T[:3, 3] for p in program.poses}
    assert np.allclose(P["P1"], c, atol=1e-15)
    diagonal = math.sqrt(3) * s
    for name, corner in (("P2", 1), ("P3", 2), ("P4", 7), ("P5", 8)):
        assert abs(np.linalg.norm(P[name] - C[corner]) - 0.1 * diagonal) < 1e-12, name
        assert abs(np.linalg.norm(P[name] - c) - 0.4 * diagonal) < 1e-12, name
    # by hand: P2 = C1 + 0.1 (C7 − C1) = c − 0.4 s (1, 1, 1)
    assert np.allclose(P["P2"], c - 0.4 * s, atol=1e-15)
    assert np.allclose(P["P4"], c + 0.4 * s, atol=1e-15)
    # the plane C1-C2-C7-C8: y − c_y = z − c_z
    for p in P.values():
        assert abs((p[1] - c[1]) - (p[2] - c[2])) < 1e-12


def test_the_cube_corners_are_reachable(planned: tuple[Robot, iso.TestProgram]) -> None:
    """Each corner reached from P1's joint targets along the straight line from the centre (five
    steps, each seeded by the last), within the limits: the cube is in the workspace."""
    robot, program = planned
    q1 = program.poses[0].q
    R = program.poses[0].T[:3, :3]
    for k, corner in enumerate(program.cube.corners):
        q = q1
        for f in (0.2, 0.4, 0.6, 0.8, 1.0):
            goal = np.eye(4)
            goal[:3, :3] = R
            goal[:3, 3] = program.cube.centre + f * (corner - program.cube.centre)
            sol = ik.solve(
                robot.table,
                goal[None],
                q[None],
                program.tool_point,
                T_base=robot.T_base,
                limits=robot.limits,
            )
            assert sol.converged[0], f"C{k + 1} at {f}"
            q = sol.q[0]
        T = tool_frame(robot, q, program.tool_point)
        assert np.max(np.abs(T[:3, 3] - corner)) < 1e-9 and within(robot, q)


def test_the_paths_are_reached_point_by_point(planned: tuple[Robot, iso.TestProgram]) -> None:
    """The line P2 → P4 through P1 and the two circles about P1 (diameters 80 % of the edge and
    10 % of that) in the plane: every commanded point reached by its joint targets (1e-9 m and
    rad), within the limits, the targets continuous (no joint moves more than 0.1 rad between
    neighbouring points: no branch change)."""
    robot, program = planned
    s, c = program.cube.size, program.cube.centre
    P = {p.name: p.T[:3, 3] for p in program.poses}
    paths = {p.name: p for p in program.paths}
    assert list(paths) == ["line", "circle_large", "circle_small"]
    line = paths["line"].points
    assert np.allclose(line[0], P["P2"]) and np.allclose(line[-1], P["P4"])
    assert np.allclose(line[len(line) // 2], P["P1"])
    for name, diameter in (("circle_large", 0.8 * s), ("circle_small", 0.08 * s)):
        radius = np.linalg.norm(paths[name].points - c, axis=1)
        assert np.allclose(radius, diameter / 2, atol=1e-12), name
        assert np.allclose(paths[name].points[0], paths[name].points[-1])
    R = program.poses[0].T[:3, :3]
    for path in program.paths:
        assert 50 <= len(path.points) <= 200 and path.speed == 0.25
        p = path.points
        assert np.all(np.abs((p[:, 1] - c[1]) - (p[:, 2] - c[2])) < 1e-12), path.name
        T = tool_frame(robot, path.q, program.tool_point)
        assert np.max(np.abs(T[:, :3, 3] - p)) < 1e-9, path.name
        assert np.max(angle(T[:, :3, :3] @ R.T)) < 1e-9, path.name
        assert within(robot, path.q), path.name
        assert np.max(np.abs(np.diff(path.q, axis=0))) < 0.1, path.name


def test_a_cube_given_is_checked() -> None:
    """The cube of edge and centre given is used as is; one out of reach is one error naming the
    corner, and a size no centre fits is one error naming the size."""
    robot = load_robot("ur5")
    program = iso.test_program(
        robot, cube_size=0.3, cube_centre=np.array([0.4, 0.1, 0.3]), cycles=3
    )
    assert program.cube.size == 0.3 and np.allclose(program.cube.centre, [0.4, 0.1, 0.3])
    with pytest.raises(iso.TestProgramError, match=r"corner C\d \(") as err:
        iso.test_program(robot, cube_size=0.8, cube_centre=np.array([0.4, 0.0, 0.3]))
    assert "\n" not in str(err.value) and isinstance(err.value, UsageError)
    with pytest.raises(iso.TestProgramError, match="no test cube of edge 3000 mm"):
        iso.test_program(robot, cube_size=3.0)
    with pytest.raises(UsageError, match="plane"):
        iso.test_program(robot, plane="C1-C2-C3-C4")


def test_the_program_csv_round_trips(
    planned: tuple[Robot, iso.TestProgram], tmp_path: Path
) -> None:
    """The CSV holds 30 pose cycles (P1 → P5 → P4 → P3 → P2) then 10 path cycles (line,
    circles), and reads back to the same table exactly (numbers written to round-trip)."""
    robot, program = planned
    path = tmp_path / "program.csv"
    path.write_text(iso.program_csv(program))
    back = iso.read_program(path, robot.n)
    rows = iso.program_rows(program)
    k = sum(len(p.points) for p in program.paths)
    assert len(back.kind) == 30 * 5 + 10 * k
    assert back.name[:6] == ["P1", "P5", "P4", "P3", "P2", "P1"]  # clause 7.2.1's order
    assert list(back.cycle[:6]) == [1, 1, 1, 1, 1, 2] and list(back.step[:6]) == [1, 2, 3, 4, 5, 1]
    assert back.kind[150] == "path" and back.name[150] == "line" and back.cycle[-1] == 10
    assert np.array_equal(back.q, rows.q) and np.array_equal(back.xyz, rows.xyz)
    assert back.name == rows.name and np.array_equal(back.index, rows.index)
    assert np.array_equal(back.step, rows.step)
    header = path.read_text().splitlines()[0]
    assert (
        header
        == "cycle,step,kind,name,index,"
        + ",".join(f"j{j}" for j in range(1, robot.n + 1))
        + ",x,y,z"
    )


@pytest.mark.parametrize(
    ("line", "said"),
    [
        ("1,1,pose,P9,0,0,0,0,0,0,0,0,0,0", "line 2: name 'P9'"),
        ("1,1,move,P1,0,0,0,0,0,0,0,0,0,0", "line 2: kind 'move'"),
        ("0,1,pose,P1,0,0,0,0,0,0,0,0,0,0", "line 2: cycle '0'"),
        ("1,1,pose,P1,0,0,nan,0,0,0,0,0,0,0", "line 2: j2 'nan'"),
        ("1,1,pose,P1,0,0,0,0", "line 2: has 8 fields"),
        ("1,1,path,line,-1,0,0,0,0,0,0,0,0,0", "line 2: index '-1'"),
    ],
)
def test_a_damaged_program_is_one_line(tmp_path: Path, line: str, said: str) -> None:
    path = tmp_path / "p.csv"
    path.write_text("cycle,step,kind,name,index,j1,j2,j3,j4,j5,j6,x,y,z\n" + line + "\n")
    with pytest.raises(InputError, match=said) as err:
        iso.read_program(path, 6)
    assert "\n" not in str(err.value)
    with pytest.raises(InputError, match="header"):
        iso.read_program(path, 7)


def test_the_plan_command_writes_the_program(tmp_path: Path) -> None:
    """``dhlog plan kr5 --iso9283 -o x.csv``: the tables and the CSV; an existing output is
    refused without --force; an unreachable --cube-size is one line, exit 1."""
    out = tmp_path / "x.csv"
    done = runner.invoke(app, ["plan", "kr5", "--iso9283", "--cycles", "3", "-o", str(out)])
    assert done.exit_code == 0, done.output
    assert "ISO 9283 test cube of kr5" in done.output and "circle_large" in done.output
    back = iso.read_program(out, 6)
    assert back.kind.count("pose") == 15 and back.cycle[:15].max() == 3
    again = runner.invoke(app, ["plan", "kr5", "--iso9283", "-o", str(out)])
    assert again.exit_code == 1 and "--force" in again.output
    bad = runner.invoke(
        app, ["plan", "kr5", "--iso9283", "--cube-size", "5000", "-o", str(tmp_path / "y.csv")]
    )
    assert bad.exit_code == 1 and "5000 mm" in bad.output
    assert len(bad.output.strip().splitlines()) == 1, bad.output
    assert not (tmp_path / "y.csv").exists()
    worse = runner.invoke(app, ["plan", "kr5", "--iso9283", "--cube-centre", "1,2"])
    assert worse.exit_code == 1 and "--cube-centre" in worse.output


@pytest.mark.parametrize("plane", list(iso.PLANES))
def test_each_plane_holds_its_poses_and_paths(plane: str) -> None:
    """In each of the four planes of clause 6.3 (a bottom edge and the opposite top edge):
    P2–P5 at 10 % of the diagonal from the named corners, in order; P2–P4 and P3–P5 through P1;
    every pose and path point in the plane of the four corners."""
    c, s = np.array([0.5, -0.2, 0.4]), 0.3
    cube = iso.TestCube(c, s, plane, iso.cube_corners(c, s))
    P = iso.pose_points(cube)
    corners = [int(name[1:]) - 1 for name in plane.split("-")]
    C = cube.corners[corners]
    for k in range(4):
        assert np.allclose(P[k + 1], C[k] + 0.1 * (C[(k + 2) % 4] - C[k]), atol=1e-15)
        assert np.isclose(np.linalg.norm(C[k] - C[(k + 2) % 4]), math.sqrt(3) * s)
    assert np.allclose((P[1] + P[3]) / 2, c) and np.allclose((P[2] + P[4]) / 2, c)
    assert np.isclose(np.linalg.norm(C[1] - C[0]), s)  # a cube's edge, then a face diagonal
    assert np.isclose(np.linalg.norm(C[2] - C[1]), math.sqrt(2) * s)
    normal = np.cross(C[1] - C[0], C[3] - C[0])
    normal /= np.linalg.norm(normal)
    points = np.vstack([P, *iso.path_points(cube).values()])
    assert np.max(np.abs((points - c) @ normal)) < 1e-12


def test_a_centre_given_gets_the_largest_cube_about_it() -> None:
    """--cube-centre alone: the edge is searched (bisection) about that centre; the cube found
    there is reached, and it is no larger than the one the full search finds."""
    robot = load_robot("ur5")
    program = iso.test_program(robot, cube_centre=np.array([0.35, 0.0, 0.3]))
    assert np.allclose(program.cube.centre, [0.35, 0.0, 0.3])
    assert 0.1 < program.cube.size <= iso.test_program(robot).cube.size
    for pose in program.poses:
        T = tool_frame(robot, pose.q, program.tool_point)
        assert np.max(np.abs(T[:3, 3] - pose.T[:3, 3])) < 1e-9


def test_a_program_that_is_not_text_is_one_line(tmp_path: Path) -> None:
    for data, said in ((b"\xff\xfec\x00y\x00", "UTF-16"), (b"cycle,\x00", "NUL")):
        path = tmp_path / "p.csv"
        path.write_bytes(data)
        with pytest.raises(InputError, match=said):
            iso.read_program(path, 6)
    with pytest.raises(InputError, match=r"missing\.csv"):
        iso.read_program(tmp_path / "missing.csv", 6)
    (tmp_path / "empty.csv").write_text("\n")
    with pytest.raises(InputError, match="is empty"):
        iso.read_program(tmp_path / "empty.csv", 6)
