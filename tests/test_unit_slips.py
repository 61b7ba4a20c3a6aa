"""No silent unit slip (issue 31, item 4): a UR10-style export — ``;``-separated, decimal
commas, ``measurement_x … measurement_z`` in mm, ``measurement_rx … measurement_rz`` in degrees
(the flange's orientation, rotation angles about the fixed axes x, y, z as ``--euler`` reads by
default), ``measurement_std_*`` beside them, joints ``shoulder_pan_joint … wrist_3_joint`` in
radians and a temperature — written from a UR5 off its nominal at random poses through dhlog's
own FK. Imported with the one option a user cannot avoid (``--joint-angle-unit rad``), or none
when the header states the joints' unit, the σ columns become each sample's covariance; each
slip (joints read as degrees, the orientation read as radians while in degrees or the reverse)
is refused naming the option that fixes it; ``dhlog process`` warns on a log whose joints were
written in the wrong unit, and not on the right one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.cli.common import EXIT_IMPLAUSIBLE
from dhlog.io.decode.frames import COVARIANCE_COLUMNS, ORIENTATION_COLUMNS
from dhlog.io.exports.slips import joint_unit_slip, orientation_unit_slip
from dhlog.io.importer import STOP_JOINT_TIMES
from dhlog.io.reader import read_log
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot

runner = CliRunner()
POSES = 200
NOISE_MM = 0.03  # the tracker's σ per coordinate, as the export's std columns say
UR_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
)


def session(seed: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A UR5 off its nominal (0.5 mm, 0.05°) at ``POSES`` random poses, the tracker 2 m away:
    joint values (rad), probe positions (mm, with the tracker's noise) and the flange's
    orientation as rotation angles about the fixed axes x, y, z (deg)."""
    rng = np.random.default_rng(seed)
    robot = load_robot("ur5")
    t = robot.table
    true = StandardDH(
        t.joint_types,
        t.theta_offset + rng.normal(0, math.radians(0.05), 6),
        t.d_offset + rng.normal(0, 5e-4, 6),
        t.a + rng.normal(0, 5e-4, 6),
        t.alpha + rng.normal(0, math.radians(0.05), 6),
    )
    q = rng.uniform(-math.pi, math.pi, (POSES, 6))
    q[:, 1] = rng.uniform(-2.5, -0.6, POSES)
    q[:, 2] = rng.uniform(-2.4, 2.4, POSES)
    T_base = np.eye(4)
    T_base[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    T_base[:3, 3] = [2.0, 0.5, -0.3]
    last = fk_frames(true, q, T_base=T_base @ robot.T_base)[:, -1]
    xyz = last[:, :3, :3] @ robot.tool_point + last[:, :3, 3]
    xyz = xyz * 1e3 + rng.normal(0, NOISE_MM, xyz.shape)
    angles = Rotation.from_matrix(last[:, :3, :3]).as_euler("xyz", degrees=True)
    return q, xyz, angles


def write_export(
    path: Path,
    q: np.ndarray,
    xyz: np.ndarray,
    angles: np.ndarray,
    *,
    joint_unit: str = "",
) -> Path:
    """The UR10 layout: ``;``, decimal commas, ``measurement_*``, ``*_std_*``, the UR joint
    names (``joint_unit``: a unit in their headers, e.g. ``" [rad]"``), a temperature."""
    head = [f"measurement_{a}" for a in ("x", "y", "z", "rx", "ry", "rz")]
    head += [f"measurement_std_{a}" for a in ("x", "y", "z", "rx", "ry", "rz")]
    head += [f"{name}{joint_unit}" for name in UR_JOINTS] + ["temperature"]
    lines = [";".join(head)]
    for k in range(q.shape[0]):
        cells = [f"{v:.4f}" for v in xyz[k]] + [f"{v:.6f}" for v in angles[k]]
        cells += [f"{NOISE_MM:.4f}"] * 3 + ["0.0050"] * 3
        cells += [f"{v:.8f}" for v in q[k]] + [f"{21.3 + 0.01 * k:.2f}"]
        lines.append(";".join(c.replace(".", ",") for c in cells))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def measured() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return session()


def imported(*args: str) -> tuple[int, str]:
    result = runner.invoke(app, ["import", *args])
    return result.exit_code, result.output


def test_the_ur10_layout_imports_with_the_joints_unit_only(
    measured: tuple[np.ndarray, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """``--joint-angle-unit rad`` and nothing else: ``;`` and decimal commas found, the
    measurement_* triple as the position and the orientation, the UR joints in chain order,
    the std columns as each sample's σ (the orientation's named as left out), the temperature
    ignored; read back, positions, orientation and joints as written."""
    q, xyz, angles = measured
    src = write_export(tmp_path / "ur10.csv", q, xyz, angles)
    code, out = imported(str(src), "--joint-angle-unit", "rad", "-o", str(tmp_path / "a.mcap"))
    assert code == 0, out
    assert "measurement_x, measurement_y, measurement_z" in out
    assert "with per-point σ as covariance" in out
    assert "measurement_std_rx, measurement_std_ry, measurement_std_rz were left out" in out
    log = read_log(tmp_path / "a.mcap")
    assert log.pipeline.streams["point"].orientation
    pts = log.points
    written = pts.select(["x", "y", "z"]).to_numpy() * 1e3
    np.testing.assert_allclose(written, xyz, rtol=0, atol=5.1e-5)  # the 4 decimals written
    cov = pts.select(list(COVARIANCE_COLUMNS)).to_numpy()
    np.testing.assert_allclose(cov[:, [0, 3, 5]], (NOISE_MM * 1e-3) ** 2, rtol=1e-9)
    np.testing.assert_allclose(cov[:, [1, 2, 4]], 0.0)
    quat = pts.select(list(ORIENTATION_COLUMNS)).to_numpy()
    back = Rotation.from_quat(quat).as_euler("xyz", degrees=True)
    turned = Rotation.from_euler("xyz", back, degrees=True).inv() * Rotation.from_euler(
        "xyz", angles, degrees=True
    )
    assert np.max(turned.magnitude()) < 1e-7  # the 6 decimals written
    assert log.joints is not None
    assert list(log.joints.columns[1:7]) == [f"q_{k}" for k in range(1, 7)]
    stored = log.joints.select([f"q_{k}" for k in range(1, 7)]).to_numpy()
    np.testing.assert_allclose(stored[:: len(STOP_JOINT_TIMES)], q, atol=1e-8)


def test_a_unit_in_the_joints_headers_needs_no_option(
    measured: tuple[np.ndarray, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """Headers first: ``shoulder_pan_joint [rad]`` imports with no option at all; the
    orientation stays in the default degrees."""
    q, xyz, angles = measured
    src = write_export(tmp_path / "ur10.csv", q, xyz, angles, joint_unit=" [rad]")
    code, out = imported(str(src), "-o", str(tmp_path / "a.mcap"))
    assert code == 0, out
    log = read_log(tmp_path / "a.mcap")
    assert log.joints is not None
    stored = log.joints.select([f"q_{k}" for k in range(1, 7)]).to_numpy()
    np.testing.assert_allclose(stored[:: len(STOP_JOINT_TIMES)], q, atol=1e-8)


@pytest.mark.parametrize(
    ("options", "says"),
    [
        ([], "give --joint-angle-unit rad"),  # the joints' radians read as degrees
        (["--angle-unit", "rad"], "--angle-unit deg"),  # one unit for both: degrees as radians
    ],
)
def test_each_slip_is_refused_naming_the_option(
    measured: tuple[np.ndarray, np.ndarray, np.ndarray],
    tmp_path: Path,
    options: list[str],
    says: str,
) -> None:
    q, xyz, angles = measured
    src = write_export(tmp_path / "ur10.csv", q, xyz, angles)
    code, out = imported(str(src), *options, "-o", str(tmp_path / "a.mcap"))
    assert code == 2, out
    assert says in out and len(out.strip().splitlines()) == 1
    assert not (tmp_path / "a.mcap").exists()


def test_an_orientation_in_radians_read_as_degrees_is_refused(
    measured: tuple[np.ndarray, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """The probe turned by a 57th of what the joints turn: refused, naming --angle-unit rad;
    with --angle-unit rad it imports."""
    q, xyz, angles = measured
    src = write_export(tmp_path / "ur10.csv", q, xyz, np.radians(angles))
    code, out = imported(str(src), "--joint-angle-unit", "rad", "-o", str(tmp_path / "a.mcap"))
    assert code == 2, out
    assert "look like radians" in out and "--angle-unit rad" in out
    code, out = imported(
        str(src), "--joint-angle-unit", "rad", "--angle-unit", "rad", "-o", str(tmp_path / "b.mcap")
    )
    assert code == 0, out


def test_the_statistics_on_their_own(measured: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    """Where the range alone cannot tell: a probe turned by joint 1 alone from −5° to +5°
    (timed samples along the path; so its degrees read as radians stay within a turn) is
    caught by the bound θ ≤ Σ|Δq| between neighbouring poses; the right unit is not; a unit
    the header (or the joints' own option) states gives a warning, not a refusal. The joints'
    range: radians read as degrees refused, degrees read as radians too."""
    q, _, _ = measured
    rng = np.random.default_rng(9)
    path = np.repeat(q[:1], 200, axis=0)
    path[:, 0] = np.radians(np.linspace(-5.0, 5.0, 200))
    angles = np.zeros((200, 3)) + rng.normal(0, 0.005, (200, 3))  # degrees
    angles[:, 2] += np.degrees(path[:, 0])
    for unit, slipped in (("deg", False), ("rad", True)):
        read = Rotation.from_euler("xyz", angles, degrees=unit == "deg").as_quat()
        slip = orientation_unit_slip("rx, ry, rz", angles, unit, "the default", read, path)
        assert (slip is not None) == slipped, slip
        if slip is not None:
            assert slip[1] and "--angle-unit deg" in slip[0] and "neighbouring poses" in slip[0]
    read = Rotation.from_euler("xyz", angles, degrees=False).as_quat()
    slip = orientation_unit_slip("rx, ry, rz", angles, "rad", "the header", read, path)
    assert slip is not None and not slip[1] and "--angle-unit deg" in slip[0]
    # joints: radians read as degrees, refused by default, warned when the header says so
    slip = joint_unit_slip(list(UR_JOINTS), q, "deg", "the default")
    assert slip is not None and slip[1]
    slip = joint_unit_slip(list(UR_JOINTS), q, "deg", "the header")
    assert slip is not None and not slip[1]
    assert joint_unit_slip(list(UR_JOINTS), q, "deg", "--joint-angle-unit") is None
    assert joint_unit_slip(list(UR_JOINTS), np.degrees(q), "deg", "the default") is None
    # a UR's joints run ±2π rad: a wrist at -3.5 rad is radians all the same
    wide = q.copy()
    wide[:, 5] = np.linspace(-3.5, 4.0, q.shape[0])
    slip = joint_unit_slip(list(UR_JOINTS), wide, "deg", "the default")
    assert slip is not None and slip[1] and "--joint-angle-unit rad" in slip[0]
    # degrees read as radians: beyond a turn
    slip = joint_unit_slip(list(UR_JOINTS), np.degrees(q), "rad", "--angle-unit")
    assert slip is not None and slip[1] and "--joint-angle-unit deg" in slip[0]
    assert joint_unit_slip(list(UR_JOINTS), q, "rad", "--angle-unit") is None


def test_process_warns_on_a_log_read_in_the_wrong_unit(
    measured: tuple[np.ndarray, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """The joints' radians forced through as degrees (``--joint-angle-unit deg``: said, so the
    import lets it pass): the calibrated model misses the points by half a metre, as the nominal
    does, so ``dhlog process`` writes the result marked implausible, its last line names the
    joints' unit, and it exits 4; the same export read right is plausible, exit 0 (its FK RMS ≈
    √3 · 0.03 mm)."""
    import json

    q, xyz, angles = measured
    src = write_export(tmp_path / "ur10.csv", q, xyz, angles)
    for unit, slipped in (("deg", True), ("rad", False)):
        log = tmp_path / f"{unit}.mcap"
        code, out = imported(str(src), "--joint-angle-unit", unit, "-o", str(log))
        assert code == 0, out
        args = ["process", str(log), "--nominal", "ur5", "--model", "geometric", "--no-rrd"]
        done = runner.invoke(app, [*args, "--out", str(tmp_path / unit)])
        assert done.exit_code == (EXIT_IMPLAUSIBLE if slipped else 0), done.output
        text = " ".join(done.output.split())
        assert ("the inputs are likely read wrong" in text) == slipped, text
        doc = json.loads((tmp_path / unit / f"{unit}.dh.json").read_text())
        assert doc["plausible"] is not slipped and bool(doc["implausible"]) == slipped
        if slipped:
            last = done.output.strip().splitlines()[-1]
            assert last.startswith("implausible result: the calibrated model misses its points")
            assert "--joint-angle-unit" in last and "exit 4" in last
            assert "more than any robot's nominal does" in doc["implausible"][0]


def test_the_process_side_thresholds() -> None:
    """Hand-computed cases of the FK check against the noise and the nominal's own miss
    (identify/check/plausible.py). Plausible, no warning: a heavy robot's nominal 8 mm off and
    its calibration 0.5 mm (the FANUC R-2000iC of ../shared/realdata); issue 39's geometric run,
    2.1 mm FK on a robot whose nominal misses by 3.2 mm (a fixed 2 mm would call it a slip).
    Implausible, naming the slips: 8 mm FK there (2.5 times the nominal's miss), 25 mm without
    a nominal. A warning alone: a calibration 2.5 mm off without a nominal to compare with, a
    model-error σ of 1.2 mm beyond a nominal's 1 mm, a nominal 25 mm off."""
    from dhlog.identify.check.plausible import fk_beyond, slip_notes

    noise = math.sqrt(3.0) * 0.01e-3
    for fk, miss in ((5e-4, 8e-3), (2.1e-3, 3.2e-3), (5e-5, None)):
        assert fk_beyond(fk, noise, miss) is None
        assert slip_notes(miss, fk, 3e-4, False) == []
    said = fk_beyond(8e-3, noise, 3.2e-3)
    assert said is not None and "2.5 times the nominal's own miss (3.20 mm)" in said, said
    assert "joints in the wrong order or of the wrong sign" in said
    said = fk_beyond(25e-3, noise, None)
    assert said is not None and "more than any robot's nominal misses its points by" in said
    assert fk_beyond(8e-3, 1e-3, 3.2e-3) is None  # within 10 times a noise of 1 mm
    for miss, fk, model_error in ((None, 2.5e-3, None), (1e-3, 5e-4, 1.2e-3), (25e-3, 5e-4, None)):
        notes = slip_notes(miss, fk, model_error, False)
        assert len(notes) == 1 and "joints in the wrong order or of the wrong sign" in notes[0]
        assert slip_notes(miss, fk, model_error, True) == []  # an implausible result says it


def test_lengths_all_k_times_the_nominals_name_the_unit() -> None:
    """A table whose lengths are all k times the nominal's (σ-sized errors on top) is
    implausible, k's units named (1000: mm read as m; 1/25.4: inches read as mm); 1.3 times
    names the nominal of another robot; 1.01 times (a robot off its nominal by 1 %), lengths
    that disagree and lengths of the other sign (a DH branch) are not judged."""
    from dhlog.identify.check.plausible import length_slip
    from dhlog.io.dhfile import DHModel

    ur5 = load_robot("ur5").table
    nominal = DHModel(ur5, np.eye(4), np.zeros(3), UR_JOINTS, "ur5")
    rng = np.random.default_rng(2)

    def scaled(k: float, spread: float = 1e-4) -> StandardDH:
        return StandardDH(
            ur5.joint_types,
            ur5.theta_offset,
            k * ur5.d_offset + rng.normal(0, spread, 6),
            k * ur5.a + rng.normal(0, spread, 6),
            ur5.alpha,
        )

    for k, says in ((1000.0, "mm read as m"), (1 / 25.4, "inches read as mm")):
        said = length_slip(scaled(k), nominal, set())
        assert said is not None and says in said and "length_unit" in said, said
    said = length_slip(scaled(1.3), nominal, set())
    assert said is not None and "another robot" in said, said
    assert length_slip(scaled(1.01), nominal, set()) is None
    assert length_slip(scaled(1.0, spread=0.2), nominal, set()) is None
    # a length's sign is a DH branch (a2 = +425 mm on the other branch of the line), no slip
    flipped = scaled(1.0)
    flipped = StandardDH(
        flipped.joint_types, flipped.theta_offset, flipped.d_offset, -flipped.a, flipped.alpha
    )
    assert length_slip(flipped, nominal, set()) is None
    slipped = scaled(1000.0)
    slipped = StandardDH(
        slipped.joint_types, slipped.theta_offset, slipped.d_offset, -slipped.a, slipped.alpha
    )
    said = length_slip(slipped, nominal, set())
    assert said is not None and "mm read as m" in said


def test_a_spherical_pipeline_on_cartesian_points_is_one_line(tmp_path: Path) -> None:
    """The hostile run of issue 31: ``coordinates = "spherical"`` under the point stream of the
    shipped ROS 2 pipeline, on a log of PointStamped (x, y, z): a TypeError in
    ``io/decode/frames.py`` before; now exit 2 and one line naming the stream, the topic and
    what to do."""
    root = Path(__file__).parents[1]
    shipped = (root / "pipelines" / "ros2_tracker.toml").read_text()
    spherical = shipped.replace(
        'topic = "/tracker/point"\n', 'topic = "/tracker/point"\ncoordinates = "spherical"\n', 1
    )
    assert spherical != shipped
    (tmp_path / "sph.toml").write_text(spherical)
    args = ["process", str(root / "sample_logs" / "kr5_0.1mm.mcap"), "--no-rrd"]
    done = runner.invoke(
        app, [*args, "--pipeline", str(tmp_path / "sph.toml"), "--out", str(tmp_path)]
    )
    assert done.exit_code == 2, done.output
    assert len(done.output.strip().splitlines()) == 1 and "Traceback" not in done.output
    assert "[streams.point]" in done.output and "/tracker/point" in done.output
    assert "leave coordinates out" in " ".join(done.output.split())
