"""The check of a result against every sample: forward kinematics of the DH table at each
sample's encoder values, per joint and overall; the predicted FK error from the covariance."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.identify.extract import Extraction
from dhlog.identify.propagate import state_vector
from dhlog.identify.segment import Segmentation
from dhlog.identify.sweeps import JointReport
from dhlog.identify.whole import WholeFit
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_point, fk_points_chunked


class Identified(Protocol):
    """What :func:`fk_prediction_std` reads of a run's result (``identify.run.ProcessResult``):
    the whole-model fit, else the extraction and its propagated covariance."""

    @property
    def whole(self) -> WholeFit | None: ...

    @property
    def extraction(self) -> Extraction | None: ...

    @property
    def covariance(self) -> FloatArray | None: ...


@dataclass
class Validation:
    """FK of the result against each assigned sample with encoder values (m), and summaries:
    ``vectors`` (table rows, 3) sample − FK, NaN at rows not checked; ``residuals`` their
    lengths."""

    vectors: FloatArray
    residuals: FloatArray
    per_joint: dict[int, tuple[float, float, int]]
    rms: float
    max: float
    n_points: int

    @classmethod
    def of(
        cls,
        vectors: FloatArray,
        per_joint: dict[int, tuple[float, float, int]],
        used: FloatArray,
    ) -> Validation:
        """The validation of the residual ``vectors``, with RMS, max and count over the
        residual lengths ``used`` (m)."""
        return cls(
            vectors=vectors,
            residuals=np.sqrt(np.sum(vectors**2, axis=1)),
            per_joint=per_joint,
            rms=float(np.sqrt(np.mean(used**2))) if used.size else float("nan"),
            max=float(used.max()) if used.size else float("nan"),
            n_points=int(used.size),
        )


def model_from_state(
    x: FloatArray, types: tuple[JointType, ...], R0: FloatArray
) -> tuple[StandardDH, FloatArray, FloatArray]:
    """Inverse of :func:`state_vector`: (table, tool point, T_measurement_base)."""
    n = len(types)
    rows = x[: 4 * n].reshape(n, 4)
    table = StandardDH(types, rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3])
    tool = x[4 * n : 4 * n + 3]
    R = R0 @ rotation_from_vector(x[4 * n + 6 : 4 * n + 9])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, x[4 * n + 3 : 4 * n + 6]
    return table, tool, T


def fk_prediction_std(result: Identified, Q: FloatArray) -> FloatArray:
    """Predicted RMS position error (m, 3-D) of the result's FK at each joint vector in ``Q``,
    to first order: from the whole-model fit's own covariance and its analytic Jacobian when the
    result is that fit's (the DH table reproduces it exactly, and its DH parameters may be
    ill-conditioned where the fit's are not), else from the DH model's propagated covariance."""
    whole = result.whole
    if whole is not None:
        from dhlog.identify.prediction import predict

        _, Jw = predict(whole.model, Q, whole.layout, whole.bases)
        assert Jw is not None
        var_w = np.einsum("mij,jk,mik->m", Jw, whole.covariance, Jw)
        return np.asarray(np.sqrt(np.clip(var_w, 0.0, None)), dtype=np.float64)
    ex, cov = result.extraction, result.covariance
    assert ex is not None and cov is not None
    R0 = ex.T_measurement_base[:3, :3]
    x0 = state_vector(ex, R0)
    types = ex.standard.joint_types

    def fk(x: FloatArray) -> FloatArray:
        table, tool, T = model_from_state(x, types, R0)
        return fk_point(table, Q, tool, T_base=T)

    J = np.zeros((Q.shape[0], 3, x0.size))
    for i in range(x0.size):
        h = 1e-7
        e = np.zeros(x0.size)
        e[i] = h
        J[:, :, i] = (fk(x0 + e) - fk(x0 - e)) / (2 * h)
    var = np.einsum("mij,jk,mik->m", J, cov, J)
    return np.asarray(np.sqrt(np.clip(var, 0.0, None)), dtype=np.float64)


def validate_sweeps(
    seg: Segmentation, joints: list[JointReport], ex: Extraction
) -> Validation | None:
    """FK of the result at every assigned inlier sample's own encoder values against the sample."""
    if not seg.has_encoders:
        return None
    table = seg.table
    cols = [f"q_{i + 1}" for i in range(seg.n_joints)]
    Q = table.select(cols).to_numpy()
    P = table.select(["x", "y", "z"]).to_numpy()
    vectors = np.full((table.height, 3), np.nan)
    per_joint: dict[int, tuple[float, float, int]] = {}
    used: list[FloatArray] = []
    for j in joints:
        rows = j.rows[j.inliers]
        if rows.size == 0:
            continue
        pred = fk_points_chunked(ex.standard, Q[rows], ex.tool_point, T_base=ex.T_measurement_base)
        vectors[rows] = P[rows] - pred
        r = np.linalg.norm(vectors[rows], axis=1)
        per_joint[j.index] = (float(np.sqrt(np.mean(r**2))), float(r.max()), int(r.size))
        used.append(r)
    return Validation.of(vectors, per_joint, np.concatenate(used) if used else np.zeros(0))


def validate_samples(
    seg: Segmentation,
    rows: NDArray[np.int64],
    Q: FloatArray,
    P: FloatArray,
    ex: Extraction,
    inliers: NDArray[np.bool_],
    tools: FloatArray | None = None,
    which: NDArray[np.int64] | None = None,
) -> Validation:
    """FK of the DH result at every sample with encoder values against the sample (per joint by
    the sweep it belongs to; coupled moves and still poses under joint 0). ``tools`` (k, 3):
    the tool point of each target in the last frame, ``which`` each sample's target."""
    if tools is None or which is None:
        pred = fk_points_chunked(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    else:
        pred = np.empty_like(P)
        for k, tool in enumerate(tools):
            mask = which == k
            pred[mask] = fk_points_chunked(ex.standard, Q[mask], tool, T_base=ex.T_measurement_base)
    r = np.sqrt(np.sum((pred - P) ** 2, axis=1))
    vectors = np.full((seg.table.height, 3), np.nan)
    vectors[rows[inliers]] = (P - pred)[inliers]
    labels = seg.table["joint"].fill_null(0).to_numpy()[rows]
    per_joint: dict[int, tuple[float, float, int]] = {}
    for k in np.unique(labels[inliers]):
        rk = r[inliers & (labels == k)]
        per_joint[int(k)] = (float(np.sqrt(np.mean(rk**2))), float(rk.max()), int(rk.size))
    return Validation.of(vectors, per_joint, r[inliers])


def check_residual(validation: Validation, sigma: float, notes: list[str]) -> None:
    expected = math.sqrt(3.0) * sigma
    if validation.rms > 1.5 * expected:
        notes.append(
            f"the FK residual RMS ({validation.rms * 1e3:.4f} mm, 3-D) is larger than the fit "
            f"noise explains ({expected * 1e3:.4f} mm): the axes disagree with one "
            "kinematic chain more than the noise allows."
        )


def table_gap(whole: WholeFit, ex: Extraction, Q: FloatArray, Q_table: FloatArray) -> float:
    """Largest distance (m) between the fitted model and its DH table at up to 64 of the
    sampled joint vectors ``Q`` (the table's joint values ``Q_table``: the encoders scaled and
    deflected by the terms as the table sees them): 0 up to rounding when the extraction is
    exact."""
    from dhlog.identify.prediction import predict

    pick = np.unique(np.linspace(0, Q.shape[0] - 1, min(64, Q.shape[0])).astype(int))
    fitted, _ = predict(whole.model, Q[pick])
    table = fk_points_chunked(
        ex.standard, Q_table[pick], ex.tool_point, T_base=ex.T_measurement_base
    )
    return float(np.max(np.linalg.norm(fitted - table, axis=1)))
