"""One pass of the whole-model fit over the samples, chunk by chunk (bounded memory, no
per-parameter pass over the data).

:func:`accumulate` gives the normal equations ``JᵀWJ``, ``JᵀWr`` from the analytic columns
(:func:`~dhlog.identify.fit.prediction.predict_columns`); :func:`gradient` gives ``JᵀWr`` alone by
the adjoint of the chain, without forming ``J``. Both hold gross outliers out by a truncated
quadratic at ``limit`` (whitened residual norm) and give the cost, the inlier count and χ².
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.identify.fit.prediction import (
    cross_rows,
    orientation_residual,
    predict_columns,
    predict_orientation,
    prefix_motions,
    rotate,
    skew,
)
from dhlog.identify.segment.persample import PerSample
from dhlog.model.dh import JointType

#: Samples per chunk of the normal-equation accumulation.
CHUNK = 16384
#: Orientation residuals (in their own σ) beyond this are outliers, whatever the positions' limit.
ROTATION_LIMIT = 5.0

#: The whitening of points (c, 3) given their own whitening (c, 3, 3) or None: that, or the
#: noise model's (per sample, or one scalar for all).
Whitening = Callable[[FloatArray, FloatArray | None], FloatArray | float]


@dataclass(frozen=True)
class Samples:
    """The samples of a pass: encoder values ``Q`` (m, n), points ``P`` (m, 3), which may enter
    (``keep``), their own whitening ``W`` (m, 3, 3) or None (``whiten`` then gives the noise
    model's), each one's target (``which``), a 6-DoF target's measured orientations ``R``
    (m, 3, 3) weighted by ``1/sigma_rot``, and the joints' speeds ``Qd`` (m, n: clock offset)."""

    Q: FloatArray | PerSample
    P: FloatArray | PerSample
    keep: NDArray[np.bool_]
    W: FloatArray | None
    whiten: Whitening
    which: NDArray[np.int64] | None = None
    R: FloatArray | None = None
    sigma_rot: float = 1.0
    Qd: FloatArray | PerSample | None = None

    @property
    def per_sample(self) -> int:
        """Residual components per sample: 3, or 6 with the target frame's orientation."""
        return 3 if self.R is None else 6

    def strided(self, stride: int) -> Samples:
        """Every ``stride``-th sample."""
        return Samples(
            self.Q[::stride],
            self.P[::stride],
            self.keep[::stride],
            None if self.W is None else self.W[::stride],
            self.whiten,
            None if self.which is None else self.which[::stride],
            None if self.R is None else self.R[::stride],
            self.sigma_rot,
            None if self.Qd is None else self.Qd[::stride],
        )


def _truncated(
    rw: FloatArray, keep: NDArray[np.bool_], limit: float
) -> tuple[FloatArray, NDArray[np.bool_], float]:
    """Per sample of whitened residuals ``rw`` (3, c): the norm, whether it enters (allowed and
    within ``limit``), and the truncated quadratic cost of the allowed ones."""
    nrm = np.sqrt(rw[0] ** 2 + rw[1] ** 2 + rw[2] ** 2)
    use = keep & (nrm <= limit)
    return nrm, use, float(np.sum(np.minimum(nrm[keep], limit) ** 2))


@dataclass(frozen=True)
class Rows:
    """One block of samples at a model: the prediction's residuals ``r`` (3, c: predicted −
    measured, m) and Jacobian ``J`` (size, 3, c), their whitened forms ``rw``, ``Jw`` (``Jw`` is
    ``J`` unscaled when ``folded`` ≠ 1: a scalar weight left for the caller to apply), and with a
    6-DoF target the orientation residuals ``ro`` (3, c) and their Jacobian ``Jr`` (size, 3, c),
    both already in units of ``sigma_rot``."""

    r: FloatArray
    J: FloatArray
    rw: FloatArray
    Jw: FloatArray
    folded: float
    ro: FloatArray | None
    Jr: FloatArray | None


def whitened_rows(
    model: AxisModel,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    data: Samples,
    sl: slice,
    *,
    fold: bool = False,
) -> Rows:
    """The residuals and Jacobian of the samples ``sl`` of ``data`` at ``model``, whitened
    (``fold``: a scalar whitening of a positions-only pass is returned as ``folded`` instead of
    applied to ``Jw``, which saves a pass over it)."""
    rates = None if data.Qd is None else data.Qd[sl]
    Q, P = data.Q[sl], data.P[sl]
    prefix = prefix_motions(model, Q, rates)
    which = None if data.which is None else data.which[sl]
    pred, J = predict_columns(model, Q, layout, bases, which, prefix, rates)
    assert J is not None
    r = pred - P.T  # (3, c)
    W = data.whiten(P, None if data.W is None else data.W[sl])
    folded = 1.0  # a scalar weight of J applied to H and g instead of to every entry
    if isinstance(W, float):
        rw, Jw = r * W, J
        if data.R is None and fold:
            folded = W
        else:
            Jw = J * W
    else:
        Wt = np.transpose(W, (1, 2, 0))  # (3, 3, c)
        rw = rotate(Wt, r)
        Jw = np.moveaxis(rotate(Wt, np.moveaxis(J, 0, 1)), 1, 0)
    ro = Jr = None
    if data.R is not None:  # the target frame's orientation, weighted by 1/σ_rot
        R_pred, Jo = predict_orientation(model, Q, layout, bases, prefix, rates)
        ro = orientation_residual(R_pred, np.moveaxis(data.R[sl], 0, 2)) / data.sigma_rot
        Jr = Jo / data.sigma_rot
    return Rows(r, J, rw, Jw, folded, ro, Jr)


def accumulate(
    model: AxisModel,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    data: Samples,
    limit: float,
    norms: FloatArray,
    progress: Callable[[float], None] | None = None,
) -> tuple[FloatArray, FloatArray, float, int, float]:
    """One pass over the samples at ``model`` (``progress`` is told the fraction done):
    ``JᵀWJ``, ``JᵀWr`` over the samples allowed in ``data.keep`` whose whitened residual is at
    most ``limit``, the truncated cost, the inlier count and the sum of squared whitened inlier
    residuals. Writes each sample's whitened residual norm into ``norms``."""
    m = data.Q.shape[0]

    def chunk(start: int) -> tuple[FloatArray, FloatArray, float, int, float]:
        sl = slice(start, min(start + CHUNK, m))
        rows = whitened_rows(model, layout, bases, data, sl, fold=True)
        Jw, rw = rows.Jw, rows.rw
        nrm, use, cost = _truncated(rw, data.keep[sl], limit)
        norms[sl] = nrm
        if rows.ro is not None and rows.Jr is not None:
            # σ_rot is the orientations' own scale (or declared): judged on theirs, not on
            # a position limit that declared covariances far above the residuals make tiny
            _, use_o, part = _truncated(rows.ro, data.keep[sl], max(limit, ROTATION_LIMIT))
            use &= use_o
            cost += part
            rw = np.concatenate([rw, rows.ro])
            Jw = np.concatenate([Jw, rows.Jr], axis=1)
        folded = rows.folded
        if not np.all(use):
            Jw, rw = Jw[:, :, use], rw[:, use]
        Ju = Jw.reshape(layout.size, -1)
        ru = rw.reshape(-1)
        H = Ju @ Ju.T
        if folded != 1.0:
            H *= folded * folded
        return H, (Ju @ ru) * folded, cost, int(np.count_nonzero(use)), float(ru @ ru)

    # one thread: two were measured slower on the 2-core machine (1.6 s → 2.3 s per million
    # samples; numpy's many small operations hold the GIL between its kernels)
    starts = range(0, m, CHUNK)
    parts = []
    for k, start in enumerate(starts):
        parts.append(chunk(start))
        if progress is not None and k % 16 == 15:
            progress((k + 1) / len(starts))
    H = np.sum([p[0] for p in parts], axis=0)
    g = np.sum([p[1] for p in parts], axis=0)
    cost = float(sum(p[2] for p in parts))
    count = int(sum(p[3] for p in parts))
    chi2 = float(sum(p[4] for p in parts))
    return H, g, cost, count, chi2


def _turn(
    K: FloatArray, x: FloatArray, s: FloatArray, c1: FloatArray, sign: float = 1.0
) -> FloatArray:
    """``R x`` (``sign`` 1) or ``Rᵀ x`` (``sign`` −1) for the per-sample rotation
    ``R = I + sin δ K + (1 − cos δ) K²`` of vectors ``x`` (3, m)."""
    Kx = K @ x
    return x + (sign * s) * Kx + c1 * (K @ Kx)


def gradient(
    model: AxisModel,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    data: Samples,
    limit: float,
    norms: FloatArray,
    progress: Callable[[float], None] | None = None,
) -> tuple[FloatArray, float, int, float]:
    """``JᵀWr`` over every allowed inlier of ``data`` (positions only) by the adjoint of the
    chain, without forming ``J``; the truncated cost, inlier count and χ² as
    :func:`accumulate` gives them, and each sample's whitened residual norm in ``norms``.

    With ``x_i = g_i ⋯ g_n(target)`` (the target carried back to joint i's frame at the
    reference pose) and ``ρ_i = R_<iᵀ Wᵀ W r``, the columns of :func:`predict_columns` give
    ``b × D_i · ρ = a · ((x_i − c_i) × ρ_i)`` with ``a = (I − R_i) w``, so each axis needs only
    the sums of ``sin δ``, ``1 − cos δ`` (and the encoder move) times ``(x_i − c_i) × ρ_i`` and
    ``ρ_i``: two rotations of a vector per joint and sample in place of 27 columns."""
    m, n = data.Q.shape[0], model.n
    g = np.zeros(layout.size)
    cost, count, chi2 = 0.0, 0, 0.0
    Ks = [skew(a.direction) for a in model.axes]
    targets = model.targets()
    starts = range(0, m, CHUNK)
    for k_chunk, start in enumerate(starts):
        sl = slice(start, min(start + CHUNK, m))
        c = sl.stop - sl.start
        rates = None if data.Qd is None else data.Qd[sl]
        moves = model.moves(data.Q[sl], rates).T  # (n, c)
        dq = moves * model.scales[:, None]
        speeds = None
        if rates is not None and layout.clock_at is not None:
            speeds = rates.T * model.scales[:, None]
        sins = np.sin(dq)
        coss = 1.0 - np.cos(dq)
        which = None if data.which is None else data.which[sl]
        x = (
            np.repeat(model.target[:, None], c, axis=1)
            if which is None or not len(model.extra_targets)
            else np.ascontiguousarray(targets[which].T)
        )
        rel: list[FloatArray | None] = [None] * n
        for i in range(n - 1, -1, -1):  # inward to outward: x_i = g_i(x_{i+1})
            axis = model.axes[i]
            if model.types[i] is JointType.PRISMATIC:
                x = x + axis.direction[:, None] * dq[i]
                continue
            v = x - axis.point[:, None]
            v = _turn(Ks[i], v, sins[i], coss[i])
            rel[i] = v
            x = v + axis.point[:, None]
        P = data.P[sl]
        r = x - P.T
        W = data.whiten(P, None if data.W is None else data.W[sl])
        if isinstance(W, float):
            rw = r * W
            rho = rw * W
        else:
            Wt = np.transpose(W, (1, 2, 0))  # (3, 3, c)
            rw = rotate(Wt, r)
            rho = rotate(np.transpose(Wt, (1, 0, 2)), rw)
        nrm, use, part = _truncated(rw, data.keep[sl], limit)
        norms[sl] = nrm
        cost += part
        count += int(np.count_nonzero(use))
        chi2 += float(np.sum(nrm[use] ** 2))
        rho = np.where(use, rho, 0.0)
        for i in range(n):  # outward to inward: ρ_{i+1} = R_iᵀ ρ_i
            axis, k = model.axes[i], layout.axis_at[i]
            u, v = bases[i]
            q_i = moves[i]
            held = i in model.held_axes  # a held axis: no gradient (its columns are zero)
            if model.types[i] is JointType.PRISMATIC:
                t = rho @ dq[i]
                for col, w in enumerate(() if held else (u, v)):
                    g[k + col] += np.cross(w, axis.direction) @ t
                if layout.scale_at is not None:
                    g[layout.scale_at + i] += axis.direction @ (rho @ q_i)
                if speeds is not None:
                    g[layout.clock_at] -= axis.direction @ (rho @ speeds[i])
                continue
            rel_i = rel[i]
            assert rel_i is not None
            z = cross_rows(rel_i, rho)
            zs, zc, rs, rc = z @ sins[i], z @ coss[i], rho @ sins[i], rho @ coss[i]
            K = Ks[i]
            for col, w in enumerate(() if held else (u, v)):
                Kw, KKw = K @ w, K @ (K @ w)
                g[k + col] -= Kw @ zs + KKw @ zc
                g[k + 2 + col] -= Kw @ rs + KKw @ rc
            if layout.scale_at is not None:
                g[layout.scale_at + i] += axis.direction @ (z @ q_i)
            if speeds is not None:
                g[layout.clock_at] -= axis.direction @ (z @ speeds[i])
            rho = _turn(K, rho, sins[i], coss[i], -1.0)
        t0 = layout.target_at
        if which is None or not len(model.extra_targets):
            g[t0 : t0 + 3] += rho.sum(axis=1)
        else:
            for j in range(len(targets)):
                g[t0 + 3 * j : t0 + 3 * j + 3] += rho[:, which == j].sum(axis=1)
        if progress is not None and k_chunk % 16 == 15:
            progress((k_chunk + 1) / len(starts))
    return g, cost, count, chi2
