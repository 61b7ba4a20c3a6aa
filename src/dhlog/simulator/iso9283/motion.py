"""Where the simulated robot's target is at any time of an ISO 9283 test (:func:`motion_at`): its
true forward kinematics of the commanded joints plus the repeatability's offset and rotation,
the drift, the overshoot along the approach direction (:func:`approach_directions`) and the
paths' systematic deviation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.iso9283.plan import (
    Iso9283Run,
    _segment_state,
)
from dhlog.simulator.iso9283.shapes import drift_shape, overshoot_shape
from dhlog.simulator.robot import smooth_model_error


@dataclass(frozen=True)
class Motion:
    """The robot at the times ``t`` (s): the commanded joints ``q`` (m, n), the position it
    attains without overshoot ``settled`` (m, 3) and with it ``position`` (m, 3) in the base
    frame, its flange's orientation ``R`` (m, 3, 3) in the base frame, and what makes them up:
    ``true_fk`` (the true robot at ``q``), ``drift`` and ``path_offset`` (m, 3)."""

    t: FloatArray
    q: FloatArray
    settled: FloatArray
    position: FloatArray
    R: FloatArray
    true_fk: FloatArray
    drift: FloatArray
    path_offset: FloatArray


def motion_at(
    robot: Robot,
    cfg: SimulationConfig,
    run: Iso9283Run,
    table: StandardDH,
    t: FloatArray,
) -> Motion:
    """The robot of the run at the sorted times ``t`` (s)."""
    from scipy.spatial.transform import Rotation

    n = robot.n
    m = t.size
    q = np.empty((m, n))
    off = np.zeros((m, 3))
    rotvec = np.zeros((m, 3))
    overshoot = np.zeros((m, 3))
    path_offset = np.zeros((m, 3))
    starts = np.array([s.t0 for s in run.segments])
    which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(run.segments) - 1)
    bounds = np.searchsorted(which, np.arange(len(run.segments) + 1))
    tool = np.asarray(run.program.tool_point, dtype=np.float64)
    for i, seg in enumerate(run.segments):
        lo, hi = int(bounds[i]), int(bounds[i + 1])
        if lo == hi:
            continue
        ts = t[lo:hi]
        q[lo:hi], frac, off[lo:hi], rotvec[lo:hi] = _segment_state(seg, ts)
        if seg.path >= 0 and (cfg.path_error > 0 or cfg.path_repeatability > 0):
            pr = run.path_runs[seg.path]
            points = np.asarray(run.program.paths[pr["index"]].points, dtype=np.float64)
            tangent = np.gradient(points, axis=0) if points.shape[0] > 1 else np.zeros((1, 3))
            tan = np.column_stack([np.interp(frac, seg.f, tangent[:, c]) for c in range(3)])
            tan /= np.maximum(np.linalg.norm(tan, axis=1, keepdims=True), 1e-12)
            w = run.deviation_directions[pr["index"]]
            normal = w - np.sum(tan * w, axis=1, keepdims=True) * tan
            normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
            r = pr["random_offset"]
            path_offset[lo:hi] = (
                cfg.path_error * np.sin(np.pi * frac)[:, None] * normal
                + r
                - np.sum(tan * r, axis=1, keepdims=True) * tan
            )
        if seg.visit >= 0 and cfg.overshoot > 0:
            v = run.visits[seg.visit]
            shape = overshoot_shape(ts - seg.t0, cfg.overshoot_frequency, cfg.overshoot_damping)
            overshoot[lo:hi] = cfg.overshoot * shape[:, None] * v["approach"]
    frames = fk_frames(table, q, T_base=robot.T_base)[:, -1]
    true_fk = frames[:, :3, :3] @ tool + frames[:, :3, 3]
    if cfg.model_error > 0:
        true_fk = true_fk + smooth_model_error(robot, cfg)(q)
    drift = cfg.drift * drift_shape(t, run.drift_t0, run.drift_tau, run.drift_scale)[:, None]
    drift = drift * run.drift_direction
    settled = true_fk + off + drift + path_offset
    R = frames[:, :3, :3]
    if np.any(rotvec):
        R = Rotation.from_rotvec(rotvec).as_matrix() @ R
    return Motion(t, q, settled, settled + overshoot, R, true_fk, drift, path_offset)


def approach_directions(robot: Robot, run: Iso9283Run, table: StandardDH, tool: FloatArray) -> None:
    """Each visit's ``approach``: the unit direction (base frame) of the true robot's motion at
    its arrival (zeros where it did not move), in place."""
    arrivals = np.array([v["t_arrival"] for v in run.visits])
    starts = np.array([s.t0 for s in run.segments])
    q_end = np.empty((arrivals.size, robot.n))
    q_before = np.empty((arrivals.size, robot.n))
    for i, t_arr in enumerate(arrivals):
        seg = run.segments[int(np.searchsorted(starts, t_arr, side="left")) - 1]
        q_end[i] = seg.q[-1]
        q_before[i] = seg.q[0] + (seg.q[-1] - seg.q[0]) * 0.98
    pts = []
    for qq in (q_end, q_before):
        frames = fk_frames(table, qq, T_base=robot.T_base)[:, -1]
        pts.append(frames[:, :3, :3] @ tool + frames[:, :3, 3])
    d = pts[0] - pts[1]
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    d = np.where(norm > 1e-12, d / np.maximum(norm, 1e-300), 0.0)
    for v, direction in zip(run.visits, d, strict=True):
        v["approach"] = direction
