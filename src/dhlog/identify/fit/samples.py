"""What the log says of the samples the whole-model fit uses beyond their positions (a 6-DoF
target's orientation, per-sample covariances), and the start model from them: the further
targets and the target frame's orientation at the reference pose, from the samples moved back
through the start's axes."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, nearest_rotation
from dhlog.geometry.lines import Line
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData
from dhlog.identify.segment.persample import SampleArray, rows_where
from dhlog.identify.segment.segment import Segmentation
from dhlog.model.dh import JointType
from dhlog.model.screws import motions_back, points_at_reference

#: Largest number of samples the target at the reference pose is averaged over for the start.
START_TARGET_POINTS = 20000


def measured_rotations(seg: Segmentation, rows: NDArray[np.int64]) -> FloatArray | None:
    """The target frame's measured orientation (m, 3, 3) at ``rows`` when the log carries it
    (``orientation = true`` in the pipeline), else None."""
    from dhlog.io.reader import ORIENTATION_COLUMNS

    if not all(c in seg.points.columns for c in ORIENTATION_COLUMNS):
        return None
    from scipy.spatial.transform import Rotation  # 0.35 s of imports: only when needed

    quat = np.column_stack([seg.column(c, rows) for c in ORIENTATION_COLUMNS])
    return np.asarray(Rotation.from_quat(quat).as_matrix(), dtype=np.float64)  # x, y, z, w


def rotation_at_reference(
    axes: list[Line], types: tuple[JointType, ...], Q: SampleArray, R: FloatArray, ref: FloatArray
) -> FloatArray:
    """The target frame's orientation at the reference pose: every measured orientation moved
    back through the axes (at most 20 000, evenly strided), their chordal mean."""
    stride = max(1, Q.shape[0] // START_TARGET_POINTS)
    Rt, _ = motions_back(axes, types, Q[::stride], ref)
    return nearest_rotation(np.einsum("mij,mjk->ik", Rt, R[::stride]))


def mean_at_reference(
    axes: list[Line],
    types: tuple[JointType, ...],
    Q: SampleArray,
    P: SampleArray,
    rows: NDArray[np.integer],
    ref: FloatArray,
) -> FloatArray:
    """A target's position at the reference pose: its samples ``rows`` of ``Q``, ``P`` (at most
    20 000 of them, evenly strided, the only ones read) moved back through the axes and
    averaged."""
    if rows.size == 0:
        raise DegenerateGeometryError("a further target has no sample with encoder values.")
    pick = rows[:: max(1, rows.size // START_TARGET_POINTS)]
    back = points_at_reference(axes, types, Q[pick], P[pick], ref)
    return np.asarray(back.mean(axis=0), dtype=np.float64)


def sample_covariance(seg: Segmentation, rows: NDArray[np.int64]) -> FloatArray | None:
    """The position covariance (m, 3, 3) the log carries for the samples ``rows``
    (``PoseWithCovarianceStamped``), or None when any of them has none or one that is not
    positive definite (the noise model then applies to all)."""
    from dhlog.io.reader import COVARIANCE_COLUMNS

    if not all(c in seg.points.columns for c in COVARIANCE_COLUMNS):
        return None
    c = np.column_stack([seg.column(name, rows) for name in COVARIANCE_COLUMNS])
    if not np.all(np.isfinite(c)):
        return None
    cov = np.empty((rows.size, 3, 3))
    for k, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
        cov[:, a, b] = cov[:, b, a] = c[:, k]
    if not np.all(np.linalg.eigvalsh(cov)[:, 0] > 0):
        return None
    return cov


def start_model(
    axes: list[Line],
    types: tuple[JointType, ...],
    target: FloatArray,
    ref: FloatArray,
    data: FitData,
    held_axes: frozenset[int] = frozenset(),
) -> AxisModel:
    """The whole model's start: ``axes``, ``types`` and ``target`` at the reference pose ``ref``,
    unit encoder scales, each further target (``data.which`` > 0) and the target frame's
    orientation (``data.rotations``) from the samples ``data.Q``, ``data.P`` moved back through
    the axes; ``held_axes`` the joints whose axes the fit holds."""
    Q, P, which, rotations = data.Q, data.P, data.which, data.rotations
    extra = np.zeros((0, 3))
    if which is not None:  # further targets: their samples moved back to the reference pose
        extra = np.array(
            [
                mean_at_reference(axes, types, Q, P, rows_where(which == k), ref)
                for k in range(1, int(which.max()) + 1)
            ]
        ).reshape(-1, 3)
    return AxisModel(
        tuple(axes),
        types,
        target,
        ref,
        np.ones(len(axes)),
        extra,
        None if rotations is None else rotation_at_reference(axes, types, Q, rotations, ref),
        held_axes=held_axes,
    )
