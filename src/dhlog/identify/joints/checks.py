"""What the log and the fits say of the run's inputs before anything is believed: a length or
angle unit slipped (stop, naming the pipeline key that fixes it), a nominal or reference pose of
another robot, a joint whose fit is far noisier than the others, residuals the declared noise
model does not explain."""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np

from dhlog.errors import InputError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.joints.sweeps import JointReport
from dhlog.identify.segment.segment import BLOCK, Segmentation
from dhlog.identify.segment.timing import SweepPhase
from dhlog.io.dhfile import DHModel
from dhlog.io.reader import LogData
from dhlog.model.noise import NoiseModel

#: Target samples spanning more (m) than this are not of a robot: a length unit slipped.
LARGEST_ROBOT = 100.0
#: ... nor less than this (m), with sweeps found.
SMALLEST_ROBOT = 0.005
#: What makes residuals exceed the noise, in the order a metrologist checks them.
LIKELY_CAUSES = (
    "likely causes: a clock offset between tracker and joint states (set clock_offset, or let "
    "dhlog estimate it), a joint of the wrong type, a joint that gives under load (compliance), "
    "or a target that slipped on the flange"
)
#: A joint's fit RMS this many times the median of all joints' is worth a warning.
RMS_OUTLIER = 3.0


def check_fit_noise(joints: Sequence[JointReport]) -> tuple[Note, ...]:
    """A warning (``fit-noise``) for each joint whose fit RMS is far above the other joints'
    (the same tracker measured them all), naming the likely causes."""
    rms = {j.index: j.fit.rms for j in joints if j.fit is not None and j.ok}
    if len(rms) < 3:
        return ()
    typical = float(np.median(list(rms.values())))
    return tuple(
        Note.warning(
            f"joint {j.index} ({j.name}): its fit RMS {r * 1e3:.4f} mm is "
            f"{r / typical:.1f}x the joints' median ({typical * 1e3:.4f} mm); {LIKELY_CAUSES}.",
            "fit-noise",
        )
        for j in joints
        if (r := rms.get(j.index)) is not None and typical > 0 and r > RMS_OUTLIER * typical
    )


def _span(column: FloatArray) -> float:
    """``nanmax - nanmin`` of a column, a block at a time (NaN when all are NaN)."""
    lo, hi = math.inf, -math.inf
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN blocks
        for start in range(0, column.size, BLOCK):
            part = column[start : start + BLOCK]
            lo, hi = min(lo, float(np.nanmin(part))), max(hi, float(np.nanmax(part)))
    return hi - lo if lo <= hi else math.nan


def check_units(seg: Segmentation, log: LogData, phases: list[SweepPhase]) -> tuple[Note, ...]:
    """Stop on a unit slip the geometry shows, naming the pipeline key and the value that
    fits: target samples spanning more than :data:`LARGEST_ROBOT` or less than
    :data:`SMALLEST_ROBOT`, or a joint whose samples turn (move) by 1/57.3, 57.3, 10⁻³ or 10³
    per encoder unit; a warning (``encoder-slope``) for any other encoder slope far from 1."""
    pipe = log.pipeline
    columns = seg.xyz_columns
    extent = float(np.linalg.norm([_span(c) for c in columns])) if seg.height else 0
    where = f"{log.path}: the target's samples span {extent:.4g} m"
    if extent > LARGEST_ROBOT:
        fits = "mm" if pipe.length_unit == "m" else "a unit 1000x smaller than mm"
        raise InputError(
            f"{where}, far more than any robot: the log's lengths look like {fits} read as "
            f"'{pipe.length_unit}'; set length_unit = \"mm\" in the pipeline ({pipe.source})."
        )
    if 0 < extent < SMALLEST_ROBOT and seg.segments.height:
        raise InputError(
            f"{where}, less than any robot's sweeps: the lengths look like metres read as "
            f"'{pipe.length_unit}'; set length_unit = \"m\" in the pipeline ({pipe.source})."
        )
    slips = {
        math.pi / 180.0: ("look like degrees", 'set angle_unit = "deg" in the pipeline'),
        180.0 / math.pi: ("look like radians", 'set angle_unit = "rad" in the pipeline'),
        1e-3: ("look like millimetres", 'set length_unit = "mm" and declare the type prismatic'),
        1e3: ("look like metres", 'set length_unit = "m" and declare the type prismatic'),
    }
    notes: list[Note] = []
    by_joint: dict[int, list[float]] = {}
    for p in phases:
        by_joint.setdefault(p.joint, []).append(abs(p.slope))
    for joint, slopes in sorted(by_joint.items()):
        r = float(np.median(slopes))
        name = seg.joint_names[joint - 1]
        for ratio, (looks, fix) in slips.items():
            if abs(r / ratio - 1.0) < 0.1:
                raise InputError(
                    f"{log.path}: joint {joint} ({name}): the target turns (moves) {r:.4g} per "
                    f"encoder unit: its encoder values {looks}; {fix} ({pipe.source})."
                )
        if not 0.8 < r < 1.25:
            notes.append(
                Note.warning(
                    f"joint {joint} ({name}): the target turns (moves) {r:.4g} per encoder "
                    "unit, not 1: check the joint's unit, type and name order in the pipeline.",
                    "encoder-slope",
                )
            )
    return tuple(notes)


def check_sizes(
    name: str, n: int, nominal: DHModel | None, reference_pose: FloatArray | None
) -> None:
    """Stop when the nominal or the reference pose is not of the log's ``n`` joints."""
    if nominal is not None and nominal.table.n != n:
        raise InputError(
            f"{nominal.source}: the nominal table has {nominal.table.n} joints but {name} "
            f"has {n}; give the nominal of this robot."
        )
    if reference_pose is not None and np.asarray(reference_pose).shape != (n,):
        raise InputError(
            f"--reference-pose has {np.asarray(reference_pose).size} values but {name} has {n} "
            "joints; give one value per joint."
        )


#: Beyond these the inputs, not the robot, are wrong (:mod:`dhlog.identify.check.plausible`
#: judges by them): the nominal placed on the points missing them by more than NOMINAL_SLIP
#: (m, RMS 3-D; a real robot's published nominal, its base and tool fitted, misses by a few
#: mm: 1 mm for the KR5 sample, 8 mm for the 165-kg FANUC R-2000iC of ../shared/realdata), the
#: calibrated model by more than FIT_SLIP (m, FK RMS 3-D, the figure without a nominal, whose
#: own miss is the measure otherwise; a calibration with a tracker leaves a fraction of a mm:
#: 0.5 mm on that FANUC), or a model-error σ above MODEL_ERROR_SLIP (m per coordinate).
NOMINAL_SLIP = 0.02
FIT_SLIP = 2e-3
MODEL_ERROR_SLIP = 1e-3
#: What makes a calibration miss its points by centimetres.
LIKELY_SLIPS = (
    "likely slips: joint values in the wrong unit (radians read as degrees or the reverse: "
    "--joint-angle-unit of dhlog import, angle_unit in the pipeline), lengths in the wrong unit "
    "(--length-unit, length_unit), joints in the wrong order or of the wrong sign "
    "(--joint-columns, the pipeline's joint names), or the nominal of another robot (--nominal)"
)


def check_noise_model(noise: NoiseModel, chi2_dof: float) -> tuple[Note, ...]:
    """A warning (``noise-model``) when a declared noise model (not the isotropic σ found from
    the residuals) is contradicted by the whole-model fit's χ²/dof."""
    declared = noise.model != "isotropic" or noise.sigma is not None
    if not declared or 0.5 < chi2_dof < 2.0:
        return ()
    causes = f" ({LIKELY_CAUSES})" if chi2_dof >= 2.0 else " (the model's σ is too large)"
    return (
        Note.warning(
            f"χ²/dof = {chi2_dof:.2f} under the {noise.described} noise model: the "
            f"residuals contradict it{causes}; the uncertainty is scaled by the residuals.",
            "noise-model",
        ),
    )
