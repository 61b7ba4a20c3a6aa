"""The ISO 9283 test run by a simulated robot whose performance is known (protocol ``iso9283``).

The robot runs the test program (:mod:`dhlog.iso9283.program`): ``iso_cycles`` cycles of the pose
test, each visiting P1 → P5 → P4 → P3 → P2 (clause 7.2.1) with a dwell of ``iso_dwell`` s at each,
then ``iso_path_cycles`` cycles of the path test, each running every test path at its commanded
speed. The joints are commanded point to point (the smooth profile of
:func:`dhlog.simulator.protocols.joints_at`) and along each path by arc length at constant speed
(trapezoidal, with ramps of ``PATH_RAMP`` s). The robot is the robot off its nominal (the session's
perturbed table and model error, the same draws as a calibration session of the same seed), so the
pose accuracy is its model error at the poses; on its true forward kinematics come

* the repeatability: each visit attains its position off by a random offset (σ ``repeatability``
  per coordinate, base frame) and its orientation by a random rotation (σ
  ``orientation_repeatability`` per axis), blended in during the move into the pose;
* the drift: ``drift`` · u · k (1 − e^(−(t − t₀)/τ)), a warm-up along a fixed direction u from
  the first arrival t₀ (τ = ``drift_time``, or a third of the pose test), k such that the
  barycentre of a cycle's attained positions moves by ``drift`` from the first cycle to the last
  (from 0 to the last cycle with one cycle), going on through the paths;
* the overshoot: at each arrival, ``overshoot`` · v · e^(−ζωt) sin(ωt) / peak along the approach
  direction v, ω = 2π ``overshoot_frequency``, ζ = ``overshoot_damping``, scaled so that its
  largest distance from the final position is ``overshoot``;
* on the paths, a systematic deviation ``path_error`` · sin(π f) · n(f) (f: the fraction of the
  path's length, n: a fixed direction made normal to the path's tangent) and a random offset
  per path cycle (σ ``path_repeatability`` per coordinate, its part normal to the tangent,
  blended in on the way to the path's start and out after its end).

The tracker samples the target at its rate with its noise; the encoders read the commanded joint
trajectory; ``/joint_command`` carries each commanded joint target when it is commanded. The
truth (:func:`truth_block`) lists every visit and every path cycle without tracker noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.iso9283.cube import CYCLE_ORDER, TestProgram
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.robot import perturbed, smooth_model_error
from dhlog.simulator.session import START_NS, Session
from dhlog.simulator.tracker import (
    add_outliers,
    base_points,
    default_measurement_pose,
    dropouts,
    scatter,
)

#: the order of the poses in each cycle of the pose test (clause 7.2.1)
#: seconds still at each path's start and end
PATH_DWELL = 0.5
#: seconds of acceleration to (and from) a path's speed
PATH_RAMP = 0.2
#: the truth block's format
TRUTH_FORMAT = "dhlog.iso9283-truth/1"


@dataclass(frozen=True)
class Segment:
    """One piece of the commanded trajectory from ``t0`` to ``t1`` (s): the joints go through
    ``q`` (k, n) at the arc fractions ``f`` (k,), by the ``profile`` ``smooth`` (point to point,
    zero speed at both ends) or ``path`` (constant speed with ramps); ``off0``/``off1`` and
    ``rot0``/``rot1``: the repeatability's position offset (m) and rotation vector (rad),
    blended from the first to the second along the segment. ``visit``: the visit this segment
    holds (a dwell), ``path``: the path cycle it runs, else −1."""

    t0: float
    t1: float
    q: FloatArray
    f: FloatArray
    profile: str
    off0: FloatArray
    off1: FloatArray
    rot0: FloatArray
    rot1: FloatArray
    visit: int = -1
    path: int = -1


@dataclass
class Iso9283Run:
    """What the ``iso9283`` protocol simulated, for :func:`truth_block` and the writers."""

    program: TestProgram
    segments: list[Segment]
    visits: list[dict[str, Any]]
    path_runs: list[dict[str, Any]]
    drift_direction: FloatArray
    drift_t0: float
    drift_tau: float
    drift_scale: float
    deviation_directions: list[FloatArray]
    command_t: FloatArray
    command_q: FloatArray


#: test programs planned in this process, by robot (planning takes seconds; it is deterministic)
_PROGRAMS: dict[tuple[str, bytes, bytes, bytes, bytes], TestProgram] = {}


def program_of(robot: Robot, cfg: SimulationConfig) -> TestProgram:
    """The ISO 9283 test program of ``robot`` (:func:`dhlog.iso9283.program.test_program`, on
    its nominal model) with the cycles and dwell of ``cfg``."""
    from dhlog.iso9283.program import test_program

    key = (
        robot.name,
        np.asarray(robot.table.link_transforms(np.zeros(robot.n))).tobytes(),
        np.asarray(robot.T_base).tobytes(),
        np.asarray(robot.tool_point).tobytes(),
        np.asarray(robot.limits).tobytes(),
    )
    if key not in _PROGRAMS:
        _PROGRAMS[key] = test_program(robot)
    return replace(
        _PROGRAMS[key], cycles=cfg.iso_cycles, path_cycles=cfg.iso_path_cycles, dwell=cfg.iso_dwell
    )


def overshoot_shape(t: FloatArray, frequency: float, damping: float) -> FloatArray:
    """The arrival's oscillation e^(−ζωt) sin(ωt) (0 before arrival, t < 0), divided by its
    peak: its largest value is 1, at t = atan(1/ζ)/ω."""
    w = 2.0 * math.pi * frequency
    t_peak = math.atan(1.0 / damping) / w
    peak = math.exp(-damping * w * t_peak) * math.sin(w * t_peak)
    shape = np.exp(-damping * w * np.maximum(t, 0.0)) * np.sin(w * np.maximum(t, 0.0)) / peak
    return np.asarray(np.where(t > 0, shape, 0.0), dtype=np.float64)


def stabilisation_truth(
    overshoot: float, frequency: float, damping: float, band: float, horizon: float = 60.0
) -> float:
    """The truth's stabilisation time (s after arrival) of the noise-free arrival of an
    ``overshoot`` (m) with this oscillation: the last instant its distance from the final
    position exceeds ``band`` (m), to 1 µs (0 when it never does)."""
    if overshoot <= band:
        return 0.0
    w = 2.0 * math.pi * frequency
    # beyond the envelope's crossing the oscillation stays within the band
    t_peak = math.atan(1.0 / damping) / w
    peak = math.exp(-damping * w * t_peak) * math.sin(w * t_peak)
    end = min(horizon, math.log(overshoot / (band * peak)) / (damping * w) + 1e-3)
    grid = np.arange(0.0, end, 1e-6)
    outside = np.flatnonzero(overshoot * np.abs(overshoot_shape(grid, frequency, damping)) > band)
    return float(grid[outside[-1]]) if outside.size else 0.0


def drift_shape(t: FloatArray, t0: float, tau: float, scale: float) -> FloatArray:
    """The drift's warm-up ``scale`` · (1 − e^(−(t − t₀)/τ)), 0 until t₀."""
    return np.asarray(-np.expm1(-np.maximum(t - t0, 0.0) / tau) * scale, dtype=np.float64)


def _fraction(tau: FloatArray, profile: str, ramp: float) -> FloatArray:
    """The fraction of a segment's way at its normalised time ``tau`` (0 … 1)."""
    if profile == "smooth":
        return tau * tau * (3.0 - 2.0 * tau)
    r = min(max(ramp, 1e-9), 0.5)
    v = 1.0 / (1.0 - r)
    return np.where(
        tau < r,
        0.5 * v * tau * tau / r,
        np.where(tau > 1.0 - r, 1.0 - 0.5 * v * (1.0 - tau) ** 2 / r, v * (tau - r / 2.0)),
    )


def _segment_state(
    seg: Segment, t: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """At times ``t`` within ``seg``: the commanded joints (m, n), the arc fraction (m,), the
    repeatability's offset (m, 3) and rotation vector (m, 3)."""
    duration = seg.t1 - seg.t0
    tau = np.clip((t - seg.t0) / duration, 0.0, 1.0) if duration > 0 else np.ones_like(t)
    frac = _fraction(tau, seg.profile, PATH_RAMP / duration if duration > 0 else 0.5)
    if seg.q.shape[0] == 2 and seg.f[-1] == 1.0 and seg.f[0] == 0.0:
        q = seg.q[0] + (seg.q[1] - seg.q[0]) * frac[:, None]
    else:
        q = np.column_stack([np.interp(frac, seg.f, seg.q[:, j]) for j in range(seg.q.shape[1])])
    blend = frac if seg.profile == "smooth" else np.ones_like(frac)
    off = seg.off0 + (seg.off1 - seg.off0) * blend[:, None]
    rot = seg.rot0 + (seg.rot1 - seg.rot0) * blend[:, None]
    return np.asarray(q, dtype=np.float64), frac, off, rot


def _normal_part(v: FloatArray, chord: FloatArray) -> FloatArray:
    """``v`` (3,) without its component along ``chord`` (2, 3): its part normal to the path
    where the chord lies (the path's end tangent, as :func:`motion_at` takes it)."""
    d = chord[-1] - chord[0]
    norm = float(np.linalg.norm(d))
    if norm < 1e-12:
        return np.asarray(v, dtype=np.float64)
    d = d / norm
    return np.asarray(v - (v @ d) * d, dtype=np.float64)


def _arc_fractions(points: FloatArray) -> FloatArray:
    """Cumulative length along the polyline ``points`` (k, 3) as a fraction of the whole."""
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    length = np.concatenate([[0.0], np.cumsum(step)])
    return length / max(float(length[-1]), 1e-12)


def _poses_in_order(program: TestProgram) -> list[int]:
    """Indices of the program's poses in the order of a cycle (P1, P5, P4, P3, P2; the
    program's own order for poses named otherwise)."""
    names = [p.name for p in program.poses]
    if sorted(names) == sorted(CYCLE_ORDER):
        return [names.index(name) for name in CYCLE_ORDER]
    return list(range(len(names)))


def plan_run(
    robot: Robot, cfg: SimulationConfig, program: TestProgram, q_home: FloatArray
) -> Iso9283Run:
    """The commanded trajectory of the test (segments), the visits and path cycles with their
    random draws (from the generator ``[seed, 9283]``) and the commanded joint targets."""
    rng = np.random.default_rng([cfg.seed, 9283])
    revolute = np.array([jt is JointType.REVOLUTE for jt in robot.table.joint_types])
    speed = np.where(revolute, cfg.speed, cfg.linear_speed) * 1.5
    segments: list[Segment] = []
    visits: list[dict[str, Any]] = []
    path_runs: list[dict[str, Any]] = []
    commands: list[tuple[float, FloatArray]] = []
    zero = np.zeros(3)
    t, q = 0.0, np.asarray(q_home, dtype=np.float64)
    off, rot = zero, zero

    def move(target: FloatArray, off1: FloatArray, rot1: FloatArray) -> None:
        nonlocal t, q, off, rot
        duration = max(float(np.max(np.abs(target - q) / speed)), 0.25)
        commands.append((t, target.copy()))
        pair = np.stack([q, target])
        segments.append(
            Segment(t, t + duration, pair, np.array([0.0, 1.0]), "smooth", off, off1, rot, rot1)
        )
        t, q, off, rot = t + duration, target.copy(), off1, rot1

    def hold(seconds: float, visit: int = -1) -> None:
        nonlocal t
        pair = np.stack([q, q])
        segments.append(
            Segment(t, t + seconds, pair, np.array([0.0, 1.0]), "smooth", off, off, rot, rot, visit)
        )
        t += seconds

    order = _poses_in_order(program)
    for cycle in range(1, cfg.iso_cycles + 1):
        for k in order:
            pose = program.poses[k]
            offset = rng.normal(scale=cfg.repeatability, size=3)
            rotvec = rng.normal(scale=cfg.orientation_repeatability, size=3)
            move(np.asarray(pose.q, dtype=np.float64), offset, rotvec)
            visits.append(
                {
                    "cycle": cycle,
                    "pose": pose.name,
                    "index": k,
                    "t_arrival": t,
                    "t_leave": t + cfg.iso_dwell,
                    "repeatability_offset": offset,
                    "rotation": rotvec,
                }
            )
            hold(cfg.iso_dwell, len(visits) - 1)
    # the drift: from the first arrival, scaled so that the barycentre of a cycle's visits (at
    # the middle of their dwells) moves by ``drift`` from the first cycle to the last
    drift_t0 = float(visits[0]["t_arrival"])
    mids = np.array([v["t_arrival"] + cfg.iso_dwell / 2 for v in visits]).reshape(
        cfg.iso_cycles, len(order)
    )
    drift_tau = cfg.drift_time if cfg.drift_time > 0 else max(mids[-1, -1] - drift_t0, 1e-3) / 3.0
    warm = drift_shape(mids, drift_t0, drift_tau, 1.0).mean(axis=1)
    span = float(warm[-1] - warm[0]) if cfg.iso_cycles > 1 else float(warm[-1])
    drift_scale = 1.0 / span if span > 0 else 0.0
    drift_direction = rng.normal(size=3)
    drift_direction /= np.linalg.norm(drift_direction)
    deviation_directions = []
    for _ in program.paths:
        w = rng.normal(size=3)
        deviation_directions.append(w / np.linalg.norm(w))
    for cycle in range(1, cfg.iso_path_cycles + 1):
        for k, path in enumerate(program.paths):
            path_q = np.asarray(path.q, dtype=np.float64)
            points = np.asarray(path.points, dtype=np.float64)
            random_offset = rng.normal(scale=cfg.path_repeatability, size=3)
            # the cycle's random offset (its part normal to the path) blended in on the way to
            # the path's start and out after its end: the robot never jumps
            ends = [
                _normal_part(random_offset, points[:2]),
                _normal_part(random_offset, points[-2:]),
            ]
            move(path_q[0], ends[0], zero)
            hold(PATH_DWELL)
            fractions = _arc_fractions(points)
            length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
            duration = length / path.speed + PATH_RAMP
            path_runs.append(
                {
                    "cycle": cycle,
                    "path": path.name,
                    "index": k,
                    "t_start": t,
                    "t_end": t + duration,
                    "random_offset": random_offset,
                }
            )
            # the commanded targets as the interpolator reaches them
            grid = np.linspace(0.0, 1.0, 2001)
            reached = np.interp(fractions, _fraction(grid, "path", PATH_RAMP / duration), grid)
            at = t + reached * duration
            commands += [(float(a), qk) for a, qk in zip(at, path_q, strict=True)]
            segments.append(
                Segment(
                    t, t + duration, path_q, fractions, "path", zero, zero, zero, zero,
                    path=len(path_runs) - 1,
                )
            )  # fmt: skip
            t, q, off = t + duration, path_q[-1].copy(), ends[1]
            hold(PATH_DWELL)
    return Iso9283Run(
        program=program,
        segments=segments,
        visits=visits,
        path_runs=path_runs,
        drift_direction=drift_direction,
        drift_t0=drift_t0,
        drift_tau=drift_tau,
        drift_scale=drift_scale,
        deviation_directions=deviation_directions,
        command_t=np.array([c[0] for c in commands]),
        command_q=np.stack([c[1] for c in commands]),
    )


def commanded_at(run: Iso9283Run, t: FloatArray) -> FloatArray:
    """The commanded joints (m, n) of the run at the sorted times ``t`` (s): what the encoders
    read."""
    starts = np.array([s.t0 for s in run.segments])
    which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(run.segments) - 1)
    bounds = np.searchsorted(which, np.arange(len(run.segments) + 1))
    q = np.empty((t.size, run.segments[0].q.shape[1]))
    for i, seg in enumerate(run.segments):
        lo, hi = int(bounds[i]), int(bounds[i + 1])
        if lo < hi:
            q[lo:hi] = _segment_state(seg, t[lo:hi])[0]
    return q


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


def simulate_iso9283(
    robot: Robot,
    cfg: SimulationConfig,
    *,
    program: TestProgram | None = None,
    T_measurement_robot: FloatArray | None = None,
) -> Session:
    """One ISO 9283 test session of ``robot`` (a :class:`~dhlog.simulator.session.Session` with
    its commanded stream and the ``iso9283`` truth block); ``program``: the test program (by
    default :func:`program_of`)."""

    prog = program_of(robot, cfg) if program is None else program
    rng = np.random.default_rng(cfg.seed)  # the robot: the draws of a calibration session
    table = (
        perturbed(robot.table, rng, cfg)
        if (cfg.perturb_length or cfg.perturb_angle)
        else robot.table
    )
    T_mr = default_measurement_pose() if T_measurement_robot is None else T_measurement_robot
    T_mb = T_mr @ robot.T_base  # the result's base: the table's frame 0
    q_home = np.clip(np.zeros(robot.n), robot.limits[:, 0], robot.limits[:, 1])
    run = plan_run(robot, cfg, prog, q_home)
    tool = np.asarray(prog.tool_point, dtype=np.float64)
    approach_directions(robot, run, table, tool)
    duration = run.segments[-1].t1
    noise_rng = np.random.default_rng([cfg.seed, 9283, 1])
    t_trk = np.arange(0.0, duration, 1.0 / cfg.tracker_rate) + noise_rng.uniform(
        0, 1.0 / cfg.tracker_rate
    )
    t_trk = t_trk[t_trk < duration]
    motion = motion_at(robot, cfg, run, table, t_trk)
    # the program's frame (the nominal's forward kinematics with the robot's base transform)
    xyz = motion.position @ T_mr[:3, :3].T + T_mr[:3, 3]
    point_rot = None
    R_tool = None
    if cfg.tool_rotation is not None:
        from scipy.spatial.transform import Rotation

        R_tool = rotation_from_vector(np.asarray(cfg.tool_rotation, dtype=np.float64))
        point_rot = T_mr[:3, :3] @ motion.R @ R_tool
        if cfg.orientation_noise > 0:
            tilt = noise_rng.normal(scale=cfg.orientation_noise, size=(t_trk.size, 3))
            point_rot = Rotation.from_rotvec(tilt).as_matrix() @ point_rot
    xyz = scatter(xyz, cfg, noise_rng)
    n_out = add_outliers(xyz, cfg, noise_rng)
    keep = dropouts(xyz.shape[0], cfg, noise_rng)
    base_time = 2.0 if cfg.base_points else 0.0
    start_ns = START_NS + round(cfg.start_day * 86_400e9)

    def stamp(seconds: FloatArray) -> NDArray[np.int64]:
        return np.asarray(start_ns + ((seconds + base_time) * 1e9).astype(np.int64))

    t_enc = np.arange(0.0, duration, 1.0 / cfg.joint_rate) + noise_rng.uniform(
        0, 1.0 / cfg.joint_rate
    )
    t_enc = np.sort(t_enc + noise_rng.uniform(-cfg.clock_jitter, cfg.clock_jitter, t_enc.size))
    t_enc = np.clip(t_enc, 0.0, duration)
    q_enc = commanded_at(run, t_enc)
    base = base_points(cfg, T_mb, noise_rng)
    base_t = start_ns + (np.linspace(0.1, base_time - 0.2, cfg.base_points) * 1e9).astype(np.int64)
    block = truth_block(robot, cfg, run, table, motion, stamp, T_mr)
    return Session(
        robot_name=robot.name,
        joint_names=[f"joint_{j + 1}" for j in range(robot.n)],
        joint_types=table.joint_types,
        point_t_ns=stamp(t_trk)[keep],
        point_xyz=np.asarray(xyz[keep], dtype=np.float64),
        joint_t_ns=stamp(t_enc - cfg.clock_offset) if cfg.encoders else np.zeros(0, np.int64),
        joint_q=q_enc if cfg.encoders else np.zeros((0, robot.n)),
        base_t_ns=base_t,
        base_xyz=np.asarray(base, dtype=np.float64),
        phase=[],
        table=table,
        T_measurement_base=T_mb,
        tool_point=tool,
        reference_pose=np.asarray(q_home, dtype=np.float64),
        config=cfg,
        n_outliers=n_out,
        n_dropped=int(np.count_nonzero(~keep)),
        tool_rotation=R_tool,
        point_rotation=None if point_rot is None else np.asarray(point_rot[keep]),
        sweeps=np.zeros(robot.n),
        model_error_xyz=np.zeros((0, 3)),
        command_t_ns=stamp(run.command_t),
        command_q=run.command_q,
        iso9283=block,
    )


def _rounded(values: FloatArray, digits: int = 12) -> Any:
    """``values`` as nested lists of floats rounded to ``digits`` decimals (pm in metres)."""
    return np.round(np.asarray(values, dtype=np.float64), digits).tolist()


def truth_block(
    robot: Robot,
    cfg: SimulationConfig,
    run: Iso9283Run,
    table: StandardDH,
    motion: Motion,
    stamp: Any,
    T_mr: FloatArray,
) -> dict[str, Any]:
    """The truth file's ``iso9283`` block (documented in docs/iso9283.md, "Simulating the
    test"): the settings, the program, every visit and every path cycle, in the robot's base
    frame without tracker noise."""
    prog = run.program
    tool = np.asarray(prog.tool_point, dtype=np.float64)
    # each visit's attained pose at the middle of its dwell, without overshoot
    mid = np.array([0.5 * (v["t_arrival"] + v["t_leave"]) for v in run.visits])
    at_mid = motion_at(robot, replace(cfg, overshoot=0.0), run, table, mid)
    visits = []
    for i, v in enumerate(run.visits):
        pose = prog.poses[v["index"]]
        visits.append(
            {
                "cycle": v["cycle"],
                "pose": v["pose"],
                "t_arrival_ns": int(stamp(np.array([v["t_arrival"]]))[0]),
                "t_leave_ns": int(stamp(np.array([v["t_leave"]]))[0]),
                "q": _rounded(pose.q, 15),
                "commanded": _rounded(np.asarray(pose.T)[:3, 3]),
                "commanded_R": _rounded(np.asarray(pose.T)[:3, :3], 15),
                "attained": _rounded(at_mid.settled[i]),
                "attained_R": _rounded(at_mid.R[i], 15),
                "true_fk": _rounded(at_mid.true_fk[i]),
                "repeatability_offset": _rounded(v["repeatability_offset"]),
                "drift_offset": _rounded(at_mid.drift[i]),
                "approach": _rounded(v["approach"], 15),
            }
        )
    paths = []
    for k, pr in enumerate(run.path_runs):
        inside = (motion.t >= pr["t_start"]) & (motion.t <= pr["t_end"])
        seg = next(s for s in run.segments if s.path == k)
        nominal = fk_frames(robot.table, motion.q[inside], T_base=robot.T_base)[:, -1]
        paths.append(
            {
                "cycle": pr["cycle"],
                "path": pr["path"],
                "t_start_ns": int(stamp(np.array([pr["t_start"]]))[0]),
                "t_end_ns": int(stamp(np.array([pr["t_end"]]))[0]),
                "random_offset": _rounded(pr["random_offset"]),
                "t_ns": stamp(motion.t[inside]).tolist(),
                "commanded": _rounded(nominal[:, :3, :3] @ tool + nominal[:, :3, 3]),
                "attained": _rounded(motion.settled[inside]),
                "true_fk": _rounded(motion.true_fk[inside]),
                "duration_s": seg.t1 - seg.t0,
            }
        )
    return {
        "format": TRUTH_FORMAT,
        "frame": "base",
        "settings": {
            "cycles": cfg.iso_cycles,
            "path_cycles": cfg.iso_path_cycles,
            "dwell_s": cfg.iso_dwell,
            "cycle_order": [prog.poses[k].name for k in _poses_in_order(prog)],
            "repeatability_m": cfg.repeatability,
            "orientation_repeatability_rad": cfg.orientation_repeatability,
            "drift_m": cfg.drift,
            "drift_time_s": run.drift_tau,
            "drift_direction": _rounded(run.drift_direction, 15),
            "drift_t0_ns": int(stamp(np.array([run.drift_t0]))[0]),
            "drift_scale": run.drift_scale,
            "overshoot_m": cfg.overshoot,
            "overshoot_frequency_hz": cfg.overshoot_frequency,
            "overshoot_damping": cfg.overshoot_damping,
            "path_error_m": cfg.path_error,
            "path_repeatability_m": cfg.path_repeatability,
            "path_deviation_directions": [_rounded(w, 15) for w in run.deviation_directions],
            "path_ramp_s": PATH_RAMP,
            "path_dwell_s": PATH_DWELL,
            "tracker_rate_hz": cfg.tracker_rate,
            "noise_m": cfg.noise,
        },
        "program": {
            "robot": prog.robot,
            "tool_point": _rounded(tool, 15),
            "cube": {
                "centre": _rounded(prog.cube.centre),
                "size": float(prog.cube.size),
                "plane": prog.cube.plane,
                "corners": _rounded(prog.cube.corners),
            },
            "poses": [
                {"name": p.name, "T": _rounded(p.T, 15), "q": _rounded(p.q, 15)} for p in prog.poses
            ],
            "paths": [
                {
                    "name": p.name,
                    "points": _rounded(p.points),
                    "q": _rounded(p.q, 15),
                    "speed": float(p.speed),
                }
                for p in prog.paths
            ],
        },
        "T_measurement_base": _rounded(T_mr, 15),
        "visits": visits,
        "paths": paths,
    }
