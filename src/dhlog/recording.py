"""The Rerun recording of a processed log (``<stem>.rrd``) and of a robot (``dhlog show``).

One ``log_*`` function per thing shown. Fitted geometry is static; samples and residuals are on
the sensor time line (``sensor_time``, the samples' own stamps), sent as columns. The default
blueprint opens on the 3D view with the DH table and the residual plots beside it.

Entities:

* ``world/samples/segment_<k>`` target samples of each sweep (coloured per segment),
  ``world/samples/set_aside`` the others (dimmed), ``world/samples/outliers`` rejected samples;
* ``world/joints/j<k>/fit`` the fitted circle or line, ``world/joints/j<k>/axis`` the oriented
  axis as a labelled arrow;
* ``world/dh/frame_<i>`` DH frame i (transform + axes + label), ``world/robot/links`` link
  segments between frame origins at the reference pose;
* ``world/base_plane`` probed base points and the fitted plane patch;
* ``residuals/fk/j<k>`` FK residual (mm) of each sample, ``residuals/fit/j<k>`` fit residual;
* ``report/dh_table`` the DH tables and fit summary as Markdown.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dhlog.dh import JointType, StandardDH
from dhlog.geometry._checks import FloatArray, perpendicular_basis
from dhlog.kinematics import fk_frames

PALETTE = np.array(
    [
        [230, 25, 75],
        [60, 180, 75],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [170, 110, 40],
        [128, 128, 0],
        [0, 0, 128],
    ],
    dtype=np.uint8,
)
DIM = np.array([150, 150, 150, 90], dtype=np.uint8)
TIMELINE = "sensor_time"


@contextmanager
def _recording_file(
    path: str | Path, application_id: str, blueprint: rrb.Blueprint, recording_id: str | None = None
) -> Iterator[rr.RecordingStream]:
    """A recording streamed to a temporary file beside ``path``, renamed into place (complete:
    flushed and disconnected) only when the block finishes without error."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    try:
        # a signal while the stream is being built would leave a half-made object whose
        # finaliser prints a traceback: defer signals until it exists
        from dhlog.io.writer import signals_deferred

        with signals_deferred():
            rec = rr.RecordingStream(application_id, recording_id=recording_id)
        rec.save(tmp, default_blueprint=blueprint)
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        yield rec
        rec.flush()
        rec.disconnect()
        from dhlog.io.writer import publish

        publish(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _color(k: int) -> FloatArray:
    return np.asarray(PALETTE[(k - 1) % len(PALETTE)])


def _time_column(t_ns: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(
        TIMELINE, timestamp=np.asarray(t_ns, dtype=np.int64).astype("datetime64[ns]")
    )


def log_frames(
    rec: rr.RecordingStream,
    frames: FloatArray,
    *,
    prefix: str = "world/dh",
    axis_length: float = 0.08,
) -> None:
    """Each DH frame as a transform with its axes and a label (static)."""
    for i, T in enumerate(frames, start=1):
        path = f"{prefix}/frame_{i}"
        rec.log(path, rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True)
        rec.log(path, rr.TransformAxes3D(axis_length), static=True)
        rec.log(
            f"{path}/label",
            rr.Points3D([[0.0, 0.0, 0.0]], labels=[f"F{i}"], radii=0.003),
            static=True,
        )


def log_links(
    rec: rr.RecordingStream,
    frames: FloatArray,
    tool_world: FloatArray | None,
    *,
    path: str = "world/robot/links",
) -> None:
    """The robot as a chain of segments between frame origins (and the target)."""
    points = [T[:3, 3] for T in frames]
    if tool_world is not None:
        points.append(tool_world)
    rec.log(
        path,
        rr.LineStrips3D([np.asarray(points)], colors=[[200, 200, 200]], radii=0.004),
        static=True,
    )


def _circle_points(
    center: FloatArray, normal: FloatArray, radius: float, n: int = 128
) -> FloatArray:
    u, v = perpendicular_basis(normal)
    a = np.linspace(0.0, 2.0 * np.pi, n)
    return np.asarray(center + radius * (np.outer(np.cos(a), u) + np.outer(np.sin(a), v)))


def write_process_recording(result: object, path: str | Path) -> None:
    """Write the recording of a :class:`~dhlog.process.ProcessResult` to ``path`` atomically."""
    from dhlog.process import ProcessResult
    from dhlog.report import result_markdown

    assert isinstance(result, ProcessResult)
    with _recording_file(
        path, "dhlog", _process_blueprint(result), result.sha256[:32] or None
    ) as rec:
        log_samples(rec, result)
        log_fits(rec, result)
        log_base(rec, result)
        if result.extraction is not None:
            frames = result.extraction.frames
            if not result.complete:
                frames = frames[:-1]
            log_frames(rec, frames)
            log_links(rec, frames, result.target if result.complete else None)
        log_residuals(rec, result)
        rec.log(
            "report/dh_table",
            rr.TextDocument(result_markdown(result), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )


def log_samples(rec: rr.RecordingStream, result: object) -> None:
    """Target samples on the sensor time line: per sweep, set aside (dimmed), outliers."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    table = result.segmentation.table
    t = table["t_ns"].to_numpy()
    xyz = table.select(["x", "y", "z"]).to_numpy()
    segment = table["segment"].fill_null(0).to_numpy()
    joint = table["joint"].fill_null(0).to_numpy()
    outlier = np.zeros(table.height, dtype=bool)
    for j in result.joints:
        outlier[j.rows[~j.inliers]] = True
    for sid in np.unique(segment[segment > 0]):
        sel = (segment == sid) & ~outlier
        k = int(joint[sel][0]) if np.any(sel) else 1
        _send_points(rec, f"world/samples/segment_{int(sid)}", t[sel], xyz[sel], _color(k), 0.0015)
    aside = segment == 0
    _send_points(rec, "world/samples/set_aside", t[aside], xyz[aside], DIM, 0.001)
    if np.any(outlier):
        _send_points(
            rec,
            "world/samples/outliers",
            t[outlier],
            xyz[outlier],
            np.array([255, 0, 0], dtype=np.uint8),
            0.003,
        )


def _send_points(
    rec: rr.RecordingStream,
    path: str,
    t: np.ndarray,
    xyz: FloatArray,
    color: np.ndarray,
    radius: float,
) -> None:
    if t.size == 0:
        return
    rec.log(path, rr.Points3D.from_fields(colors=[color], radii=[radius]), static=True)
    rec.send_columns(path, indexes=[_time_column(t)], columns=rr.Points3D.columns(positions=xyz))


def log_fits(rec: rr.RecordingStream, result: object) -> None:
    """Per joint: the fitted circle (or line) and the oriented axis as a labelled arrow."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    for j in result.joints:
        if j.fit is None:
            continue
        f = j.fit
        color = _color(j.index)
        if f.kind == "circle":
            strip = _circle_points(f.center, f.axis.direction, f.radius)
            length = max(0.1, 0.5 * f.radius)
        else:
            half = 0.5 * f.sweep + 0.02
            strip = np.stack(
                [f.center - half * f.axis.direction, f.center + half * f.axis.direction]
            )
            length = 0.1
        rec.log(
            f"world/joints/j{j.index}/fit",
            rr.LineStrips3D([strip], colors=[color], radii=0.001),
            static=True,
        )
        axis = j.axis if j.axis is not None else f.axis
        rec.log(
            f"world/joints/j{j.index}/axis",
            rr.Arrows3D(
                origins=[axis.point - 0.25 * length * axis.direction],
                vectors=[length * axis.direction],
                colors=[color],
                radii=0.003,
                labels=[f"J{j.index} {j.name}"],
            ),
            static=True,
        )


def log_base(rec: rr.RecordingStream, result: object) -> None:
    """The probed base points and the fitted base plane (a square patch)."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    base = result.log.base
    if base is None or base.height == 0:
        return
    pts = base.select(["x", "y", "z"]).to_numpy()
    rec.log(
        "world/base_plane/points",
        rr.Points3D(pts, colors=[[255, 255, 0]], radii=0.003),
        static=True,
    )
    if result.base is None:
        return
    plane = result.base.plane
    u, v = result.base.basis
    half = 1.2 * float(np.max(np.abs((pts - plane.point) @ np.stack([u, v]).T))) + 0.05
    corners = [
        plane.point + half * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))
    ]
    rec.log(
        "world/base_plane/plane",
        rr.Mesh3D(
            vertex_positions=corners,
            triangle_indices=[[0, 1, 2], [0, 2, 3]],
            vertex_colors=[[255, 255, 0, 60]] * 4,
        ),
        static=True,
    )


def log_residuals(rec: rr.RecordingStream, result: object) -> None:
    """FK residual and fit residual of every sample (mm) as time series per joint."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    t_all = result.segmentation.table["t_ns"].to_numpy()
    for j in result.joints:
        if j.fit is None:
            continue
        rows = j.rows[j.inliers]
        color = _color(j.index)
        fit_path = f"residuals/fit/j{j.index}"
        rec.log(fit_path, rr.SeriesLines(colors=[color], names=[f"fit J{j.index}"]), static=True)
        rec.send_columns(
            fit_path,
            indexes=[_time_column(t_all[rows])],
            columns=rr.Scalars.columns(scalars=np.linalg.norm(j.fit.residuals, axis=1) * 1e3),
        )
        val = result.validation
        if val is not None:
            r = val.residuals[rows]
            fk_path = f"residuals/fk/j{j.index}"
            rec.log(fk_path, rr.SeriesLines(colors=[color], names=[f"FK J{j.index}"]), static=True)
            rec.send_columns(
                fk_path,
                indexes=[_time_column(t_all[rows])],
                columns=rr.Scalars.columns(scalars=r * 1e3),
            )


def _process_blueprint(result: object) -> rrb.Blueprint:
    del result
    everything = rrb.VisibleTimeRange(
        TIMELINE,
        start=rrb.TimeRangeBoundary.infinite(),
        end=rrb.TimeRangeBoundary.cursor_relative(),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="Calibration", origin="world", time_ranges=[everything]),
            rrb.Vertical(
                rrb.TextDocumentView(name="DH parameters", origin="report/dh_table"),
                rrb.TimeSeriesView(name="Residuals (mm)", origin="residuals"),
                row_shares=[3, 2],
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=False,
    )


# ---- dhlog show ---------------------------------------------------------------------------


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
    (seed 004's visualisation): the frames, the links and the tool path."""
    n = table.n
    if limits is None:
        limits = np.array(
            [
                [-math.pi / 2, math.pi / 2] if t is JointType.REVOLUTE else [0.0, 0.1]
                for t in table.joint_types
            ]
        )
    everything = rrb.VisibleTimeRange(
        "step", start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()
    )
    bp = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name=title, origin="world"),
            rrb.Spatial3DView(name="tool path", origin="world/tool_path", time_ranges=[everything]),
            column_shares=[3, 1],
        )
    )
    with _recording_file(path, "dhlog_show", bp) as rec:
        home = np.clip(np.zeros(n), limits[:, 0], limits[:, 1])
        step = 0
        scale = max(0.05, float(np.sum(np.abs(table.a)) + np.sum(np.abs(table.d_offset))) / (3 * n))
        for k in range(n):
            for value in np.linspace(limits[k, 0], limits[k, 1], steps):
                q = home.copy()
                q[k] = value
                frames = fk_frames(table, q, T_base=T_base)
                rec.set_time("step", sequence=step)
                for i, T in enumerate(frames, start=1):
                    rec.log(
                        f"world/frames/frame_{i}",
                        rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]),
                    )
                rec.log(
                    "world/links",
                    rr.LineStrips3D(
                        [frames[:, :3, 3]], radii=0.01 * scale, colors=[[200, 200, 200]]
                    ),
                )
                rec.log(
                    "world/tool_path",
                    rr.Points3D([frames[-1][:3, 3]], colors=[_color(k + 1)], radii=0.01 * scale),
                )
                step += 1
        for i in range(1, n + 2):
            rec.log(f"world/frames/frame_{i}", rr.TransformAxes3D(scale), static=True)
