"""The ground truth of a simulated session as a result document (``dhlog.result/1``), for
comparing a calibration with the robot it was simulated from."""

from __future__ import annotations

import numpy as np

from dhlog.geometry.lines import Line
from dhlog.identify.read.extract import extract_dh
from dhlog.model.fk import fk_point, joint_axes
from dhlog.result.contract import RESULT_FORMAT, dh_documents, relation_documents
from dhlog.simulator.config import PATH_PROTOCOLS
from dhlog.simulator.protocols import protocol_config
from dhlog.simulator.session import Session


def truth_document(
    session: Session, *, source_path: str, sha256: str, pipeline: str, version: str
) -> dict[str, object]:
    """The ground truth of ``session`` in the shape of the result contract (``dhlog.result/1``)."""
    table, q = session.table, session.reference_pose
    points, dirs = joint_axes(table, q, T_base=session.T_measurement_base)
    target = fk_point(table, q, session.tool_point, T_base=session.T_measurement_base)
    relations = extract_dh(
        [Line(p, d) for p, d in zip(points, dirs, strict=True)],
        table.joint_types,
        target=target,
        reference_pose=q,
    ).relations
    standard, modified = dh_documents(table, q, np.zeros(4 * table.n))
    cfg = session.config
    plan = protocol_config(cfg)
    return {
        "format": RESULT_FORMAT,
        "dhlog_version": version,
        "source": {"path": source_path, "sha256": sha256, "pipeline": pipeline},
        "units": {"length": "m", "angle": "rad"},
        "reference_pose": q.tolist(),
        "joints": [
            {
                "index": i + 1,
                "name": session.joint_names[i],
                "type": table.joint_types[i].value,
                "axis": {"point": points[i].tolist(), "direction": dirs[i].tolist()},
            }
            for i in range(table.n)
        ],
        "standard_dh": standard,
        "modified_dh": modified,
        "relations": relation_documents(relations),
        "base": {"T_measurement_base": session.T_measurement_base.tolist()},
        "tool": {"point": session.tool_point.tolist()},
        "validation": {"fk_rms": 0.0, "fk_max": 0.0, "n_points": int(session.point_xyz.shape[0])},
        "warnings": [],
        "simulation": {
            "robot": session.robot_name,
            "noise_m": cfg.noise,
            "noise_kind": cfg.noise_kind,
            "tracker_rate_hz": cfg.tracker_rate,
            "joint_rate_hz": cfg.joint_rate,
            "motion": plan.motion,
            "sweep_rad": cfg.sweep,
            "travel_m": cfg.travel,
            "lock_poses": cfg.lock_poses,
            "base_points": cfg.base_points,
            "outliers": session.n_outliers,
            "dropped": session.n_dropped,
            "encoders": cfg.encoders,
            "phase": cfg.phase,
            "seed": cfg.seed,
            "clock_offset_s": cfg.clock_offset,
            "clock_drift": cfg.clock_drift,
            **(
                {"clock_step_s": cfg.clock_step, "clock_step_at": cfg.clock_step_at}
                if cfg.clock_step
                else {}
            ),
            "joint_sweeps": [float(v) for v in session.sweeps],
            "perturb_length_m": cfg.perturb_length,
            "perturb_angle_rad": cfg.perturb_angle,
            "protocol": cfg.protocol,
            **({"path_length_m": cfg.path_length} if cfg.protocol in PATH_PROTOCOLS else {}),
            "restation": cfg.restation,
            "remount": cfg.remount,
            "poses": int(session.poses.shape[0]),
            "model_error_m": cfg.model_error,
            "steps": cfg.steps if plan.motion == "step" and not session.poses.size else None,
            "coupled": [[a, b, ratio] for a, b, ratio in plan.coupled],
            "tool_rotation_rotvec": None if cfg.tool_rotation is None else list(cfg.tool_rotation),
            "orientation_noise_rad": cfg.orientation_noise,
            "extra_targets_m": [list(extra) for extra in cfg.extra_tools],
            "compliance_rad_per_nm": [[j, c] for j, c in cfg.compliance],
            "payload_kg": cfg.payload,
            "harmonic_rad": [[j, a, b] for j, a, b in cfg.harmonic],
        },
        **({} if session.terms is None else {"nongeometric": session.terms.document()}),
        **({} if session.iso9283 is None else {"iso9283": session.iso9283}),
    }
