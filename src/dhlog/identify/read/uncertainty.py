"""The DH model's uncertainty, by either path: its covariance (:func:`state_vector` order,
4n + 9), each parameter's σ, what is fixed and why, and the shown form of nearly parallel pairs
(Hayati–Mirmirani rows, :mod:`dhlog.identify.read.conditioning`) with σ.

* :func:`analytic_uncertainty`: the analytic extraction's, by central differences of the
  extraction over each per-joint axis fit (:func:`propagate_analytic`).
* :func:`whole_uncertainty`: the whole-model fit's, carried through the extraction
  (:func:`propagate`), with the target frame's orientation and the further targets as tool
  points.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from dhlog.errors import Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.fitting import PlaneFit
from dhlog.geometry.lines import Line
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.read.analytic import (
    JointAxes,
    hayati_rows,
    near_parallel,
    propagate_analytic,
)
from dhlog.identify.read.conditioning import (
    Conditioned,
    conditioned,
    correlation_notes,
    near_parallel_pairs,
    nominal_rows,
)
from dhlog.identify.read.extract import Extraction
from dhlog.identify.read.hayati import HayatiRow
from dhlog.identify.read.propagate import Extractor, fixed_reasons, propagate
from dhlog.model.dh import StandardDH


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """The DH model's covariance, each parameter's σ (NaN where fixed), why the fixed ones are
    held, the Hayati–Mirmirani rows of nearly parallel pairs (with their σ from the whole-model
    fit), the table with those rows (None without them), and from the whole-model fit the
    target frame's orientation and the further targets as tool points, with σ."""

    covariance: FloatArray
    std: FloatArray
    fixed: dict[int, str]
    hayati: list[HayatiRow]
    conditioned: Conditioned | None
    hayati_std: list[FloatArray] = field(default_factory=list)
    tool_orientation: FloatArray | None = None
    tool_orientation_std: FloatArray | None = None
    extra_tool_points: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    extra_tool_std: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    #: the σ of the shown table (4n: θ, d or β, a, α; NaN where fixed), from the whole-model fit
    shown_std: FloatArray | None = None
    #: what a reader should know of it: the nearly parallel pairs given in the Hayati form
    #: (``hayati``), the free parameters strongly correlated (``correlated``)
    notes: tuple[Note, ...] = ()


def analytic_uncertainty(
    fitted: JointAxes,
    target: FloatArray,
    target_cov: FloatArray,
    analytic: Extraction,
    target_of: Callable[[list[Line | None]], FloatArray] | None,
) -> Uncertainty:
    """The uncertainty of the ``analytic`` extraction of the ``fitted`` axes
    (:func:`propagate_analytic`: ``target`` with its covariance ``target_cov``, ``target_of``
    the target for other axes), of its table in the Hayati form where pairs are nearly parallel
    (said in its notes), and what the extraction's conventions fix."""
    joints, ref, base, nominal = fitted.joints, fitted.reference_pose, fitted.base, fitted.nominal
    rows = hayati_rows(analytic)
    nominal_h = nominal_rows(nominal, ref, rows)
    covariance, mixed_cov = propagate_analytic(
        fitted, target, target_cov, analytic, target_of, rows, nominal_h
    )
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    fixed = std < 1e-12
    reasons = fixed_reasons(
        analytic, fixed, base_plane=base is not None, nominal=nominal is not None
    )
    std = np.where(fixed, np.nan, std)
    hayati, notes = near_parallel([j.axis for j in joints], analytic, std, nominal)
    held = None
    if mixed_cov is not None:
        mixed_std = np.sqrt(np.clip(np.diag(mixed_cov), 0.0, None))
        held = conditioned(analytic, rows, nominal_h, mixed_std, mixed_std < 1e-12, reasons)
    return Uncertainty(covariance, std, reasons, hayati, held, notes=notes)


def whole_uncertainty(
    whole: WholeFit,
    base: PlaneFit | None,
    extract: Extractor,
    ex: Extraction,
    ref: FloatArray,
    nominal: StandardDH | None,
) -> Uncertainty:
    """The uncertainty of ``ex``, the DH model ``extract`` reads off the ``whole`` fit
    (:func:`propagate`), of its table in the Hayati form where pairs are nearly parallel, and what
    is fixed: by the extraction's conventions, by the relations the fit holds, or not determined
    by the poses. Said in its notes: the nearly parallel pairs, the free parameters correlated
    beyond :data:`~dhlog.identify.read.conditioning.CORRELATION_WARNING`."""
    pairs = near_parallel_pairs(ex)
    h_rows = hayati_rows(ex)
    nominal_h = nominal_rows(nominal, ref, h_rows)
    prop = propagate(whole, base, extract, ex, pairs, h_rows, nominal_h, nominal)
    std = np.sqrt(np.clip(np.diag(prop.covariance), 0.0, None))
    std = np.where(prop.fixed, np.nan, std)
    reasons = fixed_reasons(
        ex,
        prop.fixed,
        base_plane=base is not None,
        nominal=nominal is not None,
        constrained=whole.constrained,
        undetermined=prop.undetermined,
        unseen=whole.held,
    )
    hayati, said = near_parallel(list(ex.axes), ex, std, nominal)
    hayati_std = [
        np.sqrt(np.clip(np.diag(prop.hayati_covariance)[4 * k : 4 * k + 4], 0.0, None))
        for k in range(len(pairs))
    ]
    held = None
    if prop.mixed_covariance is not None and prop.mixed_fixed is not None:
        mixed_std = np.sqrt(np.clip(np.diag(prop.mixed_covariance), 0.0, None))
        held = conditioned(
            ex,
            h_rows,
            nominal_h,
            mixed_std,
            prop.mixed_fixed,
            {**reasons, **whole.held},
            prop.mixed_undetermined,
        )
    shown_std = std[: 4 * ex.standard.n]
    if prop.mixed_covariance is not None:
        shown_std = np.sqrt(np.clip(np.diag(prop.mixed_covariance), 0.0, None))
        if prop.mixed_fixed is not None:
            shown_std = np.where(prop.mixed_fixed, np.nan, shown_std)
    extra_std = np.sqrt(np.clip(np.diag(prop.extra_tool_covariance), 0.0, None)).reshape(-1, 3)
    return Uncertainty(
        prop.covariance,
        std,
        reasons,
        hayati,
        held,
        hayati_std,
        prop.tool_orientation,
        prop.tool_orientation_std,
        prop.extra_tool_points,
        extra_std,
        shown_std,
        (*said, *correlation_notes(prop.covariance, prop.fixed, ex.standard.n)),
    )
