"""What a camera calibration checks of its input: frames whose corners share their error
(:func:`frame_clustered`), a board of another size than the pipeline's (:func:`board_scale`), a
camera that moved (:func:`camera_moved`), and the set-up the nominal fits
(:func:`placed_nominal_px`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.identify.camera.frames.observations import Observations
from dhlog.identify.camera.pixels import Corners, PixelFit, PixelModel
from dhlog.identify.camera.poses import corners_of
from dhlog.identify.check.plausible import SCALE_MIN_LENGTH as SCALE_MIN_LENGTH
from dhlog.identify.check.plausible import common_scale
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.read.extract import Extraction
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import StandardDH

if TYPE_CHECKING:  # the run's result, which this module's checks read (stages is above it)
    from dhlog.identify.stages import Identification

#: Below this design effect the corners of a frame are taken as independent (σ within 5 %).
SMALL_EFFECT = 1.1


def frame_clustered(fit: PixelFit, frame: NDArray[np.intp]) -> tuple[PixelFit, tuple[Note, ...]]:
    """``fit`` with every covariance times the design effect of corners grouped by frame,
    where it reaches :data:`SMALL_EFFECT` (said in a note, ``frame-clustered``): a frame's
    corners share part of their error (the detector's, the image's: blur, exposure, a board's
    print), which the corners' scatter about the model does not show as independent. ``effect`` =
    1 + (k̄ − 1) ρ, k̄ the corners a frame, ρ the share of the residual variance common to a
    frame's corners (as the tracker's design effect of samples a pose, identify.variance)."""
    use = fit.inliers & np.all(np.isfinite(fit.residuals), axis=1)
    r, f = fit.residuals[use], frame[use]
    n = r.shape[0]
    frames = np.unique(f)
    g = frames.size
    if g == 0 or n < 2 * g:
        return fit, ()
    _, local = np.unique(f, return_inverse=True)
    count = np.bincount(local).astype(np.float64)
    sums = np.column_stack([np.bincount(local, weights=r[:, k]) for k in range(r.shape[1])])
    squares = float(np.sum(r**2))
    between = float(np.sum(np.sum(sums**2, axis=1) / count))
    d = r.shape[1]
    # one-way analysis of variance over the frames: the frames' mean squares against the
    # corners' within them, F-tested (at 99.9 %: independent corners give F about 1, a bit
    # under it as the fit takes up part of each frame's mean); where significant, the
    # frames' share of the variance ρ = σ_b² / (σ_b² + σ_w²), σ_b² = (MSB − MSW) / k̄
    from scipy.stats import f as f_dist

    msb = between / (d * g)
    msw = (squares - between) / (d * (n - g))
    if msw <= 0 or msb / msw <= float(f_dist.ppf(0.999, d * g, d * (n - g))):
        return fit, ()
    k_bar = n / g
    sigma_b2 = (msb - msw) / k_bar
    rho = sigma_b2 / (sigma_b2 + msw)
    effect = 1.0 + (k_bar - 1.0) * rho
    if effect < SMALL_EFFECT:
        return fit, ()
    said = (
        f"{n} corners in {g} frames ({n / g:.1f} a frame) share their frame's error "
        f"({rho:.0%} of the residual variance): the uncertainty is scaled by the design "
        f"effect, σ ×{math.sqrt(effect):.2f}."
    )
    whole = replace(fit.whole, covariance=fit.whole.covariance * effect)
    own = None if fit.own_covariance is None else fit.own_covariance * effect
    scaled = replace(
        fit, whole=whole, own_covariance=own, full_covariance=fit.full_covariance * effect
    )
    return scaled, (Note.info(said, "frame-clustered"),)


#: A camera measures lengths in units of the board's squares: the robot's lengths (d, a of at
#: least :data:`~dhlog.identify.check.plausible.SCALE_MIN_LENGTH`) coming out this far from the
#: nominal's by one common factor mean the pipeline's board size is not the printed one's.
SCALE_TOLERANCE = 0.01


def board_scale(
    ex: Extraction, nominal: StandardDH | None, obs: Observations, fixed: set[int]
) -> str | None:
    """Why a calibration whose lengths are the nominal's times one factor k ≠ 1 (by more than
    :data:`SCALE_TOLERANCE`: :func:`~dhlog.identify.check.plausible.common_scale`) is
    implausible: a camera cannot tell a board k times larger seen k times further, so the
    pipeline's ``[target]`` size is then most likely not the printed board's. ``fixed``: the
    table's entries (4 a row: θ, d, a, α) held by convention, left out. None otherwise."""
    if nominal is None:
        return None
    k = common_scale(ex.standard, nominal, fixed)
    if k is None or abs(k - 1.0) <= SCALE_TOLERANCE:
        return None
    b = obs.board
    return (
        f"the robot's lengths come out {k:.4f} times the nominal's, all of them: a camera "
        f"measures in units of the board, so the board is most likely not the "
        f"{b.square_m * 1e3:g} mm squares the pipeline's [target] says but about "
        f"{b.square_m * 1e3 / k:.1f} mm: measure the printed board and give its square_m "
        "(and marker_m)."
    )


#: Splits of the frames (shares of them, in time order) the moved-camera test places the
#: calibrated model on each side of, and the fewest frames a side needs.
MOVED_SPLITS = (0.25, 0.5, 0.75)


MOVED_MIN_FRAMES = 8


#: The drop of the cost (in σ², over the corners) that placing the model separately on each
#: side of a split must exceed to call the fixed part moved: 12 more parameters give a χ² of
#: 12 ± 5 when nothing moved.
MOVED_DROP = 100.0


#: The camera's fit missing the corners this many times the RMS each frame's board alone is
#: placed to: the frames disagree beyond the corners' noise (read with the camera info's other
#: reading, the simulator's small camera's rectified images: 0.36 against 0.095 px; its raw
#: images 0.061 against 0.061).
FRAMES_DISAGREE = 2.0


def frames_disagree(
    obs: Observations, pnp_rms: FloatArray, used: NDArray[np.bool_], fit_rms: float
) -> str | None:
    """A warning where the whole model misses the corners by :data:`FRAMES_DISAGREE` times the
    RMS of the boards placed frame by frame (``pnp_rms`` per frame, pooled over the frames
    ``used``), else None."""
    counts = np.array([ids.size for ids in obs.ids], dtype=np.float64)
    ok = used & np.isfinite(pnp_rms)
    if not np.any(ok):
        return None
    pooled = math.sqrt(float(np.sum(counts[ok] * pnp_rms[ok] ** 2) / np.sum(counts[ok])))
    if not fit_rms > FRAMES_DISAGREE * pooled:
        return None
    return (
        f"{obs.camera}: the whole model misses the corners by {fit_rms:.3g} px RMS, "
        f"{fit_rms / pooled:.1f}× the {pooled:.3g} px each frame's board alone is placed to "
        "(PnP): the frames disagree beyond the corners' noise. Intrinsics that are not the "
        "images' (rectified images read with K and D, or raw ones with P: the pipeline's "
        "[camera] rectified), a camera or board that moved during the session, or a robot the "
        "model does not describe do this; check them."
    )


def camera_moved(
    fit: PixelFit, data: Corners, obs: Observations, ex: Extraction, ref: FloatArray
) -> str | None:
    """A warning when the fixed part (the camera eye-to-hand, the board eye-in-hand) moved
    during the session, else None: the calibrated table placed (its measurement's
    :meth:`~dhlog.identify.fit.measure.Measurement.place`: the fixed part's pose and the mount)
    separately on the frames before and after a split (in time order) explains the corners
    better than one placement by more than :data:`MOVED_DROP` σ². The best of
    :data:`MOVED_SPLITS`, then narrowed by halving between its neighbours, names the frames it
    moved between."""
    from dhlog.identify.fit.measure import residuals as measured

    order = np.argsort(obs.t_ns, kind="stable")
    f = data.frames
    if f < 2 * MOVED_MIN_FRAMES:
        return None
    assert fit.whole.model.tool_rotation is not None
    R_tool = ex.frames[-1][:3, :3].T @ fit.whole.model.tool_rotation
    start = (ex.standard, ref, ex.T_measurement_base, ex.tool_point, R_tool)
    sigma2 = fit.sigma**2
    limit2 = fit.whole.limit**2

    def truncated(r: FloatArray) -> float:  # a corner behind the camera (NaN) costs the limit
        return float(np.sum(np.minimum(np.nan_to_num(np.sum(r**2, axis=1), nan=limit2), limit2)))

    def cost(placed: tuple[AxisModel, PixelModel], corners: Corners) -> float:
        return truncated(measured(placed[0], placed[1], corners))

    whole = truncated(fit.residuals)

    def drop(k: int) -> float:
        before = np.zeros(f, dtype=bool)
        before[order[:k]] = True
        sides = [data.of_frames(before), data.of_frames(~before)]
        placed = [fit.measurement.place(*start, c) for c in sides]
        return (whole - sum(cost(p, c) for p, c in zip(placed, sides, strict=True))) / sigma2

    splits = sorted(
        {round(q * f) for q in MOVED_SPLITS}
        & set(range(MOVED_MIN_FRAMES, f - MOVED_MIN_FRAMES + 1))
    )
    if not splits:
        return None
    found = {k: drop(k) for k in splits}
    best = max(found, key=lambda k: found[k])
    if found[best] <= MOVED_DROP:
        return None
    lo = max([k for k in splits if k < best], default=MOVED_MIN_FRAMES)
    hi = min([k for k in splits if k > best], default=f - MOVED_MIN_FRAMES)
    while hi - lo > 2:  # the cost drop peaks at the move: halve towards the larger side
        a, b = (lo + best) // 2, (best + hi) // 2
        for k in (a, b):
            if MOVED_MIN_FRAMES <= k <= f - MOVED_MIN_FRAMES and k not in found:
                found[k] = drop(k)
        if found.get(a, -math.inf) > found[best]:
            hi, best = best, a
        elif found.get(b, -math.inf) > found[best]:
            lo, best = best, b
        else:
            lo, hi = a, b
    first, after = int(obs.frame[order[best - 1]]), int(obs.frame[order[best]])
    part = "camera" if fit.measurement.setup == "eye-to-hand" else "board"
    return (
        f"the {part} moved during the session, between frames {first} and {after} of "
        f"{obs.camera} (placing the model apart on the frames before and after explains the "
        f"corners better by {found[best]:.0f} σ²): the calibration mixes two set-ups; "
        f"calibrate from one part with --frames :{after} or --frames {after}:."
    )


#: A placement of the nominal whose corners' robust scale is this or more (px) found no pose
#: near them (the wrong set-up: hundreds of px); a nominal a few mm off its robot misses by ~1 px.
FAR_PX = 20.0


def placed_nominal_px(start: Identification, nominal: DHModel | None, obs: Observations) -> float:
    """:func:`placed_nominal`'s RMS (px)."""
    return placed_nominal(start, nominal, obs)[0]


def placed_nominal(
    start: Identification, nominal: DHModel | None, obs: Observations
) -> tuple[float, AxisModel | None]:
    """How well the nominal, placed on the corners in pixels
    (:meth:`~dhlog.identify.camera.pixels.PixelModel.place`: the fixed part's pose and the mount,
    its geometry held) from ``start``'s placement for its set-up, reproduces them: the RMS (px).
    The set-up a log was recorded in lets the nominal fit to about its own error; the other
    needs the chain's mirror image, which no placement gives (sweeps from one home pose fit
    either set-up by a free fit: each move is one joint's turn, about a line fixed in both the
    camera's and the board's frame). inf without a nominal or a start. Returns the RMS and the
    placed model (None: none)."""
    from dhlog.identify.fit.measure import residuals as measured
    from dhlog.identify.fit.measure import rms

    whole, ex, setup = start.whole, start.extraction, start.camera_setup
    if nominal is None or whole is None or ex is None or whole.model.tool_rotation is None:
        return math.inf, None
    if setup is None:  # not a camera's start
        return math.inf, None
    data = corners_of(obs, np.ones(obs.frames, dtype=bool))
    # two places to start from: the start's own (its table's base and mount) and the nominal
    # registered on the PnP poses (robust; the start's may be poor where its fit was): the better
    starts = [
        (ex.T_measurement_base, ex.tool_point, ex.frames[-1][:3, :3].T @ whole.model.tool_rotation)
    ]
    registered = _registered(start, nominal)
    if registered is not None:
        starts.append(registered)
    best: tuple[float, AxisModel | None] = (math.inf, None)
    for T_mb, tool, R_tool in starts:
        try:
            model, meas = PixelModel(setup, obs.intrinsics).place(
                nominal.table, start.reference_pose, T_mb, tool, R_tool, data, far=FAR_PX
            )
        except (DhlogError, ValueError, np.linalg.LinAlgError):
            continue
        value = rms(measured(model, meas, data))
        if math.isfinite(value) and value < best[0]:
            best = (value, model)
    return best


def _registered(
    start: Identification, nominal: DHModel
) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """The nominal registered on the start's PnP poses (its log: positions and orientations of
    the carried frame at the frames' joint values): frame 1 in M, the carried frame's origin and
    orientation on the flange (the mean over the frames); None where it cannot be."""
    from scipy.spatial.transform import Rotation

    from dhlog.identify.fit.register import register_nominal
    from dhlog.io.decode.frames import ORIENTATION_COLUMNS
    from dhlog.model.fk import fk_frames

    log = start.log
    if log.joints is None:
        return None
    Q = log.joints.select([c for c in log.joints.columns if c != "t_ns"]).to_numpy()
    P = log.points.select(["x", "y", "z"]).to_numpy()
    if Q.shape[0] != P.shape[0] or not all(c in log.points.columns for c in ORIENTATION_COLUMNS):
        return None
    try:
        reg = register_nominal(nominal.table, Q, P)
    except DhlogError:
        return None
    R_meas = Rotation.from_quat(log.points.select(list(ORIENTATION_COLUMNS)).to_numpy())
    R_flange = reg.T_measurement_base[:3, :3] @ fk_frames(nominal.table, Q)[:, -1, :3, :3]
    rel = Rotation.from_matrix(np.transpose(R_flange, (0, 2, 1))) * R_meas
    return reg.T_measurement_base, reg.tool_point, rel.mean().as_matrix()
