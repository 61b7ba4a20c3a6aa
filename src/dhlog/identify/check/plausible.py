"""What makes dhlog judge a tracker calibration implausible (``Identification.implausible``):
its lengths all one factor times the nominal's (a unit slip, :func:`length_slip`), or its FK
check far above both the noise and the nominal's own miss of the same points
(:func:`fk_beyond`). Each finding is one sentence naming the evidence and the fix; the result is
still written, marked ``plausible: false``, and ``dhlog process`` exits 4.

The nominal's own miss is the nominal placed on the session's points (base and tool fitted:
:func:`~dhlog.identify.fit.register.register_nominal`), its RMS: what the robot's real
geometry leaves against its published one. A calibration fits the same points with every
freedom the nominal has and more, so it misses them by less; one that misses them by far more
than the nominal does — and by far more than the noise — was fitted to inputs read wrong.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import GeometryError, Note
from dhlog.identify.fit.register import register_nominal
from dhlog.identify.joints.checks import FIT_SLIP, LIKELY_SLIPS, MODEL_ERROR_SLIP, NOMINAL_SLIP
from dhlog.identify.joints.sweeps import samples_with_encoders, target_labels
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import StandardDH

#: The FK check is implausible beyond this many times the noise's 3-D RMS (√3 σ) ...
FAR_NOISE = 10.0
#: ... and this many times the nominal's own miss of the same points (both must hold), or,
#: whatever the nominal misses by, beyond NOMINAL_SLIP (joints/checks.py: more than any robot's
#: nominal misses its points by, so no calibration may leave it).
FAR_NOMINAL = 2.0
#: The robot's lengths (a, d) of at least this (m) in the nominal enter the common factor.
SCALE_MIN_LENGTH = 0.05
#: A tracker measures in its own unit: lengths all one factor k off the nominal's by more than
#: this (|k − 1|, each length within a quarter of that of k) are not a robot's errors (a few
#: mm on hundreds) but a unit slip, or the nominal of another robot.
LENGTH_SLIP = 0.05
#: The samples the nominal is placed on for its own miss (evenly strided; its RMS to a few %:
#: 0.4336 mm on the kr5_real sample in 0.04 s, 0.4343 mm from 2000 in 0.8 s).
MISS_SAMPLES = 500
#: Units lengths slip between, metres each.
UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "inches": 0.0254, "feet": 0.3048}


def common_scale(table: StandardDH, nominal: StandardDH, fixed: set[int]) -> float | None:
    """The factor k > 0 when every length of ``table`` (d and a of at least
    :data:`SCALE_MIN_LENGTH` in the ``nominal``, not held by convention: ``fixed`` holds the
    table's entries, 4 a row θ, d, a, α) is k times the nominal's in size, each ratio within a
    quarter of ``|k − 1|`` of k; None when fewer than two lengths count or the ratios
    disagree."""
    n = table.n
    got = np.concatenate([table.d_offset, table.a])
    ref = np.concatenate([nominal.d_offset, nominal.a])
    free = np.array(
        [4 * i + 1 not in fixed for i in range(n)] + [4 * i + 2 not in fixed for i in range(n)]
    )
    use = (np.abs(ref) >= SCALE_MIN_LENGTH) & free
    if np.count_nonzero(use) < 2:
        return None
    ratio = np.abs(got[use]) / np.abs(ref[use])  # the sizes: a sign is a DH branch, not a unit
    k = float(np.median(ratio))
    if not math.isfinite(k) or np.max(np.abs(ratio - k)) > 0.25 * abs(k - 1.0):
        return None
    return k


def unit_pair(k: float) -> tuple[str, str] | None:
    """The units (written in, read as) whose ratio is ``k`` within 2 %: lengths written in the
    first and read as the second come out ``k`` times their size (0.03937: inches read as mm)."""
    for read, r in UNITS.items():
        for written, w in UNITS.items():
            if read != written and abs(k * w / r - 1.0) < 0.02:
                return written, read
    return None


def length_slip(table: StandardDH, nominal: DHModel, fixed: set[int]) -> str | None:
    """The reason a table whose lengths are all k times the nominal's (``|k − 1|`` beyond
    :data:`LENGTH_SLIP`) is implausible, naming the units k is the ratio of; None otherwise."""
    k = common_scale(table, nominal.table, fixed)
    if k is None or abs(k - 1.0) <= LENGTH_SLIP:
        return None
    pair = unit_pair(k)
    if pair is not None:
        written, read = pair
        why = (
            f"the log's lengths look like {written} read as {read} (or the nominal's like "
            f"{read} read as {written}): give the log's length unit (length_unit in the "
            "pipeline, --length-unit of dhlog import) or the nominal's (units in its DH file)"
        )
    else:
        why = (
            "the nominal is likely of another robot, or the log's lengths in another unit: "
            "check --nominal and the log's length unit (length_unit, --length-unit)"
        )
    return (
        f"the calibrated lengths are all {k:.4g} times the nominal's ({nominal.source}): a robot "
        f"is not {k:.3g} times its nominal; {why}."
    )


def inlier_picks(seg: Any, rows: NDArray[np.intp], whole: Any, count: int) -> NDArray[np.intp]:
    """Up to ``count`` of the session's samples with encoder values (indices into ``rows``,
    evenly strided): the whole-model fit's inliers (``whole``, when it judged these rows) of
    the primary target — what the nominal is placed on to measure its own miss. Strided
    first, so no array of every sample is made."""
    m = rows.size
    pick = np.arange(0, m, max(1, m // (4 * count)))
    keep = np.ones(pick.size, dtype=bool)
    if whole is not None and whole.inliers.shape[0] == m:
        keep &= np.asarray(whole.inliers[pick], dtype=bool)
    which = target_labels(seg, rows)
    if which is not None:
        keep &= which[pick] == 0
    pick = pick[keep]
    return pick[:: max(1, pick.size // count)]


def nominal_miss(result: Any) -> float | None:
    """The nominal's own miss of the session's points (m, RMS over the registration's inliers):
    the registration the run made (a session without sweeps), else the nominal placed on up to
    :data:`MISS_SAMPLES` of the whole-model fit's inlier samples of the primary target. None
    without a nominal, without encoder values, or when the poses cannot place it."""
    if result.registration is not None:
        return float(result.registration.rms)
    nominal, seg = result.nominal, result.segmentation
    if nominal is None or not seg.has_encoders:
        return None
    rows, Q, P = samples_with_encoders(seg)
    if rows.size < 3:
        return None
    pick = inlier_picks(seg, rows, result.whole, MISS_SAMPLES)
    try:
        reg = register_nominal(
            nominal.table,
            nominal.joint_values(Q[pick]),
            P[pick],
            tool_point=nominal.tool_point,
            T_base=nominal.T_base,
        )
    except (GeometryError, np.linalg.LinAlgError):
        return None
    return float(reg.rms)


def noise_rms(result: Any) -> float | None:
    """The tracker's noise as a 3-D RMS (m, √3 σ) from what measures it apart from the model:
    the sharpest per-joint circle fit's σ (the tracker is no noisier than its sharpest joint's
    points lie on their circle; joints misjoined by a clock or read wrong show millimetres
    there, and their mean would hide an FK check as far off), else the pipeline's declared σ;
    None when neither exists."""
    sigmas = [j.fit.sigma for j in result.joints if j.fit is not None]
    if sigmas:
        return math.sqrt(3.0) * float(min(sigmas))
    declared = result.noise.sigma
    return None if declared is None else math.sqrt(3.0) * float(declared)


def fk_beyond(fk_rms: float, noise: float | None, miss: float | None) -> str | None:
    """The reason an FK check (RMS, m) is implausible: beyond :data:`FAR_NOISE` times the noise
    (3-D RMS, m; None: unknown) and beyond :data:`FAR_NOMINAL` times the nominal's own miss
    (m; None: no nominal), or beyond :data:`NOMINAL_SLIP` whatever the nominal misses by; None
    otherwise."""
    if not math.isfinite(fk_rms):
        return None
    if noise is not None and fk_rms <= FAR_NOISE * noise:
        return None
    ceiling = NOMINAL_SLIP if miss is None else min(FAR_NOMINAL * miss, NOMINAL_SLIP)
    if fk_rms <= ceiling:
        return None
    limit_mm = f"{NOMINAL_SLIP * 1e3:.0f}"
    said = [f"the calibrated model misses its points by {fk_rms * 1e3:.1f} mm (FK RMS)"]
    if noise is not None:
        said.append(f"{fk_rms / noise:.0f} times the noise ({noise * 1e3:.3f} mm, 3-D)")
    if miss is None:
        said.append(f"more than any robot's nominal misses its points by ({limit_mm} mm)")
    elif miss > NOMINAL_SLIP:
        said.append(
            f"and the nominal placed on them misses by {miss * 1e3:.1f} mm, more than any "
            f"robot's nominal does ({limit_mm} mm)"
        )
    else:
        said.append(
            f"{fk_rms / miss:.1f} times the nominal's own miss ({miss * 1e3:.2f} mm): a "
            "calibration fits its points better than its nominal does"
        )
    return f"{', '.join(said)}; the inputs are likely read wrong — {LIKELY_SLIPS}."


def slip_notes(
    miss: float | None, fk_rms: float, model_error: float | None, explained: bool
) -> list[str]:
    """The warning of what a run's misses say of its inputs short of an implausible result:
    the nominal's own miss beyond :data:`NOMINAL_SLIP` (no robot's nominal misses by so much);
    without a nominal, the FK check beyond :data:`FIT_SLIP` (the one figure there is to compare
    with); a model-error σ (m per coordinate) beyond :data:`MODEL_ERROR_SLIP` whose 3-D size
    (√3 σ) exceeds the nominal's miss too. ``explained``: the result is already implausible
    for a reason naming the slip, so the misses are not said again. Empty when none holds."""
    found = []
    if miss is not None and miss > NOMINAL_SLIP and not explained:
        found.append(f"the nominal placed on the points misses them by {miss * 1e3:.1f} mm (RMS)")
    if miss is None and fk_rms > FIT_SLIP and not explained:
        found.append(f"the calibrated model misses them by {fk_rms * 1e3:.1f} mm (FK RMS)")
    if model_error is not None and model_error > MODEL_ERROR_SLIP and not explained:
        if miss is None or math.sqrt(3.0) * model_error > miss:
            found.append(f"the model-error σ is {model_error * 1e3:.2f} mm per coordinate")
    if not found:
        return []
    return [
        f"{'; '.join(found)}: far more than any robot leaves (a few mm before calibration, "
        f"less after); the inputs are likely read wrong — {LIKELY_SLIPS}."
    ]


def judge(result: Any) -> Any:
    """A tracker run's ``Identification`` with what makes it implausible added to its
    ``implausible`` — lengths all k times the nominal's (:func:`length_slip`), an FK check far
    above the noise and the nominal's own miss (:func:`fk_beyond`) — and to its warnings what
    the misses say short of that (:func:`slip_notes`)."""
    ex, nominal, val = result.extraction, result.nominal, result.validation
    named = bool(result.implausible)  # a cause already named (a joint permutation): said once
    if ex is None or not result.complete:
        return result
    implausible = list(result.implausible)
    if nominal is not None and nominal.table.n == ex.standard.n:
        said = length_slip(ex.standard, nominal, set(result.fixed))
        if said is not None:
            implausible.append(said)
    if val is None:
        return replace(result, implausible=tuple(implausible))
    miss = nominal_miss(result) if nominal is not None else None
    beyond = fk_beyond(val.rms, noise_rms(result), miss)
    if beyond is not None and not named:
        implausible.append(beyond)
    slips = slip_notes(miss, val.rms, result.noise.model_error, bool(implausible))
    told = tuple(Note.warning(slip, "input-slip") for slip in slips)
    return replace(result, implausible=tuple(implausible), notes=(*result.notes, *told))
