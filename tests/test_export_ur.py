"""The UR calibration export against Universal Robots' own files: a nominal robot's export equals
ur_description's factory-format ``default_kinematics.yaml`` (tests/data/ur_description, copied
from UniversalRobots/Universal_Robots_ROS2_Description), and the file composed as ur_macro.xacro
composes it reproduces dhlog's forward kinematics of a calibrated robot."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import dhlog
from dhlog.cli.app import app
from dhlog.model.robots import load_robot

runner = CliRunner()
DATA = Path(__file__).parent / "data" / "ur_description"

#: UR5e's published DH (Universal Robots, "DH parameters for calculations of kinematics and
#: dynamics"; the same values as ur_description's config/ur5e/default_kinematics.yaml): d, a, α
UR5E = {
    "d": [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996],
    "a": [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0],
    "alpha": [math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0],
}


def _dh_file(
    path: Path,
    theta: list[float],
    d: list[float],
    a: list[float],
    alpha: list[float],
    tool: list[float],
    T_base: np.ndarray | None = None,
) -> Path:
    rows = [
        {"type": "R", "theta_offset": t, "d_offset": dd, "a": aa, "alpha": al}
        for t, dd, aa, al in zip(theta, d, a, alpha, strict=True)
    ]
    doc: dict[str, Any] = {"standard_dh": rows, "tool": {"point": tool}}
    if T_base is not None:
        doc["base"] = {"T_measurement_base": T_base.tolist()}
    path.write_text(json.dumps(doc))
    return path


def _export(dh: Path, out: Path) -> dict[str, Any]:
    made = runner.invoke(app, ["export", str(dh), "-o", str(out), "--format", "ur"])
    assert made.exit_code == 0, made.output
    return dict(yaml.safe_load(out.read_text())["kinematics"])


def _comment(out: Path, key: str) -> np.ndarray:
    text = out.read_text().split(f"{key}: [")[1].split("]")[0]
    return np.array([float(v) for v in text.split(",")])


def _tcp(out: Path) -> np.ndarray:
    return _comment(out, "tcp")


def _base_link(out: Path) -> np.ndarray:
    """base_link in M: the file's base_link_inertia turned back by π about z."""
    base = _comment(out, "T_measurement_base").reshape(4, 4)
    return base @ np.linalg.inv(_origin([0, 0, 0], [0, 0, np.pi]))


@pytest.mark.parametrize("robot", ["ur5", "ur5e"])
def test_a_nominal_robots_export_is_the_factory_file(robot: str, tmp_path: Path) -> None:
    """Every entry's x, y, z, roll, pitch, yaw equals ur_description's default_kinematics.yaml
    to 1e-9 (m, rad): the factory rounds α to 1.570796327, 2e-10 from π/2, which also puts
    −2e-11 m in wrist_2.z and wrist_3.z; nothing else may differ."""
    if robot == "ur5":
        rob = load_robot("ur5")
        d, a, alpha = list(rob.table.d_offset), list(rob.table.a), list(rob.table.alpha)
    else:
        d, a, alpha = UR5E["d"], UR5E["a"], UR5E["alpha"]
    dh = _dh_file(tmp_path / f"{robot}.json", [0.0] * 6, d, a, alpha, [0.0, 0.0, 0.0])
    got = _export(dh, tmp_path / "k.yaml")
    want = yaml.safe_load((DATA / f"{robot}_default_kinematics.yaml").read_text())["kinematics"]
    assert list(got) == list(want)  # the same entries in the same order, and the hash
    for entry in ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"):
        assert list(got[entry]) == ["x", "y", "z", "roll", "pitch", "yaw"]
        for key, value in want[entry].items():
            assert got[entry][key] == pytest.approx(value, abs=1e-9), (entry, key)
    assert np.abs(_tcp(tmp_path / "k.yaml")).max() < 1e-15  # the flange itself: tool0


def _origin(xyz: list[float], rpy: list[float]) -> np.ndarray:
    """A URDF joint origin: Translation(xyz) · Rz(yaw) Ry(pitch) Rx(roll)."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x, y, z = URDF rpy
    T[:3, 3] = xyz
    return T


def ur_description_tool0(kinematics: dict[str, Any], q: np.ndarray) -> np.ndarray:
    """tool0 in base_link at joint values ``q`` as ur_macro.xacro builds the chain: base_link →
    base_link_inertia (rpy 0 0 π) → per joint its origin (the entry's xyz, rpy) then the
    joint's turn about z → flange (rpy 0 −π/2 −π/2) → tool0 (rpy π/2 0 π/2)."""
    T = _origin([0, 0, 0], [0, 0, np.pi])
    for k, entry in enumerate(
        ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
    ):
        e = kinematics[entry]
        T = T @ _origin([e["x"], e["y"], e["z"]], [e["roll"], e["pitch"], e["yaw"]])
        T = T @ _origin([0, 0, 0], [0, 0, q[k]])
    T = T @ _origin([0, 0, 0], [0, -np.pi / 2, -np.pi / 2])
    return np.asarray(T @ _origin([0, 0, 0], [np.pi / 2, 0, np.pi / 2]))


def test_a_calibrated_ur5e_composed_as_the_description_does_is_dhlogs_fk(tmp_path: Path) -> None:
    """A UR5e off its nominal as a calibration finds it (0.3 mm, 0.03° on every parameter, zero
    offsets on every joint, d2 and d3 ≠ 0, a tool), placed in a tracker's frame: its export,
    composed as the description does, puts the TCP where ``Calibration.fk`` does to 1e-9 m at 200
    random joint vectors, and tool0 where the DH frame 7 is (a6 = α6 = 0). d2 and d3 are moved
    onto d4 by the factory's axis correction: upper_arm.z and forearm.z are 0, as in every factory
    file."""
    rng = np.random.default_rng(7)
    mm, deg = 3e-4, math.radians(0.03)
    theta = list(rng.normal(0, deg, 6))
    d = list(np.array(UR5E["d"]) + rng.normal(0, mm, 6))
    a = list(np.array(UR5E["a"]) + rng.normal(0, mm, 6) * [1, 1, 1, 1, 1, 0])
    alpha = list(np.array(UR5E["alpha"]) + rng.normal(0, deg, 6) * [1, 1, 1, 1, 1, 0])
    tool = [0.012, -0.031, 0.145]
    T_base = _origin([1.2, -0.4, 0.3], [0.1, -0.2, 2.5])
    dh = _dh_file(tmp_path / "ur5e.json", theta, d, a, alpha, tool, T_base)
    out = tmp_path / "ur5e_calibration.yaml"
    kin = _export(dh, out)
    tcp = _tcp(out)
    assert kin["upper_arm"]["z"] == 0 and kin["forearm"]["z"] == 0
    assert kin["shoulder"]["z"] == pytest.approx(d[0], abs=1e-15)
    assert kin["wrist_1"]["x"] < -0.39 and kin["wrist_2"]["y"] < -0.099 and kin["hash"]

    cal = dhlog.load(dh)
    Q = rng.uniform(-2 * np.pi, 2 * np.pi, (200, 6))
    base_link = _base_link(out)
    frames = cal.fk_frames(Q)
    for q, want, frame in zip(Q, cal.fk(Q), frames, strict=True):
        tool0 = base_link @ ur_description_tool0(kin, q)
        assert np.abs((tool0 @ np.r_[tcp, 1.0])[:3] - want).max() < 1e-9
        assert np.abs(tool0[:3, 3] - frame[-1][:3, 3]).max() < 1e-9  # the flange: a6 = 0


def test_a_processed_ur5_exports_in_the_factory_shape_and_its_fk(
    ur5_result: Path, tmp_path: Path
) -> None:
    """The processed result, exported with its nominal (``--nominal ur5``, for the flange's
    d6): every entry within 1 mm and 0.1° of the factory file (the robot is 0.2 mm / 0.02° off
    its nominal; the fit's branch and last-frame convention turned to the factory's), the TCP
    printed is the file's, and the description's composition puts it where ``Calibration.fk``
    does to 1e-9 m at 200 random joint vectors."""
    out = tmp_path / "ur5_calibration.yaml"
    made = runner.invoke(
        app, ["export", str(ur5_result), "-o", str(out), "--format", "ur", "--nominal", "ur5"]
    )
    assert made.exit_code == 0, made.output
    kin = yaml.safe_load(out.read_text())["kinematics"]
    tcp = _tcp(out)
    assert f"{tcp[2] * 1e3:.4f}" in made.output and "nominal's d6" in out.read_text()
    factory = yaml.safe_load((DATA / "ur5_default_kinematics.yaml").read_text())["kinematics"]
    for entry in ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"):
        for key in ("x", "y", "z"):
            assert abs(kin[entry][key] - factory[entry][key]) < 1e-3, (entry, key)
        got = _origin([0, 0, 0], [kin[entry][k] for k in ("roll", "pitch", "yaw")])
        want = _origin([0, 0, 0], [factory[entry][k] for k in ("roll", "pitch", "yaw")])
        turn = np.arccos(np.clip((np.trace(got[:3, :3].T @ want[:3, :3]) - 1) / 2, -1, 1))
        assert np.degrees(turn) < 0.1, entry
        for key in ("roll", "pitch", "yaw"):  # the factory's branch of the angles, too
            assert abs(kin[entry][key] - factory[entry][key]) < math.radians(0.1), (entry, key)
    rob = load_robot("ur5")
    assert np.abs(tcp - rob.tool_point).max() < 1e-3  # the simulated tool, in tool0

    cal = dhlog.load(ur5_result)
    Q = np.random.default_rng(4).uniform(rob.limits[:, 0], rob.limits[:, 1], (200, 6))
    base_link = _base_link(out)
    for q, want in zip(Q, cal.fk(Q), strict=True):
        tool0 = base_link @ ur_description_tool0(kin, q)
        assert np.abs((tool0 @ np.r_[tcp, 1.0])[:3] - want).max() < 1e-9


#: UR10e's nominal and a real UR10e's controller calibration (its calibration.conf deltas), as
#: in ur_calibration's own test (Universal_Robots_ROS2_Driver, ur_calibration/test/
#: calibration_test.cpp at 696e1a7): the factory's raw table puts joint 3's origin 439 m out
#: along axis 2, which the factory's axis correction brings back.
UR10E = {
    "d": [0.1807, 0, 0, 0.17415, 0.11985, 0.11655],
    "a": [0, -0.6127, -0.57155, 0, 0, 0],
    "alpha": [1.570796327, 0, 0, 1.570796327, -1.570796327, 0],
}
UR10E_DELTA = {
    "d": [
        -0.000160188285741325043,
        439.140974079900957,
        -446.027059806332147,
        6.88618689642360149,
        -3.86588496858186748e-05,
        -0.00087908274257374186,
    ],
    "a": [
        2.12234865571205891e-05,
        0.632017132627700651,
        0.00229833638891230319,
        -4.61409023720933908e-05,
        -6.39280053471801522e-05,
        0,
    ],
    "theta": [
        -2.41478068943590252e-07,
        1.60233952386694556,
        -1.68607190752171299,
        0.0837331147700118711,
        -1.01260355871157781e-07,
        3.91986209186123702e-08,
    ],
    "alpha": [
        -0.000650246557584166496,
        0.00139416666825590402,
        0.00693818880325995126,
        -0.000811641562390219562,
        0.000411120504570705592,
        0,
    ],
}


def test_a_real_ur10e_factory_table_exported_as_the_factory_corrects_it(tmp_path: Path) -> None:
    """A real UR10e's raw factory table (nominal + its controller's deltas; d2 = 439 m, d3 =
    −446 m) as a DH file: the export moves d2 and d3 onto d4 (upper_arm.z = forearm.z = 0), every
    entry lands within 5 mm and 0.5° of the UR10e's nominal entries, and composed as the
    description does it is the raw table's FK to 1e-9 m (the factory's own test asks 1e-12 at
    FK ~1 m; 1e-9 leaves room for the 446 m lever arms' rounding)."""
    theta = UR10E_DELTA["theta"]
    d, a, alpha = (list(np.add(UR10E[k], UR10E_DELTA[k])) for k in ("d", "a", "alpha"))
    dh = _dh_file(tmp_path / "ur10e_raw.json", theta, d, a, alpha, [0.0, 0.0, 0.05])
    out = tmp_path / "ur10e.yaml"
    kin = _export(dh, out)
    nominal = _export(
        _dh_file(
            tmp_path / "ur10e.json",
            [0.0] * 6,
            UR10E["d"],
            UR10E["a"],
            UR10E["alpha"],
            [0.0, 0.0, 0.0],
        ),
        tmp_path / "ur10e_nominal.yaml",
    )
    assert kin["upper_arm"]["z"] == 0 and kin["forearm"]["z"] == 0
    for entry in ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"):
        for key in ("x", "y", "z"):
            assert abs(kin[entry][key] - nominal[entry][key]) < 5e-3, (entry, key)
        for key in ("roll", "pitch", "yaw"):
            assert abs(kin[entry][key] - nominal[entry][key]) < math.radians(0.5), (entry, key)
    cal = dhlog.load(dh)
    Q = np.random.default_rng(11).uniform(-2 * np.pi, 2 * np.pi, (200, 6))
    base_link = _base_link(out)
    tcp = _tcp(out)
    for q, want in zip(Q, cal.fk(Q), strict=True):
        tool0 = base_link @ ur_description_tool0(kin, q)
        assert np.abs((tool0 @ np.r_[tcp, 1.0])[:3] - want).max() < 1e-9


def test_the_nominal_for_the_flange_is_checked_and_reaches_the_api(
    ur5_result: Path, tmp_path: Path
) -> None:
    """``--nominal`` with a robot that is not six-jointed is one line and exit 2; the Python
    API's export takes the loaded nominal's d6 as the command does."""
    made = runner.invoke(
        app,
        [
            "export",
            str(ur5_result),
            "-o",
            str(tmp_path / "u.yaml"),
            "--format",
            "ur",
            "--nominal",
            "scara",
        ],
    )
    assert made.exit_code == 2 and "a UR has six" in made.output
    assert not (tmp_path / "u.yaml").exists()
    with_nominal = dhlog.load(ur5_result, nominal="ur5").export("ur")
    assert "nominal's d6 = 0.0823 m" in with_nominal
    without = yaml.safe_load(dhlog.load(ur5_result).export("ur"))["kinematics"]
    assert abs(without["wrist_3"]["y"]) < 1e-12  # the result's own d6: the target's foot
    assert yaml.safe_load(with_nominal)["kinematics"]["wrist_3"]["y"] == pytest.approx(0.0823)
