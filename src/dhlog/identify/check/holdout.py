"""The error of a calibration at poses not used to fit it, before (the nominal) and after.

Poses, not samples, are held out: consecutive samples whose joint vectors differ by less than
``SAME_POSE`` (:mod:`dhlog.identify.fit.leaveout`) form one pose (a tracker's dwell at a static
pose), so no held-out pose has a sample among the fitted ones; on a motion sampled in steps
below it (a tracker at 1 kHz along a sweep) the run deals stretches of its still poses instead
(``identify.wholefit``, :meth:`~dhlog.identify.fit.leaveout.PoseFolds.of_stretches`) and hands
them in. A pose's error is the length of the mean of its samples' residual vectors (measured −
predicted).

* :func:`cross_validate` (``--holdout K``): the poses split into K folds (seeded); for each fold
  the whole model is fitted again to the other folds (from the full fit, which the fold's
  optimum lies close to, or from the model ``--model auto`` chose from that fold's poses: see
  :mod:`dhlog.identify.model.select`), held to the pairs the fold holds parallel, and the nominal
  placed on the same poses (its base and tool point registered,
  :func:`dhlog.identify.fit.register.register_nominal`); both predict the fold.
* another session's log (``--validate LOG``) is scored by
  :func:`dhlog.identify.check.footing.score_poses`, on one footing for the nominal and the
  calibrated model.

Pure numpy/scipy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.data import FitData, FitOptions
from dhlog.identify.fit.leaveout import (
    PoseFolds,
    fold_of_poses,
    pose_groups,
    pose_means,
)
from dhlog.identify.fit.prediction import predict
from dhlog.identify.fit.register import register_nominal
from dhlog.identify.fit.whole import WholeFit, fit_whole_model
from dhlog.identify.segment.persample import SampleArray
from dhlog.io.dhfile import DHModel
from dhlog.model.fk import fk_point

#: Fewest poses a held-out statistic is given for.
MIN_POSES = 5
#: A fold's fit whose χ²/dof is this many times the session's did not converge from its start.
BROKEN_FIT = 4.0


def enough_poses(poses: int, folds: int) -> None:
    """An :class:`~dhlog.errors.InputError` where ``poses`` distinct poses are too few for
    ``folds``-fold cross-validation (fewer than the folds, or than :data:`MIN_POSES`)."""
    from dhlog.errors import InputError

    if poses >= max(folds, MIN_POSES):
        return
    raise InputError(
        f"--holdout {folds}: the session has {poses} distinct poses; hold out fewer "
        "folds or measure more poses."
    )


@dataclass(frozen=True)
class ErrorStats:
    """Position errors (m) at held-out poses: mean, RMS, 95th percentile, max, count."""

    mean: float
    rms: float
    p95: float
    max: float
    n_poses: int

    @classmethod
    def of(cls, errors: FloatArray) -> ErrorStats:
        e = np.asarray(errors, dtype=np.float64)
        return cls(
            float(e.mean()),
            float(np.sqrt(np.mean(e**2))),
            float(np.percentile(e, 95)),
            float(e.max()),
            int(e.size),
        )

    def document(self) -> dict[str, float | int]:
        return {
            "mean": self.mean,
            "rms": self.rms,
            "p95": self.p95,
            "max": self.max,
            "n_poses": self.n_poses,
        }


@dataclass(frozen=True)
class Holdout:
    """One held-out check: ``kind`` ``"cross-validation"`` (``folds``) or ``"log"`` (``path``;
    ``registered``: the base was placed again on ``n_registration_poses`` of its poses because
    the tracker moved); the statistics of the nominal and of the calibrated model, and per
    scored pose its measured position and both error vectors (measured − predicted, m)."""

    kind: str
    nominal: ErrorStats | None
    calibrated: ErrorStats
    positions: FloatArray
    nominal_vectors: FloatArray | None
    calibrated_vectors: FloatArray
    folds: int | None = None
    path: str | None = None
    registered: bool = False
    n_registration_poses: int = 0
    notes: tuple[str, ...] = ()
    #: where the positions' frame M stands (its ``T_measurement_base``) when it is not the
    #: result's own: another log measured after the tracker moved
    T_measurement_base: FloatArray | None = None
    #: the calibrated model's RMS predicted FK σ (m) over every combination of the session's
    #: joint ranges (a cross-validation: poses the session may never have visited among them)
    range_sd: float | None = None
    #: per scored pose (``positions``' order), the index of its first sample among those fitted
    pose_samples: NDArray[np.int64] | None = None
    #: per scored pose, its name (the export's point id of its first sample, else ``#k``)
    pose_names: list[str] | None = None
    #: a cross-validation of a motion sampled below ``SAME_POSE`` a step: the stretches of it
    #: the folds held out (0: poses dealt one by one) and the still poses in one (the mean)
    stretches: int = 0
    stretch_poses: float = 0.0

    @property
    def expected_rms(self) -> float | None:
        """The error expected over the session's joint ranges (m): the held-out RMS with the
        model's own σ there added in quadrature."""
        if self.range_sd is None:
            return None
        return math.sqrt(self.calibrated.rms**2 + self.range_sd**2)

    def document(self) -> dict[str, object]:
        doc: dict[str, object] = {"kind": self.kind}
        if self.folds is not None:
            doc["folds"] = self.folds
        if self.path is not None:
            doc["path"] = self.path
            doc["registered"] = self.registered
            doc["n_registration_poses"] = self.n_registration_poses
        doc["n_poses"] = self.calibrated.n_poses
        if self.stretches:
            doc["stretches"] = self.stretches
            doc["stretch_poses"] = self.stretch_poses
        doc["nominal"] = None if self.nominal is None else self.nominal.document()
        doc["calibrated"] = self.calibrated.document()
        if self.range_sd is not None:
            doc["range_sd"] = self.range_sd
            doc["expected_rms"] = self.expected_rms
        doc["notes"] = list(self.notes)
        return doc


def _pose_errors(
    groups: NDArray[np.int64], mask: NDArray[np.bool_], P: SampleArray, pred: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Per pose with samples in ``mask``: the mean measured position and the mean residual
    (``pred``: the prediction at the samples in ``mask``)."""
    g, measured = groups[mask], P[mask]
    return pose_means(g, measured)[1], pose_means(g, measured - pred)[1]


def cross_validate(
    whole: WholeFit,
    data: FitData,
    options: FitOptions,
    folds: int,
    *,
    nominal: DHModel | None = None,
    poses: PoseFolds | None = None,
    starts: Sequence[AxisModel] = (),
    refine: Callable[[WholeFit, int], WholeFit] | None = None,
) -> Holdout:
    """K-fold cross-validation over poses (see the module docstring) of the fit of ``data``
    weighted by ``options`` (noise, σ, per-sample covariance, orientations, …);
    ``nominal``: its table, base and tool point placed on each fold's fitted poses. Only the
    full fit's inliers are used; with several targets only the primary one is scored.
    ``poses``: each sample's pose and fold (default: :func:`pose_groups` and
    :func:`fold_of_poses` of them, seed 0);
    ``starts``: per fold, the model to fit to its training poses (default ``whole``'s) — the
    model ``--model auto`` chose from those poses alone; ``refine(fit, k)``: fold k's fit as the
    run would finish it from those poses (its pairs held parallel)."""

    Q, P, which = data.Q, data.P, data.which
    groups = pose_groups(Q) if poses is None else poses.groups
    usable = whole.inliers.copy()
    if which is not None:
        usable &= which == 0
    enough_poses(int(np.unique(groups[usable]).size), folds)
    fold = fold_of_poses(groups, folds, 0) if poses is None else poses.fold
    positions, cal_vecs, nom_vecs = [], [], []
    firsts: list[int] = []
    refitted: list[tuple[int, float, float]] = []  # (fold, χ²/dof from its start, then)
    notes: tuple[str, ...] = ()
    first_of = dict(zip(*np.unique(groups, return_index=True), strict=True))
    for k in range(folds):
        test = usable & (fold == k)
        firsts.extend(first_of[g] for g in np.unique(groups[test]).tolist())
        train = whole.inliers & (fold != k)
        start = starts[k] if k < len(starts) else whole.model
        fit = fit_whole_model(start, data.kept(train), options)
        if start is not whole.model and fit.chi2_dof > BROKEN_FIT * whole.chi2_dof:
            # the fold's own choice did not converge: the geometry alone fitted to the fold
            again = fit_whole_model(replace(whole.model, terms=None), data.kept(train), options)
            if again.chi2_dof < fit.chi2_dof:
                refitted.append((k, fit.chi2_dof, again.chi2_dof))
                fit = again
        if refine is not None:
            fit = refine(fit, k)
        pred, _ = predict(fit.model, Q[test])
        pos, vec = _pose_errors(groups, test, P, pred)
        positions.append(pos)
        cal_vecs.append(vec)
        if nominal is not None:
            table, T_base, tool = nominal.table, nominal.T_base, nominal.tool_point
            primary = train if which is None else train & (which == 0)
            reg = register_nominal(table, Q[primary], P[primary], tool_point=tool, T_base=T_base)
            pn = fk_point(table, Q[test], reg.tool_point, T_base=reg.T_measurement_base)  # at test
            nom_vecs.append(_pose_errors(groups, test, P, pn)[1])
    cal = np.vstack(cal_vecs)
    nom = np.vstack(nom_vecs) if nom_vecs else None
    if nominal is not None:
        notes = (
            "the nominal's base and tool point were placed on each fold's fitted poses "
            "(a robust registration), as a calibration would be judged without one.",
        )
    if refitted:
        said = "; ".join(f"fold {k + 1}: χ²/dof {a:.3g}, then {b:.3g}" for k, a, b in refitted)
        notes = (
            *notes,
            f"the fit of {len(refitted)} fold(s) from the model its own training poses chose "
            f"did not converge, or fits its training poses {BROKEN_FIT:g}× worse than the "
            f"session's model does (χ²/dof {whole.chi2_dof:.3g}); the geometry alone was fitted "
            f"to it instead ({said}), so for those folds the figure is not quite the whole "
            "procedure's.",
        )
    return Holdout(
        kind="cross-validation",
        nominal=None if nom is None else ErrorStats.of(np.linalg.norm(nom, axis=1)),
        calibrated=ErrorStats.of(np.linalg.norm(cal, axis=1)),
        positions=np.vstack(positions),
        nominal_vectors=nom,
        calibrated_vectors=cal,
        folds=folds,
        notes=notes,
        pose_samples=np.asarray(firsts, dtype=np.int64),
    )
