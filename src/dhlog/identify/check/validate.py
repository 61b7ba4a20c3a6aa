"""The check of a result against every sample: forward kinematics of the DH table at each
sample's encoder values, per joint and overall; the predicted FK error from the covariance."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note
from dhlog.geometry._checks import FloatArray, rotation_from_vector
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.joints.sweeps import JointReport
from dhlog.identify.read.extract import Extraction
from dhlog.identify.read.propagate import state_vector
from dhlog.identify.segment.persample import SampleArray, blocks
from dhlog.identify.segment.segment import Segmentation
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_point, fk_points_chunked


class Identified(Protocol):
    """What :func:`fk_prediction_std` reads of a run's result (``identify.run.Identification``):
    the whole-model fit, else the extraction and its propagated covariance."""

    @property
    def whole(self) -> WholeFit | None: ...

    @property
    def extraction(self) -> Extraction | None: ...

    @property
    def covariance(self) -> FloatArray | None: ...


#: At most this many samples' FK residual vectors are kept for the recording (evenly strided
#: over the measurement table: the viewer shows no more), whatever the log's length.
SHOWN_SAMPLES = 500_000


def shown_stride(height: int) -> int:
    """Every how many rows of a measurement table of ``height`` rows the recording shows one."""
    return max(1, -(-height // SHOWN_SAMPLES))


@dataclass(frozen=True)
class Validation:
    """FK of the result against each assigned sample with encoder values, summarised: RMS, max
    and count over the samples checked, per joint (``per_joint``: joint → RMS, max, count; 0 for
    coupled moves and still poses) and overall; the residual vectors (sample − FK) kept at the
    rows the recording shows (``rows``: table rows, ascending; every :func:`shown_stride`-th)."""

    rows: NDArray[np.intp]
    vectors: FloatArray
    per_joint: dict[int, tuple[float, float, int]]
    rms: float
    max: float
    n_points: int

    @property
    def residuals(self) -> FloatArray:
        """The lengths of the kept residual vectors."""
        return np.asarray(np.sqrt(np.sum(self.vectors**2, axis=1)), dtype=np.float64)

    def at(self, rows: NDArray[np.intp]) -> FloatArray:
        """The residual vectors (k, 3) at table ``rows``: NaN where none was kept."""
        out = np.full((rows.size, 3), np.nan)
        if self.rows.size:
            where = np.minimum(np.searchsorted(self.rows, rows), self.rows.size - 1)
            hit = self.rows[where] == rows
            out[hit] = self.vectors[where[hit]]
        return out


class _Tally:
    """Residual lengths summed per joint and overall, and the vectors at the shown rows."""

    def __init__(self, height: int) -> None:
        self.stride = shown_stride(height)
        self.joints: dict[int, list[float]] = {}  # joint → [sum of squares, max, count]
        self.rows: list[NDArray[np.intp]] = []
        self.vectors: list[FloatArray] = []

    def add(self, rows: NDArray[np.intp], vectors: FloatArray, joints: NDArray[np.integer]) -> None:
        r = np.sqrt(np.sum(vectors**2, axis=1))
        for k in np.unique(joints):
            rk = r[joints == k]
            acc = self.joints.setdefault(int(k), [0.0, 0.0, 0])
            acc[0] += float(rk @ rk)
            acc[1] = max(acc[1], float(rk.max()))
            acc[2] += rk.size
        shown = rows % self.stride == 0
        self.rows.append(rows[shown])
        self.vectors.append(vectors[shown])

    def validation(self) -> Validation:
        rows = np.concatenate(self.rows) if self.rows else np.zeros(0, dtype=np.intp)
        vectors = np.vstack(self.vectors) if self.vectors else np.zeros((0, 3))
        order = np.argsort(rows, kind="stable")
        per_joint = {
            k: (math.sqrt(s / c), mx, int(c)) for k, (s, mx, c) in sorted(self.joints.items()) if c
        }
        total = int(sum(c for _, _, c in self.joints.values()))
        ss = sum(s for s, _, _ in self.joints.values())
        return Validation(
            rows=rows[order],
            vectors=vectors[order],
            per_joint=per_joint,
            rms=math.sqrt(ss / total) if total else float("nan"),
            max=max((mx for _, mx, _ in self.joints.values()), default=float("nan"))
            if total
            else float("nan"),
            n_points=total,
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
        from dhlog.identify.fit.prediction import predict

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
    tally = _Tally(seg.height)
    for j in joints:
        rows = j.rows[j.inliers]
        for sl in blocks(rows.size):
            at = rows[sl]
            pred = fk_points_chunked(
                ex.standard, seg.q(at), ex.tool_point, T_base=ex.T_measurement_base
            )
            tally.add(at, seg.xyz(at) - pred, np.full(at.size, j.index))
    return tally.validation()


def validate_samples(
    seg: Segmentation,
    rows: NDArray[np.intp],
    Q: SampleArray,
    P: SampleArray,
    ex: Extraction,
    inliers: NDArray[np.bool_],
    tools: FloatArray | None = None,
    which: NDArray[np.int64] | None = None,
) -> Validation:
    """FK of the DH result at every sample with encoder values against the sample (per joint by
    the sweep it belongs to; coupled moves and still poses under joint 0), a block at a time.
    ``Q``: the table's joint values at the samples ``rows`` of the measurement table, ``P``
    their points; ``tools`` (k, 3): the tool point of each target in the last frame, ``which``
    each sample's target."""
    tally = _Tally(seg.height)
    T = ex.T_measurement_base
    for sl in blocks(rows.size):
        use = np.flatnonzero(inliers[sl])
        if not use.size:
            continue
        at = sl.start + use
        Qb, Pb = Q[at], P[at]
        if tools is None or which is None:
            pred = fk_points_chunked(ex.standard, Qb, ex.tool_point, T_base=T)
        else:
            pred = np.empty_like(Pb)
            wb = which[at]
            for k, tool in enumerate(tools):
                mask = wb == k
                pred[mask] = fk_points_chunked(ex.standard, Qb[mask], tool, T_base=T)
        tally.add(rows[at], Pb - pred, seg.joint(rows[at]))
    return tally.validation()


def check_residual(validation: Validation, sigma: float) -> tuple[Note, ...]:
    """A warning (``fk-residual``) when the FK residual RMS exceeds what the fit's noise σ
    explains (1.5 × √3 σ, 3-D)."""
    expected = math.sqrt(3.0) * sigma
    if validation.rms <= 1.5 * expected:
        return ()
    said = (
        f"the FK residual RMS ({validation.rms * 1e3:.4f} mm, 3-D) is larger than the fit "
        f"noise explains ({expected * 1e3:.4f} mm): the axes disagree with one "
        "kinematic chain more than the noise allows."
    )
    return (Note.warning(said, "fk-residual"),)


def table_gap(whole: WholeFit, ex: Extraction, Q: SampleArray, Q_table: SampleArray) -> float:
    """Largest distance (m) between the fitted model and its DH table at up to 64 of the
    sampled joint vectors ``Q`` (the table's joint values ``Q_table``: the encoders scaled and
    deflected by the terms as the table sees them): 0 up to rounding when the extraction is
    exact."""
    from dhlog.identify.fit.prediction import predict

    pick = np.unique(np.linspace(0, Q.shape[0] - 1, min(64, Q.shape[0])).astype(int))
    fitted, _ = predict(whole.model, Q[pick])
    table = fk_points_chunked(
        ex.standard, Q_table[pick], ex.tool_point, T_base=ex.T_measurement_base
    )
    return float(np.max(np.linalg.norm(fitted - table, axis=1)))
