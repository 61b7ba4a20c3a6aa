"""What a run is asked (:class:`ProcessOptions`), one frozen value built once — by ``dhlog
process`` through :func:`dhlog.process`, a batch's job, a plan — and read by every stage."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import ANGLE_TOL, DISTANCE_TOL
from dhlog.identify.model.select import AUTO, ModelRequest
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import Pipeline


@dataclass(frozen=True)
class ProcessOptions:
    """What a run is asked, built once (by ``dhlog process``, :func:`dhlog.process`, a batch's
    job or a plan) and read by every stage.

    ``nominal``: the robot's nominal model (its conventions, joint names, the start of joints
    never moved alone); ``reference_pose``: the pose the DH table is read at (None: the
    session's); ``fit_method``: the per-joint circle fit; ``angle_tol`` (rad), ``distance_tol``
    (m): when the extraction calls axes parallel or meeting; ``analytic_only``: the seed method's
    result alone; ``fit_scales``: encoder scales fitted; ``parallel_sigma``: None, nearly
    parallel pairs held where that does not raise the error at held-out poses; K, those within
    K σ (0: never); ``holdout`` K > 1: K-fold cross-validation over the session's poses;
    ``model``: the terms beyond the geometry to try or force; ``known_noise``: the tracker's σ
    (m) where it is known rather than measured (a plan). Reading the log: ``pipeline`` (None:
    the log's own), ``fast`` (the column decoders), ``validate`` (further logs scored on one
    footing), and a camera log's ``camera_setup``, ``refine_intrinsics``, ``jobs`` and
    ``frames`` (the range of frames on the image topic, end excluded)."""

    nominal: DHModel | None = None
    reference_pose: FloatArray | None = None
    fit_method: str = "auto"
    angle_tol: float = ANGLE_TOL
    distance_tol: float = DISTANCE_TOL
    analytic_only: bool = False
    fit_scales: bool = False
    parallel_sigma: float | None = None
    holdout: int = 0
    model: ModelRequest = AUTO
    known_noise: float | None = None
    pipeline: Pipeline | None = None
    fast: bool = True
    validate: tuple[str | Path, ...] = ()
    camera_setup: str | None = None
    refine_intrinsics: bool = False
    jobs: int = 1
    frames: tuple[int | None, int | None] | None = None


#: A run asked nothing beyond the defaults.
DEFAULTS = ProcessOptions()
