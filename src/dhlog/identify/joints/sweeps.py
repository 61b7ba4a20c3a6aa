"""Per joint: the sweeps to use, the joint type, the robust axis fit, the axis carried to the
reference pose, and the target at the reference pose (the analytic start's inputs)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import polars as pl
from numpy.typing import NDArray

from dhlog.errors import GeometryError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.axisfit import AxisFit
from dhlog.geometry.fitting import detect_joint_type, fit_axis_robust, inlier_limit, within
from dhlog.geometry.lines import Line
from dhlog.identify.segment.persample import PerSample, blocks, fills, rows_where
from dhlog.identify.segment.segment import Segmentation
from dhlog.io import scratch
from dhlog.io.dhfile import DHModel
from dhlog.io.reader import LogData
from dhlog.model.dh import JointType
from dhlog.model.screws import chain_motion, points_at_reference


@dataclass(frozen=True)
class JointReport:
    """What became of one joint: its type (and where the type came from), the fit, the axis at
    the reference pose, the sweeps used, the outliers set aside, or why it failed."""

    index: int
    name: str
    type: JointType | None = None
    type_source: str = ""
    fit: AxisFit | None = None
    axis: Line | None = None
    segments: list[int] = field(default_factory=list)
    rows: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    inliers: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    lock_pose: FloatArray | None = None
    carried: bool = False
    reason: str | None = None

    @property
    def ok(self) -> bool:
        """True when the joint's axis was identified."""
        return self.axis is not None and self.reason is None

    @property
    def n_outliers(self) -> int:
        """Samples of the joint's sweeps set aside as gross outliers."""
        return int(np.count_nonzero(~self.inliers))


def _groups_by_lock(seg: Segmentation, joint: int, tol: float) -> list[list[int]]:
    """The joint's segments grouped by compatible locked poses (each group: segment ids)."""
    rows = seg.segments.filter(pl.col("joint") == joint)
    locks = rows.select([f"lock_q_{j + 1}" for j in range(seg.n_joints)]).to_numpy()
    ids = rows["segment"].to_list()
    groups: list[tuple[FloatArray, list[int]]] = []
    for sid, lock in zip(ids, locks, strict=True):
        for pose, members in groups:
            both = ~np.isnan(pose) & ~np.isnan(lock)
            if np.all(np.abs(pose[both] - lock[both]) <= tol):
                members.append(int(sid))
                break
        else:
            groups.append((lock, [int(sid)]))
    return [members for _, members in groups]


def _lock_matches(lock: FloatArray, ref: FloatArray, joint: int, tol: float) -> bool:
    others = np.arange(lock.size) != joint - 1
    values = lock[others]
    known = ~np.isnan(values)
    return bool(np.all(np.abs(values[known] - ref[others][known]) <= tol))


def _joint_type(
    k: int, name: str, points: FloatArray, log: LogData, nominal: DHModel | None
) -> tuple[JointType, str, tuple[Note, ...]]:
    declared = log.pipeline.joint_types
    if declared is not None and k - 1 < len(declared) and declared[k - 1] is not None:
        jt = declared[k - 1]
        assert jt is not None
        return jt, "pipeline", ()
    if nominal is not None:
        return nominal.table.joint_types[k - 1], "nominal", ()
    kind, why = detect_joint_type(points, what=f"joint {k} ({name})")
    jt = JointType(kind)
    said = f"joint {k} ({name}): detected as prismatic ({why})."
    notes = (Note.warning(said, "prismatic"),) if jt is JointType.PRISMATIC else ()
    return jt, f"detected: {why}", notes


def fit_joint(
    report: JointReport,
    seg: Segmentation,
    log: LogData,
    ref: FloatArray,
    identified: list[JointReport],
    nominal: DHModel | None,
    fit_method: str,
    max_points: int | None = None,
) -> tuple[JointReport, tuple[Note, ...]]:
    """Joint ``report`` with its axis fitted from its sweeps (a new report: the sweeps used,
    the type, the fit, the axis at the reference pose, or why it failed), and what the fit
    said: a joint detected as prismatic (``prismatic``), the axis fit's warnings
    (``axis-fit``), an axis carried from another pose (``carried``)."""
    notes: list[Note] = []
    k, name = report.index, report.name
    tol = log.pipeline.segmentation.lock_tolerance
    what = f"joint {k} ({name})"
    groups = _groups_by_lock(seg, k, tol)
    if not groups:
        report = replace(report, reason="it was never swept (no segment in which it alone moved)")
        return report, tuple(notes)
    segments = seg.segments
    chosen = groups[0]
    for group in groups:
        lock = (
            segments.filter(pl.col("segment") == group[0])
            .select([f"lock_q_{j + 1}" for j in range(seg.n_joints)])
            .to_numpy()[0]
        )
        if _lock_matches(lock, ref, k, tol):
            chosen = group
            break
    else:
        chosen = max(
            groups, key=lambda g: int(segments.filter(pl.col("segment").is_in(g))["n"].sum())
        )
    lock = (
        segments.filter(pl.col("segment") == chosen[0])
        .select([f"lock_q_{j + 1}" for j in range(seg.n_joints)])
        .to_numpy()[0]
    )
    report = replace(report, segments=chosen)
    # the per-joint fits use the primary target's circles
    rows = seg.rows_in(chosen, primary=True)
    report = replace(report, rows=rows)
    # the start fits take an evenly strided subset; every sample is judged against them in
    # blocks (a sweep of millions of samples is never whole in memory)
    m = rows.size
    every = 1 if max_points is None or m <= max_points else -(-m // max_points)
    fitted = rows[::every]
    try:
        typed = rows[:: 1 if max_points is None else max(1, m // max_points)]
        jt, source, said = _joint_type(k, name, seg.xyz(typed), log, nominal)
        notes.extend(said)
        report = replace(report, type=jt, type_source=source)
        settings = log.pipeline.segmentation
        fit, inliers = fit_axis_robust(
            seg.xyz(fitted),
            kind="line" if jt is JointType.PRISMATIC else "circle",
            encoder=seg.q(fitted, [k - 1])[:, 0] if seg.has_encoders else None,
            method=fit_method,  # type: ignore[arg-type]
            min_sweep=settings.min_sweep,
            what=what,
        )
        if every > 1:
            limit = inlier_limit(fit, seg.xyz(fitted[inliers]))
            inliers = scratch.empty(m, np.bool_)
            for sl in blocks(m):
                inliers[sl] = within(fit, seg.xyz(rows[sl]), limit)
    except GeometryError as exc:
        report = replace(report, reason=str(exc).removeprefix(f"{what}: "))
        return report, tuple(notes)
    report = replace(report, fit=fit, inliers=inliers)
    notes.extend(Note.warning(w, "axis-fit") for w in fit.warnings)
    report = replace(report, lock_pose=np.where(np.isnan(lock), ref, lock))
    report = replace(
        report, carried=bool(seg.has_encoders and not _lock_matches(lock, ref, k, tol))
    )
    if report.carried:
        upstream = identified[: k - 1]
        if any(not j.ok for j in upstream):
            report = replace(
                report,
                reason="it was swept only from another pose, and an upstream joint needed to "
                "carry its axis to the reference pose was not identified",
            )
            return report, tuple(notes)
        notes.append(
            Note.warning(
                f"{what}: swept from another pose; its axis was carried to the reference pose "
                "through the upstream axes.",
                "carried",
            )
        )
    report = replace(report, axis=carried_axis(report, fit.axis, identified, ref))
    return report, tuple(notes)


def carried_axis(
    report: JointReport, fitted: Line, joints: list[JointReport], ref: FloatArray
) -> Line:
    """The joint's axis at the reference pose: as fitted when it was swept there, else moved
    back from its locked pose through the upstream axes (product of exponentials)."""
    if not report.carried:
        return fitted
    k = report.index
    assert report.lock_pose is not None
    upstream = joints[: k - 1]
    axes = [j.axis for j in upstream]
    types = [j.type for j in upstream]
    M = chain_motion(axes, types, report.lock_pose[: k - 1], ref[: k - 1])  # type: ignore[arg-type]
    return fitted.transformed(np.linalg.inv(M))


class TargetAtReference:
    """The target at the reference pose, from the inlier samples of all sweeps.

    With encoders: every inlier sample moved back to the reference pose through the axes
    (``M_n(q)⁻¹ p``, product of exponentials), averaged; its covariance is the scatter over the
    number of samples. Without encoders: the point nearest all fitted circles (every sweep starts
    from the same pose, so every circle passes through it).
    """

    def __init__(
        self,
        seg: Segmentation,
        joints: list[JointReport],
        ref: FloatArray,
        max_rows: int | None = None,
    ) -> None:
        self.joints, self.ref = joints, ref
        self.encoders = seg.has_encoders
        if self.encoders:
            rows = np.concatenate([j.rows[j.inliers] for j in joints])
            if max_rows is not None and rows.size > max_rows:
                rows = rows[:: -(-rows.size // max_rows)]
            self.Q = seg.q(rows)
            self.P = seg.xyz(rows)

    def __call__(self, axes: list[Line | None] | None = None) -> tuple[FloatArray, FloatArray]:
        joints = self.joints
        if not self.encoders:
            fits = [j.fit for j in joints if j.fit is not None]
            spread = max(f.sigma for f in fits) ** 2 / len(fits)
            return _common_point_of_circles(fits), np.eye(3) * spread
        axes = [j.axis for j in joints] if axes is None else axes
        types = [j.type for j in joints]
        back = points_at_reference(axes, types, self.Q, self.P, self.ref)  # type: ignore[arg-type]
        return back.mean(axis=0), np.cov(back.T) / back.shape[0]


def _common_point_of_circles(fits: list[AxisFit]) -> FloatArray:
    """The point nearest (least squares) to all circles, from the best-agreeing sample."""
    from scipy.optimize import least_squares

    def distances(p: FloatArray) -> FloatArray:
        out = []
        for f in fits:
            w = p - f.center
            h = w @ f.axis.direction
            rho = np.linalg.norm(w - h * f.axis.direction)
            out += [h, rho - f.radius]
        return np.asarray(out)

    candidates = []
    for f in fits:
        u, v = f.basis
        for a in np.linspace(0, 2 * np.pi, 72, endpoint=False):
            candidates.append(f.center + f.radius * (np.cos(a) * u + np.sin(a) * v))
    start = min(candidates, key=lambda c: float(np.sum(distances(c) ** 2)))
    return np.asarray(least_squares(distances, start).x, dtype=np.float64)


def samples_with_encoders(seg: Segmentation) -> tuple[NDArray[np.intp], PerSample, PerSample]:
    """Rows of the measurement table with every encoder value (sweeps, coupled moves, still
    poses), and their encoder values (m, n) and points (m, 3), read a block at a time. Up to
    :data:`~dhlog.identify.segment.persample.FILL_BYTES` the encoder values are interpolated
    once, into an array (a scratch file when large) every later pass reads; beyond, at each pass."""
    n = seg.n_joints
    q_all = scratch.empty((seg.height, n)) if fills((seg.height, n)) else None
    ok = scratch.empty(seg.height, np.bool_)
    for sl in blocks(seg.height):
        q = seg.q(sl)
        if q_all is not None:
            q_all[sl] = q
        ok[sl] = np.isfinite(q).all(axis=1) & np.isfinite(seg.xyz(sl)).all(axis=1)
    rows = rows_where(ok)
    del ok
    if q_all is not None and rows.size == seg.height:
        Q = PerSample.kept(q_all)
    elif q_all is not None:
        kept = q_all
        Q = PerSample(
            (rows.size, n), lambda index: scratch.in_spans(index, lambda i: kept[rows[i]])
        ).filled()
    else:  # Segmentation.q and .xyz gather a piece at a time themselves
        Q = PerSample((rows.size, n), lambda index: seg.q(rows[index]))
    del q_all
    P = PerSample((rows.size, 3), lambda index: seg.xyz(rows[index]))
    return rows, Q, P


def target_labels(seg: Segmentation, rows: NDArray[np.intp]) -> NDArray[np.int64] | None:
    """Which target each of ``rows`` measured (0 the primary one), or None with one target."""
    if "target" not in seg.points.columns:
        return None
    return scratch.gathered(seg.points["target"].to_numpy(), rows, np.int64)
