"""A camera pipeline's ``[streams.image]``, ``[target]`` and ``[camera]`` (issue 32, items 1-2):
the board and the intrinsics parsed from the pipeline file, each bad key one line naming the
file and the key; the shipped ros2_camera pipeline; ``dhlog process`` refusing a vision log or a
camera pipeline in one line."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.writer import Writer

from dhlog.errors import PipelineError
from dhlog.io import ros2
from dhlog.io.pipeline import load_pipeline, parse_pipeline, pipeline_by_name
from dhlog.io.reader import read_log
from dhlog.simulator.camera import BOARD
from dhlog.vision.boards import BoardSpec

S = 1_000_000_000

CALIBRATION = """image_width: 1280
image_height: 800
camera_name: cell_camera
camera_matrix:
  rows: 3
  cols: 3
  data: [1800.0, 0.0, 641.5, 0.0, 1797.0, 398.2, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.12, 0.08, 0.0004, -0.0003, 0.0]
"""

TARGET = """
[target]
kind = "charuco"
dictionary = "DICT_4X4_50"
squares = [9, 6]
square_m = 0.03
marker_m = 0.022
"""


def camera_pipeline(camera: str = 'calibration = "cam/ost.yaml"', target: str = TARGET) -> str:
    return (
        'name = "cell_camera"\nencoding = "cdr"\n\n[streams.image]\ntopic = "/cam/image"\n\n'
        f'[streams.joints]\ntopic = "/joint_states"\nrequired = true\n\n[camera]\n{camera}\n'
        f"{target}"
    )


def write(folder: Path, pipeline: str, calibration: str | None = CALIBRATION) -> Path:
    (folder / "cam").mkdir(exist_ok=True)
    if calibration is not None:
        (folder / "cam" / "ost.yaml").write_text(calibration, encoding="utf-8")
    path = folder / "cell.toml"
    path.write_text(pipeline, encoding="utf-8")
    return path


def test_a_camera_pipeline_parses_to_the_board_and_the_intrinsics(tmp_path: Path) -> None:
    p = load_pipeline(write(tmp_path, camera_pipeline()))
    assert p.is_camera and p.image is not None and p.image.topic == "/cam/image"
    assert "point" not in p.streams and p.streams["joints"].topic == "/joint_states"
    assert p.target == BoardSpec("charuco", "DICT_4X4_50", (9, 6), 0.03, 0.022)
    assert p.camera is not None and p.camera.info_topic is None
    # the relative path is taken from the pipeline file's folder, not the working directory
    assert p.camera.calibration == str(tmp_path / "cam" / "ost.yaml")
    cam = p.camera.intrinsics
    assert cam is not None and cam.size == (1280, 800) and cam.model == "plumb_bob"
    np.testing.assert_array_equal(cam.K, [[1800.0, 0, 641.5], [0, 1797.0, 398.2], [0, 0, 1]])
    np.testing.assert_array_equal(cam.coefficients, [-0.12, 0.08, 0.0004, -0.0003, 0.0])


def test_an_opencv_calibration_file_and_the_camera_info_topic(tmp_path: Path) -> None:
    fs = cv2.FileStorage("c.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", np.array([[600.0, 0, 320], [0, 601.0, 240], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.array([[0.1, -0.05, 0.0, 0.0, 0.01]]))
    text = fs.releaseAndGetString()
    cam = load_pipeline(write(tmp_path, camera_pipeline(), text)).camera
    assert cam is not None and cam.intrinsics is not None and cam.intrinsics.size == (640, 480)
    # no [camera] table: the intrinsics from the log's CameraInfo on the default topic
    no_table = camera_pipeline(camera="").replace("[camera]\n", "")
    p = parse_pipeline(no_table, "cell.toml")
    assert p.camera is not None and p.camera.info_topic == "/camera/camera_info"
    assert p.camera.intrinsics is None


def _error(tmp_path: Path, text: str, calibration: str | None = CALIBRATION) -> str:
    path = write(tmp_path, text, calibration)
    with pytest.raises(PipelineError) as caught:
        load_pipeline(path)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"{path}: "), message
    assert len(message) < 400, message
    return message


ZERO_K = CALIBRATION.replace(
    "[1800.0, 0.0, 641.5, 0.0, 1797.0, 398.2, 0.0, 0.0, 1.0]", "[0, 0, 0, 0, 0, 0, 0, 0, 0]"
)


@pytest.mark.parametrize(
    ("text", "calibration", "says"),
    [
        (camera_pipeline(target=TARGET.replace("DICT_4X4_50", "DICT_4X4_5O")), None, "dictionary"),
        (camera_pipeline(target=TARGET.replace("0.022", "-0.022")), None, "marker_m is -0.022"),
        (camera_pipeline(target=TARGET.replace("0.03", "0")), None, "square_m is 0"),
        (camera_pipeline(target=TARGET.replace("[9, 6]", "[9, true]")), None, "squares[1]"),
        (camera_pipeline(target=TARGET.replace("kind", "knd")), None, "key knd"),
        (camera_pipeline(target=""), None, "needs a [target] table"),
        (camera_pipeline(), None, "[camera] calibration: "),
        (camera_pipeline(), "", "[camera] calibration: "),
        (camera_pipeline(), ZERO_K, "[camera] calibration: "),
        (camera_pipeline(), "image_width: 1280\nimage_height: 800\n", "camera_matrix is missing"),
        (camera_pipeline(camera="calibration = 5"), None, "[camera] calibration must be a string"),
        (camera_pipeline(camera='info = "/ci"'), None, "did you mean 'info_topic'"),
        (
            camera_pipeline(camera='info_topic = "/ci"\ncalibration = "x.yaml"'),
            None,
            "both info_topic and calibration",
        ),
        (
            camera_pipeline().replace('topic = "/cam/image"', 'topic = "/cam/image"\nfields = 1'),
            None,
            "[streams.image]: unknown key 'fields'",
        ),
        (
            camera_pipeline() + '\n[streams.point]\ntopic = "/tracker/point"\n',
            None,
            "both [streams.point] and [streams.image]",
        ),
    ],
)
def test_each_bad_key_is_one_line_naming_the_pipeline_and_the_key(
    tmp_path: Path, text: str, calibration: str | None, says: str
) -> None:
    assert says in _error(tmp_path, text, calibration)


def test_the_calibration_files_faults_name_the_file(tmp_path: Path) -> None:
    missing = _error(tmp_path, camera_pipeline(), None)
    assert str(tmp_path / "cam" / "ost.yaml") in missing and "cannot be read" in missing
    assert "pipeline file's folder" in missing
    zero = _error(tmp_path, camera_pipeline(), ZERO_K)
    assert "K is all zeros" in zero and "ost.yaml" in zero
    big = _error(tmp_path, camera_pipeline(), "#" * (2**20 + 1))
    assert "larger than any calibration file" in big


def test_target_and_camera_belong_to_a_camera_pipeline() -> None:
    tracker = '[streams.point]\ntopic = "/tracker/point"\n'
    with pytest.raises(PipelineError, match=r"\[target\] is for a camera pipeline"):
        parse_pipeline(tracker + TARGET, "t.toml")
    with pytest.raises(PipelineError, match=r"\[camera\] is for a camera pipeline"):
        parse_pipeline(tracker + '[camera]\ninfo_topic = "/c"\n', "t.toml")
    with pytest.raises(PipelineError, match=r"no \[streams.point\].*\[streams.image\]"):
        parse_pipeline('[streams.joints]\ntopic = "/j"\n', "t.toml")


def test_the_shipped_camera_pipeline_reads_the_simulators_logs() -> None:
    p = pipeline_by_name("ros2_camera")
    assert p is not None and p.image is not None and p.camera is not None
    assert p.target == BOARD
    assert p.image.topic == "/camera/image_raw/compressed"
    assert p.image.alternatives[0] == "/camera/image_raw"  # then image_pipeline's other names
    assert "/camera/image_rect_color/compressed" in p.image.alternatives
    assert p.camera.info_topic == "/camera/camera_info" and p.camera.intrinsics is None
    assert p.streams["joints"].topic == "/joint_states"


def _vision_log(path: Path, image_topic: str) -> Path:
    """A small ROS 2 vision log: two PNG frames, a CameraInfo and joint states."""
    ok, png = cv2.imencode(".png", np.full((8, 8), 128, np.uint8))
    assert ok
    names = [f"joint_{k}" for k in range(1, 7)]
    t = np.array([S, 2 * S])
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="ros2", library="dhlog test")
        topics = {
            image_topic: (
                ros2.COMPRESSED_IMAGE,
                [ros2.encode_compressed_image(int(s), "camera", png.tobytes(), "png") for s in t],
            ),
            "/joint_states": (
                ros2.JOINT_STATE,
                ros2.encode_joint_state(t, names, np.zeros((2, 6))),
            ),
        }
        for topic, (schema, payloads) in topics.items():
            sid = writer.register_schema(schema, "ros2msg", ros2.MSGDEFS[schema].encode())
            cid = writer.register_channel(topic, "cdr", sid)
            for s, payload in zip(t.tolist(), payloads, strict=True):
                writer.add_message(cid, s, payload, s)
        writer.finish()  # type: ignore[no-untyped-call]
    return path


@pytest.mark.parametrize("topic", ["/camera/image_raw/compressed", "/camera/image_raw"])
def test_process_refuses_a_vision_log_naming_the_camera_pipeline(
    tmp_path: Path, topic: str
) -> None:
    log = _vision_log(tmp_path / "v.mcap", topic)
    with pytest.raises(PipelineError) as caught:
        read_log(log)
    message = str(caught.value)
    assert f"a vision log (camera images on {topic})" in message
    assert "the shipped pipeline ros2_camera describes it" in message
    assert "calibrate from it with dhlog process" in message and "\n" not in message
    camera = pipeline_by_name("ros2_camera")
    with pytest.raises(PipelineError, match=r"is a camera pipeline \(ros2_camera") as named:
        read_log(log, camera)
    assert "\n" not in str(named.value)


def test_the_readmes_camera_pipeline_block_parses() -> None:
    """docs/pipeline.md's "A camera pipeline" example is a pipeline as it stands."""
    import re

    page = Path(__file__).resolve().parents[1] / "docs" / "pipeline.md"
    text = page.read_text(encoding="utf-8")
    after = text[text.index("**A camera pipeline**") :]
    found = re.search(r"```toml\n(.*?)```", after, re.S)
    assert found is not None
    p = parse_pipeline(found.group(1), "docs/pipeline.md")
    assert p.target == BOARD and p.image is not None and p.image.alternatives
    assert p.camera is not None and p.camera.info_topic == "/camera/camera_info"
