"""Which terms beyond the geometry a session supports (``--model``): gravity compliance and
transmission harmonics (:mod:`dhlog.model.terms`), kept only where held-out poses prove them.

Each family's candidate model (the geometric one, then with a family of terms added) is fitted
by the whole-model maximum likelihood to the same samples (the geometric fit's inliers, at most
:data:`SELECT_SAMPLES` of them, evenly strided) and linearised at its optimum
(:mod:`dhlog.identify.fit.leaveout`); a candidate with some joints' terms dropped is its family's
with those terms held at zero (constrained least squares), and the fit to a subset of the
samples a small solve. Each is scored three ways:

* the Bayesian information criterion ``N ln(RSS/N) + p ln N`` (``N`` whitened residual
  components, ``RSS`` their sum of squares, ``p`` the parameters the samples determine);
* the RMS error at held-out poses of a K-fold cross-validation over poses (the same folds for
  every candidate; each fold's fit the linearised one);
* the RMS FK σ its covariance predicts over the joint vectors the session's ranges span (every
  combination of the joints' ranges): held-out poses lie among the fitted ones, and a model the
  poses determine only there (many lumped terms fitted to sweeps from one pose) would miss the
  robot elsewhere.

``auto`` adds a family (forward selection: each alone, the best proven one kept, then the
others added to it) only when it lowers the criterion, the held-out mean squared error by more
than :data:`HELD_OUT_SIGMA` standard errors of the paired difference over the held-out poses (a
gain within the folds' own scatter is no proof), and the error expected over the ranges
(held-out mean square plus the predicted variance there). The
cross-validation runs only for a candidate the criterion prefers: a family it rejects is
rejected without it.
``compliance``, ``harmonic`` and ``full`` force their families; ``geometric`` tries nothing.

With ``--holdout K`` the whole choice is made again inside each of its folds from that fold's
training poses alone (its own inner K-fold test), so that the run's held-out error is that of
the procedure (nested cross-validation). A direction a fold's poses do not determine keeps the
value the full fit gave it (as a fold's Levenberg–Marquardt fit from the full fit would).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.leaveout import (
    Linear,
    fold_of_poses,
    linearise,
    pose_groups,
    pose_means,
)
from dhlog.identify.fit.whole import WholeFit, fit_whole_model
from dhlog.model.dh import JointType
from dhlog.model.terms import Lump, Term, Terms, design

#: The ``--model`` choices and the families each forces (``auto`` tries them in this order).
MODELS = {
    "auto": ("compliance", "harmonic"),
    "geometric": (),
    "compliance": ("compliance",),
    "harmonic": ("harmonic",),
    "full": ("compliance", "harmonic"),
}
#: Why a family that adds no term on the robot is not taken, by family.
NO_TERM = {
    "compliance": (
        "adds no term: every revolute axis stays along gravity (as assumed: along the first "
        "revolute axis unless --gravity says), which exerts no torque about it (a SCARA, a "
        "rotary table)"
    ),
    "harmonic": "adds no term: no revolute joint carries one",
}
#: Most samples the candidates are fitted and scored on (evenly strided).
SELECT_SAMPLES = 5000
#: Folds of the selection's cross-validation when ``--holdout`` does not name K.
SELECT_FOLDS = 5
#: Joint vectors (seeded, uniform in the box of the session's per-joint ranges) over which each
#: candidate's predicted FK σ is taken.
RANGE_POINTS = 300


@dataclass(frozen=True)
class ModelRequest:
    """What ``--model`` asks: the mode (:data:`MODELS`), gravity in M (None: along the first
    axis, :func:`default_gravity`) and the harmonics' joints (0-based; None: every revolute)."""

    mode: str = "auto"
    gravity: tuple[float, float, float] | None = None
    harmonic_joints: tuple[int, ...] | None = None
    #: a URDF whose links' ``<inertial>`` masses give the gravity torques (None: lumped terms)
    masses: str | None = None


#: The default request: ``--model auto``.
AUTO = ModelRequest()


#: A candidate's identity: its families and the (family, joint) whose terms it leaves out.
Key = tuple[tuple[str, ...], frozenset[tuple[str, int]]]


@dataclass(frozen=True)
class Candidate:
    """One model tried: its families, term count, determined parameters, BIC, held-out RMS (m;
    None when not cross-validated) and whether it was chosen."""

    families: tuple[str, ...]
    terms: int
    parameters: int
    bic: float
    holdout_rms: float | None = None
    chosen: bool = False
    fit: WholeFit | None = None
    why: str = ""
    #: per held-out pose, the squared error (m²), in the cross-validation's order
    squared: FloatArray | None = None
    #: RMS predicted FK σ (m) over the joint vectors the session's ranges span (every
    #: combination: :data:`RANGE_POINTS` seeded vectors in the per-joint box)
    range_sd: float = math.nan
    #: (family, joint) whose terms were left out: the poses do not determine them over the
    #: ranges
    dropped: frozenset[tuple[str, int]] = frozenset()
    #: in-sample mean squared 3-D residual (m²)
    residual_ms: float = math.nan

    @property
    def key(self) -> Key:
        """Its families and the terms it leaves out: one candidate per key in a selection."""
        return self.families, self.dropped

    @property
    def expected(self) -> float:
        """The mean squared error expected over the session's ranges (m²): held-out error plus
        what the model's uncertainty adds where the session did not go."""
        held = math.inf if self.holdout_rms is None else self.holdout_rms
        return held**2 + self.range_sd**2

    @property
    def name(self) -> str:
        if not self.families:
            return "geometric"
        parts = []
        for family in self.families:
            out = sorted(j + 1 for f, j in self.dropped if f == family)
            parts.append(family + (f" (not {','.join(map(str, out))})" if out else ""))
        return "+".join(parts)

    def document(self) -> dict[str, Any]:
        return {
            "model": self.name,
            "terms": self.terms,
            "parameters": self.parameters,
            "bic": self.bic,
            "holdout_rms": self.holdout_rms,
            "range_sd": self.range_sd,
            "chosen": self.chosen,
            "why": self.why,
        }


@dataclass(frozen=True)
class Selection:
    """What ``--model`` asked, the candidates tried in order, and the folds used."""

    mode: str
    candidates: tuple[Candidate, ...]
    folds: int
    n_samples: int
    #: with ``--holdout K``: per fold, the candidate ``auto`` chose from that fold's training
    #: poses alone, and its model to start the fold's fit from (nested cross-validation)
    fold_choices: tuple[str, ...] = ()
    fold_starts: tuple[AxisModel, ...] = ()

    @property
    def chosen(self) -> Candidate:
        return next(c for c in self.candidates if c.chosen)

    def document(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "chosen": self.chosen.name,
            "folds": self.folds,
            "n_samples": self.n_samples,
            "candidates": [c.document() for c in self.candidates],
        }


def default_gravity(whole: WholeFit) -> FloatArray:
    """Gravity along the first revolute joint's axis (a robot on the floor or the ceiling; on a
    rail, the arm's first axis, not the rail's), pointing against the measurement frame's z
    where the axis has a z component (a levelled tracker's z is up)."""
    revolute = [i for i, t in enumerate(whole.model.types) if t is JointType.REVOLUTE]
    d = whole.model.axes[revolute[0] if revolute else 0].direction
    return np.asarray(-d if d[2] >= 0 else d, dtype=np.float64)


def family_of(kind: str) -> str:
    """The family of a term kind: ``compliance`` or ``harmonic``."""
    return "compliance" if kind.startswith("compliance") else "harmonic"


@dataclass(frozen=True)
class TermDesign:
    """What the terms beyond the geometry are built from besides the fitted axes and target
    (:func:`dhlog.model.terms.design`): ``gravity`` in M (a unit vector), the harmonics'
    joints (0-based; None: every revolute) and the links' ``masses`` as lumps in M (empty:
    lumped gravity terms)."""

    gravity: FloatArray
    harmonic_joints: tuple[int, ...] | None = None
    masses: tuple[Lump, ...] = ()


def terms_for(
    whole: WholeFit,
    families: tuple[str, ...],
    term_design: TermDesign,
    dropped: frozenset[tuple[str, int]] = frozenset(),
) -> Terms | None:
    """The terms of ``families`` on ``whole``'s axes, built as ``term_design`` says, without
    the (family, joint) ``dropped`` (None for none)."""
    if not families:
        return None
    model = whole.model
    terms = design(
        families,
        [a.point for a in model.axes],
        [a.direction for a in model.axes],
        model.target,
        [t is JointType.REVOLUTE for t in model.types],
        term_design.gravity,
        term_design.harmonic_joints,
        term_design.masses,
    )
    return terms.without(lambda t: (family_of(t.kind), t.joint) in dropped)


def select_model(
    mode: str,
    whole: WholeFit,
    data: FitData,
    options: FitOptions,
    *,
    term_design: TermDesign,
    folds: int = SELECT_FOLDS,
    reuse: bool = False,
    outer: NDArray[np.int64] | None = None,
) -> Selection:
    """Score the candidates of ``mode`` (see the module docstring) on ``whole``'s inliers, their
    terms built as ``term_design`` says, over ``folds`` folds.
    ``data`` and ``options``: the whole fit's samples and weights; ``reuse``: ``whole`` was
    fitted with exactly these, so that on every sample it is
    the geometric candidate itself (no fit again); ``outer`` (m,): each sample's fold of the
    run's ``--holdout K`` — the choice of ``auto`` is then made again inside each fold from its
    training poses alone (``Selection.fold_starts``: nested cross-validation)."""
    Q = data.Q
    pick, sub = data.strided(SELECT_SAMPLES)
    stride = int(pick[1] - pick[0]) if pick.size > 1 else 1
    keep = np.asarray(whole.inliers[pick], dtype=bool)
    Qs = np.asarray(sub.Q)  # cut to the picked samples: an array
    candidate = replace(sub, keep=keep)  # a candidate's fit: on the inliers, no cut
    unbounded = replace(options, threshold=math.inf)
    used = Qs[keep] if np.any(keep) else Qs
    box = np.random.default_rng(0).uniform(
        used.min(axis=0), used.max(axis=0), (RANGE_POINTS, Q.shape[1])
    )
    groups = pose_groups(Qs)
    which = sub.which
    primary = np.ones(pick.size, dtype=bool) if which is None else np.asarray(which) == 0
    per = sub.per_sample
    parents: dict[tuple[str, ...], tuple[WholeFit, Linear]] = {}

    def parent(families: tuple[str, ...]) -> tuple[WholeFit, Linear]:
        """The candidate of ``families`` with every joint's terms, fitted to the samples, and
        linearised at its optimum."""
        if families not in parents:
            terms = terms_for(whole, families, term_design)
            if terms is None and reuse and stride == 1:
                fit = whole  # its optimum over its inliers is the candidate's
            else:
                start = replace(whole.model, terms=terms)
                fit = fit_whole_model(start, candidate, unbounded)
            parents[families] = (fit, linearise(fit, sub, box, options))
        return parents[families]

    def held(fit: WholeFit, lin: Linear, dropped: frozenset[tuple[str, int]]) -> Constraint:
        """``dropped``'s terms held at zero, as a constraint on ``lin``'s ``z``."""
        terms, k = fit.model.terms, fit.layout.terms_at
        if not dropped or terms is None or k is None:
            return None
        at = [k + i for i, t in enumerate(terms.terms) if (family_of(t.kind), t.joint) in dropped]
        return lin.B[at], -lin.values[at]

    def scored(
        families: tuple[str, ...], dropped: frozenset[tuple[str, int]], train: NDArray[np.bool_]
    ) -> Candidate:
        """The candidate fitted to the samples ``train`` (linearised), with its BIC, predicted
        σ over the ranges and in-sample mean squared error there."""
        fit, lin = parent(families)
        constraint = held(fit, lin, dropped)
        A, g, count = lin.normal(train)
        z, Ainv = lin.step(A, g, constraint)
        held_count = 0 if constraint is None else int(np.linalg.matrix_rank(constraint[0]))
        p = lin.rank - held_count
        n_res = per * count
        rss = lin.rss(z, train)
        bic = n_res * math.log(max(rss, 1e-300) / n_res) + p * math.log(max(n_res, 1))
        chi2_dof = rss / max(n_res - p, 1)
        res = lin.residuals(z, train & lin.use)
        n_terms = 0 if fit.model.terms is None else fit.model.terms.size
        return Candidate(
            families,
            n_terms - sum(1 for t in _terms_of(fit) if (family_of(t.kind), t.joint) in dropped),
            p,
            bic,
            range_sd=lin.range_sd(Ainv * chi2_dof),
            dropped=dropped,
            residual_ms=float(np.mean(np.sum(res**2, axis=1))) if res.size else math.nan,
        )

    def cross_validated(
        c: Candidate, train: NDArray[np.bool_], fold: NDArray[np.int64]
    ) -> Candidate:
        """``c`` with its held-out RMS and squared errors per pose over the folds ``fold`` of
        the samples ``train`` (each fold predicted by the candidate fitted to the others);
        ``c`` itself when it has them already."""
        if c.holdout_rms is not None:
            return c
        fit, lin = parent(c.families)
        constraint = held(fit, lin, c.dropped)
        k_folds = int(fold[train].max(initial=-1)) + 1
        squared = []
        for k in range(k_folds):
            test = train & primary & (fold == k)
            if not np.any(test):
                continue
            A, g, _ = lin.normal(train & (fold != k))
            z, _ = lin.step(A, g, constraint)
            _, vec = pose_means(groups[test], lin.residuals(z, test))
            squared.append(np.sum(vec**2, axis=1))
        if not squared:
            return replace(c, why="not cross-validated: no poses to hold out")
        errors = np.concatenate(squared)
        return replace(c, squared=errors, holdout_rms=math.sqrt(float(np.mean(errors))))

    def chosen_on(
        train: NDArray[np.bool_], fold: NDArray[np.int64]
    ) -> tuple[Candidate, tuple[Candidate, ...]]:
        """The candidate ``mode`` chooses from the samples ``train`` (inner folds ``fold``),
        and every candidate shown, in the order tried, as the choice left it."""
        # each key's candidate as far as the choice has scored it: a step that adds to one
        # (its held-out error, its why) stores the candidate with it in place of the one before
        latest: dict[Key, Candidate] = {}

        def kept(c: Candidate) -> Candidate:
            latest[c.key] = c
            return c

        def fitted(
            families: tuple[str, ...], dropped: frozenset[tuple[str, int]] = frozenset()
        ) -> Candidate:
            key = (families, dropped)
            if key not in latest:
                latest[key] = scored(families, dropped, train)
            return latest[key]

        def validated(c: Candidate) -> Candidate:
            return kept(cross_validated(latest[c.key], train, fold))

        def pruned(cand: Candidate, family: str) -> Candidate:
            """``cand`` without the joints of ``family`` the poses do not determine over the
            ranges: one joint's terms at a time, while dropping them lowers the in-sample mean
            squared error plus the predicted variance over the ranges."""
            while True:
                fit, _ = parent(cand.families)
                joints = sorted(
                    {
                        t.joint
                        for t in _terms_of(fit)
                        if family_of(t.kind) == family and (family, t.joint) not in cand.dropped
                    }
                )
                if len(joints) <= 1:
                    return cand
                trials = [fitted(cand.families, cand.dropped | {(family, j)}) for j in joints]
                best = min(trials, key=lambda c: c.residual_ms + c.range_sd**2)
                if best.residual_ms + best.range_sd**2 >= cand.residual_ms + cand.range_sd**2:
                    return cand
                cand = best

        def proves(cand: Candidate, over: Candidate) -> bool:
            """Whether ``cand`` lowers both the BIC and the held-out error of ``over`` (its
            ``why`` says how it fared)."""
            cand, over = latest[cand.key], latest[over.key]
            if cand.terms <= over.terms:  # the family has no joint to carry it on this robot
                added = [f for f in cand.families if f not in over.families]
                kept(replace(cand, why=NO_TERM.get(added[0] if added else "", "adds no term")))
                return False
            if cand.bic >= over.bic:
                kept(replace(cand, why=f"BIC {cand.bic - over.bic:+.1f} against {over.name}"))
                return False
            over = validated(over)
            cand = validated(cand)
            if over.holdout_rms is None or cand.holdout_rms is None:
                kept(replace(cand, why=cand.why or "not cross-validated"))
                return False
            gain, spread = _paired_gain(over, cand)
            held_text = (
                f"held-out RMS {over.holdout_rms * 1e3:.4f} → {cand.holdout_rms * 1e3:.4f} mm "
                f"(mean squared error {gain * 1e6:+.4g} ± {spread * 1e6:.2g} mm² a pose)"
            )
            if gain + HELD_OUT_SIGMA * spread >= 0.0:
                why = f"BIC {cand.bic - over.bic:+.1f} but {held_text}: not lower beyond its spread"
                kept(replace(cand, why=why))
                return False
            if cand.expected >= over.expected:
                why = (
                    f"BIC {cand.bic - over.bic:+.1f}, {held_text}, but its σ over the session's "
                    f"joint ranges is {cand.range_sd * 1e3:.4f} mm ({over.range_sd * 1e3:.4f} mm "
                    f"for {over.name}): the poses do not determine it where they did not go"
                )
                kept(replace(cand, why=why))
                return False
            why = f"BIC {cand.bic - over.bic:+.1f} against {over.name}, {held_text}"
            kept(replace(cand, why=why))
            return True

        base = fitted(())
        shown = [base]
        if mode == "geometric":
            current = base
        elif mode != "auto":
            current = fitted(MODELS[mode])
            validated(base)
            current = kept(replace(validated(current), why=f"forced by --model {mode}"))
            shown.append(current)
        else:
            # forward selection: each family alone, the best proven one kept, then the rest
            # added to it (compliance and a joint's first harmonic can look alike: cos of the
            # arm's angle)
            current, left = base, list(MODELS[mode])
            while left:
                tried = []
                for family in left:
                    cand = fitted((*current.families, family))
                    if cand.bic < current.bic:  # worth its best form: joints it cannot carry
                        cand = pruned(cand, family)  # dropped
                    tried.append(cand)
                shown += tried
                proven = [latest[c.key] for c in tried if proves(c, current)]
                if not proven:
                    break
                best = min(proven, key=lambda c: (c.expected, c.bic))
                left = [f for f in left if f not in best.families]
                current = best
            if current.key == base.key:
                kept(
                    replace(
                        latest[base.key],
                        why="no family lowered both the BIC and the held-out error",
                    )
                )
        return latest[current.key], tuple(latest[c.key] for c in shown)

    everything = keep.copy()
    fold = fold_of_poses(groups, folds, 0)
    chosen, shown = chosen_on(everything, fold)
    # the exact fits of the candidates shown (the chosen one's for its terms)
    fits = {c.key: parent(c.families)[0] for c in shown if not c.dropped}
    if chosen.dropped:
        fit, _ = parent(chosen.families)
        start = replace(fit.model, terms=_kept_terms(fit, chosen.dropped))
        fits[chosen.key] = fit_whole_model(start, candidate, unbounded)
    candidates = tuple(replace(c, chosen=c.key == chosen.key, fit=fits.get(c.key)) for c in shown)
    choices: list[str] = []
    starts: list[AxisModel] = []
    if outer is not None and mode == "auto":
        outer_pick = np.asarray(outer, dtype=np.int64)[pick]
        for k in range(folds):
            train = keep & (outer_pick != k)
            inner = np.full(pick.size, -1, dtype=np.int64)
            inner[train] = fold_of_poses(groups[train], folds, 1 + k)
            c, _ = chosen_on(train, inner)
            fit, _ = parent(c.families)
            choices.append(c.name)
            starts.append(replace(fit.model, terms=_kept_terms(fit, c.dropped)))
    return Selection(
        mode, candidates, folds, int(np.count_nonzero(keep)), tuple(choices), tuple(starts)
    )


#: A constraint on a linearised fit's ``z``: (C, d) for ``C z = d``, or None.
Constraint = tuple[FloatArray, FloatArray] | None


def _terms_of(fit: WholeFit) -> tuple[Term, ...]:
    return () if fit.model.terms is None else fit.model.terms.terms


def _kept_terms(fit: WholeFit, dropped: frozenset[tuple[str, int]]) -> Terms | None:
    """``fit``'s terms less those of the (family, joint) ``dropped`` (None for none left)."""
    terms = fit.model.terms
    if terms is None:
        return None
    kept = terms.without(lambda t: (family_of(t.kind), t.joint) in dropped)
    return kept if kept.size else None


#: A family is added only when its held-out mean squared error is lower by more than this many
#: standard errors of the paired difference over the held-out poses.
HELD_OUT_SIGMA = 2.0


def _paired_gain(current: Candidate, cand: Candidate) -> tuple[float, float]:
    """The change of the mean squared held-out error from ``current`` to ``cand`` (m²) over the
    same poses and folds, and its standard error."""
    assert current.squared is not None and cand.squared is not None
    d = cand.squared - current.squared
    spread = float(np.std(d, ddof=1) / np.sqrt(d.size)) if d.size > 1 else math.inf
    return float(np.mean(d)), spread


def selected_terms(selection: Selection) -> Terms | None:
    """The chosen candidate's fitted terms (None for the geometric model)."""
    fit = selection.chosen.fit
    return None if fit is None else fit.model.terms


def term_std(fit: WholeFit) -> FloatArray:
    """The σ of each term's coefficient (NaN where the samples do not determine it)."""
    terms = fit.model.terms
    k = fit.layout.terms_at
    if terms is None or k is None:
        return np.zeros(0)
    var = np.diag(fit.covariance)[k : k + terms.size]
    std = np.sqrt(np.clip(var, 0.0, None))
    undetermined: NDArray[np.bool_] = np.zeros(terms.size, dtype=bool)
    d = fit.determined
    if d is not None and d.null.shape[1]:
        undetermined = np.linalg.norm(d.null[k : k + terms.size], axis=1) > 0.5
    return np.where(undetermined, np.nan, std)
