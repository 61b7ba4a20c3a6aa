"""The camera and its targets (issue 32, items 1–2): intrinsics checked and projected through
OpenCV, boards described from an untrusted table and drawn, and detected by OpenCV in images of
a known board placed by a known pose before a known camera (with lens distortion and noise);
frames without a usable target rejected with a reason, never an exception.

The scene: the board is drawn flat by ``BoardSpec.image`` and each camera pixel looks it up
through the lens — the pixel undistorted by OpenCV (``cv2.undistortPoints``, iterated to
1e-12), its ray cut with the board's plane, the board point found in the flat image by its
homography (``cv2.remap``, bilinear). The truth is ``Intrinsics.project`` of the board's corners.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from dhlog.identify.camera.frames.detect import (
    REASONS,
    Detection,
    Rejected,
    detect,
    edge_rise_px,
    tally,
)
from dhlog.vision.boards import BoardError, BoardSpec
from dhlog.vision.camera import CameraError, Intrinsics

K640 = np.array([[800.0, 0.0, 321.3], [0.0, 805.0, 238.7], [0.0, 0.0, 1.0]])
CAMERAS = {
    "pinhole": Intrinsics(640, 480, K640, "plumb_bob", np.zeros(5)),
    "plumb_bob": Intrinsics(640, 480, K640, "plumb_bob", np.array([-0.2, 0.1, 1e-3, -5e-4, 0.0])),
    "fisheye": Intrinsics(
        640,
        480,
        np.array([[400.0, 0.0, 321.3], [0.0, 402.0, 238.7], [0.0, 0.0, 1.0]]),
        "equidistant",
        np.array([0.05, -0.01, 0.002, 0.0]),
    ),
}
BOARDS = {
    "charuco": BoardSpec(),
    "aruco_grid": BoardSpec(
        kind="aruco_grid",
        dictionary="DICT_4X4_50",
        squares=(5, 4),
        square_m=0.05,
        marker_m=0.04,
        first_id=3,
    ),
    "checkerboard": BoardSpec(kind="checkerboard", squares=(9, 6), square_m=0.03),
    "apriltag_grid": BoardSpec(
        kind="aruco_grid",
        dictionary="DICT_APRILTAG_36h11",
        squares=(5, 4),
        square_m=0.05,
        marker_m=0.04,
    ),
}


def rotation(rx: float, ry: float, rz: float) -> NDArray[np.float64]:
    return np.asarray(cv2.Rodrigues(np.array([rx, ry, rz]))[0], dtype=np.float64)


def placed(board: BoardSpec, angles: tuple[float, float, float], z: float) -> tuple:
    """R, t of the board frame in the camera frame: the board's centre about z m ahead."""
    R = rotation(*angles)
    w, h = board.size_m
    return R, -R @ np.array([w / 2, h / 2, 0.0]) + np.array([0.01, -0.005, z])


def render(
    cam: Intrinsics,
    board: BoardSpec,
    R: NDArray[np.float64],
    t: NDArray[np.float64],
    *,
    px_per_m: float,
    noise: float = 0.0,
    seed: int = 0,
) -> NDArray[np.uint8]:
    """The camera's grey image (h, w) of the board at pose (R, t), on a mid-grey background,
    with Gaussian noise of ``noise`` grey levels."""
    drawn = board.image(px_per_m, margin_px=round(0.02 * px_per_m))
    v, u = np.mgrid[0 : cam.height, 0 : cam.width].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    if cam.model == "equidistant":
        xy = cv2.fisheye.undistortPoints(pixels, cam.K, cam.coefficients, criteria=criteria)
    else:
        xy = cv2.undistortPoints(pixels, cam.K, cam.coefficients, criteria=criteria)
    rays = np.column_stack([xy.reshape(-1, 2), np.ones(cam.width * cam.height)])
    # s·ray = R[:, 0] x + R[:, 1] y + t: the board point (x, y) each ray meets, and s.
    A = np.stack(
        [np.broadcast_to(R[:, 0], rays.shape), np.broadcast_to(R[:, 1], rays.shape), -rays], 2
    )
    x, y, s = np.linalg.solve(A, -np.broadcast_to(t, rays.shape)[..., None])[..., 0].T
    q = np.column_stack([x, y, np.ones_like(x)]) @ drawn.image_from_board.T
    shape = (cam.height, cam.width)
    map_x = np.where(s > 0, q[:, 0] / q[:, 2], -1e6).reshape(shape).astype(np.float32)
    map_y = (q[:, 1] / q[:, 2]).reshape(shape).astype(np.float32)
    image = cv2.remap(drawn.pixels, map_x, map_y, cv2.INTER_LINEAR, borderValue=128)
    image = image.astype(np.float64) + np.random.default_rng(seed).normal(0.0, noise, shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def errors(cam: Intrinsics, found: Detection, R: NDArray, t: NDArray, board: BoardSpec) -> NDArray:
    """Each found corner's distance (px) from its true projection, by its id."""
    np.testing.assert_array_equal(found.object_points, board.object_points()[found.ids])
    truth = cam.project(found.object_points @ R.T + t)
    return np.asarray(np.linalg.norm(found.corners_px - truth, axis=1))


# --- Intrinsics ---------------------------------------------------------------------------


def test_camera_info_round_trip_and_equality() -> None:
    k = [810.5, 0.0, 330.2, 0.0, 812.0, 241.9, 0.0, 0.0, 1.0]
    d = [-0.21, 0.08, 1e-4, -2e-4, 0.01]
    cam = Intrinsics.from_camera_info(640, 480, "plumb_bob", d, k)
    assert (cam.width, cam.height, cam.model) == (640, 480, "plumb_bob")
    np.testing.assert_array_equal(cam.K.ravel(), k)
    np.testing.assert_array_equal(cam.coefficients, d)
    assert cam == Intrinsics(640, 480, np.array(k).reshape(3, 3), "plumb_bob", np.array(d))
    assert not cam.K.flags.writeable
    fisheye = Intrinsics.from_camera_info(640, 480, "kannala_brandt", d[:4], k)  # Foxglove's name
    assert fisheye.model == "equidistant"


def test_projection_against_hand_computed_pinhole() -> None:
    cam = Intrinsics(
        640, 480, np.array([[800.0, 0, 320], [0, 805.0, 240], [0, 0, 1]]), "plumb_bob", np.zeros(5)
    )
    uv = cam.project([[0.1, -0.05, 2.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    np.testing.assert_allclose(uv[0], [800 * 0.05 + 320, 805 * -0.025 + 240], atol=1e-9)
    np.testing.assert_allclose(uv[1], [320, 240], atol=1e-12)
    assert np.isnan(uv[2]).all()  # behind the camera: no image
    # Radial distortion k1 alone: the normalised point scaled by 1 + k1 r².
    radial = Intrinsics(640, 480, cam.K, "plumb_bob", np.array([-0.2, 0, 0, 0, 0]))
    x, y = 0.05, -0.025
    scale = 1 - 0.2 * (x * x + y * y)
    np.testing.assert_allclose(
        radial.project([[0.1, -0.05, 2.0]])[0],
        [800 * x * scale + 320, 805 * y * scale + 240],
        atol=1e-9,
    )


@pytest.mark.parametrize("name", sorted(CAMERAS))
def test_projection_jacobian_is_the_derivative(name: str) -> None:
    """OpenCV's Jacobian columns picked right: against central differences (step 1e-6; the
    error of the difference is ~1e-6 of the pixel derivative)."""
    cam = CAMERAS[name]
    points = np.array([[0.1, 0.2, 1.0], [-0.3, 0.1, 2.0], [0.02, -0.15, 0.7]])
    uv, d_point, d_intrinsics = cam.project_jacobian(points)
    np.testing.assert_allclose(uv, cam.project(points), atol=1e-12)
    h = 1e-6
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        numeric = (cam.project(points + step) - cam.project(points - step)) / (2 * h)
        np.testing.assert_allclose(d_point[:, :, j], numeric, rtol=1e-5, atol=1e-3)
    for j, (r, c) in enumerate([(0, 0), (1, 1), (0, 2), (1, 2)]):
        up, down = cam.K.copy(), cam.K.copy()
        up[r, c] += h
        down[r, c] -= h
        numeric = (
            Intrinsics(640, 480, up, cam.model, cam.coefficients).project(points)
            - Intrinsics(640, 480, down, cam.model, cam.coefficients).project(points)
        ) / (2 * h)
        np.testing.assert_allclose(d_intrinsics[:, :, j], numeric, rtol=1e-5, atol=1e-5)
    for j in range(cam.coefficients.size):
        up, down = cam.coefficients.copy(), cam.coefficients.copy()
        up[j] += h
        down[j] -= h
        numeric = (
            Intrinsics(640, 480, cam.K, cam.model, up).project(points)
            - Intrinsics(640, 480, cam.K, cam.model, down).project(points)
        ) / (2 * h)
        np.testing.assert_allclose(d_intrinsics[:, :, 4 + j], numeric, rtol=1e-5, atol=1e-3)


GOOD_K = [800.0, 0.0, 320.0, 0.0, 800.0, 240.0, 0.0, 0.0, 1.0]


@pytest.mark.parametrize(
    ("model", "d", "k", "says"),
    [
        ("plumb_bob", [0.0] * 5, [0.0] * 9, "give its calibration file"),
        ("plumb_bob", [0.0] * 4, GOOD_K, "are 4 for the plumb_bob model, which takes 5"),
        ("rational_polynomial", [0.0] * 5, GOOD_K, "which takes 8"),
        ("equidistant", [0.0] * 5, GOOD_K, "which takes 4"),
        ("plumb_bob", [0.0, math.nan, 0, 0, 0], GOOD_K, "distortion coefficients hold NaN"),
        ("plumb_bob", [0.0] * 5, [math.nan, *GOOD_K[1:]], "K holds NaN"),
        ("plumb_bob", [0.0] * 5, [-800.0, *GOOD_K[1:]], "fx=-800"),
        (
            "plumb_bob",
            [0.0] * 5,
            [800.0, 0, 900.0, 0, 800, 240, 0, 0, 1],
            "outside the 640×480 image",
        ),
        ("plumb_bob", [0.0] * 5, GOOD_K[:8], "has 8 values, not 9"),
        ("plumb_bob", [0.0] * 5, [800.0, 1.0, *GOOD_K[2:]], "without skew"),
        ("pinhole", [0.0] * 5, GOOD_K, "'pinhole' is not known"),
    ],
)
def test_intrinsics_refused_in_one_line(model: str, d: list, k: list, says: str) -> None:
    with pytest.raises(CameraError) as caught:
        Intrinsics.from_camera_info(640, 480, model, d, k, where="/camera/camera_info")
    message = str(caught.value)
    assert says in message and message.startswith("/camera/camera_info: ")
    assert "\n" not in message


ROS_YAML = """image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [810.5, 0.0, 330.2, 0.0, 812.0, 241.9, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.21, 0.08, 0.0001, -0.0002, 0.01]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
"""


def test_calibration_files_ros_and_opencv() -> None:
    ros = Intrinsics.from_yaml_text(ROS_YAML, "ost.yaml")
    np.testing.assert_array_equal(ros.K.ravel(), [810.5, 0, 330.2, 0, 812.0, 241.9, 0, 0, 1])
    # OpenCV's own format, as cv2.FileStorage writes it (no distortion_model: 5 → plumb_bob).
    fs = cv2.FileStorage("calib.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("camera_matrix", ros.K)
    fs.write("distortion_coefficients", ros.coefficients.reshape(1, -1))
    assert Intrinsics.from_yaml_text(fs.releaseAndGetString(), "calib.yml") == ros
    fs = cv2.FileStorage("calib.xml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for key, value in (("image_width", 640), ("image_height", 480), ("camera_matrix", ros.K)):
        fs.write(key, value)
    fs.write("distortion_model", "rational_polynomial")
    fs.write("distortion_coefficients", np.arange(8.0).reshape(1, -1) / 100)
    xml = Intrinsics.from_yaml_text(fs.releaseAndGetString(), "calib.xml")  # OpenCV's XML
    assert xml.model == "rational_polynomial" and xml.coefficients[7] == 0.07
    fisheye = ROS_YAML.replace("plumb_bob", "equidistant").replace(", 0.01]", "]")
    assert Intrinsics.from_yaml_text(fisheye, "f.yaml").model == "equidistant"


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("image_width: [", "not YAML or XML OpenCV can read"),
        ("", "calibration file"),
        ("a: 1\n", "image_width is missing"),
        (ROS_YAML.replace("data: [810.5", "data: [oops"), "camera_matrix.data[0] is not a number"),
        (
            ROS_YAML.replace("distortion_model: plumb_bob\n", "").replace("0.01]", "0.01, 0.0]"),
            "6 coefficients",
        ),
        (
            ROS_YAML.replace(
                "810.5, 0.0, 330.2, 0.0, 812.0, 241.9, 0.0, 0.0, 1.0", "0, 0, 0, 0, 0, 0, 0, 0, 0"
            ),
            "uncalibrated",
        ),
    ],
)
def test_calibration_file_refused_in_one_line(text: str, says: str) -> None:
    with pytest.raises(CameraError) as caught:
        Intrinsics.from_yaml_text(text, "cam.yaml")
    assert says in str(caught.value) and str(caught.value).startswith("cam.yaml: ")
    assert "\n" not in str(caught.value)


# --- Boards -------------------------------------------------------------------------------


def test_board_from_table_and_its_points() -> None:
    table = {"dictionary": "DICT_4X4_50", "squares": [6, 4], "square_m": 0.05, "marker_m": 0.035}
    board = BoardSpec.from_table(table, "cell.toml [target]")
    assert board.kind == "charuco" and board.marker_count == 12
    points = board.object_points()
    assert points.shape == (15, 3)
    np.testing.assert_allclose(points[0], [0.05, 0.05, 0.0], atol=1e-7)
    np.testing.assert_allclose(points[6], [0.10, 0.10, 0.0], atol=1e-7)  # row by row
    grid = BoardSpec.from_table({**table, "kind": "aruco_grid", "ids": list(range(20, 44))}, "t")
    assert grid.object_points().shape == (96, 3)
    np.testing.assert_allclose(
        grid.object_points()[4:8, :2],
        [[0.05, 0], [0.085, 0], [0.085, 0.035], [0.05, 0.035]],
        atol=1e-7,
    )
    checker = BoardSpec.from_table(
        {"kind": "checkerboard", "squares": [9, 6], "square_m": 0.03}, "t"
    )
    np.testing.assert_allclose(
        checker.object_points()[[0, 1, 8]], [[0.03, 0.03, 0], [0.06, 0.03, 0], [0.03, 0.06, 0]]
    )


@pytest.mark.parametrize(
    ("change", "says"),
    [
        ({"kind": "apriltag"}, "kind is 'apriltag'"),
        ({"dictionary": "DICT_5X5_1001"}, "not one of OpenCV's"),
        ({"dictionary": 5}, "dictionary is 5"),
        ({"squares": [7]}, "squares is (7,)"),
        ({"squares": [7, 1]}, "from 2 to 200"),
        ({"squares": "7x5"}, "squares is '7x5'"),
        ({"square_m": -0.04}, "square_m is -0.04"),
        ({"square_m": "40 mm"}, "square_m is '40 mm'"),
        ({"square_m": float("nan")}, "square_m is nan"),
        ({"marker_m": 0.05}, "not below square_m"),
        ({"ids": [1, 2, 3]}, "3 ids for a board of 17 markers"),
        ({"ids": [0] * 17}, "repeats an id"),
        ({"first_id": 90}, "beyond DICT_5X5_100's 0 to 99"),
        ({"first_id": 1, "ids": list(range(17))}, "both given"),
        ({"legacy_pattern": "yes"}, "legacy_pattern is 'yes'"),
        ({"marker_size": 0.03}, "key marker_size is not a target key"),
        ({"kind": "checkerboard", "squares": [8, 6]}, "one side even and the other odd"),
    ],
)
def test_board_table_refused_in_one_line(change: dict, says: str) -> None:
    table = {"squares": [7, 5], "square_m": 0.04, "marker_m": 0.03, **change}
    with pytest.raises(BoardError) as caught:
        BoardSpec.from_table(table, "cell.toml [target]")
    message = str(caught.value)
    assert says in message and message.startswith("cell.toml [target]: "), message
    assert "\n" not in message


def test_board_table_missing_keys() -> None:
    for key in ("squares", "square_m", "marker_m"):
        table = {"squares": [7, 5], "square_m": 0.04, "marker_m": 0.03}
        del table[key]
        with pytest.raises(BoardError, match=f"{key} is missing"):
            BoardSpec.from_table(table, "t")
    with pytest.raises(BoardError, match="is a list"):
        BoardSpec.from_table([1, 2], "t")


@pytest.mark.parametrize("kind", sorted(BOARDS))
def test_board_image_maps_board_points_to_pixels(kind: str) -> None:
    """The flat drawing's homography puts every corner where OpenCV finds it (a drawing one
    pixel off, or with the pixel centre convention wrong by ½, fails: the tolerance is 0.05 px,
    0.25 px for the markers' corners, which OpenCV's refinement pulls into each marker along
    its diagonal even on this perfectly sharp drawing: 0.11 px for DICT_4X4, 0.19 px for the
    AprilTag's finer cells)."""
    board = BOARDS[kind]
    drawn = board.image(1000.0, margin_px=30)
    found = detect(drawn.pixels, board)
    assert isinstance(found, Detection) and len(found) == len(board.object_points())
    xy1 = (
        np.column_stack([found.object_points[:, :2], np.ones(len(found))])
        @ drawn.image_from_board.T
    )
    atol = 0.25 if board.kind == "aruco_grid" else 0.05
    np.testing.assert_allclose(found.corners_px, xy1[:, :2] / xy1[:, 2:], atol=atol)


def test_board_image_by_width_and_camera_info_from_the_reader() -> None:
    board = BOARDS["charuco"]
    drawn = board.image(width_px=7 * 57 + 40)  # squares of 57 px, a margin of 20
    assert drawn.pixels.shape == (5 * 57 + 40, 7 * 57 + 40)
    np.testing.assert_allclose(drawn.image_from_board[0, 0], 57 / 0.04)
    with pytest.raises(BoardError, match="needs px_per_m or width_px"):
        board.image()
    # The reader's CameraInfo (dhlog.identify.camera.frames.imagedecode) carries the fields
    # from_camera_info takes.
    from dhlog.identify.camera.frames.imagedecode import CameraInfo

    k = np.array([[810.0, 0, 330], [0, 812.0, 242], [0, 0, 1]])
    info = CameraInfo(
        0, "cam", 640, 480, "plumb_bob", (0.1, 0, 0, 0, 0), k, np.eye(3), np.eye(3, 4)
    )
    cam = Intrinsics.from_camera_info(
        info.width, info.height, info.distortion_model, info.d, info.k
    )
    np.testing.assert_array_equal(cam.K, k)


# --- Detection ----------------------------------------------------------------------------

# The tolerances come from the measured floor of OpenCV's corner refinement on these renders:
# each is a 1-bit drawing resampled bilinearly (no optical blur), on which cornerSubPix (ChArUco)
# and findChessboardCornersSB (checkerboard) reach 0.02–0.14 px RMS at pinhole poses and up to
# 0.21 px with the fisheye lens (corners 20 px apart, curved by the lens inside the refinement
# window), and the ArUco markers' outer corners — L corners, not saddle points — 0.2–0.29 px with
# a 0.15 px inward bias (OpenCV's refinement pulls an L corner into the blurred marker). Any
# misplacement they would hide is far larger: a corner numbered wrong is ≥ 25 px off, the
# half-pixel convention 0.7 px, plumb_bob's k1 = −0.2 ignored 5–15 px.
TOLERANCE = {  # (RMS, max) px without noise
    ("pinhole", "charuco"): (0.2, 0.4),
    ("plumb_bob", "charuco"): (0.2, 0.4),
    ("fisheye", "charuco"): (0.3, 0.65),
    ("pinhole", "aruco_grid"): (0.35, 0.6),
    ("plumb_bob", "aruco_grid"): (0.35, 0.6),
    ("plumb_bob", "apriltag_grid"): (0.35, 0.6),
    ("pinhole", "checkerboard"): (0.12, 0.25),
    ("plumb_bob", "checkerboard"): (0.12, 0.25),
    ("fisheye", "checkerboard"): (0.15, 0.35),
}


@pytest.mark.parametrize(("camera", "kind"), sorted(TOLERANCE))
def test_every_corner_found_where_the_camera_sees_it(camera: str, kind: str) -> None:
    cam, board = CAMERAS[camera], BOARDS[kind]
    fisheye = cam.model == "equidistant"
    R, t = placed(
        board, (0.35, -0.25, 2.9 if kind == "checkerboard" else 0.1), 0.35 if fisheye else 0.55
    )
    image = render(cam, board, R, t, px_per_m=900 if fisheye else 1600)
    found = detect(image, board)
    assert isinstance(found, Detection), found
    given = detect(image, board, camera=cam)  # OpenCV placing the corners by the board's pose
    assert isinstance(given, Detection) and len(given) == len(found)
    assert errors(cam, given, R, t, board).max() < TOLERANCE[(camera, kind)][1]
    assert len(found) == len(board.object_points())  # every corner, each id once
    assert np.all(np.diff(found.ids) > 0)
    e = errors(cam, found, R, t, board)
    rms, worst = TOLERANCE[(camera, kind)]
    assert np.sqrt(np.mean(e**2)) < rms and e.max() < worst, (np.sqrt(np.mean(e**2)), e.max())
    if camera == "plumb_bob":  # the lens matters: without it the outer corners are > 1 px off
        plain = Intrinsics(cam.width, cam.height, cam.K, "plumb_bob", np.zeros(5))
        assert errors(plain, found, R, t, board).max() > 1.0, errors(
            plain, found, R, t, board
        ).max()


def test_noise_grows_the_corner_error_within_bounds() -> None:
    """Gaussian noise of 8 and 25 grey levels (the board's contrast is 255), 8 seeds each, the
    camera's intrinsics given: every corner found each time and within 0.4 and 0.6 px (RMS
    within 0.25 and 0.3 px). Without the intrinsics, at 25, OpenCV settled one ChArUco corner
    5.3 px off in 3 of 10 such frames (seeds 0, 4, 7: interpolated from two markers, refined
    onto a neighbouring edge), hence ``camera=``. The spread about the noiseless detection, by
    the noise alone, grows with the noise."""
    cam, board = CAMERAS["pinhole"], BOARDS["charuco"]
    R, t = placed(board, (0.35, -0.25, 0.1), 0.55)
    clean = detect(render(cam, board, R, t, px_per_m=1600), board, camera=cam)
    assert isinstance(clean, Detection)
    spread = []
    for noise, worst, rms in ((8.0, 0.4, 0.25), (25.0, 0.6, 0.3)):
        shifts, errs = [], []
        for seed in range(8):
            image = render(cam, board, R, t, px_per_m=1600, noise=noise, seed=seed)
            found = detect(image, board, camera=cam)
            assert isinstance(found, Detection) and len(found) == len(clean)
            errs.append(errors(cam, found, R, t, board))
            shifts.append(np.linalg.norm(found.corners_px - clean.corners_px, axis=1))
        e = np.concatenate(errs)
        assert e.max() < worst and np.sqrt(np.mean(e**2)) < rms, (noise, e.max())
        spread.append(float(np.median(np.concatenate(shifts))))
    assert 0 < spread[0] < spread[1], spread


def test_a_partial_view_keeps_the_ids_it_sees() -> None:
    cam, board = CAMERAS["plumb_bob"], BOARDS["charuco"]
    R, t = placed(board, (0.35, -0.25, 0.1), 0.55)
    image = render(cam, board, R, t, px_per_m=1600)
    image[:, :300] = 128  # the board's left half hidden
    found = detect(image, board)
    assert isinstance(found, Detection) and 6 <= len(found) < 24
    assert errors(cam, found, R, t, board).max() < 0.4


def test_small_markers_on_a_full_hd_frame() -> None:
    """14 px markers (2 px a cell) on a 1920×1080 frame: below OpenCV's default smallest marker
    there (0.03 of 1920 px of perimeter: 14.4 px a side), found with MIN_MARKER_SIDE_PX."""
    board = BoardSpec(squares=(10, 7), square_m=0.019, marker_m=0.014)
    drawn = board.image(1000.0, margin_px=10)
    frame = np.full((1080, 1920), 128, np.uint8)
    h, w = drawn.pixels.shape
    frame[500 : 500 + h, 900 : 900 + w] = drawn.pixels
    found = detect(frame, board)
    assert isinstance(found, Detection) and len(found) == 54, found


def test_grey16_and_colour_images_give_the_same_corners() -> None:
    cam, board = CAMERAS["pinhole"], BOARDS["charuco"]
    R, t = placed(board, (0.35, -0.25, 0.1), 0.55)
    image = render(cam, board, R, t, px_per_m=1600)
    grey = detect(image, board)
    assert isinstance(grey, Detection)
    for other in (image.astype(np.uint16) * 257, cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)):
        found = detect(other, board)
        assert isinstance(found, Detection)
        np.testing.assert_array_equal(found.ids, grey.ids)
        np.testing.assert_allclose(found.corners_px, grey.corners_px, atol=1e-3)


# --- Rejections ---------------------------------------------------------------------------


def test_blank_image_is_no_target() -> None:
    for value in (0, 128, 255):
        result = detect(np.full((480, 640), value, np.uint8), BOARDS["charuco"])
        assert isinstance(result, Rejected) and result.reason == "no target"
    noisy = np.clip(np.random.default_rng(1).normal(128, 5, (480, 640)), 0, 255).astype(np.uint8)
    assert detect(noisy, BOARDS["charuco"]) == Rejected(
        "no target", "no charuco board of DICT_5X5_100 (7×5) in the image"
    )


def test_board_of_another_dictionary_is_named() -> None:
    cam = CAMERAS["pinhole"]
    printed = BoardSpec(dictionary="DICT_4X4_50")
    R, t = placed(printed, (0.35, -0.25, 0.1), 0.55)
    result = detect(render(cam, printed, R, t, px_per_m=1600), BOARDS["charuco"])
    assert isinstance(result, Rejected) and result.reason == "wrong dictionary", result
    assert "17 markers of DICT_4X4_100" in result.detail and "none of DICT_5X5_100" in result.detail


def test_blurred_board_is_named() -> None:
    """A Gaussian blur of σ = 4 px and a 25 px motion blur: edges rising over 10 and 24 px
    (edge_rise_px), beyond BLUR_RISE_PX; the sharp render measures 2.5 px."""
    cam, board = CAMERAS["pinhole"], BOARDS["charuco"]
    R, t = placed(board, (0.35, -0.25, 0.1), 0.55)
    image = render(cam, board, R, t, px_per_m=1600)
    assert edge_rise_px(image)[0] < 3.0
    motion = cv2.filter2D(image, -1, np.full((1, 25), 1 / 25))
    for blurred in (cv2.GaussianBlur(image, (0, 0), 4.0), motion):
        result = detect(blurred, board)
        assert isinstance(result, Rejected) and result.reason in ("blurred", "too few corners")
        assert result.reason == "blurred", result


@pytest.mark.parametrize("seed", range(1))
def test_any_array_is_detected_or_rejected_never_raised(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shapes = [
        (240, 320),
        (240, 320, 3),
        (240, 320, 4),
        (9, 9),
        (3,),
        (240, 320, 2),
        (0, 5),
        (4, 4, 4, 4),
    ]
    dtypes = [np.uint8, np.uint16, np.float32, np.int8]
    for shape in shapes:
        for dtype in dtypes:
            data = rng.integers(0, 256, size=shape).astype(dtype)
            for board in BOARDS.values():
                result = detect(data, board)
                assert isinstance(result, (Detection, Rejected))
                if isinstance(result, Rejected):
                    assert result.reason in REASONS
    for junk in (None, b"\x89PNG\r\n", "image", 3.0, np.array(object())):
        result = detect(junk, BOARDS["charuco"])
        assert isinstance(result, Rejected) and result.reason == "unreadable image"


def test_tally_counts_and_names_frames() -> None:
    board = BOARDS["charuco"]
    drawn = board.image(1000.0).pixels
    blank = np.full((480, 640), 128, np.uint8)
    outcomes = [detect(x, board) for x in (drawn, blank, blank, drawn, blank, blank, b"x")]
    summary = tally(outcomes, first_index=10).summary()
    assert summary == (
        "2 of 7 frame(s) with the target; 4 no target (frames 11, 12, 14, …), "
        "1 unreadable image (frame 16)"
    )
