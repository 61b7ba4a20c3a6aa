"""The truth of a simulated ISO 9283 test (:func:`truth_block`, format :data:`TRUTH_FORMAT`): every
visit and every path cycle without tracker noise, for the truth file beside the log.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.iso9283.motion import Motion, motion_at
from dhlog.simulator.iso9283.plan import (
    PATH_DWELL,
    PATH_RAMP,
    Iso9283Run,
    _poses_in_order,
)

#: the truth block's format
TRUTH_FORMAT = "dhlog.iso9283-truth/1"


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
