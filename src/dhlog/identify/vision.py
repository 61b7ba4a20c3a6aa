"""A camera calibration: from a camera's detected board corners to the DH model, the camera's
pose (the hand-eye calibration) and the error at held-out frames (issue 32).

1. Each frame's board pose in the camera by OpenCV's PnP (:func:`board_poses`).
2. Those poses are a 6-DoF target's samples: the board's centre and orientation in the camera
   (eye-to-hand), or the camera's in the board's frame (eye-in-hand). The tracker's run
   (:func:`dhlog.identify.run.process_data`, the geometric model) makes its start from them:
   the seed method where joints were swept alone, the nominal placed on them otherwise.
3. The whole model is fitted again to every corner in pixels (:mod:`dhlog.identify.pixels`):
   the maximum likelihood of the detections. Its DH table, covariance and fixed parameters are
   read off as for a tracker.
4. The camera's and the board's poses with their σ (:func:`hand_eye`), the FK check against
   the PnP poses (mm), and with ``holdout`` K the error at held-out frames in pixels and in mm
   (:func:`cross_validate_pixels`), the nominal placed on the same training frames.

The set-up (``eye-to-hand`` / ``eye-in-hand``) is the caller's, or decided by which one places
the nominal on the poses better.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np
import polars as pl
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from dhlog.errors import DhlogError, InputError
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line
from dhlog.identify.axismodel import AxisModel, ParameterLayout
from dhlog.identify.extract import Extraction, extract_dh
from dhlog.identify.leaveout import fold_of_poses
from dhlog.identify.measure import place
from dhlog.identify.pixels import CamerasModel, Corners, PixelFit, PixelModel, fit_pixels
from dhlog.identify.prediction import predict as predict_points
from dhlog.identify.prediction import predict_orientation
from dhlog.identify.select import ModelRequest
from dhlog.identify.uncertainty import whole_uncertainty
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import pipeline_by_name
from dhlog.io.reader import LogData
from dhlog.model.dh import StandardDH
from dhlog.vision.camera import Intrinsics
from dhlog.vision.observe import Observations
from dhlog.vision.view import CameraView, FrameView

#: the fewest frames with the board for a calibration
MIN_FRAMES = 8
#: the largest PnP reprojection RMS (px) a frame's pose may have to enter the start
PNP_RMS = 5.0


@dataclass
class PixelHoldout:
    """The error at frames not used to fit (K-fold over the frames' poses): reprojection RMS
    (px, per corner: the 2-D norm) of the nominal placed on the training frames and of the
    result; and the 3-D RMS (mm) of the board's corners in the camera between the model and
    the held-out frame's own PnP pose (the result's triangulation)."""

    folds: int
    frames: int
    nominal_px: float | None
    calibrated_px: float
    nominal_mm: float | None
    calibrated_mm: float
    fit_px: float
    #: the RMS the held-out frames' own PnP poses are expected to miss the corners by (their
    #: noise at the corners' σ, independent corners; mm): the floor of the mm figures
    pnp_noise_mm: float = math.nan
    #: the same mm figure in sample: the model fitted to every frame against the frames' PnP
    #: poses (what the PnP poses' own errors give when the model is not held out, correlated
    #: corner errors included)
    fit_mm: float = math.nan
    notes: list[str] = field(default_factory=list)

    @property
    def model_mm(self) -> float:
        """The calibrated mm figure with the PnP noise taken out (quadrature; 0 when within it)."""
        return math.sqrt(max(self.calibrated_mm**2 - self.pnp_noise_mm**2, 0.0))

    def document(self) -> dict[str, object]:
        return {
            "folds": self.folds,
            "frames": self.frames,
            "reprojection_rms_px": {"nominal": self.nominal_px, "calibrated": self.calibrated_px},
            "target_rms_mm": {
                "nominal": self.nominal_mm,
                "calibrated": self.calibrated_mm,
                "pnp_noise": _finite(self.pnp_noise_mm),
                "in_sample": _finite(self.fit_mm),
                "calibrated_beyond_noise": _finite(self.model_mm),
            },
            "in_sample_rms_px": self.fit_px,
            "notes": list(self.notes),
        }


@dataclass
class CameraResult:
    """One camera's product: the set-up, the intrinsics (held or refined, with σ), the fixed
    part's pose in the robot's base frame and the mounted part's on the flange (4×4, m) with
    their σ (rotation vector rad, translation m; 6 each), the corners' σ and RMS (px), the
    frames' tally, and the held-out check."""

    name: str
    setup: str
    intrinsics: Intrinsics
    intrinsics_refined: bool
    intrinsics_std: FloatArray | None
    T_base_fixed: FloatArray
    fixed_std: FloatArray
    T_flange_mounted: FloatArray
    mounted_std: FloatArray
    sigma_px: float
    rms_px: float
    frames: int
    corners: int
    inlier_corners: int
    tally: str
    setup_reason: str
    holdout: PixelHoldout | None = None

    @property
    def fixed_name(self) -> str:
        return "T_base_camera" if self.setup == "eye-to-hand" else "T_base_board"

    @property
    def mounted_name(self) -> str:
        return "T_flange_board" if self.setup == "eye-to-hand" else "T_flange_camera"

    def document(self) -> dict[str, object]:
        c = self.intrinsics
        return {
            "topic": self.name,
            "setup": self.setup,
            "setup_reason": self.setup_reason,
            self.fixed_name: self.T_base_fixed.tolist(),
            f"{self.fixed_name}_std": _std_doc(self.fixed_std),
            self.mounted_name: self.T_flange_mounted.tolist(),
            f"{self.mounted_name}_std": _std_doc(self.mounted_std),
            "intrinsics": {
                "width": c.width,
                "height": c.height,
                "K": c.K.tolist(),
                "distortion_model": c.model,
                "D": c.coefficients.tolist(),
                "refined": self.intrinsics_refined,
                "std": None if self.intrinsics_std is None else self.intrinsics_std.tolist(),
            },
            "corner_sigma_px": self.sigma_px,
            "reprojection_rms_px": self.rms_px,
            "frames": self.frames,
            "corners": self.corners,
            "inlier_corners": self.inlier_corners,
            "detections": self.tally,
            "holdout": None if self.holdout is None else self.holdout.document(),
        }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _std_doc(std: FloatArray) -> dict[str, list[float]]:
    return {"rotation_rad": std[:3].tolist(), "translation_m": std[3:].tolist()}


def _transform(R: FloatArray, t: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _shift(o: FloatArray) -> FloatArray:
    return _transform(np.eye(3), o)


# ---------------------------------------------------------------------------------------------
# PnP


def board_poses(obs: Observations, intrinsics: Intrinsics) -> tuple[FloatArray, FloatArray]:
    """Each frame's board pose in the camera (f, 4, 4) by OpenCV's PnP (IPPE for a planar
    board, refined by Levenberg–Marquardt), and its reprojection RMS (f,) px (NaN: failed)."""
    points = obs.board.object_points()
    f = obs.frames
    T = np.tile(np.eye(4), (f, 1, 1))
    rms = np.full(f, np.nan)
    fisheye = intrinsics.model == "equidistant"
    for k in range(f):
        obj = points[obs.ids[k]].astype(np.float64)
        uv = obs.uv[k].astype(np.float64).reshape(-1, 1, 2)
        if obj.shape[0] < 4:
            continue
        if fisheye:
            norm = cv2.fisheye.undistortPoints(uv, intrinsics.K, intrinsics.coefficients)
            K, D = np.eye(3), np.zeros(5)
            img = norm
        else:
            K, D, img = intrinsics.K, intrinsics.coefficients, uv
        try:
            ok, rvec, tvec = cv2.solvePnP(obj, img, K, D, flags=cv2.SOLVEPNP_IPPE)
            if not ok:
                continue
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, D, rvec, tvec)
        except cv2.error:
            continue
        R = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
        T[k] = _transform(R, np.asarray(tvec, dtype=np.float64).ravel())
        X = obj @ R.T + tvec.ravel()
        pred = intrinsics.project(X)
        rms[k] = float(np.sqrt(np.nanmean(np.sum((pred - obs.uv[k]) ** 2, axis=1))))
    return T, rms


def _pose_log(
    obs: Observations, T_cam_board: FloatArray, setup: str, use: NDArray[np.bool_]
) -> LogData:
    """The frames' poses as a 6-DoF target's log (the tracker run's input): the board's centre
    in the camera (eye-to-hand) or the camera in the board's centred frame (eye-in-hand)."""
    from dhlog.io.decode.frames import ORIENTATION_COLUMNS

    o = _centre(obs)
    T = T_cam_board[use] @ _shift(o)
    if setup == "eye-in-hand":
        T = np.asarray(np.linalg.inv(T), dtype=np.float64)
    quat = Rotation.from_matrix(T[:, :3, :3]).as_quat(canonical=True)
    t = obs.t_ns[use]
    points = pl.DataFrame({"t_ns": t, "x": T[:, 0, 3], "y": T[:, 1, 3], "z": T[:, 2, 3]})
    points = points.with_columns(
        pl.Series(name, quat[:, k]) for k, name in enumerate(ORIENTATION_COLUMNS)
    )
    # the joint values at each frame, as the encoders' stream: one sample at each frame's stamp
    q = obs.q[use]
    joints = pl.DataFrame({"t_ns": t, **{f"q_{j + 1}": q[:, j] for j in range(q.shape[1])}})
    base = pipeline_by_name("ros2_tracker")
    assert base is not None
    point = replace(base.streams["point"], orientation=True)
    # the encoders are known at the frames only: a joint's motion is judged over the frames
    # around each (1.5 frame intervals each side), not the tracker's 50 ms
    gaps = np.diff(t)
    spacing = float(np.median(gaps)) * 1e-9 if gaps.size else 0.0
    window = max(base.segmentation.motion_window, 1.5 * spacing)
    # and they were joined at each frame's stamp already (io.observe): no clock offset to find
    segmentation = replace(
        base.segmentation,
        motion_window=min(window, 3600.0),
        clock_offset=0.0,
        clock_offset_fixed=True,
    )
    pipe = replace(base, streams={**base.streams, "point": point}, segmentation=segmentation)
    return LogData(obs.path, pipe, points, joints, list(obs.joint_names), None, None)


def _centre(obs: Observations) -> FloatArray:
    """The board's centre in its frame (the carried frame's origin: better conditioned than
    a corner of the board)."""
    pts = obs.board.object_points()
    centre: FloatArray = np.asarray((pts.min(axis=0) + pts.max(axis=0)) / 2.0, dtype=np.float64)
    return centre


def corners_of(obs: Observations, use: NDArray[np.bool_]) -> Corners:
    """The pixel observations of the frames ``use``, the corners from the board's centre."""
    points = obs.board.object_points() - _centre(obs)
    frames = np.flatnonzero(use)
    ids = [obs.ids[k] for k in frames]
    counts = np.array([i.size for i in ids], dtype=np.intp)
    return Corners(
        obs.q[use],
        np.repeat(np.arange(frames.size, dtype=np.intp), counts),
        points[np.concatenate(ids)] if ids else np.zeros((0, 3)),
        np.vstack([obs.uv[k] for k in frames]) if ids else np.zeros((0, 2)),
    )


# ---------------------------------------------------------------------------------------------
# the run


def process_observations(
    observations: list[Observations],
    *,
    sha256: str = "",
    nominal: DHModel | None = None,
    reference_pose: FloatArray | None = None,
    setup: str | None = None,
    refine_intrinsics: bool = False,
    holdout: int = 0,
    frames: tuple[int | None, int | None] | None = None,
    progress: Callable[[str, float], None] | None = None,
    start: Callable[..., Any] | None = None,
    pipeline: str | None = None,
) -> Any:
    """The calibration of the module docstring from one camera's observations; returns the
    :class:`~dhlog.identify.run.ProcessResult` with its ``camera`` and ``cameras`` filled.
    ``start``: the tracker's run on the poses (:func:`dhlog.identify.run.process_data`, which
    ``identify.run.process_log`` passes: this module is below the run and never imports it)."""
    if start is None:  # the tracker's run makes the start (identify.run passes itself)
        raise ValueError("process_observations needs start= (identify.run.process_data)")
    process_data = start
    if not observations:
        raise InputError("the log holds no camera with detections.")
    obs = observations[0]
    if frames is not None:
        obs = of_frames(obs, frames)
    extra_cameras = [o.camera for o in observations[1:]]
    if obs.frames < MIN_FRAMES:
        raise InputError(
            f"{obs.path}: {obs.frames} frame(s) of {obs.camera} have the board and joint values "
            f"({obs.tally.summary()}); a calibration needs at least {MIN_FRAMES}: record more "
            "poses with the board in view."
        )
    T_cb, pnp_rms = board_poses(obs, obs.intrinsics)
    use = np.isfinite(pnp_rms) & (pnp_rms <= PNP_RMS)
    dropped = int(obs.frames - np.count_nonzero(use))
    notes: list[str] = list(obs.warnings)
    if dropped:
        bad = ", ".join(str(int(obs.frame[k])) for k in np.flatnonzero(~use)[:3])
        notes.append(
            f"{dropped} frame(s) left out of the start: the board's pose (PnP) misses its own "
            f"corners by more than {PNP_RMS} px there (frames {bad}"
            f"{', …' if dropped > 3 else ''}): false detections or wrong intrinsics."
        )
    if np.count_nonzero(use) < MIN_FRAMES:
        raise InputError(
            f"{obs.path}: only {int(np.count_nonzero(use))} frame(s) of {obs.camera} give the "
            f"board's pose within {PNP_RMS} px (median {np.nanmedian(pnp_rms):.2f} px): check the "
            "intrinsics (the CameraInfo topic or the pipeline's [camera] calibration) and the "
            "pipeline's [target] sizes."
        )
    model_request = ModelRequest(mode="geometric")
    candidates = [setup] if setup else ["eye-to-hand", "eye-in-hand"]
    if not setup and nominal is None:
        raise InputError(
            f"{obs.path}: the camera's set-up cannot be told without a nominal: pass "
            "--camera-setup eye-to-hand (the camera fixed, the board on the flange) or "
            "eye-in-hand (the camera on the flange), or --nominal."
        )
    starts: dict[str, Any] = {}
    for s in candidates:
        log = _pose_log(obs, T_cb, s, use)
        try:
            starts[s] = process_data(
                log,
                sha256=sha256,
                nominal=nominal,
                reference_pose=reference_pose,
                model=model_request,
                progress=progress,
            )
            starts[s].camera_setup = s
        except DhlogError as exc:
            if len(candidates) == 1:
                raise
            starts[s] = exc
    usable = {
        s: r
        for s, r in starts.items()
        if not isinstance(r, Exception) and r.whole is not None and r.validation is not None
    }
    if not usable:
        why = "; ".join(f"{s}: {r}" for s, r in starts.items() if isinstance(r, Exception))
        raise InputError(
            f"{obs.path}: no start for the pixel fit from the board's poses "
            f"({why or 'the whole-model fit failed'}): check --camera-setup and --nominal."
        )
    # a set-up the poses cannot fit is out (its FK check far beyond the other's); of the rest,
    # the one whose table is the nominal's: sweeps from one home pose fit either set-up (each
    # move is one joint's turn, about a line fixed in both the camera's and the board's frame),
    # but only the right one reads the nominal's table off them
    gap = {
        s: placed_nominal_px(r, nominal, obs) if len(usable) > 1 else math.nan
        for s, r in usable.items()
    }
    chosen = min(usable, key=lambda s: (gap[s], usable[s].validation.rms))
    if setup:
        reason = "given"
    else:
        said = "; ".join(
            f"{s}: the nominal placed on the corners misses them by {gap[s]:.3f} px RMS"
            for s in usable
        )
        reason = f"decided from the data ({said})"
    result = usable[chosen]
    if pipeline is not None:  # the camera pipeline read, not the poses' internal one
        result.log = replace(result.log, pipeline=replace(result.log.pipeline, name=pipeline))
    # what the start's run said is of the poses' fit (its noise, its pairs, its registration in
    # mm), not of the calibration: one line says how the start was made, the rest is the
    # pixel fit's
    swept = [j.index for j in result.joints if j.fit is not None]
    how = (
        f"the seed method on the sweeps of joint(s) {', '.join(map(str, swept))}"
        if swept
        else "the nominal placed on them"
    )
    result.info = [
        f"start: each frame's board pose (OpenCV PnP) as a 6-DoF target, the model from {how}; "
        "then the whole model fitted to every corner in pixels."
    ]
    result.warnings = [*notes, *(w for w in result.warnings if "never moved alone" in w)]
    fit = _pixel_stage(result, obs, T_cb, use, chosen, reason, refine_intrinsics, holdout, progress)
    if extra_cameras and chosen != "eye-to-hand":
        result.warnings.append(
            f"the log has {len(observations)} cameras; several are fitted together fixed in the "
            f"cell (eye-to-hand) only: this calibration used {obs.camera} alone "
            f"({', '.join(extra_cameras)} not used)."
        )
    elif extra_cameras:
        rest = [o if frames is None else of_frames(o, frames) for o in observations[1:]]
        _several_cameras(result, fit, [obs, *rest], holdout, progress)
    return result


def placed_nominal_px(start: Any, nominal: DHModel | None, obs: Observations) -> float:
    """How well the nominal, placed on the corners in pixels (:func:`~dhlog.identify.measure.place`:
    the fixed part's pose and the mount, its geometry held) from ``start``'s placement for its
    set-up, reproduces them: the RMS (px). The set-up a log was recorded in lets the nominal
    fit to about its own error; the other needs the chain's mirror image, which no placement
    gives (sweeps from one home pose fit either set-up by a free fit: each move is one joint's
    turn, about a line fixed in both the camera's and the board's frame). inf without a
    nominal or a start."""
    from dhlog.identify.measure import rms

    whole, ex = start.whole, start.extraction
    if nominal is None or whole is None or ex is None or whole.model.tool_rotation is None:
        return math.inf
    setup = start.camera_setup
    data = corners_of(obs, np.ones(obs.frames, dtype=bool))
    R_tool = ex.frames[-1][:3, :3].T @ whole.model.tool_rotation
    try:
        model, meas = place(
            nominal.table,
            start.reference_pose,
            ex.T_measurement_base,
            ex.tool_point,
            R_tool,
            PixelModel(setup, obs.intrinsics),
            data,
        )
    except (DhlogError, ValueError, np.linalg.LinAlgError):
        return math.inf
    from dhlog.identify.measure import residuals as measured

    value = rms(measured(model, meas, data))
    return value if math.isfinite(value) else math.inf


def of_frames(obs: Observations, frames: tuple[int | None, int | None]) -> Observations:
    """``obs`` with the frames whose index on the topic is in ``[first, end)`` only (None: from
    the first, to the last); the tally and kept images as they were."""
    first = -1 if frames[0] is None else frames[0]
    end = np.iinfo(np.int64).max if frames[1] is None else frames[1]
    keep = (obs.frame >= first) & (obs.frame < end)
    chosen = np.flatnonzero(keep)
    return replace(
        obs,
        t_ns=obs.t_ns[keep],
        frame=obs.frame[keep],
        q=obs.q[keep],
        ids=[obs.ids[k] for k in chosen],
        uv=[obs.uv[k] for k in chosen],
        warnings=[
            *obs.warnings,
            f"--frames {'' if frames[0] is None else frames[0]}:"
            f"{'' if frames[1] is None else frames[1]}: {chosen.size} of {obs.frames} frames "
            "with the board kept.",
        ],
    )


#: Below this design effect the corners of a frame are taken as independent (σ within 5 %).
SMALL_EFFECT = 1.1


def frame_clustered(fit: PixelFit, frame: NDArray[np.intp], info: list[str]) -> PixelFit:
    """``fit`` with every covariance times the design effect of corners grouped by frame,
    where it reaches :data:`SMALL_EFFECT` (said in ``info``): a frame's corners share part of
    their error (the detector's, the image's: blur, exposure, a board's print), which the
    corners' scatter about the model does not show as independent. ``effect`` =
    1 + (k̄ − 1) ρ, k̄ the corners a frame, ρ the share of the residual variance common to a
    frame's corners (as the tracker's design effect of samples a pose, identify.variance)."""
    use = fit.inliers & np.all(np.isfinite(fit.residuals), axis=1)
    r, f = fit.residuals[use], frame[use]
    n = r.shape[0]
    frames = np.unique(f)
    g = frames.size
    if g == 0 or n < 2 * g:
        return fit
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
        return fit
    k_bar = n / g
    sigma_b2 = (msb - msw) / k_bar
    rho = sigma_b2 / (sigma_b2 + msw)
    effect = 1.0 + (k_bar - 1.0) * rho
    if effect < SMALL_EFFECT:
        return fit
    info.append(
        f"{n} corners in {g} frames ({n / g:.1f} a frame) share their frame's error "
        f"({rho:.0%} of the residual variance): the uncertainty is scaled by the design "
        f"effect, σ ×{math.sqrt(effect):.2f}."
    )
    whole = replace(fit.whole, covariance=fit.whole.covariance * effect)
    own = None if fit.own_covariance is None else fit.own_covariance * effect
    return replace(
        fit, whole=whole, own_covariance=own, full_covariance=fit.full_covariance * effect
    )


def _adopt(
    result: Any, whole: Any
) -> tuple[Extraction, Any, Callable[[list[Line], FloatArray, Any], Extraction]]:
    """Put the pixel fit ``whole`` in ``result``: its DH model read off as for a tracker, the
    covariance and what is fixed, the FK check against the PnP poses. Returns the extraction,
    the uncertainty and the extraction's function."""
    from dhlog.identify.sweeps import samples_with_encoders
    from dhlog.identify.validate import validate_samples

    nominal = result.nominal
    nominal_table = nominal.table if nominal is not None else None
    ref = result.reference_pose
    types = tuple(whole.model.types)

    def extract(axes: list[Line], target: FloatArray, plane: Any) -> Extraction:
        return extract_dh(
            axes, types, target=target, reference_pose=ref, base_plane=plane, nominal=nominal_table
        )

    ex = extract(list(whole.model.axes), whole.model.target, None)
    said: list[str] = []
    found = whole_uncertainty(whole, None, extract, ex, ref, nominal_table, said)
    result.info.extend(said)
    result.method = "whole-model maximum likelihood"  # in pixels: the camera block says so
    result.extraction, result.whole = ex, whole
    result.covariance, result.std, result.fixed = found.covariance, found.std, found.fixed
    result.hayati, result.hayati_std = found.hayati, found.hayati_std
    result.conditioned = found.conditioned
    result.tool_orientation = found.tool_orientation
    result.tool_orientation_std = found.tool_orientation_std
    result.target = whole.model.target
    result.selection = None
    seg = result.segmentation
    rows, Q, P = samples_with_encoders(seg)
    # the table's joint values are the encoders' (no scales, no terms in a camera's fit)
    inl = np.ones(len(rows), dtype=bool)
    result.validation = validate_samples(seg, rows, Q, P, ex, inl, ex.tool_point[None])
    return ex, found, extract


def _pixel_stage(
    result: Any,
    obs: Observations,
    T_cb: FloatArray,
    use: NDArray[np.bool_],
    setup: str,
    reason: str,
    refine_intrinsics: bool,
    holdout: int,
    progress: Callable[[str, float], None] | None,
) -> PixelFit:
    """Refit ``result``'s whole model in pixels and put the DH model, σ and camera in it;
    returns the fit."""
    assert result.whole is not None
    if progress is not None:
        progress("fitting pixels", 0.0)
    data = corners_of(obs, np.ones(obs.frames, dtype=bool))
    measurement = PixelModel(setup, obs.intrinsics, refine=refine_intrinsics)
    fit = frame_clustered(
        fit_pixels(result.whole.model, measurement, data), data.frame, result.info
    )
    nominal = result.nominal
    nominal_table = nominal.table if nominal is not None else None
    ref = result.reference_pose
    ex, found, extract = _adopt(result, fit.whole)
    T_fixed, T_mounted, fixed_std, mounted_std = hand_eye(fit, extract, setup, _centre(obs))
    scaled = board_scale(ex, nominal_table, obs, set(found.fixed))
    if scaled is not None:
        result.warnings.insert(0, scaled)
    moved = camera_moved(fit, data, obs, ex, ref)
    if moved is not None:
        result.warnings.insert(0, moved)
    check = None
    if holdout > 1:
        if progress is not None:
            progress("cross-validating", 0.0)
        check = cross_validate_pixels(fit, data, obs, T_cb, holdout, nominal, ref)
    sigma_i = None
    if fit.own_covariance is not None:
        sigma_i = np.sqrt(np.clip(np.diag(fit.own_covariance), 0.0, None))
    cam = CameraResult(
        name=obs.camera,
        setup=setup,
        intrinsics=fit.measurement.intrinsics,
        intrinsics_refined=refine_intrinsics,
        intrinsics_std=sigma_i,
        T_base_fixed=T_fixed,
        fixed_std=fixed_std,
        T_flange_mounted=T_mounted,
        mounted_std=mounted_std,
        sigma_px=fit.sigma,
        rms_px=fit.rms,
        frames=obs.frames,
        corners=int(data.uv.shape[0]),
        inlier_corners=int(np.count_nonzero(fit.inliers)),
        tally=obs.tally.summary(),
        setup_reason=reason,
        holdout=check,
    )
    result.camera = cam
    result.sigma = None
    result.info.append(
        f"camera {obs.camera} ({setup}, {reason}): {cam.frames} frames, {cam.corners} corners "
        f"({cam.corners - cam.inlier_corners} held out as false detections); the whole model "
        f"fitted to the corners in pixels: σ {cam.sigma_px:.3f} px per coordinate. The FK "
        "check below is against the board's poses from PnP (mm), the fit's own is in pixels."
    )
    result.cameras = [camera_view(fit, data, obs, cam, check)]
    result.camera_results = [cam]
    return fit


def _several_cameras(
    result: Any,
    first: PixelFit,
    observations: list[Observations],
    holdout: int,
    progress: Callable[[str, float], None] | None,
) -> None:
    """Fit the whole model to every camera's corners at once (:class:`CamerasModel`: M the
    first camera's frame, each further camera's pose fitted with it), starting from the first
    camera's fit and each further camera placed by its frames' PnP poses against where that
    fit puts the board; every camera's pose in the base frame with σ, the held-out check
    over all frames, a view per camera."""
    from dhlog.identify.measure import fit_measured

    if progress is not None:
        progress("fitting cameras together", 0.0)
    model = first.whole.model
    centre = _centre(observations[0])
    layout = ParameterLayout.of(model.types, rotation=True)
    poses: list[FloatArray] = [np.eye(4)]
    for o in observations[1:]:
        T, pnp = board_poses(o, o.intrinsics)
        ok = np.isfinite(pnp) & (pnp <= PNP_RMS)
        if np.count_nonzero(ok) < 3:
            raise InputError(
                f"{o.path}: {o.camera} gives the board's pose in {int(np.count_nonzero(ok))} "
                "frame(s): too few to place it beside the first camera; record more frames it "
                "sees, or calibrate from one camera (--pipeline naming its topic)."
            )
        p, _ = predict_points(model, o.q[ok])
        R, _ = predict_orientation(model, o.q[ok], layout, model.bases())
        found = [
            _transform(R[:, :, f], p[f]) @ _shift(-centre) @ np.linalg.inv(T[ok][f])
            for f in range(int(np.count_nonzero(ok)))
        ]
        mean = Rotation.from_matrix(np.array([c[:3, :3] for c in found])).mean().as_matrix()
        poses.append(_transform(mean, np.median(np.array([c[:3, 3] for c in found]), axis=0)))
    data = _stacked(observations)
    measurement = CamerasModel(tuple(o.intrinsics for o in observations), tuple(poses))
    # the further cameras placed first, the model held and every corner in (their PnP start
    # misses by px, which the joint fit's outlier cut, judged mostly on the first camera's
    # corners, would hold out whole), then everything together
    held = np.zeros((ParameterLayout.of(model.types, rotation=True).size, 0))
    placed = fit_measured(model, measurement, data, within=held, threshold=math.inf)
    result.info = [line for line in result.info if "share their frame's error" not in line]
    fit = frame_clustered(fit_measured(model, placed.measurement, data), data.frame, result.info)
    ex, _, extract = _adopt(result, fit.whole)
    _, T_mounted, _, mounted_std = hand_eye(first, extract, "eye-to-hand", centre)
    cams_std = _cameras_std(fit, extract)
    base: FloatArray = np.asarray(np.linalg.inv(ex.T_measurement_base), dtype=np.float64)
    check = None
    if holdout > 1:
        if progress is not None:
            progress("cross-validating", 0.0)
        check = _cross_validate_cameras(fit, data, holdout, result.nominal, result.reference_pose)
    results = []
    views = []
    for k, o in enumerate(observations):
        at = data.camera == k
        res = fit.residuals[at]
        inl = fit.inliers[at]
        T_k = fit.measurement.poses[k]
        cam = CameraResult(
            name=o.camera,
            setup="eye-to-hand",
            intrinsics=o.intrinsics,
            intrinsics_refined=False,
            intrinsics_std=None,
            T_base_fixed=np.asarray(base @ T_k, dtype=np.float64),
            fixed_std=cams_std[k],
            T_flange_mounted=T_mounted,
            mounted_std=mounted_std,
            sigma_px=fit.sigma,
            rms_px=float(np.sqrt(np.mean(np.sum(res[inl] ** 2, axis=1)))) if inl.any() else 0.0,
            frames=o.frames,
            corners=int(np.count_nonzero(at)),
            inlier_corners=int(np.count_nonzero(inl)),
            tally=o.tally.summary(),
            setup_reason=result.camera.setup_reason if k == 0 else "the first camera's",
            holdout=check,
        )
        results.append(cam)
        own = corners_of(o, np.ones(o.frames, dtype=bool))
        sub = replace(first, residuals=res, whole=replace(first.whole, model=fit.whole.model))
        views.append(camera_view(sub, own, o, cam, check, T_base_M=base))
    result.camera, result.camera_results, result.cameras = results[0], results, views
    result.info.append(
        f"{len(observations)} cameras fitted together ({', '.join(o.camera for o in observations)}"
        f"): {int(data.uv.shape[0])} corners, σ {fit.sigma:.3f} px per coordinate; each "
        "camera's pose in the base frame with its σ in the camera blocks."
    )


def _stacked(observations: list[Observations]) -> Corners:
    """Every camera's corners in one :class:`Corners` (frames numbered across the cameras,
    each corner's camera)."""
    parts = [corners_of(o, np.ones(o.frames, dtype=bool)) for o in observations]
    offsets = np.cumsum([0] + [c.frames for c in parts[:-1]])
    return Corners(
        np.vstack([c.Q for c in parts]),
        np.concatenate([c.frame + off for c, off in zip(parts, offsets, strict=True)]).astype(
            np.intp
        ),
        np.vstack([c.points for c in parts]),
        np.vstack([c.uv for c in parts]),
        np.concatenate([np.full(c.uv.shape[0], k, dtype=np.intp) for k, c in enumerate(parts)]),
    )


def _cameras_std(
    fit: Any, extract: Callable[[list[Line], FloatArray, Any], Extraction]
) -> list[FloatArray]:
    """Each camera's pose in the base frame: its σ (rotation vector rad, translation m; 6) by
    central differences over every fitted parameter (the model's and the cameras' own)."""
    whole, meas = fit.whole, fit.measurement
    layout, model = whole.layout, whole.model
    k0 = layout.size
    bases = model.bases()

    def poses(d: FloatArray) -> list[FloatArray]:
        m = model.moved(d[:k0], layout, bases)
        T_base_M = np.linalg.inv(extract(list(m.axes), m.target, None).T_measurement_base)
        return [T_base_M @ T for T in meas.moved(d[k0:]).poses]

    zero = poses(np.zeros(fit.full_covariance.shape[0]))

    def vec(Ts: list[FloatArray]) -> FloatArray:
        out = []
        for T, T0 in zip(Ts, zero, strict=True):
            out.append(Rotation.from_matrix(T[:3, :3] @ T0[:3, :3].T).as_rotvec())
            out.append(T[:3, 3] - T0[:3, 3])
        return np.concatenate(out)

    cov = fit.full_covariance
    size = cov.shape[0]
    J = np.zeros((6 * len(zero), size))
    scale = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    for k in range(size):
        h = max(float(scale[k]), 1e-9)
        d = np.zeros(size)
        d[k] = h
        J[:, k] = (vec(poses(d)) - vec(poses(-d))) / (2 * h)
    std = np.sqrt(np.clip(np.diag(J @ cov @ J.T), 0.0, None))
    return [std[6 * k : 6 * k + 6] for k in range(len(zero))]


def _cross_validate_cameras(
    fit: Any, data: Corners, folds: int, nominal: DHModel | None, ref: FloatArray
) -> PixelHoldout:
    """K-fold over the frames of every camera: the joint fit again on the other folds' frames,
    the nominal placed there (with the further cameras' poses), both scored in pixels at the
    fold's frames (no mm figure: the PnP floor is one camera's)."""
    from dhlog.identify.holdout import pose_groups
    from dhlog.identify.measure import fit_measured
    from dhlog.identify.measure import residuals as measured

    fold = fold_of_poses(pose_groups(data.Q), folds, 0)
    nominal_start = None
    if nominal is not None:
        ex = extract_dh(
            list(fit.whole.model.axes),
            tuple(fit.whole.model.types),
            target=fit.whole.model.target,
            reference_pose=ref,
            nominal=nominal.table,
        )
        R_tool = ex.frames[-1][:3, :3].T @ fit.whole.model.tool_rotation
        nominal_start = (nominal.table, ref, ex.T_measurement_base, ex.tool_point, R_tool)
    scored = fit.inliers
    errs: dict[str, list[FloatArray]] = {"calibrated": [], "nominal": []}
    for k in range(folds):
        test = fold == k
        if not test.any() or test.all():
            continue
        train_c, test_c = data.of_frames(~test), data.of_frames(test)
        keep = scored[test[data.frame]]
        again = fit_measured(fit.whole.model, fit.measurement, train_c)
        errs["calibrated"].append(
            np.sum(measured(again.whole.model, again.measurement, test_c) ** 2, axis=1)[keep]
        )
        if nominal_start is not None:
            m, meas = place(*nominal_start, fit.measurement, train_c)
            errs["nominal"].append(np.sum(measured(m, meas, test_c) ** 2, axis=1)[keep])

    def rms_of(parts: list[FloatArray]) -> float | None:
        if not parts:
            return None
        v = np.concatenate(parts)
        v = v[np.isfinite(v)]
        return float(np.sqrt(np.mean(v))) if v.size else None

    cal = rms_of(errs["calibrated"])
    check = PixelHoldout(
        folds=folds,
        frames=data.frames,
        nominal_px=rms_of(errs["nominal"]),
        calibrated_px=math.nan if cal is None else cal,
        nominal_mm=None,
        calibrated_mm=math.nan,
        fit_px=fit.rms,
    )
    check.notes.append(
        "the cameras together: each fold refits the model and the further cameras' poses on "
        "the other folds' frames of every camera; the nominal is placed on the same frames. "
        "Pixels only (the mm figure is a single camera's PnP)."
    )
    return check


#: A camera measures lengths in units of the board's squares: the robot's lengths (d, a of at
#: least :data:`SCALE_MIN_LENGTH`) coming out this far from the nominal's by one common factor
#: mean the pipeline's board size is not the printed one's.
SCALE_TOLERANCE = 0.01
SCALE_MIN_LENGTH = 0.05


def board_scale(
    ex: Extraction, nominal: StandardDH | None, obs: Observations, fixed: set[int]
) -> str | None:
    """A warning when the calibrated lengths are the nominal's times one factor k ≠ 1 (by
    more than :data:`SCALE_TOLERANCE`, each within a quarter of that of k): a camera cannot
    tell a board k times larger seen k times further, so the pipeline's ``[target]`` size is
    then most likely not the printed board's. ``fixed``: the table's entries (4 a row: θ, d,
    a, α) held by convention, left out. None otherwise."""
    if nominal is None:
        return None
    n = ex.standard.n
    got = np.concatenate([ex.standard.d_offset, ex.standard.a])
    ref = np.concatenate([nominal.d_offset, nominal.a])
    free = np.array(
        [4 * i + 1 not in fixed for i in range(n)] + [4 * i + 2 not in fixed for i in range(n)]
    )
    use = (np.abs(ref) >= SCALE_MIN_LENGTH) & free
    if np.count_nonzero(use) < 2:
        return None
    ratio = got[use] / ref[use]
    k = float(np.median(ratio))
    if abs(k - 1.0) <= SCALE_TOLERANCE or np.max(np.abs(ratio - k)) > 0.25 * abs(k - 1.0):
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


def camera_moved(
    fit: PixelFit, data: Corners, obs: Observations, ex: Extraction, ref: FloatArray
) -> str | None:
    """A warning when the fixed part (the camera eye-to-hand, the board eye-in-hand) moved
    during the session, else None: the calibrated table placed (:func:`place`: the fixed part's
    pose and the mount) separately on the frames before and after a split (in time order)
    explains the corners better than one placement by more than :data:`MOVED_DROP` σ². The
    best of :data:`MOVED_SPLITS`, then narrowed by halving between its neighbours, names the
    frames it moved between."""
    from dhlog.identify.measure import residuals as measured

    order = np.argsort(obs.t_ns, kind="stable")
    f = data.frames
    if f < 2 * MOVED_MIN_FRAMES:
        return None
    assert fit.whole.model.tool_rotation is not None
    R_tool = ex.frames[-1][:3, :3].T @ fit.whole.model.tool_rotation
    start = (ex.standard, ref, ex.T_measurement_base, ex.tool_point, R_tool)
    sigma2 = fit.sigma**2
    limit2 = fit.whole.limit**2

    def cost(placed: tuple[AxisModel, Any], corners: Corners) -> float:
        r = measured(placed[0], placed[1], corners)
        return float(np.sum(np.minimum(np.nan_to_num(np.sum(r**2, axis=1), nan=limit2), limit2)))

    whole = float(np.sum(np.minimum(np.sum(fit.residuals**2, axis=1), limit2)))

    def drop(k: int) -> float:
        before = np.zeros(f, dtype=bool)
        before[order[:k]] = True
        sides = [data.of_frames(before), data.of_frames(~before)]
        return (whole - sum(cost(place(*start, fit.measurement, c), c) for c in sides)) / sigma2

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


def hand_eye(
    fit: PixelFit,
    extract: Callable[[list[Line], FloatArray, Any], Extraction],
    setup: str,
    centre: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The fixed part's pose in the robot's base frame (the camera eye-to-hand, the board
    eye-in-hand) and the mounted part's on the flange, with their σ (rotation vector, rad;
    translation, m) propagated from the fit's covariance by central differences."""
    whole = fit.whole
    layout, model = whole.layout, whole.model

    def poses(m: AxisModel) -> tuple[FloatArray, FloatArray]:
        ex = extract(list(m.axes), m.target, None)
        T_base_M = np.linalg.inv(ex.T_measurement_base)
        T_M_flange = ex.frames[-1]
        assert m.tool_rotation is not None
        T_M_carried = _transform(m.tool_rotation, m.target)
        T_flange_carried = np.linalg.inv(T_M_flange) @ T_M_carried
        if setup == "eye-to-hand":  # M is the camera; the carried frame the board's centre
            return np.asarray(T_base_M, dtype=np.float64), T_flange_carried @ _shift(-centre)
        return T_base_M @ _shift(-centre), np.asarray(T_flange_carried, dtype=np.float64)

    T_fixed, T_mounted = poses(model)
    bases = model.bases()

    def vec(T1: FloatArray, T2: FloatArray) -> FloatArray:
        out = []
        for T, T0 in ((T1, T_fixed), (T2, T_mounted)):
            dR = T[:3, :3] @ T0[:3, :3].T
            out.append(Rotation.from_matrix(dR).as_rotvec())
            out.append(T[:3, 3] - T0[:3, 3])
        return np.concatenate(out)

    size = layout.size
    J = np.zeros((12, size))
    scale = np.sqrt(np.clip(np.diag(whole.covariance), 0.0, None))
    for k in range(size):
        h = max(float(scale[k]), 1e-9)
        d = np.zeros(size)
        d[k] = h
        plus = vec(*poses(model.moved(d, layout, bases)))
        minus = vec(*poses(model.moved(-d, layout, bases)))
        J[:, k] = (plus - minus) / (2 * h)
    cov = J @ whole.covariance @ J.T
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return T_fixed, T_mounted, std[:6], std[6:]


def _refined_poses(
    obs: Observations, fit: PixelFit, data: Corners, use: NDArray[np.bool_]
) -> FloatArray:
    """Each frame's board pose in the camera (f, 4, 4) by PnP refined (OpenCV's
    Levenberg–Marquardt) from where the fitted model puts the board: the frame's own pose in
    the result's basin (a planar board's pose has a mirror solution of nearly the same
    reprojection error at oblique views, which a PnP from scratch may take), from the corners
    ``use`` (N,) only (the fit's inliers)."""
    model = fit.whole.model
    layout = ParameterLayout.of(model.types, rotation=True)
    p, _ = predict_points(model, data.Q)
    R, _ = predict_orientation(model, data.Q, layout, model.bases())
    o = _centre(obs)
    c = fit.measurement.intrinsics
    points = obs.board.object_points()
    T = np.tile(np.eye(4), (data.frames, 1, 1))
    for f in range(data.frames):
        carried = _transform(R[:, :, f], p[f])
        if fit.measurement.setup == "eye-to-hand":
            T0 = carried @ _shift(-o)
        else:
            T0 = np.linalg.inv(carried) @ _shift(-o)
        mine = use[data.frame == f]
        if np.count_nonzero(mine) < 4:
            T[f] = T0
            continue
        obj = points[obs.ids[f]][mine]
        uv = obs.uv[f][mine].reshape(-1, 1, 2).astype(np.float64)
        if c.model == "equidistant":
            img, K, D = cv2.fisheye.undistortPoints(uv, c.K, c.coefficients), np.eye(3), np.zeros(5)
        else:
            img, K, D = uv, c.K, c.coefficients
        rvec0 = np.asarray(cv2.Rodrigues(T0[:3, :3])[0], dtype=np.float64).reshape(3, 1)
        tvec0 = np.ascontiguousarray(T0[:3, 3], dtype=np.float64).reshape(3, 1)
        try:  # (OpenCV takes a (3,) tvec without complaint and returns garbage rotations)
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, D, rvec0.copy(), tvec0.copy())
        except cv2.error:
            T[f] = T0
            continue
        T[f] = _transform(
            np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64),
            np.asarray(tvec, dtype=np.float64).ravel(),
        )
    return T


def _pnp_points(
    obs: Observations, T_cb: FloatArray, data: Corners, sigma_px: float
) -> tuple[FloatArray, FloatArray]:
    """Each corner where its frame's PnP pose puts it in the camera (N, 3), and the variance
    (N,: the trace of its 3×3 covariance, m²) the pose's own noise gives it: the pose's
    covariance ``σ² (JᵀJ)⁻¹`` from OpenCV's projection Jacobian at the corners' σ."""
    X = np.empty((data.uv.shape[0], 3))
    var = np.full(data.uv.shape[0], np.nan)
    points = data.points + _centre(obs)
    c = obs.intrinsics
    for f in range(data.frames):
        at = data.frame == f
        T = T_cb[f]
        X[at] = points[at] @ T[:3, :3].T + T[:3, 3]
        rvec = cv2.Rodrigues(T[:3, :3])[0]
        try:
            if c.model == "equidistant":
                _, J = cv2.fisheye.projectPoints(
                    points[at].reshape(1, -1, 3), rvec, T[:3, 3], c.K, c.coefficients
                )
                J = np.asarray(J).reshape(-1, 15)[:, 8:14]
            else:
                _, J = cv2.projectPoints(points[at], rvec, T[:3, 3], c.K, c.coefficients)
                J = np.asarray(J)[:, :6]
            cov = np.linalg.inv(J.T @ J) * sigma_px**2  # (rvec, t)
        except (cv2.error, np.linalg.LinAlgError):
            continue
        # a corner moves by −[R x]× δr (to first order, δr about the rotation vector) + δt
        for k in np.flatnonzero(at):
            Rx = T[:3, :3] @ points[k]
            A = np.hstack([-_skew(Rx) @ _rodrigues_jacobian(rvec.ravel()), np.eye(3)])
            var[k] = float(np.trace(A @ cov @ A.T))
    return X, var


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rodrigues_jacobian(r: FloatArray) -> FloatArray:
    """The small rotation (in the rotated frame's parent) per change of the rotation vector
    ``r``: the left Jacobian of SO(3)."""
    theta = float(np.linalg.norm(r))
    if theta < 1e-9:
        return np.eye(3)
    K = _skew(r / theta)
    return np.asarray(
        np.eye(3) + (1 - math.cos(theta)) / theta * K + (theta - math.sin(theta)) / theta * (K @ K),
        dtype=np.float64,
    )


def cross_validate_pixels(
    fit: PixelFit,
    data: Corners,
    obs: Observations,
    T_cb: FloatArray,
    folds: int,
    nominal: DHModel | None,
    ref: FloatArray,
) -> PixelHoldout:
    """K-fold over the frames' poses: each fold refits the whole model in pixels on the other
    folds' frames (and places the nominal there: its camera pose and board mount, its geometry
    held), and both are scored at the fold's frames in pixels and, against each held-out
    frame's own PnP pose, in mm."""
    from dhlog.identify.holdout import pose_groups

    groups = pose_groups(data.Q)
    fold = fold_of_poses(groups, folds, 0)
    nominal_start = None
    if nominal is not None:
        nominal_start = _nominal_start(fit, nominal, ref)
    # the corners the fit held out as false detections, and every corner of a frame most of
    # whose corners it held out (its ids mis-assigned: a pose the board never had), are not
    # scored (decided on every frame, as the tracker's gross outliers are)
    false = np.bincount(data.frame, weights=~fit.inliers, minlength=data.frames)
    counted = np.bincount(data.frame, minlength=data.frames)
    bad_frame = false > 0.5 * np.maximum(counted, 1)
    scored = fit.inliers & ~bad_frame[data.frame]
    X_pnp, var_pnp = _pnp_points(obs, _refined_poses(obs, fit, data, scored), data, fit.sigma)
    var_pnp = np.where(scored, var_pnp, np.nan)
    err_px: dict[str, list[FloatArray]] = {"calibrated": [], "nominal": []}
    err_mm: dict[str, list[FloatArray]] = {"calibrated": [], "nominal": []}
    for k in range(folds):
        test = fold == k
        if not test.any() or test.all():
            continue
        train_c = data.of_frames(~test)
        test_c = data.of_frames(test)
        at = test[data.frame]
        fits = {"calibrated": fit_pixels(fit.whole.model, fit.measurement, train_c)}
        models = {"calibrated": (fits["calibrated"].whole.model, fits["calibrated"].measurement)}
        if nominal_start is not None:
            models["nominal"] = place(*nominal_start, fit.measurement, train_c)
        keep = scored[at]
        for name, (m, meas) in models.items():
            uv, _ = meas.predict(m, None, None, test_c, slice(None))
            err_px[name].append(np.sum((uv - test_c.uv) ** 2, axis=1)[keep])
            X, _ = meas.in_camera(m, None, None, test_c, slice(None))
            err_mm[name].append(np.sum((X - X_pnp[at]) ** 2, axis=1)[keep])

    def rms(parts: list[FloatArray]) -> float | None:
        if not parts:
            return None
        v = np.concatenate(parts)
        v = v[np.isfinite(v)]
        return float(np.sqrt(np.mean(v))) if v.size else None

    X_fit, _ = fit.measurement.in_camera(fit.whole.model, None, None, data, slice(None))
    in_mm = rms([np.sum((X_fit - X_pnp) ** 2, axis=1)[scored]])
    cal_px, cal_mm = rms(err_px["calibrated"]), rms(err_mm["calibrated"])
    assert cal_px is not None and cal_mm is not None
    finite = var_pnp[np.isfinite(var_pnp)]
    floor = float(np.sqrt(np.mean(finite))) if finite.size else math.nan
    nom_mm = rms(err_mm["nominal"])
    check = PixelHoldout(
        folds=folds,
        frames=data.frames,
        nominal_px=rms(err_px["nominal"]),
        calibrated_px=cal_px,
        nominal_mm=None if nom_mm is None else nom_mm * 1e3,
        calibrated_mm=cal_mm * 1e3,
        fit_px=fit.rms,
        pnp_noise_mm=floor * 1e3,
        fit_mm=math.nan if in_mm is None else in_mm * 1e3,
    )
    if np.any(~scored):
        frames = ", ".join(str(int(obs.frame[f])) for f in np.flatnonzero(bad_frame)[:5])
        check.notes.append(
            f"{int(np.count_nonzero(~scored))} corner(s) not scored: false detections the fit "
            "held out"
            + (
                f", with every corner of {int(np.count_nonzero(bad_frame))} frame(s) most of "
                f"whose corners it held out (frames {frames})"
                if bad_frame.any()
                else ""
            )
            + "."
        )
    check.notes.append(
        "each fold refits the whole model in pixels on the other folds' frames; the nominal is "
        "placed on the same frames (the camera's pose and the board's mount fitted, its "
        "geometry held). Pixels: the corners' reprojection (2-D norm); mm: the board's corners "
        "in the camera against each held-out frame's own PnP pose (from the fit's inlier "
        "corners), whose depth noise is in it: the PnP noise is that of independent corner "
        "errors, the in-sample figure what the frames' PnP poses give against the model "
        "fitted to them."
    )
    return check


def _nominal_start(
    fit: PixelFit, nominal: DHModel, ref: FloatArray
) -> tuple[Any, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Where the nominal's placement starts: the table with the fitted model's base in M and
    carried frame on the flange (:func:`~dhlog.identify.pixels.place`'s first five
    arguments)."""
    whole = fit.whole
    ex = extract_dh(
        list(whole.model.axes),
        tuple(whole.model.types),
        target=whole.model.target,
        reference_pose=ref,
        nominal=nominal.table,
    )
    assert whole.model.tool_rotation is not None
    R_flange_tool = ex.frames[-1][:3, :3].T @ whole.model.tool_rotation
    return nominal.table, ref, ex.T_measurement_base, ex.tool_point, R_flange_tool


def camera_view(
    fit: PixelFit,
    data: Corners,
    obs: Observations,
    cam: CameraResult,
    check: PixelHoldout | None,
    *,
    T_base_M: FloatArray | None = None,
) -> CameraView:
    """What the recording shows: the kept frames with their corners and reprojections, the
    camera and the board in the base frame at each frame. ``T_base_M``: M in the base frame
    when M is not this camera's (several cameras: the first's)."""
    from dhlog.identify.prediction import predict as predict_points
    from dhlog.identify.prediction import predict_orientation

    model = fit.whole.model
    kept = {index: (fmt, blob) for index, fmt, blob in obs.kept}
    frames: list[FrameView] = []
    centre = _centre(obs)
    # the carried frame in M at each frame, then in the base
    layout = ParameterLayout.of(model.types, rotation=True)
    p, _ = predict_points(model, data.Q)
    R, _ = predict_orientation(model, data.Q, layout, model.bases())
    if T_base_M is None:
        T_base_M = (
            cam.T_base_fixed if cam.setup == "eye-to-hand" else cam.T_base_fixed @ _shift(centre)
        )
    uv_pred = data.uv + fit.residuals
    for f in range(data.frames):
        index = int(obs.frame[f])
        at = data.frame == f
        T_M_carried = _transform(R[:, :, f], p[f])
        if cam.setup == "eye-to-hand":
            T_base_camera = cam.T_base_fixed
            T_base_board = T_base_M @ T_M_carried @ _shift(-centre)
        else:
            T_base_camera = T_base_M @ T_M_carried
            T_base_board = cam.T_base_fixed
        fmt, blob = kept.get(index, ("jpeg", None))
        frames.append(
            FrameView(
                t_ns=int(obs.t_ns[f]),
                index=index,
                image=blob,
                image_format=fmt,
                ids=obs.ids[f],
                detected_px=data.uv[at],
                reprojected_px=uv_pred[at],
                held_out=False,
                T_base_camera=T_base_camera,
                T_base_board=T_base_board,
            )
        )
    return CameraView(
        name=obs.camera,
        setup=cam.setup,
        intrinsics=cam.intrinsics,
        board_points=obs.board.object_points(),
        rms_px=cam.rms_px,
        frames=frames,
    )
