"""The identification's stage values and its result, each frozen.

:func:`dhlog.identify.run.process_data` composes the stages:

1. the session segmented and its joints fitted one by one (:class:`Session`);
2. the fit of the whole model (:class:`ModelFit`, :mod:`dhlog.identify.wholefit`), which carries
   what is read off it (:class:`Readout`: the table, its uncertainty, the terms) and its checks
   (:class:`Checks`: the FK check of every sample, the outliers, the cross-validation) — or,
   with ``--analytic-only`` or without encoders, the analytic :class:`Readout` and
   :class:`Checks` alone;
3. the one :class:`ProcessResult` built from them, which the document, the console, the
   recording and the API read.

A stage that fails is a value (None and a warning), not a field restored by hand.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note, texts
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.fitting import PlaneFit
from dhlog.identify.camera.report import CameraResult
from dhlog.identify.check.footing import Unscored
from dhlog.identify.check.holdout import Holdout
from dhlog.identify.check.validate import Validation
from dhlog.identify.fit.register import Registration
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.joints.sweeps import JointReport, samples_with_encoders
from dhlog.identify.model.beyond import Deflection
from dhlog.identify.model.select import ModelRequest, Selection
from dhlog.identify.read.conditioning import Conditioned
from dhlog.identify.read.extract import Extraction, Tolerances
from dhlog.identify.read.hayati import HayatiRow
from dhlog.identify.read.uncertainty import Uncertainty
from dhlog.identify.segment.persample import PerSample
from dhlog.identify.segment.segment import Segmentation
from dhlog.identify.segment.timing import Timing
from dhlog.io.dhfile import DHModel
from dhlog.io.reader import LogData
from dhlog.model.noise import NoiseModel
from dhlog.model.terms import Terms, table_deflection
from dhlog.vision.view import CameraView


@dataclass(frozen=True)
class Session:
    """The session as the whole-model fit starts from it: the log, its segmentation (joined
    again at the fitted clock offset, when it moved), each joint's report, the reference pose,
    the base plane, the nominal, the joints parked, the clock, the noise model, the target's
    start (m, in M; None before the analytic start) and the samples with every encoder value
    as read once (``encoded``: :func:`~dhlog.identify.joints.sweeps.samples_with_encoders` of
    the segmentation; :meth:`samples` reads them again when not given)."""

    log: LogData
    segmentation: Segmentation
    joints: tuple[JointReport, ...]
    reference_pose: FloatArray
    base: PlaneFit | None
    nominal: DHModel | None
    parked: tuple[int, ...]
    timing: Timing | None
    noise: NoiseModel
    target: FloatArray | None = None
    encoded: tuple[NDArray[np.intp], PerSample, PerSample] | None = None

    def samples(self) -> tuple[NDArray[np.intp], PerSample, PerSample]:
        """The rows of the segmentation with every encoder value, their encoder values (m, n)
        and points (m, 3)."""
        if self.encoded is not None:
            return self.encoded
        return samples_with_encoders(self.segmentation)


@dataclass(frozen=True)
class FitRequest:
    """What the run asks of the fit of the whole model: K of the cross-validation (0: none), the
    terms beyond the geometry, encoder scales, the σ within which pairs are held parallel (None:
    decided from held-out poses) and the extraction's tolerances."""

    folds: int
    model: ModelRequest
    fit_scales: bool
    parallel_sigma: float | None
    tolerances: Tolerances


@dataclass(frozen=True)
class Readout:
    """The DH model read off the fit of the whole model: the extraction (the table, the base,
    the tool), its uncertainty (covariance, σ, what is fixed, the well-conditioned forms), the
    target, and the terms beyond the geometry in the table's frames with their σ and what they
    move at the samples (None without terms). A partial result (a joint not identified) has its
    extraction alone, if any: no uncertainty, no target."""

    extraction: Extraction | None
    uncertainty: Uncertainty | None = None
    target: FloatArray | None = None
    terms: Terms | None = None
    terms_std: FloatArray = field(default_factory=lambda: np.zeros(0))
    deflection: Deflection | None = None

    def fields(self) -> dict[str, Any]:
        """:class:`ProcessResult`'s fields it sets."""
        moved, none = self.deflection, np.zeros(0)
        known = {} if self.uncertainty is None else self.uncertainty.result_fields()
        return {
            "extraction": self.extraction,
            **known,
            "target": self.target,
            "terms": self.terms,
            "terms_std": self.terms_std,
            "deflection_max": none if moved is None else moved.joints,
            "deflection_target": 0.0 if moved is None else moved.target,
            "deflection_max_std": none if moved is None else moved.joints_std,
            "deflection_target_std": 0.0 if moved is None else moved.target_std,
            "deflection_vectors": np.zeros((0, 6)) if moved is None else moved.vectors,
        }


@dataclass(frozen=True)
class Checks:
    """The result checked: forward kinematics of the table at every sample, the outliers of the
    fit by name and by row in the segmentation's point table, the errors at poses not used to
    fit (the cross-validation)."""

    validation: Validation | None
    outlier_names: tuple[str, ...] = ()
    outlier_rows: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    holdout: tuple[Holdout, ...] = ()

    def fields(self) -> dict[str, Any]:
        """:class:`ProcessResult`'s fields it sets."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class ModelFit:
    """The fit of the whole model (:mod:`dhlog.identify.wholefit`): the segmentation and clock
    it was fitted on, the noise model, the terms chosen (the selection), the analytic start,
    the fit itself and its σ; what is read off it (:class:`Readout`) and its checks
    (:class:`Checks`); with the notes this stage adds (warnings and what a reader should know,
    in the order said)."""

    segmentation: Segmentation
    timing: Timing | None
    noise: NoiseModel
    selection: Selection | None
    analytic: Extraction | None
    whole: WholeFit
    sigma: float
    readout: Readout
    checks: Checks
    notes: tuple[Note, ...]
    method: str = "whole-model maximum likelihood"

    def fields(self) -> dict[str, Any]:
        """:class:`ProcessResult`'s fields this stage sets (its notes aside: they are added,
        not set)."""
        own = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if f.name not in ("readout", "checks", "notes")
        }
        return own | self.readout.fields() | self.checks.fields()

    @property
    def warnings(self) -> tuple[str, ...]:
        """The texts of its warnings, in order."""
        return texts(self.notes, "warning")

    @property
    def info(self) -> tuple[str, ...]:
        """The texts of its notes a reader should know (level ``info``), in order."""
        return texts(self.notes, "info")


@dataclass(frozen=True)
class ProcessResult:
    """Everything ``dhlog process`` found, ready to be written and shown: built once, from the
    stages' values (:class:`Session`, :class:`ModelFit`), and never changed after — a later step
    (the plausibility judgement, a held-out log) makes a new one with
    :func:`dataclasses.replace`."""

    path: str
    sha256: str
    log: LogData
    segmentation: Segmentation
    joints: tuple[JointReport, ...]
    reference_pose: FloatArray
    extraction: Extraction | None
    std: FloatArray | None
    base: PlaneFit | None
    target: FloatArray | None
    validation: Validation | None
    nominal: DHModel | None
    #: what the run said, in the order it said it: warnings (what may need action) and notes
    #: (what a reader should know but need not act on), each with its code
    #: (:class:`~dhlog.errors.Note`); ``warnings`` and ``info`` give their texts
    notes: tuple[Note, ...]
    covariance: FloatArray | None = None
    hayati: tuple[HayatiRow, ...] = ()
    hayati_std: tuple[FloatArray, ...] = ()
    method: str = "analytic"
    analytic: Extraction | None = None
    whole: WholeFit | None = None
    fixed: Mapping[int, str] = field(default_factory=dict)
    noise: NoiseModel = field(default_factory=NoiseModel)
    sigma: float | None = None
    extra_tool_points: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    extra_tool_std: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    tool_orientation: FloatArray | None = None
    tool_orientation_std: FloatArray | None = None
    conditioned: Conditioned | None = None
    timing: Timing | None = None
    #: the nominal placed on the points (sessions without sweeps: the fit's start)
    registration: Registration | None = None
    #: joints (0-based) parked in the session (:mod:`dhlog.identify.model.parked`)
    parked: tuple[int, ...] = ()
    #: errors at poses not used to fit: K-fold cross-validation, held-out logs
    holdout: tuple[Holdout, ...] = ()
    #: the whole-model fit's gross outliers by name (the export's point ids, else ``#k``)
    outlier_names: tuple[str, ...] = ()
    #: ... and their rows in the segmentation's point table
    outlier_rows: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    #: held-out logs given (``--validate``) but not scored, each with the reason
    not_scored: tuple[Unscored, ...] = ()
    #: K of the K-fold cross-validation asked for (0: none)
    folds: int = 0
    #: the terms beyond the geometry asked for, the candidates tried, and the chosen terms in
    #: the table's frames (:func:`dhlog.model.terms.to_table`) with their σ
    model_request: ModelRequest = field(default_factory=ModelRequest)
    selection: Selection | None = None
    terms: Terms | None = None
    terms_std: FloatArray = field(default_factory=lambda: np.zeros(0))
    #: the terms' largest deflection per joint (rad or m) and of the target (m) at the samples
    deflection_max: FloatArray = field(default_factory=lambda: np.zeros(0))
    deflection_target: float = 0.0
    #: their σ at the sample where each is largest (NaN: a term it needs is undetermined)
    deflection_max_std: FloatArray = field(default_factory=lambda: np.zeros(0))
    deflection_target_std: float = 0.0
    #: up to 2000 samples: the target where the model puts it and the terms' share of that
    #: (k, 6: position, displacement; m, in M)
    deflection_vectors: FloatArray = field(default_factory=lambda: np.zeros((0, 6)))
    #: a camera calibration's product (:class:`~dhlog.identify.camera.report.CameraResult`: the
    #: set-up, the camera's and the board's poses with σ, the corners' σ, the held-out check in
    #: pixels) and what the recording shows of each camera; None and empty for a tracker log
    camera: CameraResult | None = None
    cameras: tuple[CameraView, ...] = ()
    #: with several cameras, each one's product (``camera`` is the first's)
    camera_results: tuple[CameraResult, ...] = ()
    #: a camera calibration's start (the tracker's run on the board's poses): the set-up those
    #: poses were made for; None for a tracker log
    camera_setup: str | None = None
    #: why dhlog judges this result implausible, one sentence each naming the evidence and the
    #: fix (a suspected joint permutation or unit slip, a validation session no footing could
    #: place, ...); empty when plausible. The result is still written, marked ``plausible: false``
    #: in the JSON, and ``dhlog process`` exits with ``EXIT_IMPLAUSIBLE`` (4)
    implausible: tuple[str, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """The texts of the warnings, what may need action (the JSON's ``warnings``), in
        order."""
        return texts(self.notes, "warning")

    @property
    def info(self) -> tuple[str, ...]:
        """The texts of the notes a reader should know but need not act on (the method
        chosen, forms shown: the JSON's ``notes``), in order."""
        return texts(self.notes, "info")

    def said(self, *notes: Note) -> ProcessResult:
        """This result with ``notes`` added after its own."""
        return replace(self, notes=(*self.notes, *notes))

    @property
    def complete(self) -> bool:
        """True when every joint was identified."""
        return all(j.ok for j in self.joints)

    @property
    def failed(self) -> list[JointReport]:
        """The joints that could not be identified."""
        return [j for j in self.joints if not j.ok]


def table_values_of(
    whole: WholeFit | None,
    extraction: Extraction | None,
    terms: Terms | None,
    Q: FloatArray,
    *,
    deflected: bool = True,
) -> FloatArray:
    """The table's joint values at encoder values ``Q`` (m, n): ``ref + s (Q − ref)`` with the
    fit's encoder scales, deflected by the terms beyond the geometry when there are any (and
    ``deflected``)."""
    Qt = Q
    if whole is not None and whole.layout.scale_at is not None:
        ref = whole.model.reference_pose
        Qt = ref + whole.model.scales * (Q - ref)
    if deflected and terms is not None and extraction is not None:
        Qt = Qt + table_deflection(extraction.standard, terms, Q, Qt)
    return np.asarray(Qt, dtype=np.float64)


def table_values(result: ProcessResult, Q: FloatArray, *, deflected: bool = True) -> FloatArray:
    """The result table's joint values at encoder values ``Q`` (m, n)
    (:func:`table_values_of`)."""
    return table_values_of(result.whole, result.extraction, result.terms, Q, deflected=deflected)
