"""``dhlog compensate`` as a program filter: Cartesian targets corrected in order on one
configuration, URScript programs rewritten with only their targets' numbers changed, the
rotation conventions, and every target not corrected named with exit 3.

Ground truth is independent of the code under test: the corrected program is read back with
its own regular expression, the controller emulated (the nominal's inverse kinematics of each
commanded pose from the previous joints, as URScript's motions solve it) and the calibrated
model's forward kinematics of those joints compared with the original targets."""

from __future__ import annotations

import difflib
import functools
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dhlog.cell import rotations
from dhlog.cell.compensate import compensate_poses
from dhlog.cell.sequence import Target, filter_targets
from dhlog.cli.app import app
from dhlog.errors import UsageError
from dhlog.identify.run import ProcessOptions, process_data
from dhlog.io.dhfile import DHModel, parse_dh
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_frames
from dhlog.model.ik import solve
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

runner = CliRunner()
#: The TCP of the programs below: 100 mm along the flange's z (a gripper).
TCP = np.eye(4)
TCP[2, 3] = 0.1


def _nominal() -> DHModel:
    rob = load_robot("ur5e")
    return DHModel(rob.table, rob.T_base, rob.tool_point, rob.joint_names, "ur5e")


@functools.cache
def _calibrated(tmp: str) -> tuple[DHModel, Path]:
    """A UR5e 0.5 mm / 0.05° off its nominal, identified from a simulated session; the model
    and its result file."""
    cfg = SimulationConfig(
        perturb_length=5e-4, perturb_angle=math.radians(0.05), seed=11, noise=1e-5
    )
    session = simulate_session(load_robot("ur5e"), cfg)
    result = process_data(log_data_from_session(session), ProcessOptions(nominal=_nominal()))
    doc = json.loads(json.dumps(result_document(result)))
    path = Path(tmp) / "ur5e.dh.json"
    path.write_text(json.dumps(doc))
    return parse_dh(doc, str(path)), path


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> tuple[DHModel, Path]:
    return _calibrated(str(tmp_path_factory.mktemp("ur5e")))


def _pick_and_place() -> list[np.ndarray]:
    """22 TCP poses of a pick-and-place cycle (the gripper pointing down): above, 46 mm above
    and at the pick and the place spots, with a transfer arc between them; twice."""
    down = Rotation.from_rotvec([math.pi, 0, 0])
    spots = [(-0.40, -0.30, 0.05, 0.0), (-0.45, 0.25, 0.05, 30.0)]
    xyzs: list[tuple[float, float, float, float]] = []
    for _ in range(2):
        for x, y, z, yaw in spots:
            xyzs += [(x, y, z + 0.2, yaw), (x, y, z + 0.046, yaw), (x, y, z, yaw)]
            xyzs += [(x, y, z + 0.046, yaw), (x, y, z + 0.2, yaw)]
        xyzs += [(-0.55, -0.02, 0.3, 15.0)]
    poses = []
    for x, y, z, yaw in xyzs:
        T = np.eye(4)
        T[:3, :3] = (Rotation.from_euler("z", yaw, degrees=True) * down).as_matrix()
        T[:3, 3] = x, y, z
        poses.append(T)
    return poses


START = [0.35, -1.3, 1.6, 1.3, 1.5708, -1.2]


def _script(poses: list[np.ndarray]) -> str:
    """A URScript program moving through ``poses``: a def body, comments, a string holding a
    '#', set_tcp, a movej to joints, waypoint variables and inline p[…] literals."""
    lines = [
        "def pick_and_place():",
        "  # pick at the conveyor, place on the tray",
        "  set_tcp(p[0.0, 0.0, 0.1, 0.0, 0.0, 0.0])",
        '  textmsg("cycle # start")',
        f"  movej([{', '.join(f'{v:.4f}' for v in START)}], a=1.4, v=1.05)",
    ]
    for k, T in enumerate(poses):
        r = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        p = ", ".join(f"{v:.6f}" for v in (*T[:3, 3], *r))
        if k % 5 == 0:
            lines += [f"  Waypoint_{k}_p = p[{p}]", f"  movel(Waypoint_{k}_p, a=1.2, v=0.25)"]
        else:
            lines.append(f"  movel(p[{p}], a=1.2, v=0.25, r=0.0)  # target {k + 1}")
        if k == 2:
            lines.append("  set_digital_out(0, True)  # grip")
    lines.append("end")
    return "\n".join(lines) + "\n"


def _controller(nominal: DHModel, commanded: list[np.ndarray], q0: np.ndarray) -> np.ndarray:
    """The joints a controller running ``nominal`` reaches at each commanded TCP pose, each
    solved from the previous joints (the TCP of the programs: :data:`TCP`)."""
    q, out = q0, []
    for T in commanded:
        found = solve(nominal.table, (T @ np.linalg.inv(TCP))[None], q[None], np.zeros(3))
        assert bool(found.converged[0])
        q = found.q[0]
        out.append(q)
    return np.array(out)


def _tcp_error(model: DHModel, q: np.ndarray, goal: list[np.ndarray]) -> tuple[float, float]:
    """The calibrated model's TCP at joints ``q`` against ``goal``: largest m and rad."""
    T = fk_frames(model.table, model.joint_values(q))[:, -1] @ TCP
    G = np.array(goal)
    dp = np.linalg.norm(T[:, :3, 3] - G[:, :3, 3], axis=1)
    dr = Rotation.from_matrix(np.einsum("mij,mkj->mik", T[:, :3, :3], G[:, :3, :3])).magnitude()
    return float(dp.max()), float(dr.max())


def test_a_urscript_program_is_filtered(calibrated: tuple[DHModel, Path], tmp_path: Path) -> None:
    """22 movel poses: the output differs from the input only inside the targets' literals;
    the controller's joints at the corrected poses put the calibrated TCP on the original
    targets within 1 µm and 1 µrad; the arm keeps its configuration (the Jacobian's sign,
    small joint steps — the pairs 46 mm apart 0.2 rad at most)."""
    model, result = calibrated
    nominal = _nominal()
    poses = _pick_and_place()
    source = tmp_path / "cell.script"
    source.write_text(_script(poses))
    out = tmp_path / "corrected.script"
    run = runner.invoke(
        app,
        ["compensate", str(result), "--nominal", "ur5e", "--program", str(source), "-o", str(out)],
    )
    assert run.exit_code == 0, run.output
    before, after = source.read_text(), out.read_text()
    literals = [m.span() for m in re.finditer(r"p?\[[^\[\]]*\]", before)]
    matcher = difflib.SequenceMatcher(None, before, after, autojunk=False)
    changes = [op for op in matcher.get_opcodes() if op[0] != "equal"]
    assert changes  # the calibration changed something
    for _, i1, i2, _, _ in changes:
        assert any(a <= i1 and i2 <= b for a, b in literals), before[i1 - 20 : i2 + 20]
    assert before.count("\n") == after.count("\n")
    assert "# pick at the conveyor" in after and 'textmsg("cycle # start")' in after
    # read back with a parser of its own: the movej joints, then every pose in order
    q0 = np.array(
        [float(v) for v in re.search(r"movej\(\[([^\]]*)\]", after).group(1).split(",")]  # type: ignore[union-attr]
    )
    commanded, written = _movel_poses(after), _movel_poses(before)
    assert len(commanded) == len(written) == len(poses) == 22
    q = _controller(nominal, commanded, q0)
    dp, dr = _tcp_error(model, q, written)  # the targets as the program writes them
    assert dp < 1e-8 and dr < 1e-8, (dp, dr)  # 1 µm asked; the numbers carry 1e-10
    # uncorrected, the calibrated robot misses them by far more (the correction matters)
    q_raw = _controller(nominal, poses, np.array(START))
    assert _tcp_error(model, q_raw, poses)[0] > 1e-4
    # one configuration throughout: no wrist, elbow or shoulder flip, small steps
    J = np.array([np.linalg.det(j) for j in _jacobians(nominal, q)])
    assert np.all(np.sign(J) == np.sign(J[0]))
    steps = np.abs(np.diff(np.vstack([q0, q]), axis=0)).max(axis=1)
    # 46 mm apart (and back): 0.09 rad; the largest, 1.67 rad, joint 1 on the 560 mm transfer
    assert steps[[2, 3, 7, 8]].max() < 0.2 and steps.max() < 2.0, steps


def _movel_poses(text: str) -> list[np.ndarray]:
    """The poses (4, 4) of the movel motions in ``text``, in order (variables resolved)."""
    bound = {m.group(1): m.group(2) for m in re.finditer(r"(\w+) = p\[([^\]]*)\]", text)}
    out = []
    for m in re.finditer(r"movel\((?:p\[([^\]]*)\]|(\w+))", text):
        values = [float(v) for v in (m.group(1) or bound[m.group(2)]).split(",")]
        T = np.eye(4)
        T[:3, 3] = values[:3]
        T[:3, :3] = Rotation.from_rotvec(values[3:]).as_matrix()
        out.append(T)
    return out


def _jacobians(nominal: DHModel, q: np.ndarray) -> np.ndarray:
    from dhlog.model.ik import tool_jacobian

    return tool_jacobian(nominal.table, q, np.zeros(3), T_base=nominal.T_base)


def test_solved_alone_the_same_path_flips(calibrated: tuple[DHModel, Path]) -> None:
    """The failure this replaces: each pose solved alone (from home and seeded starts) puts
    neighbours on other branches; solved in order, none."""
    model, _ = calibrated
    nominal = _nominal()
    rob = load_robot("ur5e")
    flanges = np.array([T @ np.linalg.inv(TCP) for T in _pick_and_place()])
    alone, _ = compensate_poses(model, nominal, flanges, limits=rob.limits)
    signs = np.sign([np.linalg.det(j) for j in _jacobians(nominal, alone.targets)])
    jumps = np.abs(np.diff(alone.targets, axis=0)).max(axis=1)
    assert np.any(signs != signs[0]) or jumps.max() > math.pi
    targets = [Target(f"row {k + 1}", pose=T, tcp=TCP) for k, T in enumerate(_pick_and_place())]
    ordered = filter_targets(model, nominal, targets, limits=rob.limits)
    assert not ordered.problems
    signs = np.sign([np.linalg.det(j) for j in _jacobians(nominal, ordered.joints)])
    assert np.all(signs == signs[0])
    assert ordered.largest_step < 2.0  # the transfer's joint 1 (1.67 rad)


def test_a_flip_it_cannot_avoid_is_named(calibrated: tuple[DHModel, Path]) -> None:
    """Joint 1 limited to ±0.5 rad: the place spot (joint 1 near -0.9 on this branch) is out of
    the limits; those targets are named (their row), the rest corrected."""
    model, _ = calibrated
    nominal = _nominal()
    limits = load_robot("ur5e").limits.copy()
    limits[0] = (-0.5, 0.5)
    targets = [Target(f"row {k + 1}", pose=T, tcp=TCP) for k, T in enumerate(_pick_and_place())]
    done = filter_targets(model, nominal, targets, limits=limits)
    assert done.problems and all("limits of joint 1" in w for w in done.problems.values())
    assert set(done.problems) >= {5, 6, 7}  # the place spot's five
    assert np.all(np.isfinite(done.joints[[0, 1, 2, 3, 4], 0]))
    goal = [T for k, T in enumerate(_pick_and_place()) if k not in done.problems]
    ok = np.isfinite(done.joints[:, 0])
    assert _tcp_error(model, done.joints[ok], goal)[0] < 1e-9


@pytest.mark.parametrize(
    ("convention", "values", "want"),
    [
        # KUKA A, B, C: Rz(A) · Ry(B) · Rx(C) (intrinsic z, y', x''), degrees
        ("intrinsic-zyx", [30.0, 20.0, 10.0], ("z", 30.0, "y", 20.0, "x", 10.0)),
        # fixed axes X then Y then Z: Rz(c) · Ry(b) · Rx(a)
        ("extrinsic-xyz", [10.0, 20.0, 30.0], ("z", 30.0, "y", 20.0, "x", 10.0)),
        ("intrinsic-zyz", [40.0, 30.0, -20.0], ("z", 40.0, "y", 30.0, "z", -20.0)),
    ],
)
def test_euler_conventions_by_hand(
    convention: str, values: list[float], want: tuple[object, ...]
) -> None:
    """Each named convention against the product of elementary rotations written out."""

    def elementary(axis: object, deg: object) -> np.ndarray:
        c, s = math.cos(math.radians(float(deg))), math.sin(math.radians(float(deg)))  # type: ignore[arg-type]
        return {
            "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
        }[str(axis)]

    R = elementary(want[0], want[1]) @ elementary(want[2], want[3]) @ elementary(want[4], want[5])
    got = rotations.matrices(np.array([values]), convention, degrees=True)[0]
    assert np.abs(got - R).max() < 1e-15
    back = rotations.values(got[None], convention, degrees=True)[0]
    assert np.abs(back - values).max() < 1e-9


def test_rotation_vectors_and_quaternions() -> None:
    """rotvec (rad, UR) and quaternion (w first, ABB) round trips at random rotations, the
    representation nearest the old one kept (a quaternion's sign, a rotvec near π)."""
    R = Rotation.random(50, random_state=3).as_matrix()
    for convention in ("rotvec", "quaternion"):
        v = rotations.values(R, convention, degrees=False)
        assert np.abs(rotations.matrices(v, convention, degrees=False) - R).max() < 1e-12
    q = rotations.values(R, "quaternion", degrees=False)
    assert np.abs(rotations.near(-q, q, "quaternion", degrees=False) - q).max() < 1e-15
    half = np.array([[0.0, 0.0, math.pi - 1e-4]])
    other = np.array([[0.0, 0.0, -(math.pi + 1e-4)]])  # the same turn the long way round
    nearest = rotations.near(half, other, "rotvec", degrees=False)
    assert np.allclose(nearest, [[0, 0, -math.pi - 1e-4]])
    with pytest.raises(UsageError, match="intrinsic-zyx"):
        rotations.check_convention("zyx")


def _args(result: Path, kind: str, path: Path, out: Path) -> list[str]:
    return ["compensate", str(result), "--nominal", "ur5e", kind, str(path), "-o", str(out)]


def test_poses_csv_rotvec_tcp_and_units(calibrated: tuple[DHModel, Path], tmp_path: Path) -> None:
    """--poses with UR rotation vectors in m, a TCP, the units in the output's header; a target
    out of reach is named by its line, exit 3, the rest written."""
    model, result = calibrated
    poses = _pick_and_place()[:6]
    rows = ["x_m,y_m,z_m,rx,ry,rz"]
    for T in poses:
        r = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        rows.append(",".join(f"{v:.9f}" for v in (*T[:3, 3], *r)))
    rows.insert(4, "2.5,0,0.3,3.14159,0,0")  # 2.5 m away: beyond a UR5e
    path = tmp_path / "poses.csv"
    path.write_text("\n".join(rows) + "\n")
    out = tmp_path / "corrected.csv"
    run = runner.invoke(
        app, [*_args(result, "--poses", path, out), "--rotation", "rotvec", "--tcp", "0,0,100"]
    )
    assert run.exit_code == 3, run.output
    assert "poses.csv line 5 (row 4): not corrected" in run.output
    lines = out.read_text().splitlines()
    assert lines[0] == (
        "row,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad,x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad"
    )
    assert [line.split(",")[0] for line in lines[1:]] == ["1", "2", "3", "5", "6", "7"]
    q = np.array([[float(v) for v in line.split(",")[1:7]] for line in lines[1:]])
    assert _tcp_error(model, q, poses)[0] < 1e-9


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (
            "def f():\n  movel(p[0.1, 0.2, 0.3, 0, 3.14], a=1)\nend\n",
            "line 2: 'p[0.1, 0.2, 0.3, 0, 3.14]' has 5 numbers",
        ),
        ("movej([0, -1.5, 1.5, 0, 1.5], a=1)\n", "line 1: '[0, -1.5, 1.5, 0, 1.5]' has 5 numbers"),
        ("# start\nmovel(p[0.1, 0.2, 0.3, 0, 3.14, 0]\n", "line 2: movel( is never closed"),
        ("movel(p[0.1, nan, 0.3, 0, 3.14, 0])\n", "line 1: 'nan' is not a finite number"),
        ("movel(p[0.1, 1e999, 0.3, 0, 3.14, 0])\n", "line 1: '1e999' is beyond a float"),
        ("movel()\n", "line 1: movel(…) needs pose"),
    ],
)
def test_a_program_that_does_not_parse(
    calibrated: tuple[DHModel, Path], tmp_path: Path, text: str, said: str
) -> None:
    """One line naming the file and line, exit 2, nothing written."""
    _, result = calibrated
    path = tmp_path / "bad.script"
    path.write_text(text)
    out = tmp_path / "out.script"
    run = runner.invoke(app, _args(result, "--program", path, out))
    assert run.exit_code == 2, run.output
    assert f"{path}, {said}" in " ".join(run.output.split()), run.output
    assert "Traceback" not in run.output and not out.exists()


def test_bad_csv_and_options(calibrated: tuple[DHModel, Path], tmp_path: Path) -> None:
    """NaN and wrong arity in a CSV: exit 2 naming the line; an unknown --rotation, --tcp
    without Cartesian targets, an unknown program suffix: exit 1 naming the option."""
    _, result = calibrated
    path = tmp_path / "poses.csv"
    out = tmp_path / "out.csv"
    for text, said in (
        ("x,y,z,rx,ry,rz\n100,200,nan,0,0,0\n", "line 2: a value is not finite"),
        ("x,y,z,rx,ry,rz\n100,200,300,0,0\n", "line 2: has 5 values for 6 columns"),
    ):
        path.write_text(text)
        run = runner.invoke(app, _args(result, "--poses", path, out))
        assert run.exit_code == 2 and f"{path}, {said}" in " ".join(run.output.split())
    run = runner.invoke(app, [*_args(result, "--poses", path, out), "--rotation", "abc"])
    assert run.exit_code == 1 and "--rotation 'abc' is not a rotation convention" in run.output
    targets = tmp_path / "q.csv"
    targets.write_text("0,-1,1,0,1,0\n")
    run = runner.invoke(app, [*_args(result, "--joints", targets, out), "--tcp", "0,0,1"])
    assert run.exit_code == 1 and "--tcp applies to --poses or --program only" in run.output
    other = tmp_path / "prog.txt"
    other.write_text("movel(p[0.1, 0.2, 0.3, 0, 3.14, 0])\n")
    run = runner.invoke(app, _args(result, "--program", other, tmp_path / "o.txt"))
    assert run.exit_code == 1 and "--program-format" in run.output


def test_a_target_computed_at_run_time_is_named(
    calibrated: tuple[DHModel, Path], tmp_path: Path
) -> None:
    """A motion to pose_trans(…) and one to a p[…] of expressions: named by line, left as
    written, exit 3; get_inverse_kin's pose and its qnear both corrected."""
    _, result = calibrated
    pose = "p[-0.4, -0.3, 0.25, 3.14159, 0, 0]"
    text = "\n".join(
        [
            "def cell():",
            "  global Waypoint_1_q=[0.37, -1.0, 1.39, 1.2, 1.57, -1.2]",
            f"  global Waypoint_1_p={pose}",
            "  movej(get_inverse_kin(Waypoint_1_p, qnear=Waypoint_1_q), a=1.4, v=1.05)",
            "  movel(pose_trans(Waypoint_1_p, p[0, 0, 0.05, 0, 0, 0]), a=1.2, v=0.25)",
            "  movel(p[x + 0.1, -0.3, 0.25, 3.14159, 0, 0], a=1.2, v=0.25)",
            "end",
            "",
        ]
    )
    path = tmp_path / "cell.urscript"
    path.write_text(text)
    out = tmp_path / "out.urscript"
    run = runner.invoke(app, _args(result, "--program", path, out))
    assert run.exit_code == 3, run.output
    said = " ".join(run.output.split())
    assert "cell.urscript line 5: not corrected: its target 'pose_trans(" in said
    assert "cell.urscript line 6: not corrected:" in said
    assert "computed when the program runs" in said
    before, after = text.splitlines(), out.read_text().splitlines()
    assert before[4:] == after[4:] and before[0] == after[0] and before[3] == after[3]
    assert before[1] != after[1] and before[2] != after[2]  # the pose and its qnear


def test_a_target_not_corrected_is_a_warning(calibrated: tuple[DHModel, Path]) -> None:
    """Through the Python API a target left out (the UR's wrist singularity, q5 = 0) is a
    DhlogWarning and a record of the ``dhlog`` logger, as well as a row of ``problems``."""
    import logging
    import warnings

    import dhlog

    _, result = calibrated
    calibration = dhlog.load(result, nominal="ur5e")
    records: list[logging.LogRecord] = []

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    handler = Keep()
    logging.getLogger("dhlog").addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            done = calibration.compensate([[0.3, -1.2, 1.5, 0.2, 0.0, 0.1], START])
    finally:
        logging.getLogger("dhlog").removeHandler(handler)
    assert list(done.problems) == [0]
    said = [str(w.message) for w in caught if issubclass(w.category, dhlog.DhlogWarning)]
    assert len(said) == 1 and said[0].startswith("target 1 not corrected: too near a singularity")
    assert [r.getMessage() for r in records] == said


def test_pose_csv_units_from_the_header(tmp_path: Path) -> None:
    """x_m, rx_deg and q1_deg … say the units; the output's own header reads back."""
    from dhlog.cell.posecsv import read_pose_table

    path = tmp_path / "p.csv"
    path.write_text(
        "row,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_m,y_m,z_m,rx_deg,ry_deg,rz_deg\n"
        "1,90,0,0,0,45,0,0.1,0.2,0.3,0,0,90\n"
    )
    table = read_pose_table(path, 6, rotation="rotvec")
    assert table.configuration is not None
    assert np.allclose(table.configuration[0], np.radians([90, 0, 0, 0, 45, 0]))
    assert np.allclose(table.poses[0, :3, 3], [0.1, 0.2, 0.3])
    assert np.allclose(table.poses[0, :3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    assert table.lines == [2] and table.names == ("rx", "ry", "rz")
