"""The residual plots of a result's recording: per joint, the signed fit and FK residual
components (radial, axial, tangential) against the moved joint's encoder value
(:func:`residual_parts`), logged as series on both time lines and, magnified, in 3D
(:func:`log_residuals`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr

from dhlog.geometry._checks import FloatArray, perpendicular_basis
from dhlog.model.dh import JointType
from dhlog.present.recording.scene import JOINT_TIMELINE, Shown, joint_color, time_column

if TYPE_CHECKING:
    from dhlog.identify.joints.sweeps import JointReport
    from dhlog.identify.run import Identification


#: Residual components, in the joint's own directions, and their colours in every plot.
COMPONENTS = {
    "radial": [230, 60, 60],
    "axial": [60, 170, 60],
    "tangential": [60, 120, 230],
}


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


def residual_parts(result: Identification, shown: Shown | None = None) -> list[Residuals]:
    """Per joint, signed residual components against the moved joint's encoder value: the fit
    residual (radial and axial across the fitted circle; across a fitted line in two
    directions) and the FK residual the validation reports (radial, axial, tangential)."""
    shown = shown or Shown.of(result)
    out = []
    validation = result.validation
    for j in result.joints:
        if j.fit is None:
            continue
        rows = shown.drawn(j.rows[j.inliers])
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
        if validation is None:
            continue
        checked = validation.at(rows)
        ok = np.all(np.isfinite(checked), axis=1)  # rows the validation checked
        if not np.any(ok):
            continue
        r = checked[ok]
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
            time_column(shown.t[res.rows]),
            rr.TimeColumn(JOINT_TIMELINE, sequence=res.position),
        ]
        _send_components(rec, f"residuals/{res.kind}/j{res.joint}", index, res.parts)
        if res.vectors is not None:
            pred = shown.xyz[res.rows] - res.vectors
            rec.log(
                f"world/m/magnified/j{res.joint}",
                rr.Points3D(
                    pred + k * res.vectors,
                    colors=[joint_color(res.joint)],
                    radii=shown.scene.sample,
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
