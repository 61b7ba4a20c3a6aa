"""The recordings written: a processed result's (``<stem>.rrd``, :func:`write_process_recording`)
and a robot's with each joint swept in turn (``dhlog show``, :func:`write_robot_recording`)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_frames
from dhlog.present.recording.blueprint import process_blueprint
from dhlog.present.recording.residuals import log_residuals, residual_parts
from dhlog.present.recording.scene import Shown, joint_color
from dhlog.present.recording.spatial import (
    log_base,
    log_deflection,
    log_fits,
    log_frames,
    log_holdout,
    log_links,
    log_samples,
)
from dhlog.present.recording.stream import recording_file

if TYPE_CHECKING:
    from dhlog.identify.run import Identification


def process_recording_blueprint(result: Identification) -> rrb.Blueprint:
    """The default layout of a processed result's recording (:func:`log_process_recording`)."""
    shown = Shown.of(result)
    cameras = list(getattr(result, "cameras", None) or [])  # a camera calibration's views
    return process_blueprint(shown, shown.magnification(), residual_parts(result, shown), cameras)


def write_process_recording(
    result: Identification, path: str | Path, *, with_log: bool = False
) -> None:
    """Write the recording of a :class:`~dhlog.identify.run.Identification` to ``path`` atomically.

    Each run is its own recording (a new recording id), named by the log, the time of the run
    and the nominal; the log's hash is a property. ``with_log``: the MCAP's own channels are
    imported by Rerun's MCAP loader, for context (under their topic names: Rerun 0.41's loader
    takes no entity prefix)."""
    import uuid

    with recording_file(
        path, "dhlog process", process_recording_blueprint(result), str(uuid.uuid4())
    ) as rec:
        log_process_recording(rec, result, with_log=with_log)


def log_process_recording(
    rec: rr.RecordingStream, result: Identification, *, with_log: bool = False
) -> None:
    """Log a processed result into ``rec`` (a file's stream, or a user's: a notebook's viewer)."""
    from datetime import UTC, datetime

    from dhlog._version import __version__
    from dhlog.present.console.markdown import result_markdown

    shown = Shown.of(result)
    k = shown.magnification()
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    nominal = result.nominal.source if result.nominal is not None else None
    title = f"{Path(result.path).name} — {when}" + (f" — nominal {nominal}" if nominal else "")
    found = residual_parts(result, shown)
    cameras = list(getattr(result, "cameras", None) or [])  # a camera calibration's views
    rec.send_recording_name(title)
    rec.send_property(
        "dhlog",
        rr.AnyValues(
            log=str(result.path),
            log_sha256=result.sha256,
            nominal=nominal or "none",
            dhlog_version=__version__,
            pipeline=result.log.pipeline.name,
        ),
    )
    T = shown.T
    rec.log("world/m", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True)
    log_samples(rec, shown)
    log_fits(rec, shown)
    log_base(rec, shown)
    if shown.frames is not None:
        log_frames(rec, shown.frames, prefix="world/m/dh", axis_length=shown.scene.frame)
        log_links(
            rec,
            shown.frames,
            result.target if result.complete else None,
            path="world/m/robot/links",
            radius=2 * shown.scene.line,
        )
    log_residuals(rec, shown, found, k)
    log_holdout(rec, shown)
    log_deflection(rec, shown)
    if cameras:
        from dhlog.present.recording.camera import base_in_world, log_cameras

        log_cameras(rec, cameras, T_world_base=base_in_world(shown))
    rec.log(
        "report/dh_table",
        rr.TextDocument(result_markdown(result), media_type=rr.MediaType.MARKDOWN),
        static=True,
    )
    if with_log and Path(result.path).is_file():
        rec.log_file_from_path(result.path)


def robot_blueprint(title: str = "robot") -> rrb.Blueprint:
    """The layout of a robot's recording (:func:`log_robot_recording`)."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name=f"{title} [m]", origin="world"),
            rrb.Spatial3DView(name="tool path [m]", origin="world/tool_path"),
            column_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )


def write_robot_recording(
    table: StandardDH,
    path: str | Path,
    *,
    T_base: FloatArray | None = None,
    limits: FloatArray | None = None,
    title: str = "robot",
    steps: int = 60,
) -> None:
    """A recording of ``table`` with each joint swept in turn on the ``step`` time line
    (seed 004's visualisation): the frames, the links and the tool path; written atomically."""
    with recording_file(path, "dhlog show", robot_blueprint(title)) as rec:
        log_robot_recording(rec, table, T_base=T_base, limits=limits, title=title, steps=steps)


def log_robot_recording(
    rec: rr.RecordingStream,
    table: StandardDH,
    *,
    T_base: FloatArray | None = None,
    limits: FloatArray | None = None,
    title: str = "robot",
    steps: int = 60,
) -> None:
    """Log ``table`` with each joint swept in turn into ``rec`` (see
    :func:`write_robot_recording`)."""
    n = table.n
    if limits is None:
        limits = np.array(
            [
                [-math.pi / 2, math.pi / 2] if t is JointType.REVOLUTE else [0.0, 0.1]
                for t in table.joint_types
            ]
        )
    home = np.clip(np.zeros(n), limits[:, 0], limits[:, 1])
    Q = []
    sweep_of = []
    for k in range(n):
        for value in np.linspace(limits[k, 0], limits[k, 1], steps):
            q = home.copy()
            q[k] = value
            Q.append(q)
            sweep_of.append(k)
    frames = fk_frames(table, np.asarray(Q), T_base=T_base)  # (S, n + 1, 4, 4)
    S = frames.shape[0]
    scale = max(0.05, float(np.sum(np.abs(table.a)) + np.sum(np.abs(table.d_offset))) / (3 * n))
    index = [rr.TimeColumn("step", sequence=np.arange(S))]
    tool = frames[:, -1, :3, 3]
    for i in range(n + 1):
        entity = f"world/frames/frame_{i + 1}"
        rec.log(entity, rr.TransformAxes3D(scale), static=True)
        rec.send_columns(
            entity,
            indexes=index,
            columns=rr.Transform3D.columns(
                translation=frames[:, i, :3, 3], mat3x3=frames[:, i, :3, :3]
            ),
        )
    rec.log(
        "world/links",
        rr.LineStrips3D.from_fields(radii=[0.01 * scale], colors=[[200, 200, 200]]),
        static=True,
    )
    rec.send_columns(
        "world/links",
        indexes=index,
        columns=rr.LineStrips3D.columns(strips=list(frames[:, :, :3, 3])).partition([1] * S),
    )
    sweep = np.asarray(sweep_of)
    rec.log(
        "world/tool_path/whole",
        rr.LineStrips3D(
            [tool[sweep == k] for k in range(n)],
            colors=[joint_color(k + 1) for k in range(n)],
            radii=0.006 * scale,
        ),
        static=True,
    )
    rec.log(
        "world/tool_path/now",
        rr.Points3D.from_fields(colors=[[255, 255, 255]], radii=[0.03 * scale]),
        static=True,
    )
    rec.send_columns(
        "world/tool_path/now", indexes=index, columns=rr.Points3D.columns(positions=tool)
    )
