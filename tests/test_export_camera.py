"""A camera calibration's hand-eye product in the exports (issue 32, item 4): the URDF's fixed
camera and board links checked through yourdfpy's forward kinematics against the result's own
poses and forward kinematics, and the ROS 2 static transforms (``--format tf``) read back the
way tf2_ros's static_transform_publisher reads its arguments.

The results are real: ``process_observations`` on corners projected through the simulator's rig
(a KR5 off its nominal, the small camera, 0.2 px noise), as tests/test_camera_calibration.py
makes them, written with ``result_document``."""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
import yourdfpy
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import camera_rig as cams
from dhlog.cli.app import app
from dhlog.identify.camera.flow import process_observations
from dhlog.identify.options import ProcessOptions
from dhlog.identify.run import process_poses
from dhlog.io.dhfile import DHModel, load_dh
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot
from dhlog.result.document import result_document
from dhlog.result.export.camera import T_LINK_OPTICAL, frame_name
from dhlog.simulator.camera import camera_poses, place_rig
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.robot import perturbed

runner = CliRunner()
#: The URDF's numbers are written with 17 digits; composing a 9-link chain loses ~1e-15.
EXACT = 1e-9

# ---------------------------------------------------------------------------------------------
# a real camera result (tests/camera_rig.py's corners)


def _result(setup: str, folder: Path) -> Path:
    robot = load_robot("kr5")
    cfg = SimulationConfig(perturb_length=2e-4, perturb_angle=math.radians(0.05))
    true = perturbed(robot.table, np.random.default_rng(6), cfg)
    rig = place_rig(robot, true, setup, 6)  # type: ignore[arg-type]
    Q = camera_poses(robot, true, rig, 30, 6)
    ids, uv = cams.corners(rig, true, robot, Q, np.random.default_rng(9))
    obs = cams.observations(robot, Q, ids, uv)
    nominal = DHModel(robot.table, np.eye(4), np.zeros(3), tuple(obs.joint_names), "library")
    result = process_observations(
        [obs], ProcessOptions(nominal=nominal, camera_setup=setup), start=process_poses
    )
    path = folder / f"{setup}.dh.json"
    path.write_text(json.dumps(result_document(result), allow_nan=False))
    return path


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("camera_results")
    return {setup: _result(setup, folder) for setup in ("eye-to-hand", "eye-in-hand")}


def _export(result: Path, fmt: str, out: Path, *extra: str) -> Any:
    return runner.invoke(app, ["export", str(result), "-o", str(out), "--format", fmt, *extra])


def _urdf(result: Path, out: Path, *extra: str) -> yourdfpy.URDF:
    made = _export(result, "urdf", out, *extra)
    assert made.exit_code == 0, made.output
    return yourdfpy.URDF.load(str(out), load_meshes=False, build_scene_graph=True)


def _pose(doc: dict[str, Any], name: str) -> np.ndarray:
    return np.array(doc["camera"][name], dtype=np.float64)


def _joint_vectors(n: int, count: int = 20) -> np.ndarray:
    rob = load_robot("kr5")
    return np.random.default_rng(3).uniform(rob.limits[:, 0], rob.limits[:, 1], (count, n))


# ---------------------------------------------------------------------------------------------
# the URDF


def test_eye_to_hand_camera_in_the_urdf(results: dict[str, Path], tmp_path: Path) -> None:
    """The camera's optical frame in base_link is T_base_camera (to 1e-9) at zero joints and at
    random ones (it is fixed to the base); it is the URDF's measurement frame too (M is the
    camera eye-to-hand, the base placed by T_measurement_base); camera_link is the same origin
    with x along the optical axis; the board on the flange is T_flange_board, and the board as
    the camera sees it at random joint vectors is the result's chain between them."""
    result = results["eye-to-hand"]
    doc = json.loads(result.read_text())
    model = _urdf(result, tmp_path / "robot.urdf")
    T_base_camera = _pose(doc, "T_base_camera")
    T_flange_board = _pose(doc, "T_flange_board")
    n = len(doc["standard_dh"])
    model.update_cfg(np.zeros(n))
    got = model.get_transform("camera_optical_frame", "base_link")
    assert np.abs(got - T_base_camera).max() < EXACT
    # the same frame reached through the DH base: measurement → base_link is T_measurement_base
    got_m = model.get_transform("camera_optical_frame", "measurement")
    assert np.abs(got_m - np.eye(4)).max() < 1e-9, got_m
    link = model.get_transform("camera_link", "base_link")
    assert np.abs(link[:3, 3] - T_base_camera[:3, 3]).max() < EXACT
    assert np.abs(link[:3, 0] - T_base_camera[:3, 2]).max() < EXACT  # x forward = optical z
    assert np.abs(link[:3, 1] + T_base_camera[:3, 0]).max() < EXACT  # y left = −optical x
    dh = load_dh(result)
    for q in _joint_vectors(n):
        model.update_cfg(q)
        got = model.get_transform("camera_optical_frame", "base_link")
        assert np.abs(got - T_base_camera).max() < EXACT
        flange = fk_frames(dh.table, q)[-1]
        want = np.linalg.inv(T_base_camera) @ flange @ T_flange_board
        seen = model.get_transform("calibration_board", "camera_optical_frame")
        assert np.abs(seen - want).max() < EXACT
    # the link names follow ROS: the camera's, its optical frame's, the board's
    assert {"camera_link", "camera_optical_frame", "calibration_board"} <= set(model.link_map)
    assert model.joint_map["camera_joint"].parent == "base_link"
    assert model.joint_map["calibration_board_joint"].parent == "flange"


@pytest.mark.parametrize("zero_offsets", ["origins", "calibration"])
def test_eye_in_hand_camera_in_the_urdf(
    results: dict[str, Path], tmp_path: Path, zero_offsets: str
) -> None:
    """The camera on the flange: at random joint vectors the optical frame from the URDF's chain
    is the result's FK of the flange (its standard table, not the URDF's Hayati rows) times
    T_flange_camera, to 1e-9; the board fixed in base_link is T_base_board, turned as the
    measurement frame (M is the board's centred frame eye-in-hand). With --zero-offsets
    calibration the joints stand at encoder + rising."""
    result = results["eye-in-hand"]
    doc = json.loads(result.read_text())
    model = _urdf(result, tmp_path / "robot.urdf", "--zero-offsets", zero_offsets)
    T_flange_camera = _pose(doc, "T_flange_camera")
    T_base_board = _pose(doc, "T_base_board")
    dh = load_dh(result)
    n = dh.table.n
    rising = np.zeros(n)
    if zero_offsets == "calibration":
        rising = np.array([j.calibration.rising for j in model.actuated_joints])
    assert model.joint_map["camera_joint"].parent == "flange"
    for q in [np.zeros(n), *_joint_vectors(n)]:
        model.update_cfg(q + rising)
        want = fk_frames(dh.table, q)[-1] @ T_flange_camera
        got = model.get_transform("camera_optical_frame", "base_link")
        assert np.abs(got - want).max() < EXACT, (q, got - want)
        board = model.get_transform("calibration_board", "base_link")
        assert np.abs(board - T_base_board).max() < EXACT
    measurement = model.get_transform("measurement", "base_link")
    assert np.abs(measurement[:3, :3] - T_base_board[:3, :3]).max() < 1e-9


def test_a_tracker_result_gets_no_camera_links(tmp_path: Path) -> None:
    """A result without a camera block: the URDF as before (its links only), and --format tf
    the robot's frames only (tests/test_export_xacro.py checks them), no camera's."""
    sample = Path(__file__).parents[1] / "sample_logs" / "kr5_0.01mm.truth.json"
    model = _urdf(sample, tmp_path / "robot.urdf")
    assert not [k for k in model.link_map if "camera" in k or "board" in k]
    out = tmp_path / "tf.launch.yaml"
    made = _export(sample, "tf", out)
    assert made.exit_code == 0, made.output
    assert "camera" not in out.read_text() and "--child-frame-id measurement" in out.read_text()


def _kr5_template(folder: Path) -> Path:
    """A KR5 URDF as a robot description lays it out for the template: dhlog's own URDF of the
    nominal (joints named as the camera results' joint_1 … joint_6)."""
    t = load_robot("kr5").table
    rows = [
        {
            "type": t.joint_types[i].value,
            "theta_offset": float(t.theta_offset[i]),
            "d": float(t.d_offset[i]),
            "a": float(t.a[i]),
            "alpha": float(t.alpha[i]),
        }
        for i in range(t.n)
    ]
    dh = folder / "kr5_nominal.json"
    names = [{"name": f"joint_{i + 1}"} for i in range(t.n)]
    dh.write_text(json.dumps({"standard_dh": rows, "joints": names}))
    template = folder / "kr5.urdf"
    made = _export(dh, "urdf", template)
    assert made.exit_code == 0, made.output
    return template


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
def test_a_template_gets_the_camera_and_the_board(
    results: dict[str, Path], tmp_path: Path, setup: str
) -> None:
    """--template: dhlog_camera_optical_frame and dhlog_calibration_board in dhlog_measurement
    at zero and 20 random joint vectors are the result's T_measurement_base times its pose in
    the base, or times the FK of the flange and its pose on the flange, to 1e-9; a template
    that already has dhlog_camera_link is one line."""
    result = results[setup]
    doc = json.loads(result.read_text())
    template = _kr5_template(tmp_path)
    model = _urdf(result, tmp_path / "calibrated.urdf", "--template", str(template))
    dh = load_dh(result)
    n = dh.table.n
    placed = {
        "dhlog_camera_optical_frame": "T_base_camera"
        if setup == "eye-to-hand"
        else "T_flange_camera",
        "dhlog_calibration_board": "T_flange_board" if setup == "eye-to-hand" else "T_base_board",
    }
    for q in [np.zeros(n), *_joint_vectors(n)]:
        model.update_cfg(q)
        flange = fk_frames(dh.table, q)[-1]
        for link, field in placed.items():
            in_base = (
                _pose(doc, field) if field.startswith("T_base") else flange @ _pose(doc, field)
            )
            got = model.get_transform(link, "dhlog_measurement")
            assert np.abs(got - dh.T_base @ in_base).max() < EXACT, (link, q)
    clash = tmp_path / "clash.urdf"
    clash.write_text(template.read_text().replace('"tool0"', '"dhlog_camera_link"'))
    made = _export(result, "urdf", tmp_path / "x.urdf", "--template", str(clash))
    lines = [line for line in made.output.splitlines() if line.strip()]
    assert made.exit_code == 2 and len(lines) == 1, made.output
    assert "already has a link dhlog_camera_link" in lines[0]


# ---------------------------------------------------------------------------------------------
# the static transforms


def _published(text: str) -> dict[str, tuple[str, np.ndarray]]:
    """The launch file's static_transform_publisher nodes: child → (parent, 4×4), read as
    tf2_ros reads the arguments (--x … --qw, --frame-id, --child-frame-id)."""
    doc = yaml.safe_load(text)
    out = {}
    for entry in doc["launch"]:
        node = entry["node"]
        assert (node["pkg"], node["exec"]) == ("tf2_ros", "static_transform_publisher")
        words = node["args"].split()
        args = dict(zip(words[::2], words[1::2], strict=True))
        assert set(args) == {"--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw"} | {
            "--frame-id",
            "--child-frame-id",
        }
        q = [float(args[k]) for k in ("--qx", "--qy", "--qz", "--qw")]
        assert abs(np.linalg.norm(q) - 1.0) < 1e-12
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(q).as_matrix()
        T[:3, 3] = [float(args[k]) for k in ("--x", "--y", "--z")]
        out[args["--child-frame-id"]] = (args["--frame-id"], T)
    return out


@pytest.mark.parametrize("setup", ["eye-to-hand", "eye-in-hand"])
def test_the_static_transforms_are_the_results_poses(
    results: dict[str, Path], tmp_path: Path, setup: str
) -> None:
    """--format tf: a ROS 2 launch file whose nodes compose, parent → camera_link →
    camera_optical_frame, to the result's 4×4 (quaternion round trip to 1e-12), the board's the
    same; the σ of each pose is in a comment (mm and degrees, as the JSON's in m and rad); the
    same frames and poses as the URDF's."""
    result = results[setup]
    doc = json.loads(result.read_text())
    out = tmp_path / "camera_tf.launch.yaml"
    made = _export(result, "tf", out)
    assert made.exit_code == 0, made.output
    text = out.read_text()
    tf = _published(text)
    camera, board, parent, board_parent = (
        ("T_base_camera", "T_flange_board", "base_link", "flange")
        if setup == "eye-to-hand"
        else ("T_flange_camera", "T_base_board", "flange", "base_link")
    )
    assert tf["camera_link"][0] == parent and tf["camera_optical_frame"][0] == "camera_link"
    composed = tf["camera_link"][1] @ tf["camera_optical_frame"][1]
    assert np.abs(composed - _pose(doc, camera)).max() < 1e-12
    assert np.abs(tf["camera_optical_frame"][1] - T_LINK_OPTICAL).max() < 1e-15
    assert tf["calibration_board"][0] == board_parent
    assert np.abs(tf["calibration_board"][1] - _pose(doc, board)).max() < 1e-12
    std = doc["camera"][f"{camera}_std"]
    mm = " ".join(f"{v * 1e3:.4f}" for v in std["translation_m"])
    deg = " ".join(f"{math.degrees(v):.5f}" for v in std["rotation_rad"])
    assert f"σ translation x y z {mm} mm, rotation about {parent}'s x y z {deg}°" in text
    # the direct parent → optical frame command in the comment is the same pose
    direct = next(line for line in text.splitlines() if "directly: ros2 run" in line)
    words = direct.split("static_transform_publisher ")[1].split()
    args = dict(zip(words[::2], words[1::2], strict=True))
    assert args["--frame-id"] == parent and args["--child-frame-id"] == "camera_optical_frame"
    R = Rotation.from_quat([float(args[k]) for k in ("--qx", "--qy", "--qz", "--qw")])
    assert np.abs(R.as_matrix() - _pose(doc, camera)[:3, :3]).max() < 1e-12
    # the URDF places the same frames where the launch file does
    model = _urdf(result, tmp_path / "robot.urdf")
    model.update_cfg(np.zeros(len(doc["standard_dh"])))
    for child, (frame, T) in tf.items():
        assert np.abs(model.get_transform(child, frame) - T).max() < EXACT


def test_several_cameras_each_get_their_frames(results: dict[str, Path], tmp_path: Path) -> None:
    """A result's cameras list (the second camera on /camera_2/..., moved 0.5 m and turned):
    each camera's frames named by its topic, each at its own T_base_camera, in the URDF and
    in the launch file."""
    doc = json.loads(results["eye-to-hand"].read_text())
    second = copy.deepcopy(doc["camera"])
    second["topic"] = "/camera_2/image_raw/compressed"
    aside = np.eye(4)
    aside[:3, :3] = Rotation.from_rotvec([0.0, math.radians(15.0), 0.0]).as_matrix()
    aside[:3, 3] = [-0.5, 0.0, 0.1]
    second["T_base_camera"] = (_pose(doc, "T_base_camera") @ aside).tolist()
    doc["cameras"] = [doc["camera"], second]
    result = tmp_path / "two.dh.json"
    result.write_text(json.dumps(doc))
    model = _urdf(result, tmp_path / "robot.urdf")
    model.update_cfg(np.zeros(len(doc["standard_dh"])))
    made = _export(result, "tf", tmp_path / "tf.launch.yaml")
    assert made.exit_code == 0, made.output
    tf = _published((tmp_path / "tf.launch.yaml").read_text())
    for name, block in (("camera", doc["camera"]), ("camera_2", second)):
        want = np.array(block["T_base_camera"])
        got = model.get_transform(f"{name}_optical_frame", "base_link")
        assert np.abs(got - want).max() < EXACT
        composed = tf[f"{name}_link"][1] @ tf[f"{name}_optical_frame"][1]
        assert np.abs(composed - want).max() < 1e-12


@pytest.mark.parametrize(
    ("topic", "name"),
    [
        ("/camera/image_raw/compressed", "camera"),
        ("/camera_1/image_raw", "camera_1"),
        ("/camera/color/image_raw", "camera_color"),
        ("/cell/left/image_rect_color/theora", "cell_left"),
        ("/image_raw", "camera"),
        ("camera", "camera"),
        ("/2d-cam/image", "camera_2d_cam"),
    ],
)
def test_frame_names_from_topics(topic: str, name: str) -> None:
    assert frame_name(topic) == name


# ---------------------------------------------------------------------------------------------
# damaged camera blocks


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def change(doc: dict[str, Any]) -> None:
        *head, last = path.split(".")
        holder = doc
        for key in head:
            holder = holder[key]
        holder[last] = value

    return change


def _delete(path: str) -> Callable[[dict[str, Any]], None]:
    def change(doc: dict[str, Any]) -> None:
        *head, last = path.split(".")
        holder = doc
        for key in head:
            holder = holder[key]
        del holder[last]

    return change


def _scaled(doc: dict[str, Any]) -> None:
    doc["camera"]["T_base_camera"][0][0] *= 1.01


DAMAGED = [
    ("non-rigid", _scaled, "camera.T_base_camera must be a rigid transform"),
    ("rows", _set("camera.T_base_camera", [[1, 0, 0, 0]]), "camera.T_base_camera must be a 4×4"),
    ("text", _set("camera.T_base_camera", "eye"), "camera.T_base_camera is text"),
    ("missing", _delete("camera.T_base_camera"), "camera.T_base_camera is missing"),
    ("std", _delete("camera.T_base_camera_std"), "camera.T_base_camera_std is missing"),
    (
        "negative",
        _set("camera.T_base_camera_std.translation_m", [1e-4, -1e-4, 1e-4]),
        "camera.T_base_camera_std.translation_m[1] is -0.0001",
    ),
    ("board", _delete("camera.T_flange_board"), "camera.T_flange_board is missing"),
    ("setup", _set("camera.setup", "on a tripod"), "camera.setup must be eye-to-hand or"),
    ("topic", _delete("camera.topic"), "camera.topic is missing"),
    ("nan", _set("camera.T_base_camera_std.rotation_rad", [1, "x", 1]), "rotation_rad[1]"),
    (
        "far",
        _set("camera.T_base_camera", [[1, 0, 0, 5e3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
        "camera.T_base_camera[0][3] is 5000",
    ),
    ("list", _set("cameras", [7, 8]), "cameras[0] is a number, not an object"),
]


@pytest.mark.parametrize("fmt", ["urdf", "tf"])
@pytest.mark.parametrize(("name", "change", "says"), DAMAGED, ids=[d[0] for d in DAMAGED])
def test_a_damaged_camera_block_is_one_line_exit_2(
    results: dict[str, Path], tmp_path: Path, fmt: str, name: str, change: Any, says: str
) -> None:
    doc = json.loads(results["eye-to-hand"].read_text())
    change(doc)
    result = tmp_path / "run.dh.json"
    result.write_text(json.dumps(doc))
    made = _export(result, fmt, tmp_path / "out")
    assert made.exit_code == 2, made.output
    lines = [line for line in made.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in made.output, made.output
    assert lines[0].startswith("error: ") and str(result) in lines[0] and says in lines[0], lines
    assert "dhlog process" in lines[0]  # what to do
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.dh.json"]


def test_formats_without_the_camera_say_so(results: dict[str, Path], tmp_path: Path) -> None:
    """The DH tables of a camera result are written, with a note naming the formats that carry
    the camera's pose."""
    made = _export(results["eye-to-hand"], "dh-json", tmp_path / "dh.json")
    assert made.exit_code == 0, made.output
    assert "--format tf" in made.output and "hand-eye" in made.output


def test_a_hostile_topic_and_unknown_sigma(results: dict[str, Path], tmp_path: Path) -> None:
    """A topic with quotes, a newline and markup becomes a plain frame name; the launch file
    stays one YAML document with the same nodes, the URDF loads; a σ the result gives as null
    is written as unknown."""
    doc = json.loads(results["eye-to-hand"].read_text())
    doc["camera"]["topic"] = '/cam"era\n--x 9 <b>/image_raw'
    doc["camera"]["T_base_camera_std"]["translation_m"] = [None, 1e-4, 1e-4]
    result = tmp_path / "hostile.dh.json"
    result.write_text(json.dumps(doc))
    made = _export(result, "tf", tmp_path / "tf.launch.yaml")
    assert made.exit_code == 0, made.output
    text = (tmp_path / "tf.launch.yaml").read_text()
    tf = _published(text)
    assert set(tf) == {
        "cam_era_x_9_b_link",
        "cam_era_x_9_b_optical_frame",
        "calibration_board",
    }
    assert "σ translation x y z unknown 0.1000 0.1000 mm" in text
    model = _urdf(result, tmp_path / "robot.urdf")
    assert "cam_era_x_9_b_optical_frame" in model.link_map
