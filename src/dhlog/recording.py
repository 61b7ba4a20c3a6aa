"""The Rerun recording of a processed log (``<stem>.rrd``) and of a robot (``dhlog show``).

One ``log_*`` function per thing shown. Fitted geometry is static; samples and residuals are on
two time lines: ``sensor_time`` (the samples' own stamps) and ``joint_position`` (the moved
joint's encoder value, m° or µm: the residual plots' x axis), sent as columns. Each run is its
own recording (a new recording id; the log's hash is a property). The default blueprint opens
on the 3D view and the DH table, the per-joint residual plots below the table, side panels
closed; ``dhlog.render`` draws it headless to check it.

Entities (``world`` is the robot's base frame, DH frame 1, z up; ``world/m`` carries the
measurement frame M into it, so everything below is logged in M):

* ``world/m/samples/segment_<k>`` target samples of each sweep (joint colours, sized from the
  robot's extent), ``world/m/samples/set_aside`` the others (dimmed), ``.../outliers`` (red);
* ``world/m/joints/j<k>/fit`` the fitted arc over the swept range (or the line over the travel),
  thin and lighter than its samples; ``world/m/joints/j<k>/axis`` the axis, an arrow ``Jk``;
* ``world/m/dh/frame_<i>`` DH frame i of the shown table (Hayati rows included), labelled once
  per place (``world/m/dh/labels``); ``world/m/robot/links`` segments between frame origins;
* ``world/m/base_plane`` probed base points and the fitted plane's outline;
* ``world/m/magnified/j<k>`` each sample at FK + k × FK residual (k in the view's name);
* ``residuals/{fk,fit}/j<k>/{radial,axial,tangential}`` signed residual components (mm);
* ``report/dh_table`` the DH tables, fits, set-aside counts and nominal as Markdown.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
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


#: Residual components, in the joint's own directions, and their colours in every plot.
COMPONENTS = {
    "radial": [230, 60, 60],
    "axial": [60, 170, 60],
    "tangential": [60, 120, 230],
}
#: The time line of the residual plots: the moved joint's encoder value (revolute in
#: millidegrees, prismatic in micrometres), so bias and periodic errors show against the angle.
JOINT_TIMELINE = "joint_position"
BASE_COLOR = np.array([255, 150, 30], dtype=np.uint8)


@dataclass(frozen=True)
class Scene:
    """Sizes chosen from the robot's extent ``E`` (m) so that the picture reads at any size:
    samples, lines, arrows and frame axes are fixed fractions of it."""

    extent: float

    @property
    def sample(self) -> float:
        return 0.004 * self.extent

    @property
    def line(self) -> float:
        return 0.0012 * self.extent

    @property
    def arrow(self) -> float:
        return 0.18 * self.extent

    @property
    def frame(self) -> float:
        return 0.07 * self.extent


def log_frames(
    rec: rr.RecordingStream,
    frames: FloatArray,
    *,
    prefix: str = "world/dh",
    axis_length: float = 0.08,
) -> None:
    """Each DH frame as a transform with its axes (static); one label per place: frames that
    share an origin (a spherical wrist) are labelled together, ``F4 F5 F6``."""
    groups: list[list[int]] = []
    for i, T in enumerate(frames, start=1):
        for g in groups:
            if np.linalg.norm(frames[g[0] - 1][:3, 3] - T[:3, 3]) < 0.3 * axis_length:
                g.append(i)
                break
        else:
            groups.append([i])
    for i, T in enumerate(frames, start=1):
        path = f"{prefix}/frame_{i}"
        rec.log(path, rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True)
        rec.log(path, rr.TransformAxes3D(axis_length), static=True)
    for g in groups:
        T = frames[g[0] - 1]
        at = T[:3, 3] + 0.6 * axis_length * (T[:3, 0] + T[:3, 2])  # off the origin, between x, z
        rec.log(
            f"{prefix}/labels/frame_{g[0]}",
            rr.Points3D([at], labels=[" ".join(f"F{i}" for i in g)], radii=0.05 * axis_length),
            static=True,
        )


def log_links(
    rec: rr.RecordingStream,
    frames: FloatArray,
    tool_world: FloatArray | None,
    *,
    path: str = "world/robot/links",
    radius: float = 0.004,
) -> None:
    """The robot as a chain of segments between frame origins (and the target)."""
    points = [T[:3, 3] for T in frames]
    if tool_world is not None:
        points.append(tool_world)
    rec.log(
        path,
        rr.LineStrips3D([np.asarray(points)], colors=[[200, 200, 200]], radii=radius),
        static=True,
    )


def _arc_points(
    center: FloatArray, normal: FloatArray, radius: float, start: float, stop: float, n: int = 96
) -> FloatArray:
    u, v = perpendicular_basis(normal)
    a = np.linspace(start, stop, n)
    return np.asarray(center + radius * (np.outer(np.cos(a), u) + np.outer(np.sin(a), v)))


def _display_transform(result: object) -> FloatArray:
    """M → the robot's base frame (DH frame 1, z along axis 1), turned upside down when the
    robot's frames lie below it (a robot whose axis 1 points down), so it stands on the grid."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    ex = result.extraction
    if ex is None:
        return np.eye(4)
    T = np.linalg.inv(ex.T_measurement_base)
    origins = _shown_frames(result)[:, :3, 3]  # the robot's structure, not where it reaches
    if float(np.median(origins @ T[2, :3] + T[2, 3])) < 0.0:
        T = np.diag([1.0, -1.0, -1.0, 1.0]) @ T
    return np.asarray(T, dtype=np.float64)


def _scene(result: object) -> Scene:
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    xyz = result.segmentation.table.select(["x", "y", "z"]).to_numpy()
    if xyz.size == 0:
        return Scene(1.0)
    ex = result.extraction
    centre = ex.T_measurement_base[:3, 3] if ex is not None else np.median(xyz, axis=0)
    reach = float(np.max(np.linalg.norm(xyz - centre, axis=1)))
    return Scene(max(reach, 0.05))


def _eye(result: object, scene: Scene) -> rrb.EyeControls3D:
    """A camera on the robot (not on the probed base area, which may be much wider): looking
    at the samples' centre from the front-right, above, at 1.9 times the robot's extent."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    xyz = result.segmentation.table.select(["x", "y", "z"]).to_numpy()
    T = _display_transform(result)
    centre = np.median(xyz @ T[:3, :3].T + T[:3, 3], axis=0) if xyz.size else np.zeros(3)
    centre[2] *= 0.6  # a little towards the floor: the base stays in the picture
    towards = np.array([1.0, -1.3, 0.8])
    eye = centre + 1.9 * scene.extent * towards / np.linalg.norm(towards)
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital, position=eye, look_target=centre, eye_up=[0.0, 0.0, 1.0]
    )


def write_process_recording(
    result: object, path: str | Path, *, with_log: bool = False, nominal: str | None = None
) -> None:
    """Write the recording of a :class:`~dhlog.process.ProcessResult` to ``path`` atomically.

    Each run is its own recording (a new recording id), named by the log, the time of the run
    and the nominal; the log's hash is a property. ``with_log``: the MCAP's own channels are
    imported under ``/log`` by Rerun's MCAP loader, for context."""
    import uuid
    from datetime import UTC, datetime

    from dhlog import __version__
    from dhlog.process import ProcessResult
    from dhlog.report import result_markdown

    assert isinstance(result, ProcessResult)
    scene = _scene(result)
    k = _magnification(result, scene)
    name = Path(result.path).name
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    nominal_name = nominal or (result.nominal.source if result.nominal is not None else None)
    title = f"{name} — {when}" + (f" — nominal {nominal_name}" if nominal_name else "")
    found = residual_parts(result)
    with _recording_file(
        path, "dhlog process", _process_blueprint(result, k, found), str(uuid.uuid4())
    ) as rec:
        rec.send_recording_name(title)
        rec.send_property(
            "dhlog",
            rr.AnyValues(
                log=str(result.path),
                log_sha256=result.sha256,
                nominal=nominal_name or "none",
                dhlog_version=__version__,
                pipeline=result.log.pipeline.name,
            ),
        )
        T = _display_transform(result)
        rec.log("world/m", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True)
        log_samples(rec, result, scene)
        log_fits(rec, result, scene)
        log_base(rec, result, scene)
        if result.extraction is not None:
            frames = _shown_frames(result)
            log_frames(rec, frames, prefix="world/m/dh", axis_length=scene.frame)
            log_links(
                rec,
                frames,
                result.target if result.complete else None,
                path="world/m/robot/links",
                radius=2 * scene.line,
            )
        log_residuals(rec, result, found, scene, k)
        rec.log(
            "report/dh_table",
            rr.TextDocument(result_markdown(result), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        if with_log and Path(result.path).is_file():
            rec.log_file_from_path(result.path, entity_path_prefix="log")


def _shown_frames(result: object) -> FloatArray:
    """The DH frames at the reference pose as the shown table places them: with Hayati rows
    (nearly parallel axes) the frames of that table, not the standard table's, whose origins
    run off along the near-parallel axes (d of metres)."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    ex = result.extraction
    assert ex is not None
    frames = ex.frames
    if result.conditioned is not None:
        T1 = ex.T_measurement_base
        frames = fk_frames(result.conditioned.table, ex.reference_pose, T_base=T1)
    return frames if result.complete else frames[:-1]


def _moved_position(result: object, rows: np.ndarray, joint: int) -> np.ndarray:
    """The moved joint's encoder value at ``rows`` on the joint time line (m°, or µm)."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    table = result.segmentation.table
    column = f"q_{joint}"
    if column not in table.columns:
        return np.zeros(rows.size, dtype=np.int64)
    q = table[column].to_numpy()[rows]
    prismatic = result.joints[joint - 1].type is JointType.PRISMATIC
    scale = 1e6 if prismatic else 180e3 / math.pi
    return np.asarray(np.round(np.nan_to_num(q) * scale), dtype=np.int64)


def log_samples(rec: rr.RecordingStream, result: object, scene: Scene | None = None) -> None:
    """Target samples: per sweep on the sensor and joint time lines (coloured per joint), the
    set-aside ones (dimmed) and rejected outliers (red) always shown."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    scene = scene or _scene(result)
    table = result.segmentation.table
    t = table["t_ns"].to_numpy()
    xyz = table.select(["x", "y", "z"]).to_numpy()
    segment = table["segment"].fill_null(0).to_numpy()
    joint = table["joint"].fill_null(0).to_numpy()
    outlier = np.zeros(table.height, dtype=bool)
    for j in result.joints:
        outlier[j.rows[~j.inliers]] = True
    for sid in np.unique(segment[segment > 0]):
        sel = np.flatnonzero((segment == sid) & ~outlier)
        if sel.size == 0:
            continue
        k = int(joint[sel[0]])
        path = f"world/m/samples/segment_{int(sid)}"
        rec.log(
            path, rr.Points3D.from_fields(colors=[_color(k)], radii=[scene.sample]), static=True
        )
        rec.send_columns(
            path,
            indexes=[
                _time_column(t[sel]),
                rr.TimeColumn(JOINT_TIMELINE, sequence=_moved_position(result, sel, k)),
            ],
            columns=rr.Points3D.columns(positions=xyz[sel]),
        )
    seg = result.segmentation.segments
    if seg.height:  # the sweeps named on the sensor time line
        names = [j.name for j in result.joints]
        texts = [
            f"sweep {int(s)}: joint {int(k)} ({names[int(k) - 1] if 0 < k <= len(names) else '?'})"
            for s, k in zip(seg["segment"], seg["joint"], strict=True)
        ]
        rec.send_columns(
            "sweeps",
            indexes=[_time_column(seg["t_start_ns"].to_numpy())],
            columns=rr.TextLog.columns(text=texts),
        )
    aside = segment == 0
    if np.any(aside):
        rec.log(
            "world/m/samples/set_aside",
            rr.Points3D(xyz[aside], colors=[DIM], radii=0.5 * scene.sample),
            static=True,
        )
    if np.any(outlier):
        rec.log(
            "world/m/samples/outliers",
            rr.Points3D(xyz[outlier], colors=[[255, 0, 0]], radii=1.5 * scene.sample),
            static=True,
        )


def _lighter(color: np.ndarray, amount: float = 0.55) -> np.ndarray:
    return np.asarray(color + amount * (255 - color.astype(float)), dtype=np.uint8)


def log_fits(rec: rr.RecordingStream, result: object, scene: Scene | None = None) -> None:
    """Per joint: the fitted arc over the swept range (or the line over the travel), thin and
    lighter than its samples, and the oriented axis as an arrow of a common length labelled
    ``Jk``; arrows of axes that coincide are staggered along them so both show."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    scene = scene or _scene(result)
    xyz = result.segmentation.table.select(["x", "y", "z"]).to_numpy()
    drawn: list[tuple[FloatArray, FloatArray]] = []
    for j in result.joints:
        if j.fit is None:
            continue
        f = j.fit
        color = _color(j.index)
        axis = j.axis if j.axis is not None else f.axis
        n = axis.direction
        pts = xyz[j.rows[j.inliers]] if j.rows.size else np.zeros((0, 3))
        if f.kind == "circle":
            u, v = perpendicular_basis(n)
            w = pts - f.center
            angles = np.unwrap(np.arctan2(w @ v, w @ u)) if pts.size else np.zeros(2)
            strip = _arc_points(f.center, n, f.radius, float(angles.min()), float(angles.max()))
            foot = f.center
        else:
            s = (pts - f.center) @ n if pts.size else np.array([-0.5 * f.sweep, 0.5 * f.sweep])
            strip = np.stack([f.center + s.min() * n, f.center + s.max() * n])
            foot = f.center
        rec.log(
            f"world/m/joints/j{j.index}/fit",
            rr.LineStrips3D([strip], colors=[_lighter(color)], radii=scene.line),
            static=True,
        )
        shared = sum(
            1
            for p, d in drawn
            if abs(float(d @ n)) > math.cos(math.radians(2.0))
            and np.linalg.norm(np.cross(foot - p, d)) < 0.03 * scene.extent
        )
        drawn.append((axis.point, n))
        origin = foot + (shared * 0.6 * scene.arrow) * n
        rec.log(
            f"world/m/joints/j{j.index}/axis",
            rr.Arrows3D(
                origins=[origin],
                vectors=[scene.arrow * n],
                colors=[color],
                radii=1.5 * scene.line,
                labels=[f"J{j.index}"],
                show_labels=True,
            ),
            static=True,
        )


def log_base(rec: rr.RecordingStream, result: object, scene: Scene | None = None) -> None:
    """The probed base points (orange, visible) and the fitted base plane as a thin outline."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    scene = scene or _scene(result)
    base = result.log.base
    if base is None or base.height == 0:
        return
    pts = base.select(["x", "y", "z"]).to_numpy()
    rec.log(
        "world/m/base_plane/points",
        rr.Points3D(pts, colors=[BASE_COLOR], radii=1.5 * scene.sample),
        static=True,
    )
    if result.base is None:
        return
    plane = result.base.plane
    u, v = result.base.basis
    half = 1.2 * float(np.max(np.abs((pts - plane.point) @ np.stack([u, v]).T))) + 0.05
    corners = [
        plane.point + half * (a * u + b * v)
        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1))
    ]
    rec.log(
        "world/m/base_plane/outline",
        rr.LineStrips3D([np.asarray(corners)], colors=[[150, 150, 150]], radii=scene.line),
        static=True,
    )


def _nice(value: float) -> float:
    """The 1-2-5 number nearest below ``value`` (≥ 1)."""
    if not math.isfinite(value) or value <= 1.0:
        return 1.0
    exp = 10 ** math.floor(math.log10(value))
    return float(max(m * exp for m in (1, 2, 5) if m * exp <= value))


def _fk_residuals(result: object) -> dict[int, tuple[np.ndarray, FloatArray, FloatArray]]:
    """Per identified joint: its inlier rows, the samples and the FK of the table there."""
    from dhlog.kinematics import fk_points_chunked
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    ex = result.extraction
    table = result.segmentation.table
    qcols = [f"q_{i + 1}" for i in range(len(result.joints))]
    if ex is None or not result.complete or not all(c in table.columns for c in qcols):
        return {}
    out = {}
    for j in result.joints:
        if j.fit is None:
            continue
        rows = j.rows[j.inliers]
        if "target" in table.columns:
            rows = rows[table["target"].fill_null(0).to_numpy()[rows] == 0]
        Q = table.select(qcols).to_numpy()[rows]
        ok = np.all(np.isfinite(Q), axis=1)
        rows, Q = rows[ok], Q[ok]
        P = table.select(["x", "y", "z"]).to_numpy()[rows]
        pred = fk_points_chunked(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
        out[j.index] = (rows, P, pred)
    return out


def _magnification(result: object, scene: Scene) -> float:
    """The factor that makes the FK residuals about 2 % of the robot's extent in 3D."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    v = result.validation
    if v is None or not math.isfinite(v.rms) or v.rms <= 0:
        return 1.0
    return _nice(0.02 * scene.extent / v.rms)


def _directions(joint: object, P: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """Per sample, the joint's radial, axial and tangential unit vectors (prismatic: two
    directions across the motion and the motion)."""
    from dhlog.identify.sweeps import JointReport

    assert isinstance(joint, JointReport)
    axis = joint.axis if joint.axis is not None else (joint.fit.axis if joint.fit else None)
    if axis is None:
        return None
    n = axis.direction
    if joint.type is JointType.PRISMATIC:
        u, v = perpendicular_basis(n)
        ones = np.ones((P.shape[0], 1))
        return ones * u, ones * n, ones * v
    w = P - axis.point
    w = w - np.outer(w @ n, n)
    radial = w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-12)
    tangential = np.cross(n, radial)
    return radial, np.ones((P.shape[0], 1)) * n, tangential


@dataclass(frozen=True)
class Residuals:
    """One joint's residual components (m) at its samples: ``kind`` ``fit`` or ``fk``, the
    table rows, the joint time line's values and, for ``fk``, the FK prediction."""

    kind: str
    joint: int
    rows: np.ndarray
    position: np.ndarray
    parts: dict[str, FloatArray]
    pred: FloatArray | None = None

    def ranges(self) -> tuple[tuple[int, int], tuple[float, float]]:
        """The plot's x range (joint time line, 3 % margin) and a symmetric y range (mm) that
        holds every value."""
        lo, hi = int(self.position.min()), int(self.position.max())
        pad = max(1, int(0.03 * (hi - lo)))
        top = max(float(np.max(np.abs(v))) for v in self.parts.values()) * 1e3 * 1.15
        top = top if top > 0 else 1e-3
        return (lo - pad, hi + pad), (-top, 2.2 * top)  # room above the data for the legend


def residual_parts(result: object) -> list[Residuals]:
    """Per joint, signed residual components against the moved joint's encoder value: the fit
    residual (radial and axial across the fitted circle; across a fitted line in two
    directions) and the FK residual of the final table (radial, axial, tangential)."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    xyz = result.segmentation.table.select(["x", "y", "z"]).to_numpy()
    out = []
    for j in result.joints:
        if j.fit is None or j.rows.size == 0:
            continue
        rows = j.rows[j.inliers]
        P = xyz[rows]
        dirs = _directions(j, P)
        if dirs is None or rows.size == 0:
            continue
        f = j.fit
        n = dirs[1][0]
        w = P - f.center
        axial = w @ n
        if f.kind == "circle":
            across = np.linalg.norm(w - np.outer(axial, n), axis=1) - f.radius
            parts = {"radial": across, "axial": axial}
        else:
            u, v = perpendicular_basis(n)
            parts = {"radial": w @ u, "tangential": w @ v}
        out.append(Residuals("fit", j.index, rows, _moved_position(result, rows, j.index), parts))
    for joint, (rows, P, pred) in _fk_residuals(result).items():
        dirs = _directions(result.joints[joint - 1], P)
        if dirs is None or rows.size == 0:
            continue
        r = P - pred
        parts = {
            name: np.sum(r * d, axis=1)
            for name, d in zip(("radial", "axial", "tangential"), dirs, strict=True)
        }
        position = _moved_position(result, rows, joint)
        out.append(Residuals("fk", joint, rows, position, parts, pred))
    return out


def log_residuals(
    rec: rr.RecordingStream,
    result: object,
    found: list[Residuals],
    scene: Scene | None = None,
    k: float = 1.0,
) -> None:
    """The residual components as plots on both time lines (mm), and the FK residuals magnified
    ``k`` times in 3D (``world/m/magnified``: each sample drawn at FK + k × residual)."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    scene = scene or _scene(result)
    xyz = result.segmentation.table.select(["x", "y", "z"]).to_numpy()
    t_all = result.segmentation.table["t_ns"].to_numpy()
    for res in found:
        index = [
            _time_column(t_all[res.rows]),
            rr.TimeColumn(JOINT_TIMELINE, sequence=res.position),
        ]
        _send_components(rec, f"residuals/{res.kind}/j{res.joint}", index, res.parts)
        if res.pred is not None:
            r = xyz[res.rows] - res.pred
            rec.log(
                f"world/m/magnified/j{res.joint}",
                rr.Points3D(res.pred + k * r, colors=[_color(res.joint)], radii=scene.sample),
                static=True,
            )


def _send_components(
    rec: rr.RecordingStream, path: str, index: list[rr.TimeColumn], parts: dict[str, FloatArray]
) -> None:
    for name, values in parts.items():
        entity = f"{path}/{name}"
        rec.log(
            entity,
            rr.SeriesPoints(colors=[COMPONENTS[name]], names=[name], marker_sizes=[1.5]),
            static=True,
        )
        rec.send_columns(
            entity, indexes=index, columns=rr.Scalars.columns(scalars=np.asarray(values) * 1e3)
        )


def _process_blueprint(result: object, k: float, found: list[Residuals]) -> rrb.Blueprint:
    """The default layout: the 3D evidence (samples and fits; FK residuals magnified) on the
    left, the DH table above the per-joint residual plots on the right, side panels closed."""
    from dhlog.process import ProcessResult

    assert isinstance(result, ProcessResult)
    eye = _eye(result, _scene(result))
    everything = [
        rrb.VisibleTimeRange(
            timeline,
            start=rrb.TimeRangeBoundary.infinite(),
            end=rrb.TimeRangeBoundary.infinite(),
        )
        for timeline in (TIMELINE, JOINT_TIMELINE)
    ]

    def view(res: Residuals, title: str) -> rrb.TimeSeriesView:
        (x0, x1), (y0, y1) = res.ranges()
        prismatic = result.joints[res.joint - 1].type is JointType.PRISMATIC
        return rrb.TimeSeriesView(
            name=f"J{res.joint} {title[:-1].lower().replace('fk', 'FK')} [mm] vs "
            f"q{res.joint} [{'µm' if prismatic else 'm°'}]",
            origin=f"residuals/{res.kind}/j{res.joint}",
            plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.RightTop, visible=True),
            time_ranges=everything,
            axis_x=rrb.TimeAxis(
                link=rrb.components.LinkAxis.Independent,
                view_range=rrb.TimeRange(
                    start=rrb.TimeRangeBoundary.absolute(seq=x0),
                    end=rrb.TimeRangeBoundary.absolute(seq=x1),
                ),
            ),
            axis_y=rrb.ScalarAxis(range=(y0, y1)),
        )

    def plots(kind: str, title: str) -> rrb.Grid:
        return rrb.Grid(*[view(res, title) for res in found if res.kind == kind], name=title)

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(
                rrb.Spatial3DView(
                    name="Samples and fits [m, robot base frame]",
                    origin="world",
                    contents=["+ $origin/**", "- $origin/m/magnified/**"],
                    time_ranges=everything,
                    eye_controls=eye,
                ),
                rrb.Spatial3DView(
                    name=f"FK residuals ×{k:g} [m, robot base frame]",
                    origin="world",
                    contents=[
                        "+ $origin/m/magnified/**",
                        "+ $origin/m/joints/**",
                        "+ $origin/m/robot/**",
                    ],
                    eye_controls=eye,
                ),
            ),
            rrb.Vertical(
                rrb.TextDocumentView(name="DH parameters", origin="report/dh_table"),
                rrb.Tabs(
                    *[
                        plots(kind, title)
                        for kind, title in (("fk", "FK residuals"), ("fit", "Fit residuals"))
                        if any(res.kind == kind for res in found)  # no encoders: no FK plots
                    ]
                ),
                row_shares=[1, 1],
            ),
            column_shares=[1, 1],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=JOINT_TIMELINE),
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
    bp = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name=f"{title} [m]", origin="world"),
            rrb.Spatial3DView(name="tool path [m]", origin="world/tool_path"),
            column_shares=[3, 2],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
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
    with _recording_file(path, "dhlog show", bp) as rec:
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
                colors=[_color(k + 1) for k in range(n)],
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
