"""Global refinement: one least-squares fit of the whole model to every sample.

Started from the analytic result, ``scipy.optimize.least_squares`` adjusts the DH rows, the
joint offsets (θ_offset / d_offset), the tool point and ``T_measurement_base`` so that forward
kinematics at each sample's own encoder values meets the measured point, with a robust loss
(soft L1 at 3σ) so that gross outliers do not pull. Parameters fixed by a DH convention or by the
nominal (σ = 0 in the analytic result) stay fixed; the base-plane points, when there are any,
enter as distances to frame 1's xy plane so that the height of frame 1 stays determined.
The uncertainty is σ̂² (JᵀJ)⁻¹ at the solution, σ̂ from the residuals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from dhlog.geometry._checks import FloatArray
from dhlog.kinematics import fk_point
from dhlog.process import ProcessResult, model_from_state, state_vector


@dataclass(frozen=True, eq=False)
class Refinement:
    """The refined model vector (as :func:`dhlog.process.state_vector`), its covariance, and the
    FK residual RMS (m) before and after, over the same inlier samples."""

    x: FloatArray
    covariance: FloatArray
    fk_rms_before: float
    fk_rms_after: float
    iterations: int
    n_points: int


def refine(result: ProcessResult) -> Refinement:
    """Refine the complete result ``result`` against all its inlier samples (needs encoders)."""
    ex, cov = result.extraction, result.covariance
    seg = result.segmentation
    if ex is None or cov is None or not result.complete or not seg.has_encoders:
        raise ValueError("refinement needs a complete result with encoder values")
    R0 = ex.T_measurement_base[:3, :3]
    x0 = state_vector(ex, R0)
    types = ex.standard.joint_types
    std0 = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    free = std0 > 1e-12
    for rel in ex.relations:  # d of a parallel pair is a convention (the common normal's place)
        if rel.relation.kind.is_parallel:
            free[4 * (rel.joints[0] - 1) + 1] = False
    rows = np.concatenate([j.rows[j.inliers] for j in result.joints])
    Q = seg.table.select([f"q_{i + 1}" for i in range(seg.n_joints)]).to_numpy()[rows]
    P = seg.table.select(["x", "y", "z"]).to_numpy()[rows]
    base_pts = None
    if result.base is not None and result.log.base is not None:
        base_pts = result.log.base.select(["x", "y", "z"]).to_numpy()
    sigma = math.sqrt(np.mean([j.fit.sigma**2 for j in result.joints if j.fit is not None]))

    def full(xf: FloatArray) -> FloatArray:
        x = x0.copy()
        x[free] = xf
        return x

    def residuals(xf: FloatArray) -> FloatArray:
        table, tool, T = model_from_state(full(xf), types, R0)
        r = (fk_point(table, Q, tool, T_base=T) - P).ravel() / sigma
        if base_pts is None:
            return np.asarray(r, dtype=np.float64)
        height = (base_pts - T[:3, 3]) @ T[:3, 2] / sigma
        return np.concatenate([r, height])

    before = float(
        np.sqrt(
            np.mean(
                np.sum((residuals(x0[free])[: 3 * len(rows)].reshape(-1, 3) * sigma) ** 2, axis=1)
            )
        )
    )
    sol = least_squares(
        residuals,
        x0[free],
        x_scale=np.maximum(std0[free], 1e-9),
        loss="soft_l1",
        f_scale=3.0,
        method="trf",
    )
    x = full(sol.x)
    fk_res = residuals(sol.x)[: 3 * len(rows)].reshape(-1, 3) * sigma
    after = float(np.sqrt(np.mean(np.sum(fk_res**2, axis=1))))
    # covariance from the plain (unweighted) Jacobian over the residuals the robust loss kept
    # in its quadratic zone: the loss's down-weighting would otherwise inflate it
    keep = np.abs(sol.fun) <= 3.0
    J = np.zeros((sol.fun.size, sol.x.size))
    for k in range(sol.x.size):
        h = 1e-3 * max(float(std0[free][k]), 1e-9)
        e = np.zeros(sol.x.size)
        e[k] = h
        J[:, k] = (residuals(sol.x + e) - residuals(sol.x - e)) / (2 * h)
    J = J[keep] * sigma  # d(residual in m)/dx
    dof = max(int(keep.sum()) - int(free.sum()), 1)
    s2 = float(np.sum(sol.fun[keep] ** 2)) / dof * sigma**2
    cov_free = s2 * np.linalg.pinv(J.T @ J)
    covariance = np.zeros((x.size, x.size))
    covariance[np.ix_(free, free)] = cov_free
    return Refinement(x, covariance, before, after, int(sol.nfev), len(rows))


def apply_refinement(result: ProcessResult, refinement: Refinement) -> ProcessResult:
    """``result`` with the refined model in place of the analytic one: tables, base, tool,
    frames, covariance and the FK check recomputed; the analytic axes and fits are kept."""
    from dataclasses import replace

    from dhlog.dh import standard_to_modified
    from dhlog.kinematics import fk_frames
    from dhlog.process import _validate

    ex = result.extraction
    assert ex is not None
    table, tool, T = model_from_state(
        refinement.x, ex.standard.joint_types, ex.T_measurement_base[:3, :3]
    )
    modified, T_post = standard_to_modified(table)
    refined = replace(
        ex,
        standard=table,
        modified=modified,
        T_modified_tool=T_post,
        T_measurement_base=T,
        tool_point=tool,
        frames=fk_frames(table, ex.reference_pose, T_base=T),
    )
    validation = _validate(result.segmentation, result.joints, refined)
    note = (
        f"global refinement: FK residual RMS {refinement.fk_rms_before * 1e3:.4f} mm → "
        f"{refinement.fk_rms_after * 1e3:.4f} mm over {refinement.n_points} samples."
    )
    return replace(
        result,
        extraction=refined,
        covariance=refinement.covariance,
        std=np.sqrt(np.clip(np.diag(refinement.covariance), 0.0, None)),
        validation=validation,
        refinement=refinement,
        warnings=[*result.warnings, note],
    )
