"""``dhlog.identify.camera.frames.observe.observe`` (issue 32): a simulated vision log read with the
camera pipeline — the board's corners found in every frame where the truth puts them, the encoders
joined at each frame's stamp, jobs=2 the same as jobs=1, and each bad input one line.

The logs are the simulator's (``simulate.camera.simulate_vision`` and ``write_vision_log``: the
KR5 eye-in-hand, 10 still poses, its camera scaled to 640x400 as tests/fuzz_images.py scales it,
JPEG), and variants written again by the mcap writer with messages left out or changed.

The tolerance on the corners: the rendering adds Gaussian noise of 2 grey levels and a blur of
0.6 px; OpenCV's ChArUco corners on such views are within 0.15 px RMS of the truth
(tests/test_vision.py), 0.04–0.08 px RMS at 1280x800 (tests/test_simulate_camera.py). At half
the size JPEG's 8-px blocks are twice as large against the board's squares; 0.098 px RMS (at
most 0.60 px, 143 corners) was measured here. 0.25 px RMS and 1 px at most, as
tests/test_simulate_camera.py bounds them, fail on a frame joined to another frame's pose (250 px
RMS) or a corner given a neighbour's id (a square, 20 px or more, away).
"""

from __future__ import annotations

import dataclasses
import io
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from dhlog.errors import PipelineError
from dhlog.identify.camera.frames.observations import Decimation, joint_values_at
from dhlog.identify.camera.frames.observe import VisionLogError, observe
from dhlog.io import ros2
from dhlog.io.pipeline import Pipeline, parse_pipeline, pipeline_by_name
from dhlog.simulator.camera import TOPICS, VisionSession
from dhlog.vision.camera import Intrinsics

POSES = 10
SCALE = 0.5
IMAGE, INFO, JOINTS = TOPICS["compressed"], TOPICS["info"], TOPICS["joints"]


@dataclass(frozen=True)
class Message:
    topic: str
    schema: str
    log_time: int
    data: bytes


@dataclass(frozen=True)
class Base:
    path: Path
    vision: VisionSession
    messages: tuple[Message, ...]


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Base:
    from dhlog.model.robots import load_robot
    from dhlog.simulator.camera import simulate_vision, write_vision_log
    from dhlog.simulator.config import SimulationConfig

    cfg = SimulationConfig(
        seed=3,
        poses=POSES,
        protocol="random-poses",
        joint_rate=20.0,
        instrument="camera",
        camera_setup="eye-in-hand",
    )
    vision = simulate_vision(load_robot("kr5"), cfg, "eye-in-hand", "jpeg")
    cam = vision.rig.camera
    K = cam.K.copy()
    K[:2] *= SCALE
    small = Intrinsics(round(cam.width * SCALE), round(cam.height * SCALE), K, cam.model,
                       cam.coefficients)  # fmt: skip
    vision = dataclasses.replace(vision, rig=dataclasses.replace(vision.rig, camera=small))
    path = tmp_path_factory.mktemp("observe") / "vision.mcap"
    write_vision_log(vision, path, cfg.seed)
    with path.open("rb") as f:
        messages = tuple(
            Message(c.topic, s.name if s else "", m.log_time, bytes(m.data))
            for s, c, m in make_reader(f).iter_messages()
        )
    return Base(path, vision, messages)


def written(tmp_path: Path, messages: list[Message], name: str = "variant.mcap") -> Path:
    f = io.BytesIO()
    writer = Writer(f, chunk_size=1 << 20, compression=CompressionType.ZSTD, enable_crcs=False)
    writer.start(profile="ros2", library="dhlog test")
    channels: dict[str, int] = {}
    for m in messages:
        if m.topic not in channels:
            sid = writer.register_schema(m.schema, "ros2msg", ros2.MSGDEFS[m.schema].encode())
            channels[m.topic] = writer.register_channel(m.topic, "cdr", sid)
        writer.add_message(channels[m.topic], m.log_time, m.data, m.log_time)
    writer.finish()  # type: ignore[no-untyped-call]
    out = tmp_path / name
    out.write_bytes(f.getvalue())
    return out


def with_joints(base: Base, q: np.ndarray, keep: Callable[[int], bool] = lambda t: True) -> list:
    """The log's messages with its joint states replaced by ``q`` at the session's stamps,
    those whose stamp ``keep`` refuses left out."""
    s = base.vision.session
    payloads = ros2.encode_joint_state(s.joint_t_ns, s.joint_names, q)
    joints = [
        Message(JOINTS, ros2.JOINT_STATE, int(t), p)
        for t, p in zip(s.joint_t_ns, payloads, strict=True)
        if keep(int(t))
    ]
    others = [m for m in base.messages if m.topic != JOINTS]
    return sorted(joints + others, key=lambda m: m.log_time)


PIPELINE = pipeline_by_name("ros2_camera")
assert PIPELINE is not None and PIPELINE.target is not None


def pipeline_with(text: str, folder: Path | None = None) -> Pipeline:
    """The shipped camera pipeline with ``text`` in place of its [camera] and [target]."""
    shipped = Path(__file__).parents[1] / "pipelines" / "ros2_camera.toml"
    lines = shipped.read_text().split("\n[camera]")[0]
    return parse_pipeline(lines + "\n" + text, "test.toml", folder=folder)


TARGET = """
[target]
kind = "charuco"
dictionary = "DICT_5X5_100"
squares = [7, 5]
square_m = 0.04
marker_m = 0.03
"""


def truth_px(base: Base, frame: int, ids: np.ndarray) -> np.ndarray:
    rig = base.vision.rig
    T = base.vision.T_cam_board[frame]
    P = rig.board.object_points()[ids]
    return rig.camera.project(P @ T[:3, :3].T + T[:3, 3])


def test_every_corner_where_the_truth_puts_it_with_the_pose_s_joints(base: Base) -> None:
    (obs,) = observe(base.path, PIPELINE)
    vision = base.vision
    assert obs.camera == IMAGE and obs.intrinsics == vision.rig.camera
    assert obs.board == PIPELINE.target and obs.warnings == ()
    assert obs.tally.frames == POSES and obs.tally.detected == POSES
    assert obs.frames == POSES and obs.frame.tolist() == list(range(POSES))
    assert obs.t_ns.tolist() == vision.frame_t_ns.tolist()
    assert obs.joint_names == list(vision.session.joint_names)
    # the frames are taken at still poses: the encoders there are the pose's values
    np.testing.assert_allclose(obs.q, vision.session.poses, atol=1e-12)
    errors = []
    for f, ids, uv in zip(obs.frame, obs.ids, obs.uv, strict=True):
        assert ids.dtype == np.int64 and uv.shape == (ids.size, 2) and ids.size >= 6
        errors.append(np.linalg.norm(uv - truth_px(base, int(f), ids), axis=1))
    every = np.concatenate(errors)
    assert np.sqrt(np.mean(every**2)) < 0.25 and every.max() < 1.0
    # every frame kept for the recording (10 < keep_frames), as recorded: the log's JPEG
    assert [k[0] for k in obs.kept] == list(range(POSES))
    recorded = [m.data for m in base.messages if m.topic == IMAGE]
    for index, fmt, data in obs.kept:
        assert fmt == "jpeg" and data in recorded[index]
        assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED).shape == (400, 640)


def test_two_workers_observe_what_one_does(base: Base) -> None:
    fractions: list[float] = []
    (one,) = observe(base.path, PIPELINE, keep_frames=4)
    (two,) = observe(base.path, PIPELINE, jobs=2, keep_frames=4, progress=fractions.append)
    for name in ("t_ns", "frame", "q"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    for a, b in zip(one.ids + one.uv, two.ids + two.uv, strict=True):
        np.testing.assert_array_equal(a, b)
    assert one.tally == two.tally and one.kept == two.kept and one.warnings == two.warnings
    # 10 frames, at most 4 kept: every 4th, evenly over the log
    assert [k[0] for k in one.kept] == [0, 4, 8]
    assert fractions[0] == 0.0 and fractions[-1] == 1.0 and fractions == sorted(fractions)


def test_decimation_keeps_frames_evenly_over_a_log_of_unknown_length() -> None:
    d = Decimation(200)
    for i in range(10_000):
        if d.wanted(i):
            d.add(i, "jpeg", b"")
    kept = [k[0] for k in d.frames()]
    assert 100 <= len(kept) <= 200 and kept[0] == 0 and kept[-1] > 9_800 - d.step
    assert set(np.diff(kept)) == {d.step}
    assert Decimation(0).frames() == () and not Decimation(0).wanted(0)


def test_joint_values_interpolated_and_refused_beyond_the_tolerance() -> None:
    jt = np.array([0, 100_000_000, 200_000_000, 900_000_000], dtype=np.int64)
    jq = np.array([[0.0, 1.0], [0.1, 1.0], [0.3, 1.0], [0.3, 1.0]])
    t = np.array([50_000_000, 100_000_000, 500_000_000, -1, 950_000_000], dtype=np.int64)
    at = joint_values_at(t, jt, jq, 0.15)
    assert at.ok.tolist() == [True, True, False, False, False]
    np.testing.assert_allclose(at.q[:2], [[0.05, 1.0], [0.1, 1.0]])
    # the speed at a sample's stamp: over the samples before and after it (0.3 rad in 0.2 s)
    np.testing.assert_allclose(at.speed[:2], [[1.0, 0.0], [1.5, 0.0]])
    assert np.isnan(at.q[2:]).all()


def test_frames_without_joint_states_left_out_and_named(base: Base, tmp_path: Path) -> None:
    s, stamps = base.vision.session, base.vision.frame_t_ns
    gaps = [stamps[2], stamps[5]]  # no joint state within 0.2 s of frames 2 and 5

    def keep(t: int) -> bool:
        return all(abs(t - g) > 200_000_000 for g in gaps)

    path = written(tmp_path, with_joints(base, s.joint_q, keep))
    (obs,) = observe(path, PIPELINE)
    assert obs.frame.tolist() == [0, 1, 3, 4, 6, 7, 8, 9] and obs.tally.detected == POSES
    (line,) = obs.warnings
    assert "2 of 10 frame(s)" in line and "frames 2, 5" in line and "join_tolerance" in line
    assert "\n" not in line

    def away(t: int) -> bool:  # joint states, but none within 0.2 s of any frame
        return bool(np.all(np.abs(t - stamps) > 200_000_000))

    with pytest.raises(VisionLogError, match=r"none of the 10 frame\(s\).*join_tolerance") as e:
        observe(written(tmp_path, with_joints(base, s.joint_q, away), "b.mcap"), PIPELINE)
    assert "\n" not in str(e.value)


def test_frames_taken_while_the_joints_move_are_named(base: Base, tmp_path: Path) -> None:
    s, stamps = base.vision.session, base.vision.frame_t_ns
    q = s.joint_q.copy()
    near = np.abs(s.joint_t_ns - stamps[3]) < 300_000_000
    q[near, 0] += 0.05 * (s.joint_t_ns[near] - stamps[3]) * 1e-9  # 0.05 rad/s through frame 3
    (obs,) = observe(written(tmp_path, with_joints(base, q)), PIPELINE)
    assert obs.frames == POSES
    (line,) = obs.warnings
    assert "moved while 1 of 10 frame(s)" in line and "frame 3:" in line and "0.05 rad/s" in line


def test_no_intrinsics_one_line_naming_the_pipeline_keys(base: Base, tmp_path: Path) -> None:
    path = written(tmp_path, [m for m in base.messages if m.topic != INFO])
    with pytest.raises(VisionLogError) as e:
        observe(path, PIPELINE)
    message = str(e.value)
    assert "\n" not in message and f"{INFO} is not in the log" in message
    assert "[camera] calibration" in message and "[camera] info_topic" in message
    # the fix it names: the camera's calibration file held in the pipeline
    cam = base.vision.rig.camera
    (tmp_path / "camera.yaml").write_text(
        f"image_width: {cam.width}\nimage_height: {cam.height}\ncamera_name: camera\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: {cam.K.ravel().tolist()}\n"
        "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
        f"  data: {cam.coefficients.tolist()}\n"
    )
    held = pipeline_with('[camera]\ncalibration = "camera.yaml"\n' + TARGET, tmp_path)
    (obs,) = observe(path, held)
    assert obs.frames == POSES and obs.intrinsics == cam


def test_images_of_another_size_than_the_intrinsics(base: Base, tmp_path: Path) -> None:
    K = np.array([[900.0, 0, 640], [0, 900, 400], [0, 0, 1]])
    big = ros2.encode_camera_info(
        ros2.CameraInfo.unrectified(1, "camera", (1280, 800), "plumb_bob", [0.0] * 5, K)
    )
    messages = [dataclasses.replace(m, data=big) if m.topic == INFO else m for m in base.messages]
    with pytest.raises(VisionLogError) as e:
        observe(written(tmp_path, messages), PIPELINE)
    message = str(e.value)
    assert "\n" not in message and "frames 0, 1, 2, 3 on" in message
    assert "640×400 px" in message and "1280×800 px" in message
    assert "[camera] calibration" in message


def test_no_target_names_the_wrong_dictionary(base: Base) -> None:
    wrong = pipeline_with("[camera]\n" + TARGET.replace("DICT_5X5_100", "DICT_4X4_50"))
    with pytest.raises(VisionLogError) as e:
        observe(base.path, wrong)
    message = str(e.value)
    assert "\n" not in message and "found in no frame" in message
    assert "0 of 10 frame(s) with the target; 10 wrong dictionary (frames 0, 1, 2, …)" in message
    assert "DICT_5X5" in message and "[target] dictionary" in message


def test_a_corrupt_frame_is_counted_and_the_rest_observed(base: Base, tmp_path: Path) -> None:
    frames = [i for i, m in enumerate(base.messages) if m.topic == IMAGE]
    messages = list(base.messages)
    cut = messages[frames[4]]
    messages[frames[4]] = dataclasses.replace(cut, data=cut.data[: len(cut.data) // 2])
    (obs,) = observe(written(tmp_path, messages), PIPELINE, jobs=2)
    assert obs.frame.tolist() == [0, 1, 2, 3, 5, 6, 7, 8, 9]
    (line,) = obs.warnings
    assert "1 of 10 frame(s)" in line and "frame 4" in line


def test_a_tracker_pipeline_is_refused(base: Base) -> None:
    tracker = pipeline_by_name("ros2_tracker")
    assert tracker is not None
    with pytest.raises(PipelineError, match="not a camera pipeline"):
        observe(base.path, tracker)


def test_several_cameras_each_observed_and_one_without_intrinsics_left_out(
    tmp_path: Path,
) -> None:
    from dhlog.model.robots import load_robot
    from dhlog.simulator.camera import simulate_vision, write_vision_log
    from dhlog.simulator.config import SimulationConfig

    cfg = SimulationConfig(seed=3, poses=10, protocol="random-poses", joint_rate=20.0,
                           instrument="camera", camera_setup="eye-to-hand")  # fmt: skip
    vision = simulate_vision(
        load_robot("kr5"), cfg, "eye-to-hand", "jpeg", preset="small", cameras=2
    )
    path = tmp_path / "two.mcap"
    write_vision_log(vision, path, cfg.seed)
    pipeline = dataclasses.replace(PIPELINE, target=vision.rig.board)  # the preset's board
    observed = observe(path, pipeline, jobs=2)
    assert [o.camera for o in observed] == [f"/camera_{k}/image_raw/compressed" for k in (1, 2)]
    for obs, cam in zip(observed, vision.cameras, strict=True):
        assert obs.intrinsics == cam.rig.camera and obs.warnings == ()
        assert obs.t_ns.tolist() == cam.frame_t_ns.tolist() and obs.frames >= 4
        np.testing.assert_allclose(obs.q, cam.frame_q, atol=1e-12)
        every = []
        for f, ids, uv in zip(obs.frame, obs.ids, obs.uv, strict=True):
            T = cam.T_cam_board[int(f)]
            P = cam.rig.board.object_points()[ids] @ T[:3, :3].T + T[:3, 3]
            every.append(np.linalg.norm(uv - cam.rig.camera.project(P), axis=1))
        e = np.concatenate(every)
        assert np.sqrt(np.mean(e**2)) < 0.25 and e.max() < 1.0
    # the second camera's intrinsics missing: it is left out, said on the first
    with path.open("rb") as f:
        messages = [
            Message(c.topic, s.name if s else "", m.log_time, bytes(m.data))
            for s, c, m in make_reader(f).iter_messages()
            if c.topic != "/camera_2/camera_info"
        ]
    (first,) = observe(written(tmp_path, messages), pipeline)
    assert first.camera == "/camera_1/image_raw/compressed" and first.frames == observed[0].frames
    (line,) = first.warnings
    assert "no camera intrinsics for /camera_2/image_raw/compressed" in line
    assert line.endswith("That camera is left out.") and "\n" not in line
