"""The terms beyond the geometry in a run (``--model``, ``--masses``, ``--gravity``): the
candidates fitted and chosen (:mod:`dhlog.identify.model.select`), the chosen terms fitted to every
sample, a URDF's link masses placed on the measured axes, the lumps the poses cannot tell apart
merged (:func:`merge_cancelling`), and what the terms deflect at the samples, with its σ
(:func:`deflections`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.prediction import prefix_motions
from dhlog.identify.fit.start import align_lines
from dhlog.identify.fit.variance import refit_with_model_error
from dhlog.identify.fit.whole import WholeFit, fit_whole_model
from dhlog.identify.model.select import (
    SELECT_FOLDS,
    ModelRequest,
    Selection,
    TermDesign,
    default_gravity,
    select_model,
    selected_terms,
    term_std,
    terms_for,
)
from dhlog.identify.read.extract import Extraction
from dhlog.identify.segment.persample import SampleArray, blocks
from dhlog.model.fk import fk_points_chunked
from dhlog.model.terms import Lump, Terms, table_deflection


def beyond_geometry(
    request: ModelRequest,
    whole: WholeFit,
    data: FitData,
    options: FitOptions,
    *,
    folds: int,
    names: Sequence[str],
    outer: NDArray[np.int64] | None = None,
) -> tuple[WholeFit, Selection | None, tuple[Note, ...]]:
    """The terms beyond the geometry that ``--model`` (``request``) asks for or the session
    proves (:func:`select_model`), fitted to every sample, and the candidates tried (None with
    ``--model geometric``). ``data``, ``options``: the whole-model fit's samples and weights;
    ``folds``: the run's K-fold cross-validation (else :data:`SELECT_FOLDS`); ``names``: the
    joints' (a URDF's masses are matched by them); ``outer``: each sample's fold of
    ``--holdout K``, in which ``auto`` chooses again from the fold's training poses
    (:func:`select_model`). Its notes: those of
    :func:`link_masses`."""
    if request.mode == "geometric":
        return whole, None, ()
    gravity = (
        default_gravity(whole)
        if request.gravity is None
        else np.asarray(request.gravity, dtype=np.float64)
    )
    masses: tuple[Lump, ...] = ()
    notes: tuple[Note, ...] = ()
    if request.masses is not None:
        masses, urdf_gravity, notes = link_masses(request.masses, whole, names)
        if request.gravity is None:
            gravity = urdf_gravity
    # where the declared uncertainties are far below the residuals, the candidates are weighed
    # with the model-error component as the final fit will be (U95 alone weighs badly)
    declared = data.sample_cov
    noise = options.noise
    if declared is None and noise.model == "tracker":
        declared = noise.covariance(data.P[:])  # (m, 3, 3): a tracker model's weighing holds them
    weighed = data
    if declared is not None:
        found = refit_with_model_error(whole, data, declared, options)
        if found is not None:
            weighed = replace(data, sample_cov=found.sample_cov)
    term_design = TermDesign(gravity, request.harmonic_joints, masses)
    selection = select_model(
        request.mode,
        whole,
        weighed,
        options,
        term_design=term_design,
        folds=folds if folds > 1 else SELECT_FOLDS,
        reuse=weighed is data,
        outer=outer,
    )
    chosen = selection.chosen
    terms = selected_terms(selection)
    if terms is None:
        return whole, selection, notes
    # the lumps again on the chosen candidate's axes (the geometric fit's may sit off where the
    # terms were missing), its coefficients kept where the terms are the same
    assert chosen.fit is not None
    again = terms_for(chosen.fit, chosen.families, term_design, chosen.dropped)
    if again is not None and again.names() == terms.names():
        again = again.with_coefficients(terms.coefficients)
    start = replace(whole.model, terms=again)
    return fit_whole_model(start, data, options), selection, notes


#: The URDF's joint axes farther than this (m, RMS) from the measured ones after placing it
#: are worth a warning: its masses may not be this robot's, or not where they were placed.
URDF_MISFIT = 0.01


def link_masses(
    path: str, whole: WholeFit, names: Sequence[str]
) -> tuple[tuple[Lump, ...], FloatArray, tuple[Note, ...]]:
    """The links' masses of the URDF at ``path`` as lumps in M (its joints matched by the
    ``names``, its axes placed on the fitted ones: ``align_lines``), gravity along its root's
    −z in M, and what was said: how they were placed (``masses``), and a warning when its axes
    sit far from the measured ones (``masses-misfit``)."""
    from dhlog.io.urdfmasses import read_link_masses

    lm = read_link_masses(path, tuple(names), whole.model.reference_pose)
    measured = [(a.point, a.direction) for a in whole.model.axes]
    T = align_lines(list(zip(lm.axis_points, lm.axis_dirs, strict=True)), measured)
    if T is None:
        raise InputError(
            f"{path}: its joint axes do not fix a placement on the measured ones (all parallel); "
            "give --gravity and leave --masses out for the lumped gravity terms."
        )
    R, t = T[:3, :3], T[:3, 3]
    misfit = [
        float(np.linalg.norm(np.cross(R @ p + t - a.point, a.direction)))
        for p, a in zip(lm.axis_points, whole.model.axes, strict=True)
    ]
    rms = math.sqrt(float(np.mean(np.square(misfit))))
    turned = max(
        float(np.degrees(np.arccos(np.clip(abs((R @ d) @ a.direction), -1.0, 1.0))))
        for d, a in zip(lm.axis_dirs, whole.model.axes, strict=True)
    )
    notes = [
        Note.info(
            f"--masses: {len(lm.masses)} link masses ({float(np.sum(lm.masses)):.1f} kg) from "
            f"{path}, joints matched {lm.matched}, placed on the measured axes (RMS "
            f"{rms * 1e3:.2f} mm, largest turn {turned:.3f}°); gravity along its base's −z.",
            "masses",
        )
    ]
    if rms > URDF_MISFIT:
        said = (
            f"--masses: the URDF's axes sit {rms * 1e3:.1f} mm RMS from the measured ones once "
            "placed: is it this robot's, with its joint zero at the encoder zero?"
        )
        notes.append(Note.warning(said, "masses-misfit"))
    lumps = tuple(
        Lump(k, R @ c + t, float(m))
        for k, c, m in zip(lm.moved_by, lm.centres, lm.masses, strict=True)
    )
    gravity = np.asarray(R @ np.array([0.0, 0.0, -1.0]), dtype=np.float64)
    return lumps, gravity, tuple(notes)


#: Two compliance terms of one joint whose coefficients' correlation exceeds this in magnitude
#: are one combination to the samples: their lumps' lever arms about the joint are nearly
#: proportional over the poses (at 0.95 the σ of the pair's determined combination is a third
#: of each term's, √(2(1 − 0.95)) for equal σ: the samples see their sum, not their split).
CANCEL_CORRELATION = 0.95
#: A term within this many σ of zero is not measured on its own. Two σ, not one: the Stäubli
#: pair of a real session (+2.115 and −2.114 ± 1.73 rad/m) sat at 1.2 σ each, and a value inside 2 σ
#: is what the usual test cannot tell from zero; holding it costs the samples at most 4 of χ².
UNMEASURED_SIGMA = 2.0
#: A deflection within this many σ of zero is said to be undetermined, not printed as one.
DEFLECTION_SIGMA = 2.0
#: A term whose σ alone moves its joint by more than this (rad) somewhere among the samples is
#: not measured: what the terms model (gravity deflection, a gear's first harmonic) stays well
#: below it on any arm (the KR210-sized truth of the README bends 26″ under 150 kg; 0.1° is
#: 360″), and a Stäubli session's reported "deflection" of 1.83 mm at about a metre's reach is this
#: size. Such a term is held at zero (the nominal has none), as a DH entry beyond 1° is held.
TERM_BOUND = math.radians(0.1)
#: The kinds whose terms are lumps of one joint's gravity torque (they can stand for each other).
LUMP_KINDS = ("compliance", "compliance_masses")
#: Most samples (evenly strided) over which each term's largest function value is taken.
REACH_SAMPLES = 5000


@dataclass(frozen=True)
class Hold:
    """One term held at zero: its name, joint (0-based), value and σ before, the largest
    deflection of its joint its σ gives at the samples (rad), and, where it cancels another
    lump of its joint, that one (``kept``, which then carries the pair's combination) with its
    value, σ and their correlation."""

    held: str
    joint: int
    value: float
    std: float
    reach_std: float
    kept: str | None = None
    kept_value: float = math.nan
    kept_std: float = math.nan
    correlation: float = math.nan


def cancelling(
    terms: Terms, cov: FloatArray, std: FloatArray, reach: FloatArray | None = None
) -> list[Hold]:
    """The terms to hold at zero, in order (``terms``, their coefficients' covariance ``cov``,
    ``std`` NaN where undetermined, ``reach`` each term's largest ``|b|`` at the samples).

    First the cancelling pairs: while two lump terms of one joint are correlated beyond
    :data:`CANCEL_CORRELATION`, cancel (their values lie along the combination the samples do
    not see: θa θb ρ > 0) and one of them is within :data:`UNMEASURED_SIGMA` of zero, the pair
    member nearer zero in its σ is held there (of all such pairs, the one nearest zero first).
    Then, where no pair is left, the term whose σ moves its joint most beyond
    :data:`TERM_BOUND` (σ · reach). The estimate and covariance are conditioned on each hold
    before the next is judged (the other terms take what the held one carried:
    θ − C[:, a] θa / C[a, a]), so that a group of three or more lumps on one line is merged
    down to one, and a term undetermined only with its partner is judged without it.

    A pair whose members are both measured (beyond 2 σ) is left alone even when they cancel: a
    significantly negative lump (which no mass and stiffness give) is then a finding (gravity's
    direction, a missing term), not noise to hide. Only lump terms pair: a joint's harmonics
    are orthogonal functions of its angle."""
    theta = np.asarray(terms.coefficients, dtype=np.float64).copy()
    C = np.asarray(cov, dtype=np.float64).copy()
    names = terms.names()
    usable = np.isfinite(std) & (np.diag(C) > 0)
    reach = np.zeros(terms.size) if reach is None else np.asarray(reach, dtype=np.float64)
    lumps = [k for k, t in enumerate(terms.terms) if t.kind in LUMP_KINDS and usable[k]]
    out: list[Hold] = []
    held: set[int] = set()
    while True:
        sd = np.sqrt(np.clip(np.diag(C), 0.0, None))
        best: tuple[float, int, int, float] | None = None
        for x, a in enumerate(lumps):
            for b in lumps[x + 1 :]:
                if a in held or b in held or terms.terms[a].joint != terms.terms[b].joint:
                    continue
                if sd[a] <= 0.0 or sd[b] <= 0.0:  # a term the conditioning fixed: no pair
                    continue
                rho = float(C[a, b] / (sd[a] * sd[b]))
                if abs(rho) <= CANCEL_CORRELATION or theta[a] * theta[b] * rho <= 0.0:
                    continue
                za, zb = abs(theta[a]) / sd[a], abs(theta[b]) / sd[b]
                drop, keep = (a, b) if za <= zb else (b, a)
                z = min(za, zb)
                if z < UNMEASURED_SIGMA and (best is None or z < best[0]):
                    best = (z, drop, keep, rho)
        if best is not None:
            _, d, k, rho = best
            hold = Hold(
                names[d],
                terms.terms[d].joint,
                float(theta[d]),
                float(sd[d]),
                float(sd[d] * reach[d]),
                names[k],
                float(theta[k]),
                float(sd[k]),
                rho,
            )
        else:
            spread = np.where(usable & (sd > 0), sd * reach, 0.0)
            spread[list(held)] = 0.0
            d = int(np.argmax(spread))
            if spread[d] <= TERM_BOUND:
                return out
            hold = Hold(
                names[d], terms.terms[d].joint, float(theta[d]), float(sd[d]), float(spread[d])
            )
        out.append(hold)
        theta = theta - C[:, d] * (theta[d] / C[d, d])
        C = C - np.outer(C[:, d], C[d, :]) / C[d, d]
        theta[d] = 0.0
        held.add(d)


def term_covariance(fit: WholeFit) -> FloatArray:
    """The covariance of ``fit``'s term coefficients (k, k; empty without terms)."""
    terms, k = fit.model.terms, fit.layout.terms_at
    if terms is None or k is None:
        return np.zeros((0, 0))
    return np.asarray(fit.covariance[k : k + terms.size, k : k + terms.size], dtype=np.float64)


def term_reach(model: AxisModel, Q: SampleArray) -> FloatArray:
    """Each term's largest ``|b|`` (m or 1) over the encoder values ``Q`` (at most
    :data:`REACH_SAMPLES` of them, evenly strided): how far a unit coefficient moves its joint."""
    if model.terms is None or not model.terms.size:
        return np.zeros(0)
    m = Q.shape[0]
    pick = np.unique(np.linspace(0, m - 1, min(REACH_SAMPLES, m)).astype(np.intp))
    B = prefix_motions(model, np.asarray(Q[pick], dtype=np.float64))[-1]
    assert B is not None
    return np.asarray(np.max(np.abs(B), axis=1, initial=0.0), dtype=np.float64)


def merge_cancelling(
    fit: WholeFit, Q: SampleArray, refit: Callable[[AxisModel], WholeFit]
) -> tuple[WholeFit, tuple[Note, ...]]:
    """``fit`` with the terms of :func:`cancelling` held at zero: left out and the model fitted
    again by ``refit`` (with the run's weights and covariance scale: σ decides here, so the
    caller's covariance must be the one it reports), one warning (``cancelling``) per held
    term (for a pair,
    naming both, their values before and the kept one's after). ``fit`` itself where none is.
    ``Q``: the encoder values of the samples (each term's reach, :func:`term_reach`).

    Why merge rather than print: two lumps whose lever arms about a joint are nearly
    proportional over the poses (a short range of the joints after it, a tool that keeps one
    direction, wrist lumps a few mm apart) give the samples one combination; the fit then splits
    it between them along a direction the samples barely see, often as a large pair of opposite
    sign that cancels (+2.115 and −2.114 ± 1.73 rad/m on a Stäubli), and where the
    difference of the lever arms is nearly constant the geometry (a joint offset) absorbs what
    the pair moves, so that a "deflection" of a millimetre is reported that the samples never
    saw. Holding the unmeasured member at zero leaves the other carrying the combination (its
    lever arm is the pair's, to within what the samples tell apart), which is what the samples
    determine; the fit again moves the rest to the optimum without it. A term left alone whose σ
    alone exceeds :data:`TERM_BOUND` of its joint is held the same way (a DH entry beyond its
    physical bound is held at the nominal: :mod:`dhlog.identify.model.hold`)."""
    terms = fit.model.terms
    if terms is None or not terms.size:  # every term already left out: nothing to merge
        return fit, ()
    holds = cancelling(terms, term_covariance(fit), term_std(fit), term_reach(fit.model, Q))
    if not holds:
        return fit, ()
    notes: list[Note] = []
    held = {h.held for h in holds}
    kept = terms.without(lambda t: t.name(terms.lumps) in held)
    again = refit(replace(fit.model, terms=kept if kept.size else None))
    after: dict[str, tuple[float, float]] = {}
    if again.model.terms is not None:
        now = again.model.terms
        after = {
            name: (float(v), float(sd))
            for name, v, sd in zip(now.names(), now.coefficients, term_std(again), strict=True)
        }
    for h in holds:
        said = f"{h.held} ({h.value:+.4g} ± {h.std:.3g})"
        if h.kept is None:
            alone = (
                f"{said}: its σ alone moves joint {h.joint + 1} by up to "
                f"{math.degrees(h.reach_std):.3g}° at the samples (bound "
                f"{math.degrees(TERM_BOUND):g}°): these samples do not determine it; held at "
                f"zero (left out). To determine it, add poses that change its function over "
                f"more of its range (the gravity torque about joint {h.joint + 1}, or its angle)."
            )
            notes.append(Note.warning(alone, "cancelling"))
            continue
        value, sd = after.get(h.kept, (math.nan, math.nan))
        now_said = f"now {value:+.4g} ± {sd:.3g}" if h.kept in after else "held too"
        pair = (
            f"{said} and {h.kept} ({h.kept_value:+.4g} ± {h.kept_std:.3g}) cancel (correlation "
            f"{h.correlation:+.3f}): their lumps' lever arms about joint {h.joint + 1} are "
            "nearly proportional over these poses, which determine only the pair's "
            f"combination; {h.held} is held at zero and {h.kept} carries the combination "
            f"({now_said}). To tell them apart, add poses that turn the joints after joint "
            f"{h.joint + 1} over more of their range."
        )
        notes.append(Note.warning(pair, "cancelling"))
    return again, tuple(notes)


def determined(value: float, std: float) -> bool:
    """Whether a deflection ``value`` (σ ``std``, NaN: undetermined) is beyond
    :data:`DEFLECTION_SIGMA` of zero: reported as measured, else said not to be."""
    return math.isfinite(std) and abs(value) > DEFLECTION_SIGMA * std


@dataclass(frozen=True)
class Deflection:
    """What the terms move at the samples: the largest deflection per joint (rad or m) and of
    the target (m), each with its σ at the sample where it is largest (NaN where a term it
    depends on is undetermined), and up to 2000 samples' target and its move (k, 6; m, in M)."""

    joints: FloatArray
    joints_std: FloatArray
    target: float
    target_std: float
    vectors: FloatArray


def deflections(
    ex: Extraction,
    Q: SampleArray,
    Q_table: SampleArray,
    bare: SampleArray,
    terms: Terms,
    cov: FloatArray,
    std: FloatArray,
) -> Deflection:
    """What the terms (``terms``, in the table's frames; their coefficients' covariance ``cov``
    and σ ``std``, NaN where undetermined) move at the samples, from the table's joint values
    with the terms (``Q_table``) and without (``bare``), both (m, n), and the encoder values
    ``Q`` (the harmonics' argument), a block at a time.

    The σ of each largest deflection is that of the terms' combination at the sample where it
    is largest: joint i's ``Δqᵢ = Σ θ_t b_t`` over its terms (``bᵀ C b``), the target's
    displacement ``J Δq`` along its own direction (``uᵀ D C Dᵀ u``, ``D`` the displacement per
    unit coefficient, by central differences of the forward kinematics: the deflections are
    μrad to mrad, linear to far below the noise). It is the σ of the terms alone, the geometry
    marginalised: where the geometry can take what the terms move (a lever-arm combination
    nearly constant over the poses is a joint offset), the σ says so, and a deflection within
    :data:`DEFLECTION_SIGMA` of zero is not a measurement (the console and the certificate say
    "not determined"). The largest of many is picked after the fact, so it reads somewhat high;
    its σ is that of the one picked."""
    m, n = Q_table.shape[0], Q_table.shape[1]
    T = ex.T_measurement_base

    def moves(at: slice | NDArray[np.intp]) -> tuple[FloatArray, FloatArray, FloatArray]:
        q, q0 = Q_table[at], bare[at]
        reached = fk_points_chunked(ex.standard, q, ex.tool_point, T_base=T)
        moved = reached - fk_points_chunked(ex.standard, q0, ex.tool_point, T_base=T)
        return np.abs(q - q0), reached, moved

    deflection_max, target = np.zeros(n), 0.0
    joint_at, target_at = np.zeros(n, dtype=np.intp), 0
    for sl in blocks(m):
        dq, _, moved = moves(sl)
        if dq.shape[0] == 0:
            continue
        k = np.argmax(dq, axis=0)
        better = dq[k, np.arange(n)] > deflection_max
        deflection_max = np.where(better, dq[k, np.arange(n)], deflection_max)
        joint_at = np.where(better, sl.start + k, joint_at)
        norms = np.linalg.norm(moved, axis=1)
        j = int(np.argmax(norms))
        if norms[j] > target:
            target, target_at = float(norms[j]), sl.start + j
    pick = np.unique(np.linspace(0, m - 1, min(2000, m)).astype(np.intp))
    _, reached, moved = moves(pick)
    joints_std = np.zeros(n)
    target_std = 0.0
    if terms.size and m:
        undetermined = ~np.isfinite(std)
        C = np.where(np.outer(undetermined, undetermined) | np.diag(undetermined), 0.0, cov)

        def per_unit(s: int) -> FloatArray:
            """Each term's Δq (n, k) at sample ``s`` for a unit coefficient."""
            q_e, q_t = np.asarray(Q[s : s + 1]), np.asarray(bare[s : s + 1])
            cols = [
                table_deflection(
                    ex.standard, terms.with_coefficients(np.eye(terms.size)[t]), q_e, q_t
                )[0]
                for t in range(terms.size)
            ]
            return np.column_stack(cols)

        def sd(v: FloatArray) -> float:
            """The σ of ``v @ θ``; NaN where an undetermined term enters."""
            if np.any(undetermined & (v != 0.0)):
                return math.nan
            return math.sqrt(max(float(v @ C @ v), 0.0))

        for i in range(n):
            joints_std[i] = sd(per_unit(int(joint_at[i]))[i]) if deflection_max[i] > 0 else 0.0
        if target > 0:
            s = int(target_at)
            B = per_unit(s)
            q0 = np.asarray(bare[s : s + 1])[0]
            scale = float(np.max(np.abs(B), initial=0.0))
            eps = 1e-6 / scale if scale > 0 else 1.0
            rows = np.vstack([q0 + eps * B.T, q0 - eps * B.T])
            p = fk_points_chunked(ex.standard, rows, ex.tool_point, T_base=T)
            D = (p[: terms.size] - p[terms.size :]).T / (2 * eps)  # (3, k)
            u = np.asarray(Q_table[s : s + 1])[0]
            shift = fk_points_chunked(ex.standard, np.vstack([u, q0]), ex.tool_point, T_base=T)
            direction = shift[0] - shift[1]
            direction = direction / max(float(np.linalg.norm(direction)), 1e-300)
            target_std = sd(direction @ D)
    return Deflection(
        deflection_max, joints_std, target, target_std, np.column_stack([reached, moved])
    )
