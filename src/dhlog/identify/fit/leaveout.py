"""A whole-model fit linearised at its optimum, so that the fit to any subset of its samples —
a fold's training poses, those less an inner fold, the model with some terms held at zero — is
one small solve, not another pass of Levenberg–Marquardt.

The model is linear far beyond the moves between such fits (lengths of metres against residuals
of micrometres; the folds' optima lie within a few σ of the full one): with ``J`` the whitened
Jacobian and ``r`` the whitened residuals (predicted − measured) of the samples at the optimum,
in the directions the samples determine (``z``: :class:`dhlog.identify.fit.whole.Determined`), the
optimum over a subset ``T`` is the Gauss–Newton step ``z_T = −A_T⁻¹ g_T`` with
``A_T = Σ_T JᵀJ``, ``g_T = Σ_T Jᵀr``, and with coefficients held (``C z = d``) the constrained
step ``z_T − A_T⁻¹Cᵀ(C A_T⁻¹ Cᵀ)⁻¹(C z_T − d)`` (the least-squares solution, exact for a linear
model). Its residual at any sample is ``r + J z``; its covariance ``A_T⁻¹ χ²/dof``. This is
what the leave-out figures of the model selection (:mod:`dhlog.identify.model.select`) use — every
candidate's held-out error and the whole selection again inside each fold of ``--holdout K``
(nested cross-validation) — at the cost of a few small matrix solves a fold, where refitting
would cost a pass over the samples for each. ``tests/test_nested_cv.py`` checks it against
refits.

Pure numpy.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.passes import ROTATION_LIMIT, Samples, whitened_rows
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.segment.persample import SampleArray, blocks
from dhlog.io import scratch


@dataclass(frozen=True)
class Linear:
    """A fit linearised over ``N`` samples (see the module docstring): the whitened rows
    ``Jw`` (N, k, r) and residuals ``rw`` (N, k) (k = 3, or 6 with orientations), the positions'
    Jacobian ``F`` (N, 3, r) and residuals ``e`` (N, 3, m: predicted − measured), whether each
    sample was an inlier of the fit (``use``), ``B`` (size, r) from ``z`` to the fit's local
    parameters, ``box_gram`` (r, r) = ``Σ JᵀJ`` of the positions' Jacobian at ``box_count``
    joint vectors spread over the session's ranges, and the fit's χ²/dof."""

    Jw: FloatArray
    rw: FloatArray
    F: FloatArray
    e: FloatArray
    use: NDArray[np.bool_]
    B: FloatArray
    box_gram: FloatArray
    box_count: int
    chi2_dof: float
    #: the fit's own parameter values (size,), for constraints on absolute values
    values: FloatArray

    @property
    def rank(self) -> int:
        return int(self.B.shape[1])

    def normal(self, mask: NDArray[np.bool_]) -> tuple[FloatArray, FloatArray, int]:
        """``A_T``, ``g_T`` and the sample count over the inliers in ``mask`` (N,)."""
        at = mask & self.use
        J, r = self.Jw[at], self.rw[at]
        return (
            np.einsum("nki,nkj->ij", J, J),
            np.einsum("nki,nk->i", J, r),
            int(np.count_nonzero(at)),
        )

    def step(
        self,
        A: FloatArray,
        g: FloatArray,
        constraint: tuple[FloatArray, FloatArray] | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """The optimum ``z`` of ``A``, ``g`` (with ``constraint`` = (C, d): ``C z = d``) and
        the inverse of ``A`` within the constraint (the covariance up to χ²/dof)."""
        Ainv = _inverse(A)
        z = -Ainv @ g
        if constraint is not None and constraint[0].shape[0]:
            C, d = constraint
            K = Ainv @ C.T @ _inverse(C @ Ainv @ C.T)
            z = z - K @ (C @ z - d)
            Ainv = Ainv - K @ C @ Ainv
        return z, Ainv

    def rss(self, z: FloatArray, mask: NDArray[np.bool_]) -> float:
        """The whitened sum of squares of the inliers in ``mask`` at ``z``."""
        at = mask & self.use
        res = self.rw[at] + np.einsum("nki,i->nk", self.Jw[at], z)
        return float(np.sum(res**2))

    def residuals(self, z: FloatArray, mask: NDArray[np.bool_]) -> FloatArray:
        """Predicted − measured positions (m, 3) of the samples in ``mask`` at ``z``."""
        return np.asarray(self.e[mask] + self.F[mask] @ z, dtype=np.float64)

    def range_sd(self, cov: FloatArray) -> float:
        """RMS predicted FK σ (m) over the range points for the covariance ``cov`` (r, r):
        ``√(tr(C G) / M)`` with ``G = Σ JᵀJ`` of the range points' rows."""
        return math.sqrt(max(float(np.sum(cov * self.box_gram)) / self.box_count, 0.0))


def _inverse(A: FloatArray) -> FloatArray:
    """``A``'s inverse (symmetric, positive semi-definite), by Cholesky where it is definite
    and well scaled, else the pseudo-inverse (a fold that does not determine a direction)."""
    d = np.sqrt(np.clip(np.diag(A), 1e-300, None))
    As = A / np.outer(d, d)
    try:
        L = np.linalg.cholesky(As)
        if float(np.min(np.diag(L))) > 1e-7:
            Li = np.linalg.inv(L)
            return np.asarray((Li.T @ Li) / np.outer(d, d), dtype=np.float64)
    except np.linalg.LinAlgError:
        pass
    return np.asarray(np.linalg.pinv(A, rcond=1e-13, hermitian=True), dtype=np.float64)


def linearise(fit: WholeFit, data: FitData, box: FloatArray, options: FitOptions) -> Linear:
    """``fit`` linearised over the samples of ``data`` it was fitted to (weighted as the fit
    was: ``options``' noise and σ, or the samples' covariances; orientations weighted by the
    fit's own σ), and its positions' Jacobian at the joint vectors ``box`` (M, n)."""
    from dhlog.model.noise import whitening_from_std

    model, layout, bases = fit.model, fit.layout, fit.bases
    d = fit.determined
    if d is None:
        B = np.eye(layout.size)
    else:
        B = d.basis / d.scale[:, None]
    m, noise, sigma, sample_cov = data.m, options.noise, options.sigma, data.sample_cov

    def whiten(points: FloatArray, W: FloatArray | None) -> FloatArray | float:
        return W if W is not None else noise.whiten(points, sigma)

    samples = Samples(
        data.Q,
        data.P,
        np.ones(m, dtype=bool),
        None if sample_cov is None else whitening_from_std(sample_cov),
        whiten,
        data.which,
        data.rotations,
        1.0 if fit.sigma_rotation is None else fit.sigma_rotation / math.sqrt(fit.chi2_dof),
        data.rates,
    )
    rows = whitened_rows(model, layout, bases, samples, slice(0, m))
    Jw, rw = rows.Jw, rows.rw  # (size, 3, m), (3, m)
    use = np.asarray(fit.inliers, dtype=bool).copy()
    if rows.ro is not None and rows.Jr is not None:
        Jw = np.concatenate([Jw, rows.Jr], axis=1)
        rw = np.concatenate([rw, rows.ro])
        # the fit held out the orientations beyond its limit too (passes.accumulate)
        use &= np.sqrt(np.sum(rows.ro**2, axis=0)) <= max(fit.limit, ROTATION_LIMIT)
    Jz = np.einsum("pkm,pr->mkr", Jw, B)
    F = np.einsum("pkm,pr->mkr", rows.J, B)
    _, Jb = predict(model, box, layout, bases)
    assert Jb is not None
    Jbz = Jb @ B
    return Linear(
        Jw=np.ascontiguousarray(Jz),
        rw=np.ascontiguousarray(rw.T),
        F=np.ascontiguousarray(F),
        e=np.ascontiguousarray(rows.r.T),
        use=use,
        B=B,
        box_gram=np.einsum("mki,mkj->ij", Jbz, Jbz),
        box_count=int(box.shape[0]),
        chi2_dof=fit.chi2_dof,
        values=model_values(fit),
    )


def model_values(fit: WholeFit) -> FloatArray:
    """The fit's parameters whose absolute value a constraint may name (size,): the terms'
    coefficients where the layout has them, else 0 (the local parameters start at 0)."""
    values = np.zeros(fit.layout.size)
    terms, k = fit.model.terms, fit.layout.terms_at
    if terms is not None and k is not None:
        values[k : k + terms.size] = terms.coefficients
    return values


def pose_means(
    groups: NDArray[np.int64], values: FloatArray
) -> tuple[NDArray[np.int64], FloatArray]:
    """The poses of ``groups`` (m,), sorted, and the mean of ``values`` (m, …) over each."""
    ids, inverse = np.unique(groups, return_inverse=True)
    count = np.bincount(inverse, minlength=ids.size).astype(np.float64)
    out = np.zeros((ids.size, *values.shape[1:]))
    np.add.at(out, inverse, values)
    return ids, out / count.reshape(-1, *([1] * (values.ndim - 1)))


#: Samples above which :func:`fold_of_poses` maps poses numbered in time order a block at a
#: time (no sort of the whole log).
DENSE_ABOVE = 1 << 20


def fold_of_poses(groups: NDArray[np.int64], folds: int, seed: int) -> NDArray[np.int64]:
    """A fold (0 … folds−1) per sample: its pose's, the poses dealt to the folds in a seeded
    random order (every fold gets ⌊P/K⌋ or ⌈P/K⌉ poses). Poses numbered 0 … P−1 in time order
    (:func:`dhlog.identify.check.holdout.pose_groups` of a log of more than :data:`DENSE_ABOVE`
    samples) are mapped a block at a time into a scratch array, the same folds as
    ``np.unique`` would give them; any other numbering (a subset's) through ``np.unique``."""
    rng = np.random.default_rng(seed)
    m = groups.shape[0]
    dense = m > DENSE_ABOVE and int(groups[0]) == 0
    dense = dense and bool(np.all(np.diff(groups[: 1 << 16]) >= 0))
    if dense:
        top = int(groups[m - 1]) + 1
        dense = top <= m and bool(np.all(groups[-(1 << 16) :] < top))
    if not dense:
        poses, inverse = np.unique(groups, return_inverse=True)
        fold_of_pose = np.empty(poses.size, dtype=np.int64)
        fold_of_pose[rng.permutation(poses.size)] = np.arange(poses.size) % folds
        return np.asarray(fold_of_pose[inverse], dtype=np.int64)
    fold_of_pose = np.empty(top, dtype=np.int64)
    fold_of_pose[rng.permutation(top)] = np.arange(top) % folds
    out = scratch.empty(m, np.int64)
    for sl in blocks(m):
        out[sl] = fold_of_pose[groups[sl]]
    return out


@dataclass(frozen=True)
class PoseFolds:
    """What ``--holdout K`` deals: each sample's pose (:func:`pose_groups`) and its fold
    (:func:`fold_of_poses`), found once for the selection, the pairs' decisions and the check.

    A motion sampled in steps below :data:`SAME_POSE` (a tracker at 1 kHz along a sweep) has
    no poses apart from their neighbours: :meth:`of_stretches` deals ``stretches`` stretches of
    it instead, each of ``stretch_poses`` still poses (:func:`still_poses`), and its poses are
    those still poses (runs of them where they are more than :data:`MAX_SCORED_POSES`)."""

    groups: NDArray[np.int64]
    fold: NDArray[np.int64]
    #: the stretches of the session dealt to the folds (0: the poses were dealt one by one)
    stretches: int = 0
    #: the still poses in a stretch (the mean)
    stretch_poses: float = 0.0

    @staticmethod
    def of(groups: NDArray[np.int64], folds: int, seed: int = 0) -> PoseFolds:
        return PoseFolds(groups, fold_of_poses(groups, folds, seed))

    @staticmethod
    def of_stretches(still: NDArray[np.int64], folds: int, seed: int = 0) -> PoseFolds:
        """``folds`` × :data:`STRETCHES_PER_FOLD` stretches of consecutive still poses, as many
        poses each, dealt to the folds as poses are (seeded); ``still``: each sample's still pose
        (0, 1, … in time order, :func:`still_poses`), at least as many as the stretches. A dwell
        is one still pose however long it is held, and a gap in the samples one step. The poses
        scored are the still poses, or where they are more than :data:`MAX_SCORED_POSES`, runs
        of consecutive ones within a stretch."""
        m = still.shape[0]
        poses = int(still[m - 1]) + 1 if m else 0
        count = folds * STRETCHES_PER_FOLD
        if poses < count:
            raise ValueError(f"{poses} still poses for {count} stretches")
        run = -(-poses // MAX_SCORED_POSES)  # still poses a scored pose at most
        stretch = scratch.empty(m, np.int64)
        groups = scratch.empty(m, np.int64) if run > 1 else still
        last, carried = (-1, -1), -1
        for sl in blocks(m):
            p = np.asarray(still[sl], dtype=np.int64)
            k = p * count // poses
            stretch[sl] = k
            if run > 1:  # a new scored pose where the stretch or the run of still poses changes
                r = p // run
                first = (int(k[0]), int(r[0])) != last
                new = np.r_[first, (np.diff(k) != 0) | (np.diff(r) != 0)]
                groups[sl] = carried + np.cumsum(new)
                last, carried = (int(k[-1]), int(r[-1])), int(groups[sl.stop - 1])
        return PoseFolds(groups, fold_of_poses(stretch, folds, seed), count, poses / count)


def motion_share(groups: NDArray[np.int64], still: NDArray[np.int64]) -> float:
    """The share of the samples whose pose (``groups``: :func:`pose_groups`) is a motion, not a
    pose: it spans :data:`MOTION_SPAN` or more of the still poses ``still`` (:func:`still_poses`,
    which refine the poses), steps below :data:`SAME_POSE` chained along it."""
    m = int(groups.shape[0])
    if m == 0:
        return 0.0
    firsts = np.flatnonzero(np.diff(groups, prepend=groups[0] - 1))
    ends = np.r_[firsts[1:], m]
    spans = np.asarray(still[ends - 1]) - np.asarray(still[firsts]) + 1
    return float(np.sum((ends - firsts)[spans >= MOTION_SPAN])) / m


#: Still poses a pose of :func:`pose_groups` spans from which it is a motion (about 10 mrad of
#: travel: each still pose but the last spans at least :data:`SAME_POSE`).
MOTION_SPAN = 10
#: Share of the samples in motions (:func:`motion_share`) from which ``--holdout K`` holds out
#: stretches of the session in place of its poses.
MOTION_SHARE = 0.5

#: Stretches of a fast-sampled motion each fold of ``--holdout K`` holds out
#: (:meth:`PoseFolds.of_stretches`).
STRETCHES_PER_FOLD = 10
#: Most poses a cross-validation over stretches scores (runs of still poses beyond it).
MAX_SCORED_POSES = 100_000


#: Consecutive samples whose joint values all differ by less than this (rad or m) are one pose.
SAME_POSE = 1e-3


def pose_groups(Q: SampleArray) -> NDArray[np.int64]:
    """A pose index (0, 1, …) per sample of ``Q`` (m, n) in time order: a new pose wherever a
    joint value moves by :data:`SAME_POSE` or more from the previous sample."""
    out = scratch.empty(Q.shape[0], np.int64)
    for sl, poses, _ in pose_blocks(Q):
        out[sl] = poses
    return out


def pose_blocks(Q: SampleArray) -> Iterator[tuple[slice, NDArray[np.int64], FloatArray]]:
    """:func:`pose_groups` a block of :data:`POSE_CHUNK` samples at a time: the block, its
    samples' poses and their joint values."""
    offset, previous = 0, None
    for sl in blocks(Q.shape[0], POSE_CHUNK):
        q = Q[sl]
        step = np.zeros(q.shape[0], dtype=np.int64)
        if previous is not None:
            step[0] = np.max(np.abs(q[0] - previous)) >= SAME_POSE
        if q.shape[0] > 1:
            step[1:] = np.max(np.abs(q[1:] - q[:-1]), axis=1) >= SAME_POSE
        poses = offset + np.cumsum(step)
        offset, previous = int(poses[-1]), q[-1]
        yield sl, poses, q


def still_poses(Q: SampleArray) -> NDArray[np.int64]:
    """A still pose's index (0, 1, …) per sample of ``Q`` (m, n) (:func:`still_pose_blocks`)."""
    out = scratch.empty(Q.shape[0], np.int64)
    for sl, poses, _ in still_pose_blocks(Q):
        out[sl] = poses
    return out


@dataclass(frozen=True)
class _Open:
    """The pose open at the end of a block: its first sample's joint values, the path the
    joints have travelled since (the sum of each step's largest joint move), the previous
    sample's joint values and the pose's index."""

    anchor: FloatArray
    path: float
    previous: FloatArray
    index: int


def still_pose_blocks(Q: SampleArray) -> Iterator[tuple[slice, NDArray[np.int64], FloatArray]]:
    """The still poses of ``Q`` (m, n) a block of :data:`POSE_CHUNK` samples at a time: the
    block, its samples' pose indices (0, 1, … in time order) and their joint values — what the
    design effect groups (samples that share a still pose's error).

    A new pose starts wherever a joint moves by :data:`SAME_POSE` or more from the previous
    sample (as :func:`pose_blocks`), or from the pose's first sample: a still pose's samples
    stay one pose however long it is held, and a joint moving slowly under a fast instrument
    (steps far below :data:`SAME_POSE` at 1 kHz) makes poses of :data:`SAME_POSE` each, not one
    pose of the whole motion. Where the joints have travelled less than :data:`SAME_POSE`
    since the pose began (the sum of the steps bounds the move), no joint can have left it, so
    only moving stretches are looked at sample by sample."""
    open_: _Open | None = None
    for sl in blocks(Q.shape[0], POSE_CHUNK):
        q = np.asarray(Q[sl], dtype=np.float64)
        c = q.shape[0]
        step = np.zeros(c)
        if c > 1:
            step[1:] = np.max(np.abs(q[1:] - q[:-1]), axis=1)
        if open_ is not None:
            step[0] = float(np.max(np.abs(q[0] - open_.previous)))
        new = step >= SAME_POSE  # a jump: a new pose
        new[0] |= open_ is None
        # the path walked (each step's largest joint move) since the block began, jumps left out
        walked = np.cumsum(np.where(new, 0.0, step))
        carried = 0.0 if new[0] else open_.path  # type: ignore[union-attr]
        starts = np.flatnonzero(new)
        runs = starts if new[0] else np.r_[0, starts]  # the runs between jumps
        ends = np.r_[runs[1:], c]
        gain = walked[ends - 1] - walked[runs]
        if not new[0]:  # the pose open at the block's start: its path since it began
            gain[0] = carried + walked[ends[0] - 1]
        moving = np.flatnonzero(gain >= SAME_POSE).tolist()  # only a moving run can leave
        path = walked.tolist() if moving else []  # looked up one sample at a time below
        for r in moving:
            s, e = int(runs[r]), int(ends[r])
            if s == 0 and not new[0]:
                anchor, base, lo = open_.anchor, -carried, 0  # type: ignore[union-attr]
            else:
                anchor, base, lo = q[s], path[s], s + 1
            while True:
                # no sample before the path reaches SAME_POSE can have left; moving on, the
                # first it allows usually has
                first = max(bisect.bisect_left(path, base + SAME_POSE), lo)
                if first >= e:
                    break
                left = first if _left(q[first], anchor) else _left_at(q, anchor, first + 1, e)
                if left is None:
                    break
                new[left] = True
                anchor, base, lo = q[left], path[left], left + 1
        poses = np.cumsum(new) + (-1 if open_ is None else open_.index)
        kept = np.flatnonzero(new)
        if kept.size:
            last = int(kept[-1])
            anchor, path = q[last].copy(), float(walked[-1] - walked[last])
        else:
            assert open_ is not None
            anchor, path = open_.anchor, carried + float(walked[-1])
        open_ = _Open(anchor, path, q[-1].copy(), int(poses[-1]))
        yield sl, np.asarray(poses, dtype=np.int64), q


def _left(row: FloatArray, anchor: FloatArray) -> bool:
    """Whether a joint of ``row`` is :data:`SAME_POSE` or more from ``anchor`` (on Python
    floats: a handful of joints, once a pose)."""
    return any(abs(a - b) >= SAME_POSE for a, b in zip(row.tolist(), anchor.tolist(), strict=True))


def _left_at(q: FloatArray, anchor: FloatArray, start: int, end: int) -> int | None:
    """The first sample of ``q[start:end]`` with a joint :data:`SAME_POSE` or more from
    ``anchor`` (None: none), looked at in windows that double."""
    width = 16
    while start < end:
        stop = min(start + width, end)
        hit = np.flatnonzero(np.max(np.abs(q[start:stop] - anchor), axis=1) >= SAME_POSE)
        if hit.size:
            return start + int(hit[0])
        start, width = stop, width * 2
    return None


#: Samples a chunk in :func:`pose_groups`.
POSE_CHUNK = 1 << 18
