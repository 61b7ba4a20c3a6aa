"""Where the fixed camera or board stands (:class:`Rig`) and which poses see the board.

A pose is kept only when the board is seen (:func:`seen`): at least :data:`MIN_IN_VIEW` of its
corners inside the image and its face tilted less than :data:`MAX_TILT` from the line of sight;
with the ``full-hd`` and ``small`` presets also every square imaged at least 20 px a side
(markers of 14.7 px and more, which OpenCV decodes: the 0.3 m board 2.8 m away at 60° has
squares of 8 px, and half of such frames were lost).

For still poses the fixed part is placed along the direction (of :func:`_directions`: level or
above, never under the floor) from which the most of :data:`PLACEMENT_PROBES` random joint
vectors see the board (:func:`place_rig`); the poses are drawn uniformly within the limits and
kept only where the board is seen (:func:`camera_poses`). Several cameras (eye-to-hand): along
the directions the most probes see the board from, at least :data:`CAMERA_SPREAD` apart
(:func:`_spread_rigs`), or looking at one point from :data:`CAMERA_OFFSETS` about it
(:func:`_spread_rigs_about`: the moving protocols).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot
from dhlog.simulator.camera.presets import (
    BOARD,
    CAMERA,
    CAMERA_ON_FLANGE,
    PRESETS,
    CameraPreset,
    CameraSetup,
    board_on_flange,
)
from dhlog.vision.boards import BoardSpec
from dhlog.vision.camera import Intrinsics

#: the share of the board's corners that must be in the image for a pose to be kept
MIN_IN_VIEW = 0.8


#: the largest angle between the board's face and the line of sight for a pose to be kept, rad
MAX_TILT = math.radians(60.0)


#: random joint vectors tried for placing the fixed camera or board
PLACEMENT_PROBES = 600


#: several cameras (eye-to-hand): at most this many; the least angle between two cameras'
#: directions for the still poses; the others' offsets (azimuth, elevation; degrees) from the
#: first about the board's centre at the sweeps' home
MAX_CAMERAS = 6


CAMERA_SPREAD = math.radians(40.0)


CAMERA_OFFSETS = ((35.0, 0.0), (-35.0, 0.0), (0.0, 30.0), (35.0, 30.0), (-35.0, 30.0))


@dataclass(frozen=True)
class Rig:
    """The camera set-up: ``T_fixed`` the fixed part in the robot's base frame (the camera for
    eye-to-hand, the board for eye-in-hand), ``T_mounted`` the part on the flange (the board for
    eye-to-hand, the camera for eye-in-hand); the board and the intrinsics."""

    setup: CameraSetup
    T_fixed: FloatArray
    T_mounted: FloatArray
    board: BoardSpec = BOARD
    camera: Intrinsics = CAMERA
    #: the smallest side (px) of the board's squares as imaged for a pose to be kept (0: any)
    min_square_px: float = 0.0

    def board_in_camera(self, T_base_flange: FloatArray) -> FloatArray:
        """The board's frame in the camera's (…, 4, 4) at flange poses (…, 4, 4) in the base."""
        if self.setup == "eye-to-hand":
            return np.linalg.inv(self.T_fixed) @ T_base_flange @ self.T_mounted
        return np.linalg.inv(T_base_flange @ self.T_mounted) @ self.T_fixed

    def document(self) -> dict[str, object]:
        """The truth's ``camera`` block."""
        fixed, mounted = (
            ("T_base_camera", "T_flange_board")
            if self.setup == "eye-to-hand"
            else ("T_base_board", "T_flange_camera")
        )
        b, c = self.board, self.camera
        return {
            "setup": self.setup,
            fixed: self.T_fixed.tolist(),
            mounted: self.T_mounted.tolist(),
            "board": {
                "kind": b.kind,
                "dictionary": b.dictionary,
                "squares": list(b.squares),
                "square_m": b.square_m,
                "marker_m": b.marker_m,
                "first_id": b.first_id,
            },
            "intrinsics": {
                "width": c.width,
                "height": c.height,
                "K": c.K.tolist(),
                "distortion_model": c.model,
                "D": c.coefficients.tolist(),
            },
        }


def flange_poses(robot: Robot, session_table: object, q: FloatArray) -> FloatArray:
    """The flange's frames (m, 4, 4) in the robot's base frame (the table's frame 1)."""
    return np.asarray(fk_frames(session_table, q)[..., -1, :, :])  # type: ignore[arg-type]


def seen(rig: Rig, T_cam_board: FloatArray) -> NDArray[np.bool_]:
    """Which board poses (m, 4, 4) in the camera the pose test keeps: at least
    ``MIN_IN_VIEW`` of the corners inside the image (a pixel's margin) and the face tilted
    less than ``MAX_TILT`` from the line of sight to its centre; for a ChArUco board, every
    square imaged at least ``rig.min_square_px`` a side (where that is set)."""
    P = rig.board.object_points()
    pts = np.einsum("mij,kj->mki", T_cam_board[:, :3, :3], P) + T_cam_board[:, None, :3, 3]
    uv = rig.camera.project(pts.reshape(-1, 3)).reshape(len(pts), -1, 2)
    w, h = rig.camera.size
    inside = (uv[..., 0] > 1) & (uv[..., 0] < w - 2) & (uv[..., 1] > 1) & (uv[..., 1] < h - 2)
    centre = pts.mean(axis=1)
    sight = centre / np.linalg.norm(centre, axis=1, keepdims=True)
    # the printed face looks along the board's −z: towards the camera when z is along the sight
    facing = np.einsum("mi,mi->m", T_cam_board[:, :3, 2], sight)
    ok = (inside.mean(axis=1) >= MIN_IN_VIEW) & (facing > math.cos(MAX_TILT))
    if rig.min_square_px > 0 and rig.board.kind == "charuco":
        cols, rows = rig.board.squares
        grid = uv.reshape(len(pts), rows - 1, cols - 1, 2)  # corner ids run along x first
        along_x = np.linalg.norm(np.diff(grid, axis=2), axis=-1).reshape(len(pts), -1)
        along_y = np.linalg.norm(np.diff(grid, axis=1), axis=-1).reshape(len(pts), -1)
        sides = np.concatenate([along_x, along_y], axis=1)
        with np.errstate(invalid="ignore"):
            ok &= np.all(sides >= rig.min_square_px, axis=1)  # NaN (behind the camera): not
    return np.asarray(ok)


def _directions() -> FloatArray:
    """Candidate directions from the workspace's centre: 16 azimuths at elevations 0°, 30°
    and 60°, and straight up."""
    out = [[0.0, 0.0, 1.0]]
    for el in (0.0, 30.0, 60.0):
        for az in range(0, 360, 360 // 16):
            e, a = math.radians(el), math.radians(az)
            out.append([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    return np.array(out)


def _looking_at(eye: FloatArray, target: FloatArray) -> FloatArray:
    """A frame at ``eye`` whose z looks at ``target``, its x level where it can be."""
    z = (target - eye) / np.linalg.norm(target - eye)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.95 else np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = eye
    return T


def _workspace_centre(robot: Robot, table: object, seed: int) -> FloatArray:
    """The mean flange position (3,) over ``PLACEMENT_PROBES`` random joint vectors."""
    rng = np.random.default_rng([seed, 32])
    probes = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (PLACEMENT_PROBES, robot.n))
    return np.asarray(flange_poses(robot, table, probes)[:, :3, 3].mean(axis=0))


def _rig(setup: CameraSetup, T_fixed: FloatArray, preset: CameraPreset) -> Rig:
    mounted = board_on_flange(preset.board) if setup == "eye-to-hand" else CAMERA_ON_FLANGE
    return Rig(setup, T_fixed, mounted, preset.board, preset.camera, preset.min_square_px)


def place_rig(
    robot: Robot,
    table: object,
    setup: CameraSetup,
    seed: int,
    preset: CameraPreset = PRESETS["default"],
) -> Rig:
    """The rig with its fixed part placed along the direction from the workspace's centre
    (the mean flange position over ``PLACEMENT_PROBES`` random joint vectors) from which the most
    of those vectors see the board."""
    rng = np.random.default_rng([seed, 32])
    probes = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (PLACEMENT_PROBES, robot.n))
    flanges = flange_poses(robot, table, probes)
    centre = flanges[:, :3, 3].mean(axis=0)
    best: tuple[int, Rig] | None = None
    for d in _directions():
        if setup == "eye-to-hand":
            eye = centre + preset.camera_distance * d
            rig = _rig(setup, _looking_at(eye, centre), preset)
        else:  # the board faces the centre: its z (into the board) points away from it
            far = centre + preset.board_distance * d
            T = _looking_at(centre, far)
            w, h = preset.board.size_m
            T[:3, 3] = far - T[:3, :3] @ np.array([w / 2, h / 2, 0.0])
            rig = _rig(setup, T, preset)
        count = int(np.count_nonzero(seen(rig, rig.board_in_camera(flanges))))
        if best is None or count > best[0]:
            best = (count, rig)
    assert best is not None
    return best[1]


def _spread_rigs(
    robot: Robot, table: object, kit: CameraPreset, seed: int, cameras: int
) -> list[Rig]:
    """Eye-to-hand, several cameras for the still poses: along the directions (of
    :func:`_directions`) from which the most random joint vectors see the board, each at least
    :data:`CAMERA_SPREAD` from the others."""
    rng = np.random.default_rng([seed, 32])
    probes = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (PLACEMENT_PROBES, robot.n))
    flanges = flange_poses(robot, table, probes)
    centre = flanges[:, :3, 3].mean(axis=0)
    scored = []
    for d in _directions():
        rig = _rig("eye-to-hand", _looking_at(centre + kit.camera_distance * d, centre), kit)
        scored.append((int(np.count_nonzero(seen(rig, rig.board_in_camera(flanges)))), d, rig))
    scored.sort(key=lambda item: -item[0])  # stable: ties in _directions' order
    chosen: list[tuple[FloatArray, Rig]] = []
    for _, d, rig in scored:
        if all(float(d @ other) < math.cos(CAMERA_SPREAD) for other, _ in chosen):
            chosen.append((d, rig))
        if len(chosen) == cameras:
            break
    return [rig for _, rig in chosen]


def _spread_rigs_about(rig: Rig, kit: CameraPreset, cameras: int) -> list[Rig]:
    """Eye-to-hand, several cameras for a moving protocol: the first ``rig`` and the others
    looking at the same point (the board's centre at the sweeps' home), moved about it by
    :data:`CAMERA_OFFSETS` (azimuth, elevation) from the first, never below level."""
    eye = rig.T_fixed[:3, 3]
    target = eye + kit.camera_distance * rig.T_fixed[:3, 2]
    back = (eye - target) / kit.camera_distance
    az0 = math.atan2(back[1], back[0])
    el0 = math.asin(max(-1.0, min(1.0, back[2])))
    out = [rig]
    for daz, del_ in CAMERA_OFFSETS[: cameras - 1]:
        az, el = az0 + math.radians(daz), min(max(el0 + math.radians(del_), 0.0), 1.4)
        d = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        out.append(_rig("eye-to-hand", _looking_at(target + kit.camera_distance * d, target), kit))
    return out


def camera_poses(
    robot: Robot, table: object, rig: Rig | list[Rig], count: int, seed: int
) -> FloatArray:
    """``count`` joint vectors (count, n) drawn uniformly within the limits from their own
    generator, each kept only if the board is seen (:func:`seen`; by one camera at least of
    a list of rigs)."""
    rigs = [rig] if isinstance(rig, Rig) else rig
    rng = np.random.default_rng([seed, 33])
    kept: list[FloatArray] = []
    for _ in range(200):
        q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (max(256, 4 * count), robot.n))
        flanges = flange_poses(robot, table, q)
        ok = np.zeros(len(q), dtype=bool)
        for r in rigs:
            ok |= seen(r, r.board_in_camera(flanges))
        kept.extend(q[ok])
        if len(kept) >= count:
            return np.array(kept[:count])
    raise DhlogError(
        f"{robot.name}: the board was seen at {len(kept)} of {200 * max(256, 4 * count)} random "
        f"joint vectors, fewer than the {count} asked; ask fewer --poses or the other "
        "--camera-setup"
    )
