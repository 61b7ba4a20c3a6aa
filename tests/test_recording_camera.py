"""The camera view of a result's recording (issue 32, item 7): ``present.recording.camera``
written with the real Rerun SDK, checked by ``rerun rrd verify`` and read back.

The views are built by hand from frames the simulator renders (the KR5, its ChArUco board and
plumb_bob camera, eye-to-hand and eye-in-hand), JPEG- and PNG-encoded by OpenCV and detected by
``frames.detect``; the reprojected corners are the true chain's with the camera moved 1 mm
along its x (about 1 px at the board's distance), so every error vector is a real one."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np
import pyarrow as pa
import pytest
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from dhlog.identify.camera.frames.detect import Detection, detect
from dhlog.identify.run import process_log
from dhlog.model.robots import load_robot
from dhlog.present.recording import write_process_recording
from dhlog.present.recording.blueprint import process_blueprint
from dhlog.present.recording.camera import (
    FITTED_COLOR,
    HELD_OUT_COLOR,
    REPROJECTED_COLOR,
    camera_paths,
    camera_tabs,
    log_cameras,
    pixel_magnification,
)
from dhlog.present.recording.scene import Shown
from dhlog.present.recording.stream import recording_file
from dhlog.present.render import missing, screenshot
from dhlog.simulator import camera as sim
from dhlog.vision.view import CameraView, FrameView
from test_process import SAMPLES, rrd_verify

T0 = 1_700_000_000_000_000_000
#: the reprojection's camera, 1 mm along the true camera's x: each corner about
#: f · 1 mm / distance ≈ 1 px off, a real error vector to draw
SHIFT = np.array([[1.0, 0, 0, 1e-3], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _view(setup: sim.CameraSetup, name: str, count: int = 3) -> CameraView:
    """``count`` rendered frames of ``setup``: the first PNG, the others JPEG, the last held
    out, and one more frame (detected, never kept) without an image."""
    robot = load_robot("kr5")
    rig = sim.place_rig(robot, robot.table, setup, 3)
    q = sim.camera_poses(robot, robot.table, rig, count + 1, 3)
    flanges = sim.flange_poses(robot, robot.table, q)
    board = rig.board.object_points()
    rng = np.random.default_rng(7)
    frames, errors = [], []
    for i, flange in enumerate(flanges):
        mounted = flange @ rig.T_mounted
        T_cam, T_board = (
            (rig.T_fixed, mounted) if setup == "eye-to-hand" else (mounted, rig.T_fixed)
        )
        image = sim.render(rig, np.linalg.inv(T_cam) @ T_board, rng)
        found = detect(image, rig.board, camera=rig.camera)
        assert isinstance(found, Detection), found
        seen = np.linalg.inv(T_cam @ SHIFT) @ T_board
        reprojected = rig.camera.project(board[found.ids] @ seen[:3, :3].T + seen[:3, 3])
        errors.append(reprojected - found.corners_px)
        ext = ".png" if i == 0 else ".jpg"
        data = cv2.imencode(ext, image)[1].tobytes() if i < count else None
        frames.append(
            FrameView(
                t_ns=T0 + (count - i) * 10**9,  # stamps out of order: the drawing sorts them
                index=i,
                image=data,
                image_format="png" if i == 0 else "jpeg",
                ids=found.ids,
                detected_px=found.corners_px,
                reprojected_px=reprojected,
                held_out=i == count - 1,
                T_base_camera=T_cam,
                T_base_board=T_board,
            )
        )
    rms = float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))
    return CameraView(name, setup, rig.camera, board, rms, frames)


@pytest.fixture(scope="module")
def views() -> list[CameraView]:
    return [
        _view("eye-to-hand", "/camera/image_raw/compressed"),
        _view("eye-in-hand", "/wrist/image"),
    ]


def _written(tmp_path: Path, views: list[CameraView]) -> Path:
    path = tmp_path / "cameras.rrd"
    bp = rrb.Blueprint(rrb.Tabs(*camera_tabs(views)))
    with recording_file(path, "dhlog process", bp) as rec:
        log_cameras(rec, views)
    rrd_verify(path)
    return path


def _rows(path: Path) -> dict[tuple[str, str], list[object]]:
    """Every component column of the recording: (entity, column) → its rows, in log order;
    the sensor_time stamps as integer ns under (entity, "<archetype>:sensor_time")."""
    out: dict[tuple[str, str], list[object]] = {}
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        archetype = next((n for n in batch.schema.names if ":" in n), "").split(":")[0]
        for name in batch.schema.names:
            column = batch.column(name)
            if pa.types.is_timestamp(column.type):
                column = column.cast(pa.int64())
                name = f"{archetype}:{name}"
            out.setdefault((chunk.entity_path, name), []).extend(column.to_pylist())
    return out


def _matrix(column_major: list[float]) -> np.ndarray:
    return np.asarray(column_major, dtype=np.float64).reshape(3, 3).T


def test_each_frame_is_stored_compressed_with_its_corners(
    views: list[CameraView], tmp_path: Path
) -> None:
    """Each camera's frames with an image are in the recording at their stamps (sorted), the
    image the log's own bytes (PNG or JPEG, not decoded pixels); the frame without an image is
    not drawn; the corners and the arrows come with each drawn frame."""
    rows = _rows(_written(tmp_path, views))
    for view, path in zip(views, camera_paths(views), strict=True):
        kept = sorted((f for f in view.frames if f.image), key=lambda f: f.t_ns)
        assert len(kept) == len(view.frames) - 1
        image = f"/{path}/image"
        assert rows[(image, "EncodedImage:sensor_time")] == [f.t_ns for f in kept]
        blobs = rows[(image, "EncodedImage:blob")]
        assert [bytes(blob) for (blob,) in blobs] == [f.image for f in kept]
        assert rows[(image, "EncodedImage:media_type")] == [
            ["image/png" if f.image_format == "png" else "image/jpeg"] for f in kept
        ]
        for part, kind in (
            ("detected", "Points2D"),
            ("reprojected", "Points2D"),
            ("errors", "Arrows2D"),
        ):
            assert rows[(f"{image}/{part}", f"{kind}:sensor_time")] == [f.t_ns for f in kept]
        got = rows[(f"{image}/detected", "Points2D:positions")]
        for f, points in zip(kept, got, strict=True):
            assert np.allclose(points, f.detected_px, atol=1e-4)  # float32 in the recording
        board = rows[(f"/world/base/boards/{path.rsplit('/', 1)[1]}", "Points3D:positions")]
        assert any(p and len(p) == len(view.board_points) for p in board)
        assert (f"/report/cameras/{path.rsplit('/', 1)[1]}", "TextDocument:text") in rows
    assert len({p.rsplit("/", 1)[1] for p in camera_paths(views)}) == 2


def test_the_camera_and_board_logged_reproject_onto_the_detected_corners(
    views: list[CameraView], tmp_path: Path
) -> None:
    """The camera's transform and pinhole and the board's 3D corners as the recording holds them
    put the board's corners on the detected ones: projected through the camera frame read back
    (OpenCV's RDF, ``camera_xyz`` [Right, Down, Forward]) and the intrinsics, within 0.5 px of
    the detections. The detections are within 0.1 px RMS of the true corners here (the true
    chain's reprojection); a transform logged inverted, a board on the wrong frame or the
    pinhole's K transposed puts them hundreds of pixels off. The fixed camera (eye-to-hand) is
    static, the camera on the flange (eye-in-hand) moves on sensor_time; the image plane lies
    at the board's distance."""
    rows = _rows(_written(tmp_path, views))
    for view, path in zip(views, camera_paths(views), strict=True):
        part = path.rsplit("/", 1)[1]
        cam = view.intrinsics
        kept = sorted((f for f in view.frames if f.image), key=lambda f: f.t_ns)
        (K,) = rows[(f"/{path}/image", "Pinhole:image_from_camera")][:1]
        assert np.allclose(_matrix(K[0]), cam.K, rtol=1e-6)
        assert rows[(f"/{path}/image", "Pinhole:camera_xyz")][0] == [[3, 2, 5]]  # R, D, F
        assert rows[(f"/{path}/image", "Pinhole:resolution")][0] == [[cam.width, cam.height]]
        turns = rows[(f"/{path}", "Transform3D:mat3x3")]
        shifts = rows[(f"/{path}", "Transform3D:translation")]
        boards = [p for p in rows[(f"/world/base/boards/{part}", "Points3D:positions")] if p]
        moving_camera = view.setup == "eye-in-hand"
        assert len(turns) == (len(kept) if moving_camera else 1)
        assert len(boards) == (1 if moving_camera else len(kept))
        assert ((f"/{path}", "Transform3D:sensor_time") in rows) == moving_camera
        assert ((f"/{path}/image", "Pinhole:sensor_time") in rows) == moving_camera
        axes = rows[(f"/{path}", "TransformAxes3D:axis_length")]
        assert len(axes) == (len(kept) if moving_camera else 1)  # with the camera, never alone
        distances = []
        for k, f in enumerate(kept):
            R = _matrix(turns[k if moving_camera else 0][0])
            t = np.asarray(shifts[k if moving_camera else 0][0])
            corners = np.asarray(boards[0 if moving_camera else k])[f.ids]
            in_camera = (corners - t) @ R  # Rᵀ (p − t), row-wise
            uv = cam.project(in_camera)
            assert np.max(np.linalg.norm(uv - f.detected_px, axis=1)) < 0.5
            distances.append(float(np.median(in_camera[:, 2])))
        # the image plane at the board's median depth (the board's centre, all frames)
        (plane,) = rows[(f"/{path}/image", "Pinhole:image_plane_distance")][0]
        assert abs(plane - np.median(distances)) < 0.1 * plane


def test_the_error_vectors_are_magnified_as_the_view_says(
    views: list[CameraView], tmp_path: Path
) -> None:
    """The arrows go from each detected corner towards its reprojection, k times the error, k
    the 1-2-5 number of the FK-residual tab's rule (the RMS about 2 % of the image's diagonal)
    named in the 2D view's title and the camera's text; held-out frames amber, the others
    blue."""
    path_rrd = _written(tmp_path, views)
    rows = _rows(path_rrd)
    names = [n for (n,) in _layout(path_rrd)["ViewBlueprint:display_name"]]
    for view, path in zip(views, camera_paths(views), strict=True):
        k = pixel_magnification(view)
        diagonal = math.hypot(view.intrinsics.width, view.intrinsics.height)
        assert k > 1 and 0.004 < k * view.rms_px / diagonal <= 0.02, k
        assert str(k / 10 ** math.floor(math.log10(k)))[0] in "125"
        assert any(n.startswith(view.name) and f"errors ×{k:g} [px]" in n for n in names)
        text = rows[(f"/report/cameras/{path.rsplit('/', 1)[1]}", "TextDocument:text")][0]
        assert f"×{k:g}" in text[0] and f"{view.rms_px:.3g} px" in text[0]
        kept = sorted((f for f in view.frames if f.image), key=lambda f: f.t_ns)
        arrows = f"/{path}/image/errors"
        for f, origins, vectors, colors in zip(
            kept,
            rows[(arrows, "Arrows2D:origins")],
            rows[(arrows, "Arrows2D:vectors")],
            rows[(arrows, "Arrows2D:colors")],
            strict=True,
        ):
            want = k * (f.reprojected_px - f.detected_px)
            assert np.allclose(origins, f.detected_px, atol=1e-4)
            assert np.allclose(vectors, want, atol=1e-3 * k)
            assert np.median(np.linalg.norm(want, axis=1)) > 0.3 * k  # about 1 px, magnified
            rgba = (HELD_OUT_COLOR if f.held_out else FITTED_COLOR) + [255]
            assert set(colors) == {int.from_bytes(bytes(rgba), "big")}


def test_a_view_without_images_draws_every_frame_and_no_image(
    views: list[CameraView], tmp_path: Path
) -> None:
    """Frames whose images were not kept: every frame's corners are drawn (nothing to be out
    of step with), no image; bytes that are neither JPEG nor PNG are not drawn and the
    camera's text says how many; a camera without frames is not placed anywhere."""
    bare = dataclasses.replace(
        views[0],
        name="bare",
        frames=[dataclasses.replace(f, image=None) for f in views[0].frames],
    )
    odd = dataclasses.replace(
        views[0],
        name="odd",
        frames=[dataclasses.replace(f, image=b"GIF89a...") for f in views[0].frames],
    )
    empty = dataclasses.replace(views[0], name="empty", frames=[])
    rows = _rows(_written(tmp_path, [bare, odd, empty]))
    # a camera without frames: its text only, nothing placed at the base's origin
    assert not any(e.startswith("/world/base/cameras/empty") for e, _ in rows)
    assert ("/report/cameras/empty", "TextDocument:text") in rows
    for name in ("bare", "odd"):
        image = f"/world/base/cameras/{name}/image"
        assert (image, "EncodedImage:blob") not in rows
        assert len(rows[(f"{image}/detected", "Points2D:sensor_time")]) == len(bare.frames)
    (text,) = rows[("/report/cameras/odd", "TextDocument:text")]
    assert f"{len(odd.frames)} image(s) neither JPEG nor PNG" in text[0]


def test_the_process_recording_draws_the_results_cameras(
    views: list[CameraView], tmp_path: Path
) -> None:
    """``write_process_recording`` draws a result's ``cameras`` (placed in the base frame under
    ``world/base``: the base's place in the 3D views' world), adds a tab per camera and shows
    the sensor_time line; the same result without cameras writes none of it."""
    result = process_log(SAMPLES / "scara.mcap")
    # the field Identification carries for a camera log
    with_cameras = dataclasses.replace(result, cameras=tuple(views))
    path = tmp_path / "run.rrd"
    write_process_recording(with_cameras, path)
    rrd_verify(path)
    rows = _rows(path)
    ex = result.extraction
    assert ex is not None
    (turn,) = rows[("/world/base", "Transform3D:mat3x3")]
    (shift,) = rows[("/world/base", "Transform3D:translation")]
    (turn_m,) = rows[("/world/m", "Transform3D:mat3x3")]
    (shift_m,) = rows[("/world/m", "Transform3D:translation")]
    T_world_m = np.eye(4)
    T_world_m[:3, :3], T_world_m[:3, 3] = _matrix(turn_m[0]), shift_m[0]
    T_world_base = T_world_m @ ex.T_measurement_base
    assert np.allclose(_matrix(turn[0]), T_world_base[:3, :3], atol=1e-6)
    assert np.allclose(shift[0], T_world_base[:3, 3], atol=1e-5)
    for path_ in camera_paths(views):
        assert (f"/{path_}/image", "EncodedImage:blob") in rows
    layout = _layout(path)
    titles = [n for (n,) in layout["ContainerBlueprint:display_name"]]
    assert sum(t.startswith("Camera ") for t in titles) == len(views)
    # scara has residual plots, ranged on joint_position: the time panel stays there
    assert layout["TimePanelBlueprint:timeline"] == [["joint_position"]]
    assert "ContainerBlueprint:active_tab" not in layout
    plain = tmp_path / "plain.rrd"
    write_process_recording(result, plain)
    assert not any(e.startswith("/world/base") for e, _ in _rows(plain))
    # without residual plots the recording opens on sensor_time, on the first camera's tab
    alone = tmp_path / "alone.rrd"
    bp = process_blueprint(Shown.of(result), 1.0, [], views)
    with recording_file(alone, "dhlog process", bp):
        pass
    layout = _layout(alone)
    assert layout["TimePanelBlueprint:timeline"] == [["sensor_time"]]
    assert len(layout["ContainerBlueprint:active_tab"]) == 1


def _layout(path: Path) -> dict[str, list[object]]:
    """The blueprint's component columns: column → its rows."""
    reader = RrdReader(path)
    out: dict[str, list[object]] = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if ":" in name:  # components, not the row ids and blueprint times
                out.setdefault(name, []).extend(batch.column(name).to_pylist())
    return out


@pytest.mark.skipif(missing() is not None, reason=f"cannot render here: {missing()}")
def test_the_viewer_draws_the_image_and_its_corners(
    views: list[CameraView], tmp_path: Path
) -> None:
    """The Rerun viewer itself (``present.render.screenshot``, under Xvfb) draws the camera's
    tab: in the 2D view (the picture's upper half) the decoded JPEG's white board paper, the
    detected corners in their blue (amber: held out) and the reprojected ones in magenta. A
    recording whose image the viewer cannot decode shows no white there; one without corners
    no blue, amber or magenta."""
    from PIL import Image

    path = tmp_path / "camera.rrd"
    bp = rrb.Blueprint(
        rrb.Tabs(*camera_tabs(views[:1])),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="sensor_time"),
    )
    with recording_file(path, "dhlog process", bp) as rec:
        log_cameras(rec, views[:1])
    png = tmp_path / "camera.png"
    screenshot(path, png)
    image = np.asarray(Image.open(png).convert("RGB"), dtype=np.int64)
    h = image.shape[0]
    top = image[int(0.06 * h) : int(0.5 * h)].reshape(-1, 3)

    def near(color: list[int]) -> int:
        return int(np.count_nonzero(np.all(np.abs(top - color) <= 40, axis=1)))

    assert np.count_nonzero(np.all(top > 215, axis=1)) > 0.002 * len(top)
    # the frame at the viewer's first time: fitted (blue) or held out (amber)
    assert near(FITTED_COLOR) + near(HELD_OUT_COLOR) > 100, near(HELD_OUT_COLOR)
    assert near(REPROJECTED_COLOR) > 50, near(REPROJECTED_COLOR)


def test_images_sent_in_batches_arrive_whole_and_in_order(
    views: list[CameraView], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Images handed to the SDK a batch at a time (here one frame a batch: the bound set to a
    byte) arrive as they do in one: every blob at its stamp, in order."""
    from dhlog.present.recording import camera

    monkeypatch.setattr(camera, "IMAGE_BATCH_BYTES", 1)
    rows = _rows(_written(tmp_path, views))
    chunks = [
        c
        for c in RrdReader(tmp_path / "cameras.rrd").stream()
        if "EncodedImage:blob" in c.to_record_batch().schema.names
    ]
    assert len(chunks) >= sum(1 for v in views for f in v.frames if f.image)
    for view, path in zip(views, camera_paths(views), strict=True):
        kept = sorted((f for f in view.frames if f.image), key=lambda f: f.t_ns)
        image = f"/{path}/image"
        assert rows[(image, "EncodedImage:sensor_time")] == [f.t_ns for f in kept]
        assert [bytes(b) for (b,) in rows[(image, "EncodedImage:blob")]] == [f.image for f in kept]
