"""What the robot does in a simulated session: each protocol spelled out (:func:`protocol_config`),
the random still poses, coupled moves within the limits, and the trajectory as keyframes with the
joint values between them (see :mod:`dhlog.simulator` for the protocols)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType
from dhlog.model.robots import Robot
from dhlog.simulator.config import COUPLED_PAIR, STILL_PROTOCOLS, SimulationConfig

#: smallest change of every joint from one random pose to the next, as a fraction of its range
MIN_POSE_CHANGE = 0.05


def protocol_config(cfg: SimulationConfig) -> SimulationConfig:
    """``cfg`` with what its protocol implies spelled out: step-and-measure for ``random-poses``,
    the paths (``line``, ``curve``) and ``coupled``; for ``coupled`` joint 2 never swept alone
    and moved together with 3."""
    if cfg.protocol in STILL_PROTOCOLS:
        return replace(cfg, motion="step")
    if cfg.protocol == "coupled":
        a, b, _ = COUPLED_PAIR
        pairs = cfg.coupled
        if not any((p, q) == (a, b) for p, q, _ in pairs):
            pairs = (*pairs, COUPLED_PAIR)
        skip = tuple(sorted({*cfg.skip_joints, a}))
        return replace(cfg, motion="step", skip_joints=skip, coupled=pairs)
    return cfg


def swept_joints(robot: Robot, cfg: SimulationConfig) -> list[int]:
    """The joints (1-based) a session of ``cfg`` sweeps alone."""
    if cfg.protocol in (*STILL_PROTOCOLS, "iso9283"):
        return []
    skip = {*protocol_config(cfg).skip_joints, *(j for j, _ in cfg.parked)}
    return [j for j in range(1, robot.n + 1) if j not in skip]


def parked_home(home: FloatArray, cfg: SimulationConfig) -> FloatArray:
    """``home`` with each parked joint at its parked value."""
    out = np.array(home, dtype=np.float64)
    for j, value in cfg.parked:
        out[j - 1] = value
    return out


def random_poses(robot: Robot, cfg: SimulationConfig, home: FloatArray) -> FloatArray:
    """The ``random-poses`` protocol's still poses (``cfg.poses``, n): drawn uniformly within the
    robot's joint limits from their own generator (the session's other draws stay as they are),
    every joint changing by at least ``MIN_POSE_CHANGE`` of its range from one pose to the next
    (the first from ``home``)."""
    if cfg.pose_list:
        return np.array(cfg.pose_list, dtype=np.float64)
    rng = np.random.default_rng([cfg.seed if cfg.pose_seed is None else cfg.pose_seed, 18])
    if cfg.parked:
        return _parked_poses(random_poses(robot, replace(cfg, parked=()), home), cfg, rng)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    least = MIN_POSE_CHANGE * (hi - lo)
    poses = np.empty((cfg.poses, robot.n))
    previous = home
    for i in range(cfg.poses):
        pose = rng.uniform(lo, hi)
        for _ in range(100):  # a joint too close to its previous value is drawn again
            close = np.abs(pose - previous) < least
            if not np.any(close):
                break
            pose[close] = rng.uniform(lo[close], hi[close])
        poses[i] = previous = pose
    return poses


def _parked_poses(poses: FloatArray, cfg: SimulationConfig, rng: np.random.Generator) -> FloatArray:
    """``poses`` with each parked joint at its value, wandering within ±park_wander/2."""
    out = poses.copy()
    half = cfg.park_wander / 2
    for j, value in cfg.parked:
        out[:, j - 1] = value + rng.uniform(-half, half, len(out))
    return out


def coupled_range(
    robot: Robot, home: FloatArray, pair: tuple[int, int, float], extent: float
) -> tuple[float, float]:
    """The range ``(s_start, s_end)`` of a coupled move ``q_a = home_a + s``,
    ``q_b = home_b + ratio · s``: ``extent`` wide about home where the limits of both joints
    allow it, else shifted (and if need be shortened) to fit them, so the ratio always holds."""
    a, b, ratio = pair
    lo, hi = robot.limits[:, 0] - home, robot.limits[:, 1] - home
    s_lo, s_hi = float(lo[a - 1]), float(hi[a - 1])
    if ratio != 0:
        ends = sorted((float(lo[b - 1]) / ratio, float(hi[b - 1]) / ratio))
        s_lo, s_hi = max(s_lo, ends[0]), min(s_hi, ends[1])
    width = max(0.0, min(extent, s_hi - s_lo))
    centre = min(max(0.0, s_lo + width / 2.0), s_hi - width / 2.0)
    return centre - width / 2.0, centre + width / 2.0


def keyframes(
    robot: Robot,
    home: FloatArray,
    cfg: SimulationConfig,
    rng: np.random.Generator,
    poses: FloatArray,
) -> tuple[list[tuple[float, FloatArray]], list[tuple[float, int | None]], FloatArray]:
    """Piecewise-linear trajectory (time s, q), phase markers (time s, joint or None), and each
    joint's sweep (rad) or travel (m) as the limits let it be (0 for joints not swept). ``cfg``
    with its protocol spelled out (:func:`protocol_config`); ``poses`` (k, n): the random still
    poses, visited first."""
    n = robot.n
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    frames: list[tuple[float, FloatArray]] = [(0.0, home.copy())]
    marks: list[tuple[float, int | None]] = [(0.0, None)]
    t, q = 0.0, home.copy()
    sweeps = np.zeros(n)
    revolute = [jt is JointType.REVOLUTE for jt in robot.table.joint_types]

    def go(target: FloatArray, speed_scale: float = 1.0) -> None:
        nonlocal t, q
        step = np.abs(target - q)
        speed = np.where(revolute, cfg.speed, cfg.linear_speed) * speed_scale
        duration = float(np.max(step / speed)) if np.any(step > 0) else 0.0
        t += max(duration, 0.05)
        q = target.copy()
        frames.append((t, q.copy()))

    def hold(seconds: float) -> None:
        nonlocal t
        t += seconds
        frames.append((t, q.copy()))

    for pose in poses:  # point-to-point moves of every joint, at the transitions' speed
        go(pose, 1.5)
        hold(cfg.dwell)
    # joints held at home in the lock poses: the coupled protocol's pair moves only together
    held = [j - 1 for a, b, _ in cfg.coupled for j in (a, b)] if cfg.protocol == "coupled" else []
    for k in range(n):
        if k + 1 in cfg.skip_joints or cfg.protocol in STILL_PROTOCOLS:
            continue
        if any(j == k + 1 for j, _ in cfg.parked):
            continue
        lock = home.copy()
        if cfg.lock_poses == "random":
            span = hi - lo
            lock = np.clip(home + rng.uniform(-0.15, 0.15, n) * span, lo, hi)
            if held:
                lock[held] = home[held]
            for j, _ in cfg.parked:
                lock[j - 1] = home[j - 1]
        half = (cfg.sweep if revolute[k] else cfg.travel) / 2.0
        start = float(np.clip(lock[k] - half, lo[k], hi[k]))
        end = float(np.clip(lock[k] + half, lo[k], hi[k]))
        sweeps[k] = end - start
        target = lock.copy()
        target[k] = start
        go(target, 1.5)  # transition: several joints at once
        hold(cfg.dwell)
        marks.append((t - cfg.dwell * 0.9, k + 1))
        if cfg.motion == "continuous":
            target[k] = end
            go(target)
        else:
            for value in np.linspace(start, end, cfg.steps)[1:]:
                target[k] = value
                go(target)
                hold(cfg.dwell)
        hold(cfg.dwell)
        marks.append((t - cfg.dwell * 0.1, None))
    for a, b, ratio in cfg.coupled:  # coupled moves: q_b follows ratio · q_a (e.g. q3 = −q2)
        extent = cfg.sweep if revolute[a - 1] else cfg.travel
        s_start, s_end = coupled_range(robot, home, (a, b, ratio), extent)

        def coupled_at(s: float, a: int = a, b: int = b, ratio: float = ratio) -> FloatArray:
            pose = home.copy()
            pose[a - 1] += s
            pose[b - 1] += ratio * s
            return pose

        go(coupled_at(s_start), 1.5)
        hold(cfg.dwell)
        if cfg.motion == "continuous":
            go(coupled_at(s_end))
        else:
            for s in np.linspace(s_start, s_end, cfg.steps)[1:-1]:
                go(coupled_at(float(s)))
                hold(cfg.dwell)
            go(coupled_at(s_end))
        hold(cfg.dwell)
    go(home, 1.5)
    if cfg.protocol not in STILL_PROTOCOLS:  # still poses end on the last of them
        hold(cfg.dwell)
    return frames, marks, sweeps


def joints_at(frames: list[tuple[float, FloatArray]], times: FloatArray) -> FloatArray:
    """Joint values at ``times``: each keyframe-to-keyframe move follows the smooth profile
    ``s = 3τ² − 2τ³`` (zero speed at both ends), as a robot's point-to-point motion does."""
    ft = np.array([f[0] for f in frames])
    fq = np.stack([f[1] for f in frames])
    i = np.clip(np.searchsorted(ft, times, side="right") - 1, 0, len(ft) - 2)
    tau = np.clip((times - ft[i]) / (ft[i + 1] - ft[i]), 0.0, 1.0)
    s = tau * tau * (3.0 - 2.0 * tau)
    return np.asarray(fq[i] + (fq[i + 1] - fq[i]) * s[:, None], dtype=np.float64)


def still_at(frames: list[tuple[float, FloatArray]], times: FloatArray) -> NDArray[np.bool_]:
    """True where ``times`` fall in a keyframe interval without motion."""
    ft = np.array([f[0] for f in frames])
    fq = np.stack([f[1] for f in frames])
    still = np.all(fq[1:] == fq[:-1], axis=1)
    idx = np.clip(np.searchsorted(ft, times, side="right") - 1, 0, len(still) - 1)
    return np.asarray(still[idx])
