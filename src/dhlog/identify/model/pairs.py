"""Which nearly parallel pairs of axes the whole-model fit holds parallel: decided by the error
at held-out poses, as the terms beyond the geometry are (:mod:`dhlog.identify.model.select`).

Holding a pair parallel (collinear: the same line) removes two (four) parameters' noise — where
the axes are nearly parallel, the pair's d and θ are ill-conditioned — at the price of a bias
wherever the axes are not parallel in truth, which the FK error then carries at every pose, the
more the farther from the session's poses. The rule before held a pair whose tilt was within 2σ
of parallel (Akaike's rule for two parameters), σ² the mean of the tilt's two components'
variances; that mean reads a tilt along the well-determined component as fewer σ than it is
(on a UR5 0.05° off its nominal, swept at 100 Hz with σ 30 µm, axes 3–4 7 mdeg apart read 1.9σ
against 3.3σ with their covariance, and holding them cost 1.54× the free fit's FK error at
random joint vectors; up to 2.4× in sessions measured from outside).

Now every pair within :data:`CANDIDATE_SIGMA` of parallel is a candidate, and the poses decide:
the whole-model fit is linearised at its optimum (:mod:`dhlog.identify.fit.leaveout`, on at most
:data:`PAIR_SAMPLES` samples), and for each hold the fit to the other folds of a K-fold split
over poses, under the pair's linearised constraints ``c₀ + A x = 0``
(:func:`dhlog.identify.model.relations.pair_constraints`; in the linearisation's coordinates
``(A B) z = −c₀``), predicts each held-out pose (per pose the squared length of its mean
residual). One at a time: the hold that lowers the held-out mean squared error most is taken,
the others judged again against it, until none lowers it.

The rule (:func:`holds`): a hold is taken when it does not raise the held-out mean squared error
(its paired change over the poses ≤ 0) — no margin of standard errors in its favour, unlike a
family of terms, which must lower it by :data:`dhlog.identify.model.select.HELD_OUT_SIGMA` standard
errors to be added. The two mistakes are not alike: a wrong hold is a bias, unreported by the
covariance, that grows beyond the session's poses (the UR5 sessions above: holds whose paired
change was +1.1 and +1.2 standard errors cost 1.54× and 1.33× at random joint vectors; a margin
of one standard error in the hold's favour would have taken both), while a wrong release costs
two parameters' variance, which the covariance reports and the achievable limit carries too. For
a linear model the paired change is, to first order, ``(W − 2q) σ² / N`` with ``W`` the
relation's Wald statistic under its full covariance and ``q`` its rows: Akaike's rule with the
relation's own covariance, judged on the poses themselves, so that it also sees what the first
order and the noise model miss (outliers, unmodelled error, several samples a pose). The
samples' cost check of :func:`dhlog.identify.model.relations.with_fixed_relations` stays for a hold
the first order gets wrong.

:func:`decide_pairs` takes a training mask: inside a fold of ``--holdout K`` the decision is
made again from the fold's training poses alone (inner folds over them), on the same
linearisation.

Pure numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.leaveout import (
    Linear,
    fold_of_poses,
    linearise,
    pose_groups,
    pose_means,
)
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.model.relations import pair_constraints, pairs_within, relation_tolerances
from dhlog.io.dhfile import DHModel

#: Consecutive axes within this many σ (2-D) of parallel are tried held (the candidates); the
#: held-out poses decide which are.
CANDIDATE_SIGMA = 4.0
#: Folds of the decision's cross-validation over poses.
PAIR_FOLDS = 5
#: Most samples the decision is linearised on (evenly strided), as the model selection's.
PAIR_SAMPLES = 5000
#: Fewest poses the held-out criterion is taken on; with fewer, no pair is held.
PAIR_MIN_POSES = 10


@dataclass(frozen=True)
class PairTrial:
    """One pair tried held: ``pair`` (0-based ``i``: axes i+1 and i+2), ``kind`` (parallel,
    collinear), the change of the held-out mean squared error (m², a pose) that holding it
    made against the pairs held before it, and that change's standard error over the poses;
    whether it was held."""

    pair: int
    kind: str
    gain: float
    spread: float
    held: bool


@dataclass(frozen=True)
class PairDecision:
    """The linearised fit and what the held-out poses need: each sample's pose (``groups``),
    which samples are scored (``primary``: the first target's)."""

    fit: WholeFit
    lin: Linear
    groups: NDArray[np.int64]
    primary: NDArray[np.bool_]
    #: the samples of the caller's arrays the decision is linearised on (evenly strided)
    pick: NDArray[np.int64]


def linearised(fit: WholeFit, data: FitData, options: FitOptions) -> PairDecision:
    """``fit`` linearised over at most :data:`PAIR_SAMPLES` of its samples ``data`` (evenly
    strided), weighted as it was fitted (``options``)."""
    pick, sub = data.strided(PAIR_SAMPLES)
    Qs = sub.Q
    part = replace(fit, inliers=np.asarray(fit.inliers[pick], dtype=bool))
    box = np.asarray(Qs[:1], dtype=np.float64)  # the range term is not used here
    lin = linearise(part, sub, box, options)
    which = sub.which
    primary = np.ones(pick.size, dtype=bool) if which is None else np.asarray(which) == 0
    return PairDecision(part, lin, pose_groups(Qs), primary, pick)


@dataclass(frozen=True)
class Folds:
    """The folds of a decision over ``d.pick``'s samples: each sample's fold (−1: not in the
    training samples), and per fold its samples' normal equations (``A_k``, ``g_k``), so that a
    fold's training fit is one subtraction from their sum."""

    fold: NDArray[np.int64]
    normals: list[tuple[FloatArray, FloatArray]]

    @classmethod
    def of(cls, d: PairDecision, train: NDArray[np.bool_], folds: int, seed: int) -> Folds:
        fold = np.full(d.pick.size, -1, dtype=np.int64)
        fold[train] = fold_of_poses(d.groups[train], folds, seed)
        normals = []
        for k in range(int(fold.max(initial=-1)) + 1):
            A, g, _ = d.lin.normal(fold == k)
            normals.append((A, g))
        return cls(fold, normals)


def held_out_squares(d: PairDecision, held: dict[int, str], folds: Folds) -> FloatArray:
    """Per held-out pose (in fold order), the squared error (m²) of the fit with the pairs
    ``held`` (i → "parallel" / "collinear") held, fitted to the other folds."""
    constraint = None
    if held:
        A, c0 = pair_constraints(
            d.fit,
            [i for i, k in held.items() if k == "parallel"],
            [i for i, k in held.items() if k == "collinear"],
        )
        constraint = (A @ d.lin.B, -c0)
    A_all = sum((A for A, _ in folds.normals), np.zeros((d.lin.rank, d.lin.rank)))
    g_all = sum((g for _, g in folds.normals), np.zeros(d.lin.rank))
    out = []
    for k, (A_k, g_k) in enumerate(folds.normals):
        test = d.lin.use & d.primary & (folds.fold == k)
        if not np.any(test):
            continue
        z, _ = d.lin.step(A_all - A_k, g_all - g_k, constraint)
        _, vec = pose_means(d.groups[test], d.lin.residuals(z, test))
        out.append(np.sum(vec**2, axis=1))
    return np.concatenate(out) if out else np.zeros(0)


def decide_pairs(
    d: PairDecision,
    candidates: dict[int, str],
    train: NDArray[np.bool_] | None = None,
    *,
    folds: int = PAIR_FOLDS,
    seed: int = 0,
) -> list[PairTrial]:
    """Which of ``candidates`` (i → "parallel" / "collinear") to hold, from the poses of
    ``train`` (over ``d.pick``'s samples; None: all) alone (see the module docstring): one at
    a time, the one whose hold lowers the held-out error most first."""
    n = d.pick.size
    train = np.ones(n, dtype=bool) if train is None else np.asarray(train, dtype=bool)
    train = train & d.lin.use
    if not candidates or np.unique(d.groups[train]).size < PAIR_MIN_POSES:
        return [PairTrial(i, k, math.nan, math.nan, False) for i, k in candidates.items()]
    split = Folds.of(d, train, folds, seed)
    held: dict[int, str] = {}
    current = held_out_squares(d, held, split)
    left = dict(candidates)
    trials: list[PairTrial] = []
    while left:
        tried = {}
        for i, kind in left.items():
            squares = held_out_squares(d, {**held, i: kind}, split)
            tried[i] = (squares, *_paired(current, squares))
        best = min(tried, key=lambda i: tried[i][1])
        squares, gain, spread = tried[best]
        if not holds(gain, spread):
            trials += [PairTrial(i, left[i], t[1], t[2], False) for i, t in tried.items()]
            break
        trials.append(PairTrial(best, left.pop(best), gain, spread, True))
        held[best] = trials[-1].kind
        current = squares
    return trials


def holds(gain: float, spread: float) -> bool:
    """Whether a hold that changes the held-out mean squared error by ``gain`` (standard error
    ``spread``) is taken (see the module docstring)."""
    return gain <= 0.0


def _paired(before: FloatArray, after: FloatArray) -> tuple[float, float]:
    """The mean change from ``before`` to ``after`` over the same poses, its standard error."""
    if before.size != after.size or before.size < 2:
        return math.inf, math.inf
    diff = after - before
    return float(np.mean(diff)), float(np.std(diff, ddof=1) / math.sqrt(diff.size))


def candidate_pairs(fit: WholeFit, tolerances: list[tuple[float, float]] | None) -> dict[int, str]:
    """The pairs within ``tolerances`` of parallel (i → "parallel") or the same line
    (i → "collinear")."""
    if tolerances is None:
        return {}
    parallel, collinear = pairs_within(fit, tolerances)
    return {**{i: "parallel" for i in parallel}, **{i: "collinear" for i in collinear}}


def _candidates(
    whole: WholeFit, nominal: DHModel | None, angle_tol: float, distance_tol: float
) -> tuple[list[tuple[float, float]] | None, dict[int, str]]:
    """The pairs' tolerances within :data:`CANDIDATE_SIGMA` and the pairs within them."""
    tolerances = relation_tolerances(
        whole, nominal, angle_tol, distance_tol, parallel_sigma=CANDIDATE_SIGMA
    )
    return tolerances, candidate_pairs(whole, tolerances)


def decided_tolerances(
    whole: WholeFit,
    nominal: DHModel | None,
    angle_tol: float,
    distance_tol: float,
    data: FitData,
    options: FitOptions,
    *,
    parallel_sigma: float | None,
) -> tuple[list[tuple[float, float]] | None, tuple[Note, ...]]:
    """The pairs' tolerances for :func:`dhlog.identify.model.relations.with_fixed_relations`: those
    of the pairs the held-out poses hold (``parallel_sigma`` None; the candidates within
    :data:`CANDIDATE_SIGMA`), the others narrowed so that neither the fit nor the extraction
    calls them parallel (each decision said in a note: ``held-parallel`` where held, else
    ``pair-free``). ``parallel_sigma`` K: the rule before, every pair
    within K σ (2-D) of parallel (0: none). ``data`` and ``options``: the fit's samples and
    weights."""
    if parallel_sigma is not None:
        given = relation_tolerances(
            whole, nominal, angle_tol, distance_tol, parallel_sigma=parallel_sigma
        )
        return given, ()
    tolerances, candidates = _candidates(whole, nominal, angle_tol, distance_tol)
    if tolerances is None or not candidates:
        return tolerances, ()
    d = linearised(whole, data, options)
    trials = decide_pairs(d, candidates)
    freed = {t.pair for t in trials if not t.held}
    notes = tuple(
        Note.info(_said(t), "held-parallel" if t.held and not math.isnan(t.gain) else "pair-free")
        for t in trials
    )
    narrowed = [
        (min(a, 1e-7), min(b, 1e-7)) if i in freed else (a, b)
        for i, (a, b) in enumerate(tolerances)
    ]
    return narrowed, notes


def _said(t: PairTrial) -> str:
    """The note of one pair's decision."""
    pair = f"axes {t.pair + 1}–{t.pair + 2}"
    if math.isnan(t.gain):
        return (
            f"{pair}: within {CANDIDATE_SIGMA:g}σ of {t.kind}, left free: fewer than "
            f"{PAIR_MIN_POSES} poses to judge holding them at."
        )
    change = f"{t.gain * 1e12:+.3g} ± {t.spread * 1e12:.2g} µm² a pose"
    if t.held:
        return (
            f"{pair}: held {t.kind}: the held-out error at {PAIR_FOLDS}-fold poses is no larger "
            f"held (mean squared error {change})."
        )
    return (
        f"{pair}: within {CANDIDATE_SIGMA:g}σ of {t.kind} but left free: holding them raises the "
        f"held-out error at {PAIR_FOLDS}-fold poses (mean squared error {change})."
    )


def fold_holds(
    whole: WholeFit,
    nominal: DHModel | None,
    angle_tol: float,
    distance_tol: float,
    data: FitData,
    options: FitOptions,
    *,
    outer: NDArray[np.int64],
    folds: int,
) -> list[dict[int, str]]:
    """Per fold of ``--holdout K`` (``outer``: each sample's fold), the pairs the held-out
    criterion holds when it sees that fold's training poses alone (the candidates those within
    :data:`CANDIDATE_SIGMA` of the full fit): what the fold's fit is held to, as the run's is
    (nested cross-validation)."""
    _, candidates = _candidates(whole, nominal, angle_tol, distance_tol)
    if not candidates:
        return [{} for _ in range(folds)]
    d = linearised(whole, data, options)
    at = np.asarray(outer, dtype=np.int64)[d.pick]
    return [
        {t.pair: t.kind for t in decide_pairs(d, candidates, at != k, seed=1 + k) if t.held}
        for k in range(folds)
    ]
