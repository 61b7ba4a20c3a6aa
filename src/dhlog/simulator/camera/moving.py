"""The moving protocols seen by a camera (``sweeps`` and ``coupled``): frames at the camera's frame
rate (``frame_rate``, :data:`~dhlog.simulator.config.FRAME_RATE` by default) over the whole
session, each at the true pose at its stamp, and only the frames where the board is seen kept. The
sweeps' home pose and the fixed part are chosen together (:func:`place_for_moves`): among the
robot's zero pose and :data:`HOME_PROBES` random ones, the fixed part placed square to the board
(the camera on the board's normal, or the board on the camera's axis) and level with or above the
workspace's centre, the one whose sweeps (each joint alone, and the coupled move) keep the board
seen over the longest share of the asked sweep. Each sweep is then limited to the part of it where
the board is seen (a joint's limits narrowed for the session); a sweep the board is never seen in
keeps its range and is named in a warning (:attr:`VisionSession.warnings`), as is one seen over less
than :data:`MIN_SWEEP_SEEN` or in fewer than :data:`MIN_SWEEP_FRAMES` frames: the seed method cannot
fit that joint's circle. Each frame is labelled with the move it was taken in (``joint k``, ``joints
a+b`` for the coupled move, ``transition``, ``still``). Further cameras look at the board's centre
at the sweeps' home from :data:`CAMERA_OFFSETS` about the first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType
from dhlog.model.robots import Robot
from dhlog.simulator.camera.frames import CameraFrames, VisionSession
from dhlog.simulator.camera.presets import (
    CAMERA_ON_FLANGE,
    PRESETS,
    CameraPreset,
    CameraSetup,
    ImageFormat,
    board_on_flange,
)
from dhlog.simulator.camera.render import MOTION_POSES
from dhlog.simulator.camera.rig import (
    Rig,
    _looking_at,
    _rig,
    _spread_rigs_about,
    _workspace_centre,
    flange_poses,
    seen,
)
from dhlog.simulator.config import CameraOptions, SimulationConfig
from dhlog.simulator.protocols import joints_at, keyframes, protocol_config, swept_joints
from dhlog.simulator.robot import perturbed
from dhlog.simulator.session import START_NS, simulate_session

#: random home poses tried (with the zero pose) for a moving protocol's sweeps
HOME_PROBES = 160


#: a sweep seen over less than this (rad; mm for a prismatic joint's travel) or in fewer frames
#: is named in a warning: too short for the seed method's circle (its least sweep is 5°)
MIN_SWEEP_SEEN = math.radians(10.0)


MIN_SWEEP_TRAVEL = 0.005


MIN_SWEEP_FRAMES = 5


@dataclass(frozen=True)
class Move:
    """A move of a moving protocol: the joints at ``home + s · direction`` with ``s`` within
    ``± extent / 2`` (rad or m), each joint swept alone or the coupled pair together."""

    label: str
    direction: FloatArray
    extent: float
    revolute: bool


def protocol_moves(robot: Robot, cfg: SimulationConfig) -> list[Move]:
    """The moves a session of ``cfg`` makes: each swept joint alone, then the coupled ones."""
    revolute = [jt is JointType.REVOLUTE for jt in robot.table.joint_types]
    out = []
    for j in swept_joints(robot, cfg):
        v = np.zeros(robot.n)
        v[j - 1] = 1.0
        out.append(
            Move(f"joint {j}", v, cfg.sweep if revolute[j - 1] else cfg.travel, revolute[j - 1])
        )
    for a, b, ratio in protocol_config(cfg).coupled:
        v = np.zeros(robot.n)
        v[a - 1] = 1.0
        v[b - 1] += ratio
        extent = cfg.sweep if revolute[a - 1] else cfg.travel
        out.append(Move(f"joints {a}+{b}", v, extent, revolute[a - 1]))
    return out


def _seen_runs(
    robot: Robot,
    table: object,
    rigs: list[Rig],
    homes: FloatArray,
    moves: list[Move],
    grid: int,
) -> FloatArray:
    """For each home (c, n) with its rig and each move: the part ``(s_lo, s_hi)`` (c, m, 2) of
    the move about the home, within the limits, where the board is seen without a break
    (``(0, 0)`` where it is not seen at home)."""
    c, m = len(homes), len(moves)
    frac = np.linspace(-0.5, 0.5, grid)  # grid odd: the home in the middle
    S = frac[None, :] * np.array([mv.extent for mv in moves])[:, None]  # (m, grid)
    V = np.array([mv.direction for mv in moves])  # (m, n)
    q = homes[:, None, None, :] + S[None, :, :, None] * V[None, :, None, :]
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    within = np.all((q >= lo - 1e-12) & (q <= hi + 1e-12), axis=-1)
    F = flange_poses(robot, table, q.reshape(-1, robot.n)).reshape(c, m * grid, 4, 4)
    T_fixed = np.array([rig.T_fixed for rig in rigs])[:, None]
    mounted = rigs[0].T_mounted
    if rigs[0].setup == "eye-to-hand":
        T_cb = np.linalg.inv(T_fixed) @ F @ mounted
    else:
        T_cb = np.linalg.inv(F @ mounted) @ T_fixed
    ok = seen(rigs[0], T_cb.reshape(-1, 4, 4)).reshape(c, m, grid) & within
    mid = grid // 2
    idx = np.arange(grid)
    start = np.where(~ok & (idx <= mid), idx, -1).max(axis=-1) + 1
    end = np.where(~ok & (idx >= mid), idx, grid).min(axis=-1) - 1
    found = ok[..., mid]
    runs = np.zeros((c, m, 2))
    runs[..., 0] = np.where(found, S[np.arange(m), np.clip(start, 0, grid - 1)], 0.0)
    runs[..., 1] = np.where(found, S[np.arange(m), np.clip(end, 0, grid - 1)], 0.0)
    return runs


def _square_rig(
    robot: Robot, table: object, setup: CameraSetup, kit: CameraPreset, homes: FloatArray
) -> tuple[list[Rig], NDArray[np.bool_]]:
    """For each home (c, n): the rig with its fixed part square to the mounted one (the camera
    on the board's normal through its centre, or the board across the camera's axis), and
    whether that fixed part is level with or above the workspace's centre."""
    F = flange_poses(robot, table, homes)
    centre_z = _workspace_centre(robot, table, 0)[2]
    w, h = kit.board.size_m
    rigs, ok = [], []
    for T_flange in F:
        if setup == "eye-to-hand":
            T_b = T_flange @ board_on_flange(kit.board)
            middle = T_b[:3, :3] @ np.array([w / 2, h / 2, 0.0]) + T_b[:3, 3]
            eye = middle - kit.camera_distance * T_b[:3, 2]  # the face looks along the −z
            rigs.append(_rig(setup, _looking_at(eye, middle), kit))
            ok.append(eye[2] >= centre_z)
        else:
            T_c = T_flange @ CAMERA_ON_FLANGE
            far = T_c[:3, 3] + kit.board_distance * T_c[:3, 2]
            T = _looking_at(T_c[:3, 3], far)
            T[:3, 3] = far - T[:3, :3] @ np.array([w / 2, h / 2, 0.0])
            rigs.append(_rig(setup, T, kit))
            ok.append(far[2] >= centre_z)
    return rigs, np.array(ok)


def place_for_moves(
    robot: Robot, table: object, cfg: SimulationConfig, setup: CameraSetup, kit: CameraPreset
) -> tuple[Rig, FloatArray, FloatArray]:
    """The rig, the home pose (n,) of a moving protocol's sweeps and each move's part
    ``(s_lo, s_hi)`` (m, 2) where the board is seen (see the module): among the zero pose and
    ``HOME_PROBES`` random ones, the one whose moves keep the board seen over the largest
    share of the asked sweep (the least share over the moves plus their mean)."""
    moves = protocol_moves(robot, cfg)
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    rng = np.random.default_rng([cfg.seed, 36])
    homes = np.vstack(
        [np.clip(np.zeros(robot.n), lo, hi), rng.uniform(lo, hi, (HOME_PROBES, robot.n))]
    )
    rigs, level = _square_rig(robot, table, setup, kit, homes)
    if not np.any(level):
        raise DhlogError(
            f"{robot.name}: no home pose of {HOME_PROBES + 1} tried puts the fixed "
            f"{'camera' if setup == 'eye-to-hand' else 'board'} level with or above the "
            "workspace; try another --seed or --camera-setup"
        )
    keep = np.flatnonzero(level)
    if not moves:
        return rigs[int(keep[0])], homes[int(keep[0])], np.zeros((0, 2))
    runs = _seen_runs(robot, table, [rigs[i] for i in keep], homes[keep], moves, 25)
    share = (runs[..., 1] - runs[..., 0]) / np.array([mv.extent for mv in moves])
    best = int(keep[int(np.argmax(share.min(axis=1) + share.mean(axis=1)))])
    fine = _seen_runs(robot, table, [rigs[best]], homes[best : best + 1], moves, 181)[0]
    return rigs[best], homes[best], fine


def _narrowed_limits(
    robot: Robot, home: FloatArray, moves: list[Move], runs: FloatArray
) -> FloatArray:
    """The joint limits (n, 2) that keep each move within the part of it where the board is
    seen (a move never seen keeps its joints' limits); joints no move sweeps held at home."""
    limits = np.repeat(home[:, None], 2, axis=1)
    moved = np.zeros(robot.n, dtype=bool)
    for mv, (s_lo, s_hi) in zip(moves, runs, strict=True):
        joints = np.flatnonzero(mv.direction)
        if s_hi <= s_lo:
            limits[joints] = robot.limits[joints]
            moved[joints] = True
            continue
        for j in joints:
            ends = sorted((home[j] + s_lo * mv.direction[j], home[j] + s_hi * mv.direction[j]))
            if moved[j]:
                ends = [min(ends[0], limits[j, 0]), max(ends[1], limits[j, 1])]
            limits[j] = ends
            moved[j] = True
    return np.asarray(limits)


def _move_labels(
    frames: list[tuple[float, FloatArray]], t: FloatArray, moves: list[Move]
) -> list[str]:
    """The move each instant ``t`` falls in: the keyframe interval's moving joints matched to a
    move (``joint k``, ``joints a+b``), or ``transition``; a still interval takes the label of
    the move before it."""
    ft = np.array([f[0] for f in frames])
    fq = np.stack([f[1] for f in frames])
    labels: list[str] = []
    previous = "transition"
    for k in range(len(ft) - 1):
        d = fq[k + 1] - fq[k]
        if np.any(np.abs(d) > 1e-12):
            previous = "transition"
            for mv in moves:
                v = mv.direction
                along = (d @ v) / (v @ v) * v
                if np.all(np.abs(d - along) <= 1e-9 * max(1.0, float(np.abs(d).max()))):
                    previous = mv.label
                    break
        labels.append(previous)
    i = np.clip(np.searchsorted(ft, t, side="right") - 1, 0, len(ft) - 2)
    return [labels[int(k)] for k in i]


def _moving_vision(
    robot: Robot,
    table: object,
    cfg: SimulationConfig,
    setup: CameraSetup,
    image_format: ImageFormat,
    options: CameraOptions,
) -> VisionSession:
    """``sweeps`` and ``coupled``: a frame every ``1 / frame_rate`` s where the board is seen
    by each of ``options``' cameras (its preset's), with the poses across its ``exposure`` when
    that is > 0."""
    kit = PRESETS[options.preset]
    frame_rate, cameras, exposure = options.frame_rate, options.cameras, options.exposure
    moves = protocol_moves(robot, cfg)
    rig, home, runs = place_for_moves(robot, table, cfg, setup, kit)
    moving = replace(robot, limits=_narrowed_limits(robot, home, moves, runs))
    session = simulate_session(moving, cfg, home=home)
    # the trajectory as the session ran it: its draws replayed (the perturbation, then the lock
    # poses), checked against the joint states it wrote
    rng = np.random.default_rng(cfg.seed)
    if cfg.perturb_length or cfg.perturb_angle:
        perturbed(robot.table, rng, cfg)
    frames, _, _ = keyframes(moving, home, protocol_config(cfg), rng, np.zeros((0, robot.n)))
    duration = frames[-1][0]
    start_ns = START_NS + round(cfg.start_day * 86_400e9)
    base_time = 2.0 if cfg.base_points else 0.0
    t_enc = (session.joint_t_ns - start_ns) / 1e9 - base_time + cfg.clock_offset
    if cfg.encoder_scales is None and session.joint_q.size:
        replayed = joints_at(frames, np.clip(t_enc, 0.0, duration))
        if not np.allclose(replayed, session.joint_q, atol=1e-6, rtol=0.0):
            raise AssertionError("the replayed trajectory differs from the session's")
    phase = np.random.default_rng([cfg.seed, 35]).uniform(0.0, 1.0 / frame_rate)
    t = np.arange(phase, duration, 1.0 / frame_rate)
    q = joints_at(frames, t)
    labels = np.array(_move_labels(frames, t, moves))
    flanges = flange_poses(robot, session.table, q)
    stamps = start_ns + np.rint((t + base_time) * 1e9).astype(np.int64)
    rigs = [rig] if cameras == 1 else _spread_rigs_about(rig, kit, cameras)
    sub = None
    if exposure > 0:  # the flange across each frame's exposure, its stamp in the middle
        offsets = np.linspace(-exposure / 2, exposure / 2, MOTION_POSES)
        t_sub = np.clip(t[:, None] + offsets, 0.0, duration)
        sub = flange_poses(robot, session.table, joints_at(frames, t_sub.ravel()))
    views = []
    for r in rigs:
        T_cb = r.board_in_camera(flanges)
        keep = seen(r, T_cb)
        T_exp = None
        if sub is not None:
            T_exp = r.board_in_camera(sub).reshape(len(t), MOTION_POSES, 4, 4)[keep]
        views.append(
            CameraFrames(r, stamps[keep], T_cb[keep], q[keep], tuple(map(str, labels[keep])), T_exp)
        )
    first = views[0]
    warnings, notes = _sweep_report(moves, runs, home, views)
    return VisionSession(
        session,
        first.rig,
        first.frame_t_ns,
        first.T_cam_board,
        image_format,
        first.frame_q,
        first.frame_move,
        frame_rate,
        kit.name,
        views[1:],
        warnings,
        notes,
        exposure,
        first.T_exposure,
    )


def _sweep_report(
    moves: list[Move],
    runs: FloatArray,
    home: FloatArray,
    views: list[CameraFrames],
) -> tuple[list[str], list[str]]:
    """The warnings (a move the board is seen too little in, by every camera) and notes (a
    move limited to the part where it is seen) of a moving protocol's vision log."""
    warnings, notes = [], []
    for mv, (s_lo, s_hi) in zip(moves, runs, strict=True):
        what = (
            f"the sweep of {mv.label}"
            if len(np.flatnonzero(mv.direction)) == 1
            else (f"the coupled move of {mv.label}")
        )
        unit, scale, least = ("°", math.degrees(1.0), MIN_SWEEP_SEEN)
        if not mv.revolute:
            unit, scale, least = (" mm", 1e3, MIN_SWEEP_TRAVEL)
        count, span = 0, 0.0
        for view in views:  # the camera that sees the move best
            sel = np.array([label == mv.label for label in view.frame_move], dtype=bool)
            v = mv.direction
            s = (view.frame_q[sel] - home) @ v / (v @ v)
            count = max(count, int(s.size))
            span = max(span, float(np.ptp(s)) if s.size else 0.0)
        if count == 0:
            warnings.append(
                f"{what}: the board is never seen (turned edge-on or out of the image over "
                f"the whole {mv.extent * scale:.0f}{unit}); the seed method cannot fit its "
                "axis from this log's frames"
            )
        elif count < MIN_SWEEP_FRAMES or span < least:
            warnings.append(
                f"{what}: the board is seen in {count} frames over {span * scale:.1f}{unit} "
                f"only, too little for the seed method's circle"
            )
        elif s_hi - s_lo < mv.extent * 0.999:
            notes.append(
                f"{what}: {(s_hi - s_lo) * scale:.1f}{unit} of the asked "
                f"{mv.extent * scale:.0f}{unit}, the part where the board is seen"
            )
    return warnings, notes
