"""Decoded streams straight from a simulated session, without writing an MCAP file.

For Monte Carlo studies and benchmarks: the same ``LogData`` that :func:`dhlog.io.reader.read_log`
returns for the session's file (the round-trip tests show the two are equal).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from dhlog.io.decode.setback import unfolded
from dhlog.io.pipeline import Pipeline, pipeline_by_name
from dhlog.io.reader import LogData
from dhlog.io.streams import RecordedStreams


def log_data_from_session(session: RecordedStreams, pipeline: Pipeline | None = None) -> LogData:
    """The ``LogData`` of ``session`` as the shipped ROS 2 (or phase) pipeline would read it."""
    has_encoders = session.joint_t_ns.size > 0
    pipe = pipeline or pipeline_by_name("ros2_tracker" if has_encoders else "phase_markers")
    assert pipe is not None
    xyz = session.point_xyz
    points = pl.DataFrame(
        {"t_ns": session.point_t_ns, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}
    )
    if session.point_rotation is not None:
        from scipy.spatial.transform import Rotation

        from dhlog.io.decode.frames import ORIENTATION_COLUMNS

        quat = Rotation.from_matrix(session.point_rotation).as_quat(canonical=True)
        points = points.with_columns(
            pl.Series(name, quat[:, k]) for k, name in enumerate(ORIENTATION_COLUMNS)
        )
    if session.extra_point_xyz:
        frames = [points.with_columns(pl.lit(0, dtype=pl.Int32).alias("target"))]
        for k, extra in enumerate(session.extra_point_xyz):
            frame = pl.DataFrame(
                {"t_ns": session.point_t_ns, "x": extra[:, 0], "y": extra[:, 1], "z": extra[:, 2]}
            )
            frames.append(frame.with_columns(pl.lit(k + 1, dtype=pl.Int32).alias("target")))
        points = pl.concat(frames).sort("t_ns", maintain_order=True)
    joints, set_back = None, None
    if has_encoders:
        joints = pl.DataFrame(
            {
                "t_ns": session.joint_t_ns,
                **{f"q_{j + 1}": session.joint_q[:, j] for j in range(session.joint_q.shape[1])},
            }
        )
        joints, set_back = unfolded(joints)
    base = pl.DataFrame(
        {
            "t_ns": session.base_t_ns,
            "x": session.base_xyz[:, 0],
            "y": session.base_xyz[:, 1],
            "z": session.base_xyz[:, 2],
        }
    )
    phase = None
    if session.phase:
        phase = pl.DataFrame(
            {
                "t_ns": np.array([t for t, _ in session.phase], dtype=np.int64),
                "joint": pl.Series([j for _, j in session.phase], dtype=pl.Int32),
            }
        )
    return LogData(
        f"{session.robot_name}.mcap",
        pipe,
        points,
        joints,
        list(session.joint_names),
        base,
        phase,
        clock_set_back=set_back,
    )
