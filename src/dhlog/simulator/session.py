"""One simulated session: the robot moved through its protocol, the tracker and the encoders
sampling it on their own clocks (:func:`simulate_session` → :class:`Session`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_point
from dhlog.model.robots import Robot
from dhlog.model.terms import Terms, table_deflection
from dhlog.simulator.config import PATH_PROTOCOLS, SimulationConfig
from dhlog.simulator.paths import REMOUNT_SHIFT, path_poses, restationed
from dhlog.simulator.protocols import (
    joints_at,
    keyframes,
    parked_home,
    protocol_config,
    random_poses,
    still_at,
)
from dhlog.simulator.robot import perturbed, smooth_model_error, truth_terms
from dhlog.simulator.tracker import (
    add_outliers,
    base_points,
    default_measurement_pose,
    dropouts,
    measured_rotations,
    scatter,
)

START_NS = 1_763_700_000_000_000_000


@dataclass
class Session:
    """A simulated session and its ground truth.

    ``point_t_ns``/``point_xyz``: tracker samples (m, 3) in M; ``joint_t_ns``/``joint_q``:
    encoder samples (in chain order, names ``joint_names``); ``base_xyz``: probed base points;
    ``phase``: (t_ns, joint or None) markers; ``table``, ``T_measurement_base``, ``tool_point``,
    ``reference_pose``: the truth, in the result contract's convention.
    """

    robot_name: str
    joint_names: list[str]
    joint_types: tuple[JointType, ...]
    point_t_ns: NDArray[np.int64]
    point_xyz: FloatArray
    joint_t_ns: NDArray[np.int64]
    joint_q: FloatArray
    base_t_ns: NDArray[np.int64]
    base_xyz: FloatArray
    phase: list[tuple[int, int | None]]
    table: StandardDH
    T_measurement_base: FloatArray
    tool_point: FloatArray
    reference_pose: FloatArray
    config: SimulationConfig
    n_outliers: int = 0
    n_dropped: int = 0
    notes: list[str] = field(default_factory=list)
    extra_tool_points: list[FloatArray] = field(default_factory=list)
    extra_point_xyz: list[FloatArray] = field(default_factory=list)
    tool_rotation: FloatArray | None = None
    point_rotation: FloatArray | None = None
    #: each joint's sweep (rad) or travel (m) as simulated (the limits may clip the asked one;
    #: 0 for joints not swept)
    sweeps: FloatArray = field(default_factory=lambda: np.zeros(0))
    #: the unmodelled error added to each target sample (m, 3) in M (zeros when not asked)
    model_error_xyz: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    #: the still poses (k, n) of the ``random-poses`` protocol (none for the others)
    poses: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    #: the truth's compliance and harmonics in ``table``'s frames (None: a geometric robot)
    terms: Terms | None = None
    #: the commanded joint targets (``/joint_command``) and their stamps (the ``iso9283``
    #: protocol; empty for the others)
    command_t_ns: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    command_q: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    #: the truth file's ``iso9283`` block (the ``iso9283`` protocol; None for the others)
    iso9283: dict[str, Any] | None = None


def simulate_session(
    robot: Robot,
    cfg: SimulationConfig,
    *,
    T_measurement_robot: FloatArray | None = None,
    tool_point: FloatArray | None = None,
    home: FloatArray | None = None,
) -> Session:
    """Simulate one session of ``robot`` (see :mod:`dhlog.simulator`)."""
    if cfg.protocol == "iso9283":
        raise ValueError("the iso9283 protocol: dhlog.simulator.iso9283.simulate_iso9283")
    rng = np.random.default_rng(cfg.seed)
    T_mr = default_measurement_pose() if T_measurement_robot is None else T_measurement_robot
    if cfg.restation:  # the tracker re-stationed since the calibration
        T_mr = restationed(T_mr)
    T_mb = T_mr @ robot.T_base
    table = (
        perturbed(robot.table, rng, cfg)
        if (cfg.perturb_length or cfg.perturb_angle)
        else robot.table
    )
    tool = robot.tool_point if tool_point is None else tool_point
    if cfg.remount:  # the probe re-mounted since the calibration: its point moved
        tool = np.asarray(tool, dtype=np.float64) + np.asarray(REMOUNT_SHIFT)
    q_home = (
        np.clip(np.zeros(robot.n), robot.limits[:, 0], robot.limits[:, 1]) if home is None else home
    )
    q_home = parked_home(q_home, cfg)
    plan = protocol_config(cfg)
    poses = np.zeros((0, robot.n))
    if cfg.protocol == "random-poses":
        poses = random_poses(robot, cfg, q_home)
    elif cfg.protocol in PATH_PROTOCOLS:
        poses = path_poses(robot, cfg)
    frames, marks, sweeps = keyframes(robot, q_home, plan, rng, poses)
    duration = frames[-1][0]
    base_time = 2.0 if cfg.base_points else 0.0
    # tracker: its own clock; step-and-measure triggers it only while the robot is still
    t_trk = np.arange(0.0, duration, 1.0 / cfg.tracker_rate) + rng.uniform(
        0, 1.0 / cfg.tracker_rate
    )
    if plan.motion == "step":
        t_trk = t_trk[still_at(frames, t_trk)]
    q_trk = joints_at(frames, t_trk)
    terms = truth_terms(robot, cfg, T_mr, np.asarray(tool, dtype=np.float64))
    # the joints as they stand: the encoders' values deflected by gravity and the gears
    q_arm = q_trk if terms is None else q_trk + table_deflection(table, terms, q_trk, q_trk)
    xyz = fk_point(table, q_arm, tool, T_base=T_mb)
    error = np.zeros_like(xyz)
    if cfg.model_error > 0:  # the robot's unmodelled error, in M, the same for every target
        error = smooth_model_error(robot, cfg)(q_trk) @ T_mb[:3, :3].T
        xyz = xyz + error
    # a 6-DoF target: its frame's orientation is measured too
    R_tool, point_rot = measured_rotations(table, q_arm, T_mb, cfg, rng)
    xyz = scatter(xyz, cfg, rng)
    n_out = add_outliers(xyz, cfg, rng)
    keep = dropouts(xyz.shape[0], cfg, rng)
    extra_xyz = []
    for extra in cfg.extra_tools:  # further targets, measured at the same instants
        e = fk_point(table, q_arm, np.asarray(extra, dtype=np.float64), T_base=T_mb) + error
        extra_xyz.append(scatter(e, cfg, rng))
    start_ns = START_NS + round(cfg.start_day * 86_400e9)
    t_trk_ns = start_ns + ((t_trk + base_time) * 1e9).astype(np.int64)
    # encoders: another clock phase, rate and jitter
    t_enc = np.arange(0.0, duration, 1.0 / cfg.joint_rate) + rng.uniform(0, 1.0 / cfg.joint_rate)
    t_enc = np.sort(t_enc + rng.uniform(-cfg.clock_jitter, cfg.clock_jitter, t_enc.size))
    q_enc = joints_at(frames, np.clip(t_enc, 0.0, duration))
    if cfg.encoder_scales is not None:  # encoders that count a joint's motion times a scale
        q_enc = q_home + (q_enc - q_home) / np.asarray(cfg.encoder_scales, dtype=np.float64)
    base = base_points(cfg, T_mb, rng)
    base_t = start_ns + (np.linspace(0.1, base_time - 0.2, cfg.base_points) * 1e9).astype(np.int64)
    phase = [(start_ns + int((t + base_time) * 1e9), j) for t, j in marks] if cfg.phase else []
    return Session(
        robot_name=robot.name,
        joint_names=list(robot.joint_names)
        if cfg.driver_joints and len(robot.joint_names) == robot.n
        else [f"joint_{j + 1}" for j in range(robot.n)],
        joint_types=table.joint_types,
        point_t_ns=t_trk_ns[keep],
        point_xyz=np.asarray(xyz[keep], dtype=np.float64),
        joint_t_ns=start_ns
        + (
            (
                (t_enc + base_time) * (1.0 + cfg.clock_drift)
                - cfg.clock_offset
                + np.where(t_enc > cfg.clock_step_at * duration, cfg.clock_step, 0.0)
            )
            * 1e9
        ).astype(np.int64)
        if cfg.encoders
        else np.zeros(0, dtype=np.int64),
        joint_q=q_enc if cfg.encoders else np.zeros((0, robot.n)),
        base_t_ns=base_t,
        base_xyz=np.asarray(base, dtype=np.float64),
        phase=phase,
        table=table,
        T_measurement_base=T_mb,
        tool_point=np.asarray(tool, dtype=np.float64),
        reference_pose=np.asarray(q_home, dtype=np.float64),
        config=cfg,
        n_outliers=n_out,
        n_dropped=int(np.count_nonzero(~keep)),
        extra_tool_points=[np.asarray(e, dtype=np.float64) for e in cfg.extra_tools],
        extra_point_xyz=[np.asarray(e[keep], dtype=np.float64) for e in extra_xyz],
        tool_rotation=R_tool,
        point_rotation=None if point_rot is None else np.asarray(point_rot[keep]),
        sweeps=sweeps,
        model_error_xyz=np.asarray(error[keep], dtype=np.float64),
        poses=poses,
        terms=terms,
    )


def as_published(session: Session) -> Session:
    """The session's joint states as a ROS 2 driver publishes them (``driver_joints``): the
    columns and names in the names' alphabetical order (ros2_control's), not the chain's; the
    truth stays in chain order (write it from ``session``)."""
    order = sorted(range(len(session.joint_names)), key=lambda k: session.joint_names[k])
    return dataclasses.replace(
        session,
        joint_names=[session.joint_names[k] for k in order],
        joint_q=np.asarray(session.joint_q[:, order], dtype=np.float64),
    )
