"""The Rerun recording of a processed log (``<stem>.rrd``) and of a robot (``dhlog show``).

One ``log_*`` function per thing shown. Fitted geometry is static; samples and residuals are on
two time lines: ``sensor_time`` (the samples' own stamps) and ``joint_position`` (the moved
joint's encoder value, m° or µm: the residual plots' x axis), sent as columns. Each run is its
own recording (a new recording id; the log's hash is a property). The default blueprint opens
on the 3D view and the DH table, the per-joint residual plots below the table, side panels
closed; ``dhlog.present.render`` draws it headless to check it.

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
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from dhlog.geometry._checks import FloatArray, perpendicular_basis
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_frames

if TYPE_CHECKING:
    from dhlog.identify.run import ProcessResult
    from dhlog.identify.sweeps import JointReport

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


@dataclass(frozen=True)
class Shown:
    """What a result's recording draws, read from the result once: the samples (``xyz`` in M,
    ``t`` stamps, ``q`` encoder values or None), the DH frames of the shown table, the
    transform from M to the displayed base frame and the scene's sizes."""

    result: ProcessResult
    xyz: FloatArray
    t: np.ndarray
    q: FloatArray | None
    frames: FloatArray | None
    T: FloatArray
    scene: Scene

    @classmethod
    def of(cls, result: ProcessResult) -> Shown:
        table = result.segmentation.table
        xyz = table.select(["x", "y", "z"]).to_numpy()
        qcols = [f"q_{i + 1}" for i in range(len(result.joints))]
        q = table.select(qcols).to_numpy() if all(c in table.columns for c in qcols) else None
        frames: FloatArray | None = None
        T: FloatArray = np.eye(4)
        ex = result.extraction
        if ex is not None:
            frames = ex.frames
            if result.conditioned is not None:  # the Hayati table's frames: the standard
                # table's origins run off along near-parallel axes (d of metres)
                frames = fk_frames(
                    result.conditioned.table, ex.reference_pose, T_base=ex.T_measurement_base
                )
            frames = frames if result.complete else frames[:-1]
            # M → the base frame (DH frame 1, z along axis 1), turned over when the robot's
            # frames (its structure, not where it reaches) lie below it: it stands on the grid
            T = np.asarray(np.linalg.inv(ex.T_measurement_base), dtype=np.float64)
            if float(np.median(frames[:, :3, 3] @ T[2, :3] + T[2, 3])) < 0.0:
                T = np.diag([1.0, -1.0, -1.0, 1.0]) @ T
        centre = ex.T_measurement_base[:3, 3] if ex is not None else np.median(xyz, axis=0)
        reach = float(np.max(np.linalg.norm(xyz - centre, axis=1))) if xyz.size else 1.0
        return cls(result, xyz, table["t_ns"].to_numpy(), q, frames, T, Scene(max(reach, 0.05)))

    def position(self, rows: np.ndarray, joint: int) -> np.ndarray:
        """The moved joint's encoder value at ``rows`` on the joint time line (m°, or µm)."""
        if self.q is None:
            return np.zeros(rows.size, dtype=np.int64)
        prismatic = self.result.joints[joint - 1].type is JointType.PRISMATIC
        scale = 1e6 if prismatic else 180e3 / math.pi
        return np.asarray(np.round(np.nan_to_num(self.q[rows, joint - 1]) * scale), np.int64)

    def eye(self) -> rrb.EyeControls3D:
        """A camera on the robot (not on the probed base area, which may be much wider):
        looking at the samples' centre from the front-right, above, at 1.9 times the robot's
        extent."""
        T = self.T
        xyz = self.xyz
        centre = np.median(xyz @ T[:3, :3].T + T[:3, 3], axis=0) if xyz.size else np.zeros(3)
        centre[2] *= 0.6  # a little towards the floor: the base stays in the picture
        towards = np.array([1.0, -1.3, 0.8])
        eye = centre + 1.9 * self.scene.extent * towards / np.linalg.norm(towards)
        return rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital, position=eye, look_target=centre, eye_up=[0.0, 0.0, 1.0]
        )

    def magnification(self) -> float:
        """The factor that makes the FK residuals about 2 % of the robot's extent in 3D."""
        v = self.result.validation
        if v is None or not math.isfinite(v.rms) or v.rms <= 0:
            return 1.0
        return _nice(0.02 * self.scene.extent / v.rms)


def write_process_recording(
    result: ProcessResult, path: str | Path, *, with_log: bool = False
) -> None:
    """Write the recording of a :class:`~dhlog.identify.run.ProcessResult` to ``path`` atomically.

    Each run is its own recording (a new recording id), named by the log, the time of the run
    and the nominal; the log's hash is a property. ``with_log``: the MCAP's own channels are
    imported by Rerun's MCAP loader, for context (under their topic names: Rerun 0.41's loader
    takes no entity prefix)."""
    import uuid
    from datetime import UTC, datetime

    from dhlog import __version__
    from dhlog.present.console import result_markdown

    shown = Shown.of(result)
    k = shown.magnification()
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
    nominal = result.nominal.source if result.nominal is not None else None
    title = f"{Path(result.path).name} — {when}" + (f" — nominal {nominal}" if nominal else "")
    found = residual_parts(result, shown)
    with _recording_file(
        path, "dhlog process", _process_blueprint(shown, k, found), str(uuid.uuid4())
    ) as rec:
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
        rec.log(
            "report/dh_table",
            rr.TextDocument(result_markdown(result), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        if with_log and Path(result.path).is_file():
            rec.log_file_from_path(result.path)


def log_samples(rec: rr.RecordingStream, shown: Shown) -> None:
    """Target samples: per sweep on the sensor and joint time lines (coloured per joint), the
    sweeps named on the sensor time line, the set-aside ones (dimmed) and rejected outliers
    (red) always shown."""
    result, xyz, t, scene = shown.result, shown.xyz, shown.t, shown.scene
    table = result.segmentation.table
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
                rr.TimeColumn(JOINT_TIMELINE, sequence=shown.position(sel, k)),
            ],
            columns=rr.Points3D.columns(positions=xyz[sel]),
        )
    seg = result.segmentation.segments
    if seg.height:
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


def log_fits(rec: rr.RecordingStream, shown: Shown) -> None:
    """Per joint: the fitted arc over the swept range (or the line over the travel), thin and
    lighter than its samples, and the oriented axis as an arrow of a common length labelled
    ``Jk``; arrows of axes that coincide are staggered along them so both show."""
    scene = shown.scene
    drawn: list[tuple[FloatArray, FloatArray]] = []
    for j in shown.result.joints:
        if j.fit is None:
            continue
        f = j.fit
        color = _color(j.index)
        axis = j.axis if j.axis is not None else f.axis
        n = axis.direction
        pts = shown.xyz[j.rows[j.inliers]]
        if f.kind == "circle":
            u, v = perpendicular_basis(n)
            w = pts - f.center
            angles = np.unwrap(np.arctan2(w @ v, w @ u)) if pts.size else np.zeros(2)
            strip = _arc_points(f.center, n, f.radius, float(angles.min()), float(angles.max()))
        else:
            s = (pts - f.center) @ n if pts.size else np.array([-0.5 * f.sweep, 0.5 * f.sweep])
            strip = np.stack([f.center + s.min() * n, f.center + s.max() * n])
        rec.log(
            f"world/m/joints/j{j.index}/fit",
            rr.LineStrips3D([strip], colors=[_lighter(color)], radii=scene.line),
            static=True,
        )
        shared = sum(
            1
            for p, d in drawn
            if abs(float(d @ n)) > math.cos(math.radians(2.0))
            and np.linalg.norm(np.cross(f.center - p, d)) < 0.03 * scene.extent
        )
        drawn.append((axis.point, n))
        rec.log(
            f"world/m/joints/j{j.index}/axis",
            rr.Arrows3D(
                origins=[f.center + (shared * 0.6 * scene.arrow) * n],
                vectors=[scene.arrow * n],
                colors=[color],
                radii=1.5 * scene.line,
                labels=[f"J{j.index}"],
                show_labels=True,
            ),
            static=True,
        )


def log_base(rec: rr.RecordingStream, shown: Shown) -> None:
    """The probed base points (orange, visible) and the fitted base plane as a thin outline."""
    result, scene = shown.result, shown.scene
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


def _directions(
    joint: JointReport, P: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """Per sample, the joint's radial, axial and tangential unit vectors (prismatic: two
    directions across the motion and the motion)."""
    axis = joint.axis if joint.axis is not None else (joint.fit.axis if joint.fit else None)
    if axis is None:
        return None
    n = axis.direction
    ones = np.ones((P.shape[0], 1))
    if joint.type is JointType.PRISMATIC:
        u, v = perpendicular_basis(n)
        return ones * u, ones * n, ones * v
    w = P - axis.point
    w = w - np.outer(w @ n, n)
    radial = w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-12)
    return radial, ones * n, np.cross(n, radial)


@dataclass(frozen=True)
class Residuals:
    """One joint's residual components (m) at its samples: ``kind`` ``fit`` or ``fk``, the
    table rows, the joint time line's values and, for ``fk``, the residual vectors."""

    kind: str
    joint: int
    rows: np.ndarray
    position: np.ndarray
    parts: dict[str, FloatArray]
    vectors: FloatArray | None = None

    def ranges(self) -> tuple[tuple[int, int], tuple[float, float]]:
        """The plot's x range (joint time line, 3 % margin) and a y range (mm) that holds every
        value, with room above the data for the legend."""
        lo, hi = int(self.position.min()), int(self.position.max())
        pad = max(1, int(0.03 * (hi - lo)))
        top = max(float(np.max(np.abs(v))) for v in self.parts.values()) * 1e3 * 1.15
        top = top if top > 0 else 1e-3
        return (lo - pad, hi + pad), (-top, 2.2 * top)


def residual_parts(result: ProcessResult, shown: Shown | None = None) -> list[Residuals]:
    """Per joint, signed residual components against the moved joint's encoder value: the fit
    residual (radial and axial across the fitted circle; across a fitted line in two
    directions) and the FK residual the validation reports (radial, axial, tangential)."""
    shown = shown or Shown.of(result)
    out = []
    checked = result.validation.vectors if result.validation is not None else None
    for j in result.joints:
        if j.fit is None:
            continue
        rows = j.rows[j.inliers]
        P = shown.xyz[rows]
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
        out.append(Residuals("fit", j.index, rows, shown.position(rows, j.index), parts))
        if checked is None:
            continue
        ok = np.all(np.isfinite(checked[rows]), axis=1)  # rows the validation checked
        if not np.any(ok):
            continue
        r = checked[rows[ok]]
        fk_parts = {
            name: np.sum(r * d[ok], axis=1)
            for name, d in zip(("radial", "axial", "tangential"), dirs, strict=True)
        }
        out.append(
            Residuals("fk", j.index, rows[ok], shown.position(rows[ok], j.index), fk_parts, r)
        )
    return out


def log_residuals(
    rec: rr.RecordingStream, shown: Shown, found: list[Residuals], k: float = 1.0
) -> None:
    """The residual components as plots on both time lines (mm), and the FK residuals magnified
    ``k`` times in 3D (``world/m/magnified``: each sample drawn at FK + k × residual)."""
    for res in found:
        index = [
            _time_column(shown.t[res.rows]),
            rr.TimeColumn(JOINT_TIMELINE, sequence=res.position),
        ]
        _send_components(rec, f"residuals/{res.kind}/j{res.joint}", index, res.parts)
        if res.vectors is not None:
            pred = shown.xyz[res.rows] - res.vectors
            rec.log(
                f"world/m/magnified/j{res.joint}",
                rr.Points3D(
                    pred + k * res.vectors, colors=[_color(res.joint)], radii=shown.scene.sample
                ),
                static=True,
            )


#: Colours of the held-out error arrows: the nominal's, the calibrated model's.
HOLDOUT_COLORS = {"nominal": [230, 120, 30], "calibrated": [40, 170, 90]}


def holdout_magnification(shown: Shown) -> float:
    """The factor that makes the largest held-out RMS error about 4 % of the robot's extent."""
    worst = max(
        (
            s.rms
            for h in shown.result.holdout
            for s in (h.nominal, h.calibrated)
            if s is not None and s.rms > 0
        ),
        default=0.0,
    )
    return _nice(0.04 * shown.scene.extent / worst) if worst > 0 else 1.0


def log_holdout(rec: rr.RecordingStream, shown: Shown) -> None:
    """Every held-out pose (``world/m/holdout/<check>``): its measured position and, magnified
    :func:`holdout_magnification` times, the error vector (measured − predicted) of the nominal
    and of the calibrated model. A log measured after the tracker moved is drawn in this
    session's frame M through the base both were placed on."""
    result = shown.result
    ex = result.extraction
    if not result.holdout or ex is None:
        return
    k = holdout_magnification(shown)
    for i, h in enumerate(result.holdout):
        name = "cross_validation" if h.kind == "cross-validation" else f"log_{i}"
        M = np.eye(4)
        if h.T_measurement_base is not None:  # its M → the base → this session's M
            M = ex.T_measurement_base @ np.linalg.inv(h.T_measurement_base)
        pos = h.positions @ M[:3, :3].T + M[:3, 3]
        path = f"world/m/holdout/{name}"
        rec.log(
            f"{path}/poses",
            rr.Points3D(pos, colors=[[90, 90, 90]], radii=shown.scene.sample * 1.5),
            static=True,
        )
        for model, vectors in (
            ("nominal", h.nominal_vectors),
            ("calibrated", h.calibrated_vectors),
        ):
            if vectors is None:
                continue
            rec.log(
                f"{path}/{model}",
                rr.Arrows3D(
                    origins=pos,
                    vectors=k * (vectors @ M[:3, :3].T),
                    colors=[HOLDOUT_COLORS[model]],
                    radii=shown.scene.line,
                ),
                static=True,
            )


def deflection_magnification(shown: Shown) -> float:
    """The factor that makes the terms' largest displacement of the target about 4 % of the
    robot's extent."""
    worst = shown.result.deflection_target
    return _nice(0.04 * shown.scene.extent / worst) if worst > 0 else 1.0


def log_deflection(rec: rr.RecordingStream, shown: Shown) -> None:
    """The terms beyond the geometry (``world/m/deflection``): at up to 2000 samples, the
    target's displacement by the chosen compliance and harmonics, magnified
    :func:`deflection_magnification` times."""
    vectors = shown.result.deflection_vectors
    if not vectors.size:
        return
    rec.log(
        "world/m/deflection",
        rr.Arrows3D(
            origins=vectors[:, :3] - vectors[:, 3:],
            vectors=deflection_magnification(shown) * vectors[:, 3:],
            colors=[[120, 80, 200]],
            radii=shown.scene.line,
        ),
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


def _process_blueprint(shown: Shown, k: float, found: list[Residuals]) -> rrb.Blueprint:
    """The default layout: the 3D evidence (samples and fits; FK residuals magnified) on the
    left, the DH table above the per-joint residual plots on the right, side panels closed."""
    result = shown.result
    eye = shown.eye()
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
                    contents=[
                        "+ $origin/**",
                        "- $origin/m/magnified/**",
                        "- $origin/m/holdout/**",
                        "- $origin/m/deflection/**",
                    ],
                    time_ranges=everything,
                    eye_controls=eye,
                ),
                *(
                    [
                        rrb.Spatial3DView(
                            name=f"Held-out errors ×{holdout_magnification(shown):g}: nominal "
                            "orange, calibrated green [m, robot base frame]",
                            origin="world",
                            contents=[
                                "+ $origin/m/holdout/**",
                                "+ $origin/m/joints/**",
                                "+ $origin/m/robot/**",
                            ],
                            eye_controls=eye,
                        )
                    ]
                    if result.holdout
                    else []
                ),
                *(
                    [
                        rrb.Spatial3DView(
                            name=f"Deflection by the terms ×{deflection_magnification(shown):g} "
                            "(compliance, harmonics) [m, robot base frame]",
                            origin="world",
                            contents=[
                                "+ $origin/m/deflection/**",
                                "+ $origin/m/joints/**",
                                "+ $origin/m/robot/**",
                            ],
                            eye_controls=eye,
                        )
                    ]
                    if result.deflection_vectors.size
                    else []
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
