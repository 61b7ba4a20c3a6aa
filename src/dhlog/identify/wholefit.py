"""The fit of the whole model to every sample with encoder values, and what is read off it
(:func:`identify_whole` → :class:`~dhlog.identify.stages.ModelFit`).

From the start (the per-joint axes or a nominal's): the maximum-likelihood fit
(:mod:`dhlog.identify.fit.whole`), joined again at the fitted clock offset while it moves
(:mod:`dhlog.identify.segment.timing`); the terms beyond the geometry tried or forced
(:mod:`dhlog.identify.model.beyond`, :mod:`~dhlog.identify.model.select`); the weights
(:mod:`dhlog.identify.fit.variance`); pairs the data cannot tell from parallel held parallel
(:mod:`dhlog.identify.model.pairs`, :mod:`~dhlog.identify.model.relations`); the DH model
read off the fitted axes with its covariance and what is fixed
(:mod:`dhlog.identify.read.uncertainty`, :mod:`~dhlog.identify.read.conditioning`); the FK check
at every sample, the outliers by name and the K-fold cross-validation
(:mod:`dhlog.identify.check`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line, Plane
from dhlog.identify.check.holdout import MIN_POSES, Holdout, cross_validate, enough_poses
from dhlog.identify.check.named import name_outliers, sample_names
from dhlog.identify.check.validate import check_residual, table_gap, validate_samples
from dhlog.identify.clocked import Clocked, fit_clocked
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.leaveout import (
    MOTION_SHARE,
    SAME_POSE,
    STRETCHES_PER_FOLD,
    PoseFolds,
    motion_share,
    pose_groups,
    still_poses,
)
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.variance import (
    Pass,
    pose_clustered,
    residual_norms,
    residual_pass,
    whitening,
    with_model_error,
)
from dhlog.identify.fit.whole import WholeFit, fit_whole_model
from dhlog.identify.joints.checks import check_noise_model
from dhlog.identify.model.beyond import (
    beyond_geometry,
    deflections,
    merge_cancelling,
    term_covariance,
)
from dhlog.identify.model.hold import hold_unseen, may_hold
from dhlog.identify.model.pairs import decided_tolerances, fold_holds
from dhlog.identify.model.parked import mark_parked, place_parked
from dhlog.identify.model.relations import constrain_pairs, with_fixed_relations
from dhlog.identify.model.select import RANGE_POINTS, Selection, term_std
from dhlog.identify.read.analytic import hayati_rows
from dhlog.identify.read.conditioning import identifiability_notes, nominal_rows
from dhlog.identify.read.extract import Extraction
from dhlog.identify.read.uncertainty import whole_uncertainty
from dhlog.identify.segment.persample import PerSample, SampleArray, blocks
from dhlog.identify.segment.segment import Segmentation
from dhlog.identify.stages import (
    Checks,
    FitRequest,
    ModelFit,
    Readout,
    Session,
    table_values_of,
)
from dhlog.model.dh import JointType
from dhlog.model.fk import fk_frames
from dhlog.model.terms import to_table

#: ``stage(what, fraction)``: told as each stage advances.
Stage = Callable[[str, float], None]

#: Share of the fitted samples in single-joint sweeps above which the cross-validation's note
#: says its poses lie on the sweeps.
SWEPT_SHARE = 0.5


def identify_whole(
    session: Session,
    analytic: Extraction | None,
    request: FitRequest,
    stage: Stage,
) -> ModelFit:
    """The maximum-likelihood fit of the whole model from ``session``'s axes and target (the
    analytic start's, or a nominal's when ``analytic`` is None), its DH model, covariance and
    check. Raises :class:`~dhlog.errors.GeometryError` or :class:`numpy.linalg.LinAlgError`
    when the fit fails."""
    joints, ref, base, nominal = (
        session.joints,
        session.reference_pose,
        session.base,
        session.nominal,
    )
    notes: list[Note] = []  # this stage's notes, in the order said, returned in its value
    types = tuple(j.type for j in joints)
    assert session.target is not None and all(t is not None for t in types)
    clocked = fit_clocked(session, analytic, request.fit_scales, stage)
    notes.extend(clocked.notes)
    whole, seg, rows, data = clocked.whole, clocked.segmentation, clocked.rows, clocked.data
    Q, P, which, rotations, rates = data.Q, data.P, data.which, data.rotations, data.rates
    assert isinstance(Q, PerSample)  # the session's samples, read a block at a time
    options, sigma = clocked.options, clocked.options.sigma
    dealt = None  # --holdout K: each sample's pose and fold, the same for selection and check
    if request.folds > 1:  # too few poses: said before the selection deals them to folds
        dealt = _dealt(Q, which, request.folds)
    outer = None if dealt is None else dealt.fold
    model_request = request.model
    if session.parked and model_request.harmonic_joints is None:  # none on a parked joint
        revolute = [k for k, t in enumerate(types) if t is JointType.REVOLUTE]
        model_request = replace(
            model_request,
            harmonic_joints=tuple(k for k in revolute if k not in session.parked),
        )
    whole, selection, said = beyond_geometry(
        model_request,
        whole,
        data,
        options,
        folds=request.folds,
        names=[j.name for j in joints],
        outer=outer,
    )
    notes.extend(said)
    whole, sample_cov, noise, said = with_model_error(
        whole, Q, P, data.sample_cov, options.noise, which, rates, rotations
    )
    notes.extend(said)
    # the final fit's samples and weights: the model-error component added
    data, final = replace(data, sample_cov=sample_cov), replace(options, noise=noise)
    whiten = whitening(noise, sample_cov, sigma)
    squares = None  # the whitened cost of the fit's inliers, where the design effect found it
    if rotations is None:
        whole, squares, said = pose_clustered(whole, Q, P, whiten, which, rates)
        notes.extend(said)

    def refit_terms(model: AxisModel) -> WholeFit:
        """The fit again from ``model`` (lumps merged), weighted and scaled as the final fit."""
        fit = fit_whole_model(model, data, final)
        if rotations is None:
            fit, _, _ = pose_clustered(fit, Q, P, whiten, which, rates)
        return fit

    # lumps of one joint the poses cannot tell apart (a cancelling pair): merged, said
    merged, said = merge_cancelling(whole, Q, refit_terms)
    notes.extend(said)
    if merged is not whole:
        whole, squares = merged, None
    clustered = whole
    nominal_table = nominal.table if nominal is not None else None
    tolerances, said = decided_tolerances(
        whole,
        nominal,
        request.tolerances.angle_tol,
        request.tolerances.distance_tol,
        data,
        final,
        parallel_sigma=request.parallel_sigma,
    )
    notes.extend(said)

    passes: list[tuple[AxisModel, Pass]] = []  # the passes over every sample, by their model

    def cost(fit: WholeFit) -> float:
        """The whitened sum of squares of ``whole``'s inliers under ``fit`` (positions)."""
        if fit is clustered and squares is not None:
            return squares
        done = residual_pass(fit, clustered.inliers, Q, P, whiten, which=which, rates=rates)
        passes.append((fit.model, done))
        return done.squares

    whole, tolerances, said = with_fixed_relations(whole, tolerances, cost)
    notes.extend(said)
    decided = replace(request.tolerances, pair_tolerances=tolerances)

    def extract(axes: list[Line], target: FloatArray, plane: Plane | None) -> Extraction:
        return decided.extract(
            axes,
            types,  # type: ignore[arg-type]
            target=target,
            reference_pose=ref,
            base_plane=plane,
            nominal=nominal_table,
        )

    stage("uncertainty", 0.0)
    plane = None if base is None else base.plane
    if session.parked and nominal is not None:  # placed by the nominal next to the fitted axes
        axes = place_parked(whole.model.axes, session.parked, nominal, ref)
        whole = replace(whole, model=replace(whole.model, axes=axes))
    ex = extract(list(whole.model.axes), whole.model.target, plane)
    # what the samples determine only beyond a physical bound: held at the nominal
    h_rows = hayati_rows(ex)
    nominal_h = nominal_rows(nominal_table, ref, h_rows)

    def refit(model: AxisModel, within: FloatArray) -> AxisModel:
        """The fit again from ``model`` along ``within`` only, weighted as the final fit."""
        return fit_whole_model(model, data, final, within=within).model

    found = whole_uncertainty(whole, base, extract, ex, ref, nominal_table)
    if may_hold(found.shown_std, h_rows):
        whole, _, said = hold_unseen(
            whole, extract, plane, h_rows, nominal_table, nominal_h, cost, refit
        )
        notes.extend(said)
        if whole.held:
            ex = extract(list(whole.model.axes), whole.model.target, plane)
            found = whole_uncertainty(whole, base, extract, ex, ref, nominal_table)
    notes.extend(found.notes)  # the uncertainty's notes, of the fit finally kept
    mark_parked(found.fixed, found.std, session.parked)
    if found.conditioned is not None:
        mark_parked(found.conditioned.fixed, found.conditioned.std, session.parked)
    notes.extend(identifiability_notes(whole, nominal is not None))
    notes.extend(check_noise_model(noise, whole.chi2_dof))
    stage("validating", 0.0)
    tools = np.vstack([ex.tool_point[None], found.extra_tool_points])
    terms, terms_std = None, np.zeros(0)
    if whole.model.terms is not None:  # the terms in the table's frames
        frames = fk_frames(ex.standard, ref, T_base=ex.T_measurement_base)
        terms, terms_std = to_table(whole.model.terms, frames), term_std(whole)
    # the table's joint values: ref + s (q − ref) with fitted scales, deflected by the terms
    Q_table = Q.map(lambda q: table_values_of(whole, ex, terms, q), Q.shape)
    moved = None
    if terms is not None:  # what the terms move, at the samples
        bare = Q.map(lambda q: table_values_of(whole, ex, terms, q, deflected=False), Q.shape)
        moved = deflections(ex, Q, Q_table, bare, terms, term_covariance(whole), terms_std)
    validation = validate_samples(seg, rows, Q_table, P, ex, whole.inliers, tools, which)
    stamps = np.asarray(seg.column("t_ns", rows), dtype=np.int64)
    names = sample_names(stamps, rows, session.log.point_ids)
    known = [done.norms for model, done in passes if model is whole.model]
    norms = known[0] if known else residual_norms(whole.model, Q, P, which=which, rates=rates)
    out, said = name_outliers(names, norms, whole.inliers)
    notes.extend(said)
    gap = table_gap(whole, ex, Q, Q_table)
    if gap > 1e-6:
        departs = (
            f"the DH table departs from the fitted model by up to {gap * 1e3:.4f} mm: a pair "
            "was classified (parallel / meeting) where the fitted axes are not; check the "
            "relations and the FK check."
        )
        notes.append(Note.warning(departs, "table-gap"))
    notes.extend(check_residual(validation, sigma))
    holdout: tuple[Holdout, ...] = ()
    if request.folds > 1 and dealt is not None:
        stage("cross-validating", 0.0)
        final_clock = replace(clocked, data=data, options=final)
        check = _cross_validation(whole, clustered, session, request, final_clock, dealt, selection)
        holdout = (_with_notes(check, whole, session, final_clock, names, selection, dealt),)
    return ModelFit(
        segmentation=seg,
        timing=clocked.timing,
        noise=noise,
        selection=selection,
        analytic=analytic,
        whole=whole,
        sigma=sigma * math.sqrt(whole.chi2_dof),
        readout=Readout(ex, found, whole.model.target, terms, terms_std, moved),
        checks=Checks(
            validation,
            outlier_names=tuple(names[i] for i in out.tolist()),
            outlier_rows=rows[out],
            holdout=holdout,
        ),
        notes=tuple(notes),
    )


def _dealt(Q: PerSample, which: NDArray[np.int64] | None, folds: int) -> PoseFolds:
    """``--holdout K``'s poses and folds: the session's poses dealt one by one, or where most of
    its samples are a motion sampled in steps below
    :data:`~dhlog.identify.fit.leaveout.SAME_POSE` (chained into "poses" that span whole
    sweeps; :func:`~dhlog.identify.fit.leaveout.motion_share`) or its poses are too few,
    stretches of its still poses (:meth:`PoseFolds.of_stretches`). Too few poses either way:
    the one-line error."""
    groups = pose_groups(Q)
    still = still_poses(Q)
    needed = max(folds, MIN_POSES)
    mine = groups if which is None else groups[which == 0]  # numbered in time order
    poses = int(np.count_nonzero(np.diff(mine))) + int(mine.size > 0)
    if poses >= needed and motion_share(groups, still) < MOTION_SHARE:
        return PoseFolds.of(groups, folds)
    count = folds * STRETCHES_PER_FOLD
    moving = int(still[still.shape[0] - 1]) + 1 if still.shape[0] else 0
    if moving < count:
        enough_poses(max(poses, moving), folds)  # too few poses, chained or still
        raise InputError(
            f"--holdout {folds}: the session's motion is sampled in steps below "
            f"{SAME_POSE * 1e3:g} mrad (or mm), so the folds hold out stretches of its still "
            f"poses, {STRETCHES_PER_FOLD} a fold; its {moving} still poses are fewer than the "
            f"{count} stretches of {folds} folds: hold out fewer folds, or --validate a log of "
            "other poses."
        )
    return PoseFolds.of_stretches(still, folds)


def _cross_validation(
    whole: WholeFit,
    clustered: WholeFit,
    session: Session,
    request: FitRequest,
    fit: Clocked,
    dealt: PoseFolds,
    selection: Selection | None,
) -> Holdout:
    """``--holdout K``: the K-fold cross-validation of the whole procedure over the session's
    poses (:func:`~dhlog.identify.check.holdout.cross_validate`), each fold held to the pairs
    its own training poses hold parallel (decided again there unless ``parallel_sigma`` says)."""
    nominal = session.nominal
    held_in_fold: list[dict[int, str]] = []  # the pairs each fold holds, from its poses
    if request.parallel_sigma is None:
        held_in_fold = fold_holds(
            clustered,
            nominal,
            request.tolerances.angle_tol,
            request.tolerances.distance_tol,
            fit.data,
            fit.options,
            outer=dealt.fold,
            folds=request.folds,
        )

    def refine(fitted: WholeFit, k: int) -> WholeFit:
        """Fold ``k``'s fit held to the pairs its own poses hold."""
        held = held_in_fold[k] if held_in_fold else {}
        if not held:
            return fitted
        parallel = [i for i, kind in held.items() if kind == "parallel"]
        return constrain_pairs(fitted, parallel, [i for i in held if i not in parallel])

    check = cross_validate(
        whole,
        fit.data,
        replace(fit.options, fit_scales=request.fit_scales),
        request.folds,
        nominal=nominal,
        poses=dealt,
        starts=() if selection is None else selection.fold_starts,
        refine=refine,
    )
    if any(held_in_fold):
        said = [", ".join(f"{i + 1}–{i + 2}" for i in sorted(h)) or "none" for h in held_in_fold]
        check = replace(
            check,
            notes=(
                *check.notes,
                "the pairs held parallel were decided again in each fold from its training "
                f"poses: {_tally(said, '; ')}.",
            ),
        )
    return check


def _with_notes(
    check: Holdout,
    whole: WholeFit,
    session: Session,
    fit: Clocked,
    names: Sequence[str],
    selection: Selection | None,
    dealt: PoseFolds,
) -> Holdout:
    """The cross-validation with its poses named by the export's ids, the model's own FK σ
    over the session's joint ranges, and what a reader should know of its figure: stretches
    of a fast-sampled motion held out in place of poses, the choice made again in each fold,
    the share of samples in sweeps of one joint alone."""
    notes = list(check.notes)
    if dealt.stretches:
        notes.append(_stretches_note(check, whole, fit, dealt))
    pose_names = check.pose_names
    if check.pose_samples is not None and session.log.point_ids is not None:
        pose_names = [names[i] for i in check.pose_samples.tolist()]
    check = replace(
        check,
        pose_names=pose_names,
        range_sd=range_sd(whole, fit.data.Q),
        stretches=dealt.stretches,
        stretch_poses=dealt.stretch_poses,
    )
    assert check.range_sd is not None
    if check.expected_rms is not None and check.range_sd > 0.5 * check.calibrated.rms:
        notes.append(
            f"over every combination of the session's joint ranges, poses it may never have "
            f"visited among them, the model's own FK σ is {check.range_sd * 1e3:.4f} mm RMS: "
            f"the error to expect there is about {check.expected_rms * 1e3:.4f} mm."
        )
    nested = () if selection is None else selection.fold_choices
    if nested:
        notes.append(
            "--model auto chose again in each fold from its training poses alone (nested "
            f"cross-validation): {_tally(nested, ', ')}; the held-out error is that of the "
            "whole procedure."
        )
    swept = swept_share(fit.segmentation, fit.rows)
    if swept >= SWEPT_SHARE:
        notes.append(
            f"{swept:.0%} of the samples are in sweeps of one joint alone: the held-out "
            "poses lie on the swept arcs, so an error of the joints together — at poses "
            "the session never went to — is not in this figure; --validate a log of "
            "random poses to see it."
        )
    return replace(check, notes=tuple(notes))


def _stretches_note(check: Holdout, whole: WholeFit, fit: Clocked, dealt: PoseFolds) -> str:
    """What a cross-validation over stretches held out and scored, and how much of its figure
    the noise of a pose's mean explains (σ √3 / √n, with the fit's isotropic σ)."""
    said = (
        f"most samples lie on motions sampled in steps below {SAME_POSE * 1e3:g} mrad (or mm), "
        "whose poses chained sample to sample would span whole sweeps: the folds held out "
        f"{dealt.stretches} stretches of the session instead ({STRETCHES_PER_FOLD} a fold, "
        f"each of about {dealt.stretch_poses:.0f} still poses, the samples within "
        f"{SAME_POSE * 1e3:g} mrad of a pose's first), scored at the "
        f"{check.calibrated.n_poses} poses within them; a held-out stretch's ends meet "
        "fitted samples."
    )
    if fit.data.sample_cov is not None:  # declared covariances: no one σ to say it with
        return said
    usable = np.asarray(whole.inliers, dtype=bool)
    if fit.data.which is not None:
        usable &= fit.data.which == 0
    counts = np.bincount(np.asarray(dealt.groups)[usable])
    counts = counts[counts > 0]
    sigma = fit.options.sigma * math.sqrt(whole.chi2_dof)
    floor = sigma * math.sqrt(3.0 * float(np.mean(1.0 / counts))) if counts.size else 0.0
    rms, n = check.calibrated.rms, max(check.calibrated.n_poses, 1)
    # the spread of a mean square over n poses of 3 components: √(2 / 3n) of it, 3 times
    excess = rms**2 - floor**2
    rest = (
        f"the model's own error there is about {math.sqrt(excess) * 1e3:.4f} mm"
        if excess > 3.0 * math.sqrt(2.0 / (3.0 * n)) * rms**2
        else "the rest is within what that noise spreads over the poses"
    )
    return (
        f"{said} Of its {rms * 1e3:.4f} mm RMS, the noise a pose's mean keeps is about "
        f"{floor * 1e3:.4f} mm (σ √3 / √n over a pose's n samples): {rest}."
    )


def _tally(labels: Sequence[str], sep: str) -> str:
    """Each label with how many of ``labels`` it is, in the order met: "a in 4 of 5"."""
    counts = {c: labels.count(c) for c in dict.fromkeys(labels)}
    return sep.join(f"{c} in {k} of {len(labels)}" for c, k in counts.items())


def range_sd(whole: WholeFit, Q: SampleArray) -> float:
    """The RMS predicted FK σ (m) of ``whole`` at :data:`select.RANGE_POINTS` seeded joint
    vectors uniform in the box of the joint ranges of ``Q`` (m, n)."""
    lo, hi = np.full(Q.shape[1], np.inf), np.full(Q.shape[1], -np.inf)
    for sl in blocks(Q.shape[0]):
        q = Q[sl]
        lo, hi = np.minimum(lo, q.min(axis=0)), np.maximum(hi, q.max(axis=0))
    box = np.random.default_rng(0).uniform(lo, hi, (RANGE_POINTS, Q.shape[1]))
    _, J = predict(whole.model, box, whole.layout, whole.bases)
    assert J is not None
    var = np.einsum("mij,jk,mik->m", J, whole.covariance, J)
    return math.sqrt(max(float(np.mean(var)), 0.0))


def swept_share(seg: Segmentation, rows: NDArray[np.intp]) -> float:
    """The share of the samples ``rows`` that lie in a sweep of one joint alone."""
    inside = 0
    for sl in blocks(rows.size):
        inside += int(np.count_nonzero(seg.joint(rows[sl]) > 0))
    return inside / max(rows.size, 1)
