"""The tracker of a simulated session and its faults: where it stands, its noise (isotropic
Gaussian or uniform, or the ``tracker`` model: radial and transverse along the line of sight), a
6-DoF target's orientation, gross outliers, dropouts, and the base-plane points it probes.

Every draw comes from the session's generator, in the order ``simulate_session`` calls these
functions (the default session stays the same byte for byte)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, rotation_about, rotation_from_vector
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.simulator.config import SimulationConfig


def default_measurement_pose() -> FloatArray:
    """A tracker 2.5 m in front of the robot, turned and slightly tilted (T_measurement_base)."""
    T = np.eye(4)
    T[:3, :3] = rotation_about(np.array([0.0, 0.0, 1.0]), math.radians(155.0)) @ rotation_about(
        np.array([1.0, 0.0, 0.0]), math.radians(1.5)
    )
    T[:3, 3] = [2.1, -1.3, -0.42]
    return T


def scatter(points: FloatArray, cfg: SimulationConfig, rng: np.random.Generator) -> FloatArray:
    """``points`` (m, 3) as the tracker measures them."""
    if cfg.tracker_model is not None:
        radial, transverse, per_m = cfg.tracker_model
        distance = np.linalg.norm(points, axis=1, keepdims=True)
        u = points / np.maximum(distance, 1e-9)
        e = rng.normal(size=points.shape) * (transverse + per_m * distance)
        e += u * (np.sum(u * e, axis=1, keepdims=True) * -1.0)  # transverse part only
        radial_e = u * rng.normal(scale=radial, size=(points.shape[0], 1))
        return np.asarray(points + e + radial_e, dtype=np.float64)
    if cfg.noise_kind == "uniform":
        return points + rng.uniform(-cfg.noise, cfg.noise, points.shape)
    return points + rng.normal(scale=cfg.noise, size=points.shape)


def measured_rotations(
    table: StandardDH,
    q_arm: FloatArray,
    T_mb: FloatArray,
    cfg: SimulationConfig,
    rng: np.random.Generator,
) -> tuple[FloatArray | None, FloatArray | None]:
    """A 6-DoF target's frame: its fixed rotation in the flange frame (``cfg.tool_rotation``)
    and its orientation in M at the joint values ``q_arm`` (m, n) as measured (tilted by
    ``cfg.orientation_noise``; turned on the flange by the re-mount with ``cfg.remount``); both
    None without a 6-DoF target."""
    if cfg.tool_rotation is None:
        return None, None
    from scipy.spatial.transform import Rotation

    from dhlog.simulator.paths import remounted_rotation

    R_tool = (
        remounted_rotation(cfg.tool_rotation)
        if cfg.remount
        else rotation_from_vector(np.asarray(cfg.tool_rotation, dtype=np.float64))
    )
    point_rot = fk_frames(table, q_arm, T_base=T_mb)[:, -1, :3, :3] @ R_tool
    if cfg.orientation_noise > 0:
        tilt = rng.normal(scale=cfg.orientation_noise, size=(q_arm.shape[0], 3))
        point_rot = Rotation.from_rotvec(tilt).as_matrix() @ point_rot
    return R_tool, point_rot


def add_outliers(xyz: FloatArray, cfg: SimulationConfig, rng: np.random.Generator) -> int:
    """Gross outliers added to a fraction ``cfg.outliers`` of the samples ``xyz`` (m, 3), in
    place: each 1–3 times ``cfg.outlier_size`` away in a random direction. Their count."""
    n_out = round(cfg.outliers * int(xyz.shape[0]))
    if n_out:
        idx = rng.choice(xyz.shape[0], n_out, replace=False)
        direction = rng.normal(size=(n_out, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        xyz[idx] += direction * rng.uniform(1.0, 3.0, (n_out, 1)) * cfg.outlier_size
    return n_out


def dropouts(m: int, cfg: SimulationConfig, rng: np.random.Generator) -> NDArray[np.bool_]:
    """Which of ``m`` samples the tracker keeps: runs of 3–19 samples lost until a fraction
    ``cfg.dropouts`` is."""
    keep = np.ones(m, dtype=bool)
    if cfg.dropouts:
        n_drop = round(cfg.dropouts * keep.size)
        while np.count_nonzero(~keep) < n_drop:
            start = int(rng.integers(0, keep.size))
            keep[start : start + int(rng.integers(3, 20))] = False
    return keep


def base_points(cfg: SimulationConfig, T_mb: FloatArray, rng: np.random.Generator) -> FloatArray:
    """``cfg.base_points`` points probed on frame 1's xy plane (the mounting plane) around the
    base origin, 0.15–0.45 m from it, as the tracker measures them (m, 3) in M."""
    radius = rng.uniform(0.15, 0.45, cfg.base_points)
    angle = rng.uniform(0, 2 * np.pi, cfg.base_points)
    local = np.column_stack(
        [radius * np.cos(angle), radius * np.sin(angle), np.zeros(cfg.base_points)]
    )
    return scatter(local @ T_mb[:3, :3].T + T_mb[:3, 3], cfg, rng)
