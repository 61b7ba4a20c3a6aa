"""The session of the ``iso9283`` protocol (:func:`simulate_iso9283`): the trajectory planned, the
target's motion sampled by the tracker at its rate with its noise, the encoders reading the
commanded joints and ``/joint_command`` carrying each commanded target, and the truth block.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.iso9283.cube import TestProgram
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.iso9283.motion import approach_directions, motion_at
from dhlog.simulator.iso9283.plan import (
    commanded_at,
    plan_run,
    program_of,
)
from dhlog.simulator.iso9283.truth import truth_block
from dhlog.simulator.robot import perturbed
from dhlog.simulator.session import START_NS, Session
from dhlog.simulator.tracker import (
    add_outliers,
    base_points,
    default_measurement_pose,
    dropouts,
    scatter,
)


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
