"""A camera log of rectified images, as a cell records it behind image_pipeline's rectify node
(``/camera/image_rect_color/compressed`` beside the driver's one ``camera_info``): ROS's
``CameraInfo`` gives the raw images' ``K`` and ``D`` and the rectified images' intrinsics as its
projection ``P``. The rectified log is made from the simulator's small-camera log as image_proc
makes it — each image undistorted by OpenCV onto the new camera matrix ``getOptimalNewCameraMatrix``
gives (``cv2.undistort``: ``initUndistortRectifyMap`` and ``remap``) — the camera info's ``P`` set
to ``[K_rect | 0]``. Read with ``K`` and ``D`` (as dhlog read every camera info before) the same
log gave a reprojection RMS 8x the raw log's, the camera 11 mm from the truth, exit 0.

A driver that undistorts on board may publish rectified images on ``image_raw``: the boards
placed frame by frame say which reading the images obey (``frames.obeyed``).

Tolerances: the raw log's camera lands 0.6 mm from the truth (16 random poses, 0.05 px corner
noise); resampled into the rectified images the corners lose some of the board's edges
(alpha 0 crops) and gain interpolation noise, so 1.5 mm and 0.15 px RMS bound the rectified run;
read with ``K`` and ``D`` it must miss its corners by more than twice the RMS read with ``P``
(0.56 px against 0.08 px at 30 poses of the same camera)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_ros2.decoder import DecoderFactory
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.identify.camera.frames.camerafind import rectified_topic
from dhlog.identify.camera.frames.imagedecode import camera_info_cdr
from dhlog.io.ros2 import encode_camera_info, encode_compressed_image

runner = CliRunner()
RAW, RECT = "/camera/image_raw/compressed", "/camera/image_rect_color/compressed"


def _rectified(
    raw: Path, out: Path, *, p: np.ndarray | None = None, topic: str = RECT
) -> np.ndarray:
    """``raw``'s images rectified as image_proc does, on ``topic``; its camera info's ``P``
    ``[K_rect | 0]`` (or ``p``). Returns ``K_rect``."""
    with raw.open("rb") as f:
        first = next(make_reader(f).iter_messages(topics=["/camera/camera_info"]))[2]
    info = camera_info_cdr(first.data)
    K, D, size = info.k.reshape(3, 3), np.asarray(info.d), (info.width, info.height)
    K_rect, _ = cv2.getOptimalNewCameraMatrix(K, D, size, 0.0, size)
    P = np.hstack([K_rect, np.zeros((3, 1))]) if p is None else p
    with raw.open("rb") as f, out.open("wb") as g:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        writer = Writer(g)
        writer.start(profile="ros2", library="image_proc, as the test makes it")
        schemas = {
            sid: writer.register_schema(s.name, s.encoding, s.data)
            for sid, s in summary.schemas.items()
        }
        channels = {
            cid: writer.register_channel(
                topic if c.topic == RAW else c.topic, c.message_encoding, schemas[c.schema_id]
            )
            for cid, c in summary.channels.items()
        }
        for _, channel, message, decoded in reader.iter_decoded_messages():
            data = message.data
            if channel.topic == "/camera/camera_info":
                data = encode_camera_info(replace(camera_info_cdr(message.data), p=P))
            elif channel.topic == RAW:
                image = cv2.imdecode(np.frombuffer(decoded.data, np.uint8), cv2.IMREAD_UNCHANGED)
                ok, png = cv2.imencode(".png", cv2.undistort(image, K, D, None, K_rect))
                assert ok
                stamp = decoded.header.stamp.sec * 10**9 + decoded.header.stamp.nanosec
                data = encode_compressed_image(stamp, decoded.header.frame_id, png.tobytes(), "png")
            writer.add_message(
                channels[channel.id], message.log_time, data, message.publish_time, message.sequence
            )
        writer.finish()
    return np.asarray(K_rect)


def _pipeline(tmp_path: Path, extra: str = "") -> Path:
    shipped = Path(__file__).parents[1] / "pipelines" / "ros2_camera.toml"
    text = (
        shipped.read_text()
        .replace("square_m = 0.04", "square_m = 0.06")
        .replace("marker_m = 0.03", "marker_m = 0.045")
        .replace('info_topic = "/camera/camera_info"', f'info_topic = "/camera/camera_info"{extra}')
    )
    path = tmp_path / f"small{abs(hash(extra))}.toml"
    path.write_text(text)
    return path


def _process(log: Path, pipeline: Path, out: Path) -> tuple[int, str, dict]:
    result = runner.invoke(
        app,
        [
            *("process", str(log), "--nominal", "kr5", "--no-rrd"),
            *("--pipeline", str(pipeline), "--out", str(out)),
        ],
    )
    written = list(out.glob("*.dh.json"))
    doc = json.loads(written[0].read_text()) if written else {}
    return result.exit_code, result.output, doc


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, np.ndarray, np.ndarray]:
    folder = tmp_path_factory.mktemp("rectified")
    raw = folder / "raw.mcap"
    made = runner.invoke(
        app,
        [
            *("simulate", "kr5", "-o", str(raw), "--instrument", "camera"),
            *("--protocol", "random-poses", "--poses", "16", "--camera", "small"),
            *("--image-format", "png", "--seed", "3"),
        ],
    )
    assert made.exit_code == 0, made.output
    truth = json.loads((folder / "raw.truth.json").read_text())
    rect = folder / "rect.mcap"
    K_rect = _rectified(raw, rect)
    return raw, rect, K_rect, np.array(truth["camera"]["T_base_camera"])


def test_rectified_images_are_read_with_the_projection(
    logs: tuple[Path, Path, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """The image topic's name says rectified: the camera info's P is the intrinsics (no
    distortion, in the result), the camera lands where the truth puts it; told it is not
    rectified (``[camera] rectified = false``, K and D as before), the fit misses its own
    corners several fold."""
    raw, rect, K_rect, truth = logs
    pipeline = _pipeline(tmp_path)
    rect_pipeline = tmp_path / "rect.toml"
    rect_pipeline.write_text(
        pipeline.read_text().replace("/camera/image_raw", "/camera/image_rect_color")
    )
    code, output, doc = _process(rect, rect_pipeline, tmp_path / "rect")
    assert code == 0, output
    camera = doc["camera"]
    assert np.allclose(camera["intrinsics"]["K"], K_rect)
    assert not np.any(camera["intrinsics"]["D"])
    assert camera["reprojection_rms_px"] < 0.15
    moved = np.linalg.norm(np.array(camera["T_base_camera"])[:3, 3] - truth[:3, 3])
    assert moved < 1.5e-3, moved
    told = tmp_path / "told.toml"
    told.write_text(
        rect_pipeline.read_text().replace(
            'info_topic = "/camera/camera_info"',
            'info_topic = "/camera/camera_info"\nrectified = false',
        )
    )
    code, output, doc = _process(rect, told, tmp_path / "told")
    assert code in (0, 4), output
    assert doc["camera"]["reprojection_rms_px"] > 2 * camera["reprojection_rms_px"]
    # read as told, warned that the boards say otherwise, and that the fit misses its corners
    # far beyond the boards' own RMS
    line = " ".join(output.split())
    assert "though the pipeline's [camera] rectified chose K and D" in line
    assert "the frames disagree beyond the corners' noise" in line
    code, output, doc = _process(raw, pipeline, tmp_path / "raw")  # the raw log: K and D
    assert code == 0, output
    assert doc["camera"]["intrinsics"]["K"][0][0] == 900.0
    line = " ".join(output.split())
    assert "whatever their topic" not in line and "frames disagree" not in line


def test_rectified_images_on_a_raw_topic_are_read_with_the_projection(
    logs: tuple[Path, Path, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """A driver that undistorts on board and publishes on ``image_raw`` (or a republisher that
    names its output freely): the boards placed by PnP in the frames fit P with no distortion
    (0.068 px RMS against 0.098 px with K and D: the corners' noise, and the lens's unmodelled
    part), so the log is read with P, its corners detected again with it, and a warning says
    why. Read with K and D it put the camera 19 mm from the truth, exit 0; read with P, as the
    rectified topic's run is bounded (1.5 mm; 0.26 mm measured)."""
    raw, _, K_rect, truth = logs
    onraw = tmp_path / "onraw.mcap"
    _rectified(raw, onraw, topic=RAW)
    code, output, doc = _process(onraw, _pipeline(tmp_path), tmp_path / "onraw")
    assert code == 0, output
    line = " ".join(output.split())
    assert "fit P (no distortion) better than K and D, whatever their topic's name says" in line
    camera = doc["camera"]
    assert np.allclose(camera["intrinsics"]["K"], K_rect)
    assert not np.any(camera["intrinsics"]["D"])
    moved = np.linalg.norm(np.array(camera["T_base_camera"])[:3, 3] - truth[:3, 3])
    assert moved < 1.5e-3, moved


def test_found_without_a_pipeline_and_a_zero_projection_refused(
    logs: tuple[Path, Path, np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    """The shipped camera pipeline takes image_pipeline's topics (a rectified one where the
    raw is absent); a rectified log whose camera info carries no projection (all zero, as an
    uncalibrated driver leaves it) is one line naming what to give."""
    raw, rect, _, _ = logs
    result = runner.invoke(
        app, ["process", str(rect), "--nominal", "kr5", "--no-rrd", "--out", str(tmp_path / "a")]
    )
    # the shipped pipeline's 40 mm board against this log's 60 mm one: found, and judged
    assert result.exit_code == 4, result.output
    assert "about 60.0 mm" in " ".join(result.output.split())
    zero = tmp_path / "zero.mcap"
    _rectified(raw, zero, p=np.zeros((3, 4)))
    result = runner.invoke(
        app, ["process", str(zero), "--nominal", "kr5", "--no-rrd", "--out", str(tmp_path / "z")]
    )
    assert result.exit_code == 2, result.output
    line = " ".join(result.output.split())
    assert "is not a camera's" in line and "[camera] rectified = false" in line
    assert "Traceback" not in result.output


@pytest.mark.parametrize(
    ("topic", "rectified"),
    [
        ("/camera/image_rect_color/compressed", True),
        ("/camera/image_rect", True),
        ("/camera/depth/image_rect_raw", True),
        ("/camera/image_raw/compressed", False),
        ("/camera/image_color", False),
        ("/rectifier/image", False),
    ],
)
def test_rectified_by_image_pipelines_names(topic: str, rectified: bool) -> None:
    assert rectified_topic(topic) is rectified


@pytest.mark.parametrize("extra", ["\nrectified = 1", '\nrectified = "yes"'])
def test_a_bad_rectified_key_is_one_line(tmp_path: Path, extra: str) -> None:
    from dhlog.errors import PipelineError
    from dhlog.io.pipeline import load_pipeline

    with pytest.raises(PipelineError, match=r"\[camera\] rectified"):
        load_pipeline(_pipeline(tmp_path, extra))


def test_rectified_with_a_calibration_file_is_refused(tmp_path: Path) -> None:
    from dhlog.errors import PipelineError
    from dhlog.io.pipeline import load_pipeline

    calibration = tmp_path / "camera.yaml"
    calibration.write_text(
        "image_width: 640\nimage_height: 400\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [900, 0, 320, 0, 900, 200, 0, 0, 1]\ndistortion_model: plumb_bob\n"
        "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"
    )
    path = _pipeline(tmp_path)
    path.write_text(
        path.read_text().replace(
            'info_topic = "/camera/camera_info"', 'calibration = "camera.yaml"\nrectified = true'
        )
    )
    with pytest.raises(PipelineError, match="calibration file is taken as the images' own"):
        load_pipeline(path)


def test_the_readings_are_compared_on_enough_corners_and_not_for_a_fisheye() -> None:
    """Fewer than MIN_DOF residuals beyond the boards' poses: the reading in use is kept,
    whatever the boards say; a fisheye's readings are not compared; told by the pipeline, the
    reading in use is kept with a warning."""
    from dhlog.identify.camera.frames.obeyed import MIN_DOF, Reading, judged
    from dhlog.vision.boards import BoardSpec
    from dhlog.vision.camera import Intrinsics

    board = BoardSpec(kind="checkerboard", squares=(9, 6), square_m=0.03)
    obj = board.object_points()
    K = np.array([[900.0, 0, 320], [0, 900, 200], [0, 0, 1]])
    raw = Intrinsics(640, 400, K, "plumb_bob", np.array([-0.3, 0.1, 0, 0, 0]))
    rect = Intrinsics(640, 400, K, "plumb_bob", np.zeros(5))
    frames = []
    for k in range(8):  # the board seen undistorted (rectified images) from eight poses
        rvec = np.array([0.3 * np.sin(k), 0.3 * np.cos(k), 0.1 * k])
        tvec = np.array([-0.1 + 0.02 * k, -0.07, 0.45])
        uv, _ = cv2.projectPoints(obj, rvec, tvec, K, np.zeros(5))
        frames.append((np.arange(obj.shape[0]), uv.reshape(-1, 2)))
    used, other = Reading(raw, False), Reading(rect, True)
    chosen, said = judged("log", board, frames, used, other, told=False)
    assert chosen is other and said
    kept, warned = judged("log", board, frames, used, other, told=True)
    assert kept is used and "set [camera] rectified = true" in warned[0]
    few = [(ids[:8], uv[:8]) for ids, uv in frames[:3]]
    assert sum(2 * 8 - 6 for _ in few) < MIN_DOF
    assert judged("log", board, few, used, other, told=False) == (used, ())
    fisheye = Reading(Intrinsics(640, 400, K, "equidistant", np.zeros(4)), False)
    assert judged("log", board, frames, fisheye, other, told=False) == (fisheye, ())
