"""The path protocols of a simulated session: still poses along a straight line (``line``) or a
planar curve (``curve``), the target frame's orientation held — a task session as a robot's
controller runs it (its joint targets from the nominal's inverse kinematics, so the true robot
misses the path by its own error) — and the cell changed since the calibration: the tracker
re-stationed (:data:`RESTATION`) and the probe re-mounted (:data:`REMOUNT_SHIFT`,
:data:`REMOUNT_TURN`)."""

from __future__ import annotations

import math

import numpy as np

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray, rotation_about, rotation_from_vector
from dhlog.model.ik import IKSettings, solve, tool_poses
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig

#: The joint vector a path is centred on (its first joints; clipped into the limits, zeros for
#: further joints): the flange away from singularities for the library's 6R arms.
PATH_CENTRE = (0.1, -0.3, 0.4, 0.2, 0.5, 0.3)
#: The line's direction in the robot's base frame (a unit vector); the curve's plane holds it.
PATH_DIRECTION = (0.6, 0.64, 0.48)
#: The tracker re-stationed since the calibration: moved by this (m, in the tracker's old frame)
#: and turned by this (rad) about its old vertical axis (0.61 m, 125°: to the other side).
RESTATION = ((0.42, -0.38, 0.22), math.radians(125.0))
#: The probe re-mounted since the calibration: its point moved this much on the flange (m, in
#: the last frame: 0.955 mm) …
REMOUNT_SHIFT = (0.6e-3, 0.5e-3, 0.55e-3)
#: … and its frame turned by this rotation vector (rad, in the probe's frame: 1.6°).
REMOUNT_TURN = tuple(math.radians(1.6) * v for v in (0.0, 0.6, 0.8))


class PathError(DhlogError):
    """A path the robot cannot follow within its limits."""


def restationed(T_measurement_robot: FloatArray) -> FloatArray:
    """``T_measurement_robot`` after the tracker moved by :data:`RESTATION`: the robot as the
    re-stationed tracker sees it."""
    shift, turn = RESTATION
    move = np.eye(4)  # the new station in the old tracker frame
    move[:3, :3] = rotation_about(np.array([0.0, 0.0, 1.0]), turn)
    move[:3, 3] = shift
    return np.asarray(np.linalg.inv(move) @ T_measurement_robot, dtype=np.float64)


def remounted_rotation(tool_rotation: tuple[float, float, float]) -> FloatArray:
    """The probe's frame on the flange after the re-mount: turned by :data:`REMOUNT_TURN`."""
    return np.asarray(
        rotation_from_vector(np.asarray(tool_rotation, dtype=np.float64))
        @ rotation_from_vector(np.asarray(REMOUNT_TURN, dtype=np.float64)),
        dtype=np.float64,
    )


def path_points(kind: str, k: int, length: float) -> FloatArray:
    """``k`` points (k, 3) of the path about the origin in the base frame's orientation: a
    straight ``line`` of ``length`` along :data:`PATH_DIRECTION`, or a planar ``curve`` (an S:
    ``length`` long along that direction, ``length`` / 2 across it, in the plane it spans with
    the horizontal normal to it)."""
    u = np.asarray(PATH_DIRECTION, dtype=np.float64)
    u /= np.linalg.norm(u)
    s = np.linspace(-0.5, 0.5, k)
    if kind == "line":
        return np.asarray(np.outer(s * length, u), dtype=np.float64)
    v = np.cross(u, [0.0, 0.0, 1.0])
    v /= np.linalg.norm(v)
    phi = s * math.pi
    return np.asarray(
        np.outer(0.5 * length * np.sin(phi), u) + np.outer(0.25 * length * np.sin(2 * phi), v),
        dtype=np.float64,
    )


def path_poses(robot: Robot, cfg: SimulationConfig) -> FloatArray:
    """The ``line`` or ``curve`` protocol's still poses (``cfg.poses``, n): the joint vectors
    that put the nominal's tool point on the path (:func:`path_points`, ``cfg.path_length``)
    about its position at :data:`PATH_CENTRE`, the flange's orientation there held — the
    nominal's inverse kinematics, as the controller's. Raises :class:`PathError` when a point
    of the path is out of reach within the limits."""
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    centre = np.zeros(robot.n)
    head = np.asarray(PATH_CENTRE[: robot.n], dtype=np.float64)
    centre[: head.size] = head
    centre = np.clip(centre, lo, hi)
    start = tool_poses(robot.table, centre, robot.tool_point)
    offsets = path_points(cfg.protocol, cfg.poses, cfg.path_length)
    goal = np.repeat(start[None], cfg.poses, axis=0)
    goal[:, :3, 3] += offsets
    reach = float(np.linalg.norm(start[:3, 3])) or 1.0
    found = solve(
        robot.table,
        goal,
        np.repeat(centre[None], cfg.poses, axis=0),
        robot.tool_point,
        limits=robot.limits,
        length=reach,
        settings=IKSettings(tol=1e-10),
    )
    missed = np.flatnonzero(~found.converged & (found.position_error > 1e-7))
    if missed.size:
        raise PathError(
            f"the {cfg.protocol} of {cfg.path_length * 1e3:g} mm leaves the reach of "
            f"{robot.name} within its limits at point {int(missed[0]) + 1} of {cfg.poses} "
            f"({found.position_error[missed[0]] * 1e3:.3g} mm off); give a shorter "
            "--path-length-mm."
        )
    return np.asarray(found.q, dtype=np.float64)
