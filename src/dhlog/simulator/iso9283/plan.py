"""The commanded trajectory of a simulated ISO 9283 test (:func:`plan_run`): the test program
(:func:`program_of`, planned once per robot in the process) run as segments (:class:`Segment`):
point to point into each pose with a dwell of ``iso_dwell`` s, then along each path by arc length
at constant speed with ramps of :data:`PATH_RAMP` s and :data:`PATH_DWELL` s still at its ends;
each visit's and path cycle's random offsets drawn; the commanded joints at any time
(:func:`commanded_at`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.cube import CYCLE_ORDER, TestProgram
from dhlog.model.dh import JointType
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.iso9283.shapes import drift_shape

#: seconds still at each path's start and end
PATH_DWELL = 0.5


#: seconds of acceleration to (and from) a path's speed
PATH_RAMP = 0.2


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
