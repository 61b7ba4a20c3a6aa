"""A camera calibration's inputs for tests, without rendering: the simulator's rig (a KR5 off its
nominal, its camera and board), still poses where the board is seen, and the corners projected
through the true chain with Gaussian noise of ``SIGMA_PX`` per coordinate, as
``frames.observations.Observations`` or ``identify.camera.pixels.Corners``; the model the truth is
in the fit's frames, and the truth read in the result's DH conventions."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from dhlog.identify.camera.frames.detect import Tally
from dhlog.identify.camera.frames.observations import Observations
from dhlog.identify.camera.pixels import Corners
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.read.extract import extract_dh
from dhlog.model.robots import load_robot
from dhlog.simulator.camera import BOARD, CAMERA, Rig, camera_poses, flange_poses, place_rig
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.robot import perturbed

SIGMA_PX = 0.2


def session(setup: str, seed: int, poses: int = 50, robot_name: str = "kr5") -> Any:
    """(robot, true table 0.2 mm / 0.05° off, rig, joint vectors where the board is seen)."""
    robot = load_robot(robot_name)
    cfg = SimulationConfig(perturb_length=2e-4, perturb_angle=math.radians(0.05))
    true = perturbed(robot.table, np.random.default_rng(seed), cfg)
    rig = place_rig(robot, true, setup, seed)  # type: ignore[arg-type]
    Q = camera_poses(robot, true, rig, poses, seed)
    return robot, true, rig, Q


def corners(rig: Rig, true: Any, robot: Any, Q: np.ndarray, rng: np.random.Generator) -> Any:
    """Each frame's corner ids and noisy pixels (those inside the image)."""
    T_cb = rig.board_in_camera(flange_poses(robot, true, Q))
    obj = BOARD.object_points()
    ids, uv = [], []
    for f in range(len(Q)):
        X = obj @ T_cb[f, :3, :3].T + T_cb[f, :3, 3]
        p = CAMERA.project(X)
        inside = (p[:, 0] > 0) & (p[:, 0] < CAMERA.width - 1)
        inside &= (p[:, 1] > 0) & (p[:, 1] < CAMERA.height - 1)
        ids.append(np.flatnonzero(inside).astype(np.int64))
        uv.append(p[inside] + rng.normal(scale=SIGMA_PX, size=(int(inside.sum()), 2)))
    return ids, uv


def observations(robot: Any, Q: np.ndarray, ids: Any, uv: Any) -> Observations:
    """The detections as ``frames.observe`` gives them (a frame every 2 s, every frame detected)."""
    f = len(Q)
    tally = Tally(frames=f, detected=f)
    return Observations(
        "simulated.mcap",
        "/camera/image_raw/compressed",
        CAMERA,
        BOARD,
        (np.arange(f) * 2_000_000_000).astype(np.int64),
        np.arange(f, dtype=np.int64),
        Q,
        [f"joint_{k + 1}" for k in range(robot.n)],
        ids,
        uv,
        tally,
    )


def centre() -> np.ndarray:
    pts = BOARD.object_points()
    return np.asarray((pts.min(axis=0) + pts.max(axis=0)) / 2.0, dtype=np.float64)


def model(rig: Rig, table: object, n: int) -> AxisModel:
    """The model ``table`` is in the fit's frames: M the camera (eye-to-hand) or the board's
    centred frame (eye-in-hand), the chain carrying the board's centre or the camera."""
    shift = np.eye(4)
    shift[:3, 3] = centre()
    ref = np.zeros(n)
    if rig.setup == "eye-to-hand":
        T = rig.T_mounted @ shift
        return AxisModel.of_table(
            table,  # type: ignore[arg-type]
            ref,
            T[:3, 3],
            np.asarray(np.linalg.inv(rig.T_fixed), dtype=np.float64),
            tool_rotation=T[:3, :3],
        )
    return AxisModel.of_table(
        table,  # type: ignore[arg-type]
        ref,
        rig.T_mounted[:3, 3],
        np.asarray(np.linalg.inv(rig.T_fixed @ shift), dtype=np.float64),
        tool_rotation=rig.T_mounted[:3, :3],
    )


def data(Q: np.ndarray, ids: list[np.ndarray], uv: list[np.ndarray]) -> Corners:
    points = BOARD.object_points() - centre()
    counts = [i.size for i in ids]
    return Corners(
        Q,
        np.repeat(np.arange(len(Q)), counts).astype(np.intp),
        points[np.concatenate(ids)],
        np.vstack(uv),
    )


def fixed_in_base(rig: Rig, true: Any, nominal: Any, n: int) -> np.ndarray:
    """The fixed part's true pose in the robot's base frame read in the result's conventions
    (the true axes in M, extracted with the same nominal): the camera eye-to-hand, the board
    eye-in-hand."""
    truth = model(rig, true, n)
    ex = extract_dh(
        list(truth.axes),
        truth.types,
        target=truth.target,
        reference_pose=np.zeros(n),
        nominal=nominal,
    )
    T_base_M = np.linalg.inv(ex.T_measurement_base)
    if rig.setup == "eye-in-hand":
        shift = np.eye(4)
        shift[:3, 3] = -centre()
        T_base_M = T_base_M @ shift
    return np.asarray(T_base_M, dtype=np.float64)
