"""The identification's stage values and its result, each frozen.

:func:`dhlog.identify.run.process_data` composes the stages:

1. the session segmented and its joints fitted one by one (:class:`Session`);
2. the fit of the whole model (:class:`ModelFit`, :mod:`dhlog.identify.wholefit`), which carries
   what is read off it (:class:`Readout`: the table, its uncertainty, the terms) and its checks
   (:class:`Checks`: the FK check of every sample, the outliers, the cross-validation) — or,
   with ``--analytic-only`` or without encoders, the analytic :class:`Readout` and
   :class:`Checks` alone;
3. the one :class:`Identification` built from them, which the document, the console, the
   recording and the API read.

A stage that fails is a value (None and a warning), not a field restored by hand.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import Note, texts
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.fitting import PlaneFit
from dhlog.identify.check.footing import Unscored
from dhlog.identify.check.holdout import Holdout
from dhlog.identify.check.validate import Validation
from dhlog.identify.fit.register import Registration
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.joints.sweeps import JointReport, samples_with_encoders
from dhlog.identify.model.beyond import Deflection
from dhlog.identify.model.select import ModelRequest, Selection
from dhlog.identify.read.analytic import JointAxes
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

if TYPE_CHECKING:  # a camera's product: typed, without loading OpenCV for a tracker's run
    from dhlog.vision.report import CameraResult
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

    def axes(self, tolerances: Tolerances) -> JointAxes:
        """Its joints' axes as the seed method reads them (:class:`JointAxes`: with the
        reference pose, the base plane, the nominal's table), with ``tolerances``."""
        table = None if self.nominal is None else self.nominal.table
        return JointAxes(self.joints, self.reference_pose, self.base, table, tolerances)


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


@dataclass(frozen=True)
class Checks:
    """The result checked: forward kinematics of the table at every sample, the outliers of the
    fit by name and by row in the segmentation's point table, the errors at poses not used to
    fit (the cross-validation)."""

    validation: Validation | None
    outlier_names: tuple[str, ...] = ()
    outlier_rows: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    holdout: tuple[Holdout, ...] = ()


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
    sigma: float | None
    readout: Readout
    checks: Checks
    notes: tuple[Note, ...]
    method: str = "whole-model maximum likelihood"

    @property
    def warnings(self) -> tuple[str, ...]:
        """The texts of its warnings, in order."""
        return texts(self.notes, "warning")

    @property
    def info(self) -> tuple[str, ...]:
        """The texts of its notes a reader should know (level ``info``), in order."""
        return texts(self.notes, "info")


@dataclass(frozen=True)
class Identification:
    """Everything ``dhlog process`` found, ready to be written and shown: built once from the
    stages' values — the :class:`Session`, the :class:`ModelFit` (None: the analytic result
    alone), its :class:`Readout` and :class:`Checks` — and never changed after: a later step
    (the plausibility judgement, a held-out log, the camera's pixel fit) makes a new one with
    :func:`dataclasses.replace`. What readers take of the stages (the table, its σ, the FK
    check …) are properties of the stage that holds them."""

    path: str
    sha256: str
    #: the session (its encoder values as read not kept: ``encoded`` None)
    session: Session
    readout: Readout
    checks: Checks
    #: what the run said, in the order it said it: warnings (what may need action) and notes
    #: (what a reader should know but need not act on), each with its code
    #: (:class:`~dhlog.errors.Note`); ``warnings`` and ``info`` give their texts. The fit's
    #: own notes are among them (the ``fit`` kept here carries none)
    notes: tuple[Note, ...]
    #: the fit of the whole model; None for the analytic result (``--analytic-only``, no
    #: encoders, a fit that failed)
    fit: ModelFit | None = None
    #: the nominal placed on the points (sessions without sweeps: the fit's start)
    registration: Registration | None = None
    #: held-out logs given (``--validate``) but not scored, each with the reason
    not_scored: tuple[Unscored, ...] = ()
    #: K of the K-fold cross-validation asked for (0: none)
    folds: int = 0
    #: the terms beyond the geometry asked for (the candidates tried and the terms chosen are
    #: the fit's ``selection`` and the readout's ``terms``)
    model_request: ModelRequest = field(default_factory=ModelRequest)
    #: a camera calibration's product (:class:`~dhlog.vision.report.CameraResult`: the
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

    # the session's (the fit's segmentation, clock and noise where there is a fit: the session
    # joined again at the fitted clock offset)

    @property
    def log(self) -> LogData:
        return self.session.log

    @property
    def joints(self) -> tuple[JointReport, ...]:
        return self.session.joints

    @property
    def reference_pose(self) -> FloatArray:
        return self.session.reference_pose

    @property
    def base(self) -> PlaneFit | None:
        return self.session.base

    @property
    def nominal(self) -> DHModel | None:
        return self.session.nominal

    @property
    def parked(self) -> tuple[int, ...]:
        """Joints (0-based) parked in the session (:mod:`dhlog.identify.model.parked`)."""
        return self.session.parked

    @property
    def segmentation(self) -> Segmentation:
        return self.session.segmentation if self.fit is None else self.fit.segmentation

    @property
    def timing(self) -> Timing | None:
        return self.session.timing if self.fit is None else self.fit.timing

    @property
    def noise(self) -> NoiseModel:
        return self.session.noise if self.fit is None else self.fit.noise

    # the fit's

    @property
    def method(self) -> str:
        return "analytic" if self.fit is None else self.fit.method

    @property
    def whole(self) -> WholeFit | None:
        return None if self.fit is None else self.fit.whole

    @property
    def analytic(self) -> Extraction | None:
        """The analytic start of the fit (None without a fit: ``extraction`` is the analytic
        result then)."""
        return None if self.fit is None else self.fit.analytic

    @property
    def sigma(self) -> float | None:
        return None if self.fit is None else self.fit.sigma

    @property
    def selection(self) -> Selection | None:
        """The candidates of ``--model`` tried and the one chosen."""
        return None if self.fit is None else self.fit.selection

    # the readout's

    @property
    def extraction(self) -> Extraction | None:
        return self.readout.extraction

    @property
    def target(self) -> FloatArray | None:
        return self.readout.target

    @property
    def terms(self) -> Terms | None:
        """The chosen terms beyond the geometry in the table's frames
        (:func:`dhlog.model.terms.to_table`)."""
        return self.readout.terms

    @property
    def terms_std(self) -> FloatArray:
        return self.readout.terms_std

    @property
    def std(self) -> FloatArray | None:
        known = self.readout.uncertainty
        return None if known is None else known.std

    @property
    def covariance(self) -> FloatArray | None:
        known = self.readout.uncertainty
        return None if known is None else known.covariance

    @property
    def fixed(self) -> Mapping[int, str]:
        known = self.readout.uncertainty
        return {} if known is None else known.fixed

    @property
    def hayati(self) -> tuple[HayatiRow, ...]:
        known = self.readout.uncertainty
        return () if known is None else tuple(known.hayati)

    @property
    def hayati_std(self) -> tuple[FloatArray, ...]:
        known = self.readout.uncertainty
        return () if known is None else tuple(known.hayati_std)

    @property
    def conditioned(self) -> Conditioned | None:
        known = self.readout.uncertainty
        return None if known is None else known.conditioned

    @property
    def tool_orientation(self) -> FloatArray | None:
        known = self.readout.uncertainty
        return None if known is None else known.tool_orientation

    @property
    def tool_orientation_std(self) -> FloatArray | None:
        known = self.readout.uncertainty
        return None if known is None else known.tool_orientation_std

    @property
    def extra_tool_points(self) -> FloatArray:
        known = self.readout.uncertainty
        return np.zeros((0, 3)) if known is None else known.extra_tool_points

    @property
    def extra_tool_std(self) -> FloatArray:
        known = self.readout.uncertainty
        return np.zeros((0, 3)) if known is None else known.extra_tool_std

    @property
    def deflection_max(self) -> FloatArray:
        """The terms' largest deflection per joint (rad or m) at the samples."""
        moved = self.readout.deflection
        return np.zeros(0) if moved is None else moved.joints

    @property
    def deflection_target(self) -> float:
        """The terms' largest deflection of the target (m) at the samples."""
        moved = self.readout.deflection
        return 0.0 if moved is None else moved.target

    @property
    def deflection_max_std(self) -> FloatArray:
        """The σ of ``deflection_max`` at the sample where each is largest (NaN: a term it
        needs is undetermined)."""
        moved = self.readout.deflection
        return np.zeros(0) if moved is None else moved.joints_std

    @property
    def deflection_target_std(self) -> float:
        moved = self.readout.deflection
        return 0.0 if moved is None else moved.target_std

    @property
    def deflection_vectors(self) -> FloatArray:
        """Up to 2000 samples: the target where the model puts it and the terms' share of that
        (k, 6: position, displacement; m, in M)."""
        moved = self.readout.deflection
        return np.zeros((0, 6)) if moved is None else moved.vectors

    # the checks'

    @property
    def validation(self) -> Validation | None:
        """The FK check of the table at every sample."""
        return self.checks.validation

    @property
    def holdout(self) -> tuple[Holdout, ...]:
        """Errors at poses not used to fit: K-fold cross-validation, held-out logs."""
        return self.checks.holdout

    @property
    def outlier_names(self) -> tuple[str, ...]:
        """The whole-model fit's gross outliers by name (the export's point ids, else ``#k``)."""
        return self.checks.outlier_names

    @property
    def outlier_rows(self) -> NDArray[np.intp]:
        """... and their rows in the segmentation's point table."""
        return self.checks.outlier_rows

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

    def said(self, *notes: Note) -> Identification:
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


def table_values(result: Identification, Q: FloatArray, *, deflected: bool = True) -> FloatArray:
    """The result table's joint values at encoder values ``Q`` (m, n)
    (:func:`table_values_of`)."""
    return table_values_of(result.whole, result.extraction, result.terms, Q, deflected=deflected)
