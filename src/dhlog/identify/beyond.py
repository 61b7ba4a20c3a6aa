"""The terms beyond the geometry in a run (``--model``, ``--masses``, ``--gravity``): the
candidates fitted and chosen (:mod:`dhlog.identify.select`), the chosen terms fitted to every
sample, a URDF's link masses placed on the measured axes, and what the terms deflect at the
samples."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray
from dhlog.identify.extract import Extraction
from dhlog.identify.persample import SampleArray, blocks
from dhlog.identify.select import (
    SELECT_FOLDS,
    ModelRequest,
    Selection,
    default_gravity,
    select_model,
    selected_terms,
    terms_for,
)
from dhlog.identify.start import align_lines
from dhlog.identify.variance import refit_with_model_error
from dhlog.identify.whole import WholeFit, fit_whole_model
from dhlog.model.fk import fk_points_chunked
from dhlog.model.terms import Lump


def beyond_geometry(
    request: ModelRequest,
    whole: WholeFit,
    Q: SampleArray,
    P: SampleArray,
    sigma: float,
    options: dict[str, Any],
    *,
    folds: int,
    names: Sequence[str],
    warnings: list[str],
    info: list[str],
    outer: NDArray[np.int64] | None = None,
) -> tuple[WholeFit, Selection | None]:
    """The terms beyond the geometry that ``--model`` (``request``) asks for or the session
    proves (:func:`select_model`), fitted to every sample, and the candidates tried (None with
    ``--model geometric``). ``options``: the whole-model fit's; ``folds``: the run's K-fold
    cross-validation (else :data:`SELECT_FOLDS`); ``names``: the joints' (a URDF's masses are
    matched by them); ``outer``: each sample's fold of ``--holdout K``, in which ``auto`` chooses
    again from the fold's training poses (:func:`select_model`)."""
    if request.mode == "geometric":
        return whole, None
    gravity = (
        default_gravity(whole)
        if request.gravity is None
        else np.asarray(request.gravity, dtype=np.float64)
    )
    masses: tuple[Lump, ...] = ()
    if request.masses is not None:
        masses, urdf_gravity = link_masses(request.masses, whole, names, warnings, info)
        if request.gravity is None:
            gravity = urdf_gravity
    # where the declared uncertainties are far below the residuals, the candidates are weighed
    # with the model-error component as the final fit will be (U95 alone weighs badly)
    declared = options.get("sample_cov")
    noise = options["noise"]
    if declared is None and noise.model == "tracker":
        declared = noise.covariance(P[:])  # (m, 3, 3): a tracker model's weighing holds them
    weighed = options
    if declared is not None:
        found = refit_with_model_error(
            whole,
            Q,
            P,
            declared,
            {k: options[k] for k in ("noise", "fit_scales", "rotations", "sigma_rotation")},
            which=options["which"],
            rates=options["rates"],
        )
        if found is not None:
            weighed = {**options, "sample_cov": found.sample_cov}
    selection = select_model(
        request.mode,
        whole,
        Q,
        P,
        sigma=sigma,
        options=weighed,
        gravity=gravity,
        harmonic_joints=request.harmonic_joints,
        folds=folds if folds > 1 else SELECT_FOLDS,
        masses=masses,
        reuse=weighed is options,
        outer=outer,
    )
    chosen = selection.chosen
    terms = selected_terms(selection)
    if terms is None:
        return whole, selection
    # the lumps again on the chosen candidate's axes (the geometric fit's may sit off where the
    # terms were missing), its coefficients kept where the terms are the same
    assert chosen.fit is not None
    again = terms_for(
        chosen.fit, chosen.families, gravity, request.harmonic_joints, masses, chosen.dropped
    )
    if again is not None and again.names() == terms.names():
        again = again.with_coefficients(terms.coefficients)
    start = replace(whole.model, terms=again)
    return fit_whole_model(start, Q, P, sigma=sigma, **options), selection


#: The URDF's joint axes farther than this (m, RMS) from the measured ones after placing it
#: are worth a warning: its masses may not be this robot's, or not where they were placed.
URDF_MISFIT = 0.01


def link_masses(
    path: str, whole: WholeFit, names: Sequence[str], warnings: list[str], info: list[str]
) -> tuple[tuple[Lump, ...], FloatArray]:
    """The links' masses of the URDF at ``path`` as lumps in M (its joints matched by the
    ``names``, its axes placed on the fitted ones: ``align_lines``), and gravity along its
    root's −z in M."""
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
    info.append(
        f"--masses: {len(lm.masses)} link masses ({float(np.sum(lm.masses)):.1f} kg) from "
        f"{path}, joints matched {lm.matched}, placed on the measured axes (RMS "
        f"{rms * 1e3:.2f} mm, largest turn {turned:.3f}°); gravity along its base's −z."
    )
    if rms > URDF_MISFIT:
        warnings.append(
            f"--masses: the URDF's axes sit {rms * 1e3:.1f} mm RMS from the measured ones once "
            "placed: is it this robot's, with its joint zero at the encoder zero?"
        )
    lumps = tuple(
        Lump(k, R @ c + t, float(m))
        for k, c, m in zip(lm.moved_by, lm.centres, lm.masses, strict=True)
    )
    return lumps, np.asarray(R @ np.array([0.0, 0.0, -1.0]), dtype=np.float64)


def deflections(
    ex: Extraction, Q_table: SampleArray, bare: SampleArray
) -> tuple[FloatArray, float, FloatArray]:
    """What the terms move at the samples, from the table's joint values with the terms
    (``Q_table``) and without (``bare``), both (m, n), a block at a time: the largest deflection
    per joint (rad or m), of the target (m), and up to 2000 samples' target and its move (k, 6;
    m, in M)."""
    m, n = Q_table.shape[0], Q_table.shape[1]
    T = ex.T_measurement_base

    def moves(at: slice | NDArray[np.intp]) -> tuple[FloatArray, FloatArray, FloatArray]:
        q, q0 = Q_table[at], bare[at]
        reached = fk_points_chunked(ex.standard, q, ex.tool_point, T_base=T)
        moved = reached - fk_points_chunked(ex.standard, q0, ex.tool_point, T_base=T)
        return np.abs(q - q0), reached, moved

    deflection_max, target = np.zeros(n), 0.0
    for sl in blocks(m):
        dq, _, moved = moves(sl)
        deflection_max = np.maximum(deflection_max, np.max(dq, axis=0, initial=0.0))
        target = max(target, float(np.max(np.linalg.norm(moved, axis=1), initial=0.0)))
    pick = np.unique(np.linspace(0, m - 1, min(2000, m)).astype(np.intp))
    _, reached, moved = moves(pick)
    return deflection_max, target, np.column_stack([reached, moved])
