"""The 3D view of a result's recording, one ``log_*`` per thing shown (static where fitted, the
samples as columns on both time lines): DH frames and links, samples, fitted arcs and axes, the
base plane, held-out errors and the deflection by the terms beyond the geometry."""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from dhlog.geometry._checks import FloatArray, perpendicular_basis
from dhlog.present.recording.scene import (
    DIM,
    JOINT_TIMELINE,
    Shown,
    deflection_magnification,
    holdout_magnification,
    joint_color,
    time_column,
)

#: The probed base points (orange).
BASE_COLOR = np.array([255, 150, 30], dtype=np.uint8)


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


def log_samples(rec: rr.RecordingStream, shown: Shown) -> None:
    """Target samples: per sweep on the sensor and joint time lines (coloured per joint), the
    sweeps named on the sensor time line, the set-aside ones (dimmed) and rejected outliers
    (red) always shown."""
    result, xyz, t, scene = shown.result, shown.xyz, shown.t, shown.scene
    seg = result.segmentation
    segment = seg.segment
    outlier = np.zeros(seg.height, dtype=bool)
    for j in result.joints:
        outlier[j.rows[~j.inliers]] = True
    for sid in np.unique(segment[segment > 0]):
        sel = shown.drawn(np.flatnonzero((segment == sid) & ~outlier))
        if sel.size == 0:
            continue
        k = int(seg.joint(sel[:1])[0])
        path = f"world/m/samples/segment_{int(sid)}"
        rec.log(
            path,
            rr.Points3D.from_fields(colors=[joint_color(k)], radii=[scene.sample]),
            static=True,
        )
        rec.send_columns(
            path,
            indexes=[
                time_column(t[sel]),
                rr.TimeColumn(JOINT_TIMELINE, sequence=shown.position(sel, k)),
            ],
            columns=rr.Points3D.columns(positions=xyz[sel]),
        )
    sweeps = seg.segments
    if sweeps.height:
        names = [j.name for j in result.joints]
        texts = [
            f"sweep {int(s)}: joint {int(k)} ({names[int(k) - 1] if 0 < k <= len(names) else '?'})"
            for s, k in zip(sweeps["segment"], sweeps["joint"], strict=True)
        ]
        rec.send_columns(
            "sweeps",
            indexes=[time_column(sweeps["t_start_ns"].to_numpy())],
            columns=rr.TextLog.columns(text=texts),
        )
    aside = shown.drawn(np.flatnonzero(segment == 0))
    if aside.size:
        ids = result.log.point_ids  # the static poses of an import, by the export's ids
        labels = None if ids is None else [ids.get(int(s), "") for s in np.asarray(t)[aside]]
        rec.log(
            "world/m/samples/set_aside",
            rr.Points3D(xyz[aside], colors=[DIM], radii=0.5 * scene.sample, labels=labels),
            static=True,
        )
    if np.any(outlier):  # every outlier, however many rows are drawn
        rec.log(
            "world/m/samples/outliers",
            rr.Points3D(xyz[outlier], colors=[[255, 0, 0]], radii=1.5 * scene.sample),
            static=True,
        )
    rows = result.outlier_rows
    if rows.size:  # the whole-model fit's, named as the export names them
        rec.log(
            "world/m/samples/fit_outliers",
            rr.Points3D(
                xyz[rows],
                colors=[[255, 0, 0]],
                radii=1.5 * scene.sample,
                labels=list(result.outlier_names),
            ),
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
        color = joint_color(j.index)
        axis = j.axis if j.axis is not None else f.axis
        n = axis.direction
        pts = shown.xyz[shown.drawn(j.rows[j.inliers])]
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


#: Colours of the held-out error arrows: the nominal's, the calibrated model's.
HOLDOUT_COLORS = {"nominal": [230, 120, 30], "calibrated": [40, 170, 90]}


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
            rr.Points3D(
                pos,
                colors=[[90, 90, 90]],
                radii=shown.scene.sample * 1.5,
                labels=None if h.pose_names is None else list(h.pose_names),
            ),
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
