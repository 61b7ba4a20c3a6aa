"""A camera calibration: from a camera's detected board corners to the DH model, the camera's
pose (the hand-eye calibration) and the error at held-out frames.

1. Each frame's board pose in the camera by OpenCV's PnP (:func:`board_poses`).
2. Those poses are a 6-DoF target's samples: the board's centre and orientation in the camera
   (eye-to-hand), or the camera's in the board's frame (eye-in-hand). The tracker's run
   (``start``: :func:`dhlog.identify.run.process_poses`, the geometric model) makes its start
   from them: the seed method where joints were swept alone, the nominal placed on them
   otherwise.
3. The whole model is fitted again to every corner in pixels (:mod:`dhlog.identify.camera.pixels`):
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
from dataclasses import replace
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from dhlog.errors import DhlogError, InputError, Note
from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line, Plane
from dhlog.identify.camera.checks import (
    FAR_PX,
    board_scale,
    camera_moved,
    frame_clustered,
    frames_disagree,
    placed_nominal,
)
from dhlog.identify.camera.frames.observations import Observations
from dhlog.identify.camera.hand_eye import cameras_std, hand_eye
from dhlog.identify.camera.holdout import cross_validate_cameras, cross_validate_pixels
from dhlog.identify.camera.pixels import CamerasModel, PixelFit, PixelModel, fit_pixels
from dhlog.identify.camera.poses import (
    PNP_RMS,
    board_centre,
    board_poses,
    corners_of,
    of_frames,
    pose_log,
    shift,
    stacked,
    transform,
)
from dhlog.identify.camera.view import camera_view
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.identify.fit.prediction import predict as predict_points
from dhlog.identify.fit.prediction import predict_orientation
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.model.select import ModelRequest
from dhlog.identify.options import DEFAULTS, ProcessOptions
from dhlog.identify.read.extract import Extraction, extract_dh
from dhlog.identify.read.propagate import Extractor
from dhlog.identify.read.uncertainty import Uncertainty, whole_uncertainty
from dhlog.identify.stages import Identification
from dhlog.io.dhfile import DHModel
from dhlog.io.logdata import LogData
from dhlog.vision.report import CameraResult

#: the fewest frames with the board for a calibration
MIN_FRAMES = 8


# ---------------------------------------------------------------------------------------------
# the run


class PoseRun(Protocol):
    """The tracker's run on a camera's board poses (:func:`dhlog.identify.run.process_poses`):
    the start of the pixel fit, handed in by the run (this module is below it)."""

    def __call__(
        self,
        log: LogData,
        *,
        sha256: str,
        nominal: DHModel | None,
        reference_pose: FloatArray | None,
        model: ModelRequest,
        progress: Callable[[str, float], None] | None,
    ) -> Identification: ...


def process_observations(
    observations: list[Observations],
    options: ProcessOptions = DEFAULTS,
    *,
    sha256: str = "",
    progress: Callable[[str, float], None] | None = None,
    start: PoseRun,
    pipeline: str | None = None,
) -> Identification:
    """The calibration of the module docstring from one camera's observations, as ``options``
    asks (its nominal, reference pose, ``camera_setup`` — None: decided from the data —,
    ``refine_intrinsics``, ``holdout`` K over the frames, ``frames``); returns the
    :class:`~dhlog.identify.stages.Identification` with its ``camera`` and ``cameras`` filled.
    ``start``: the tracker's run on the poses (:func:`dhlog.identify.run.process_poses`)."""
    nominal, reference_pose, setup = options.nominal, options.reference_pose, options.camera_setup
    holdout, frames = options.holdout, options.frames
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
    notes = [Note.warning(w, "log") for w in obs.warnings]
    # the further cameras' own (frames left out, unreadable images …), named by camera
    notes += [Note.warning(f"{o.camera}: {w}", "log") for o in observations[1:] for w in o.warnings]
    if dropped:
        bad = ", ".join(str(int(obs.frame[k])) for k in np.flatnonzero(~use)[:3])
        said = (
            f"{dropped} frame(s) left out of the start: the board's pose (PnP) misses its own "
            f"corners by more than {PNP_RMS} px there (frames {bad}"
            f"{', …' if dropped > 3 else ''}): false detections or wrong intrinsics."
        )
        notes.append(Note.warning(said, "pnp-misses"))
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
    starts: dict[str, Identification | DhlogError] = {}
    for s in candidates:
        log = pose_log(obs, T_cb, s, use)
        try:
            starts[s] = replace(
                start(
                    log,
                    sha256=sha256,
                    nominal=nominal,
                    reference_pose=reference_pose,
                    model=model_request,
                    progress=progress,
                ),
                camera_setup=s,
            )
        except DhlogError as exc:
            if len(candidates) == 1:
                raise
            starts[s] = exc
    # each usable start with its FK check's RMS (a start's fit of the poses)
    usable = {
        s: r
        for s, r in starts.items()
        if isinstance(r, Identification) and r.whole is not None and r.validation is not None
    }
    fk_rms = {s: r.validation.rms for s, r in usable.items() if r.validation is not None}
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
    placements = {  # the nominal on the corners: one placement a start
        s: placed_nominal(r, nominal, obs) for s, r in usable.items() if len(usable) > 1
    }
    gap = {s: placements[s][0] if s in placements else math.nan for s in usable}
    chosen = min(usable, key=lambda s: (gap[s], fk_rms[s]))
    if setup:
        reason = "given"
    else:
        said = "; ".join(
            f"{s}: the nominal placed on the corners misses them by "
            + (f"{gap[s]:.3f} px RMS" if gap[s] < 1e4 else "over 10 000 px RMS")
            for s in usable
        )
        reason = f"decided from the data ({said})"
    result = usable[chosen]
    if pipeline is not None:  # the camera pipeline read, not the poses' internal one
        piped = replace(result.log, pipeline=replace(result.log.pipeline, name=pipeline))
        result = replace(result, session=replace(result.session, log=piped))
    # what the start's run said is of the poses' fit (its noise, its pairs, its registration in
    # mm), not of the calibration: one line says how the start was made, the rest is the
    # pixel fit's
    swept = [j.index for j in result.joints if j.fit is not None]
    how = (
        f"the seed method on the sweeps of joint(s) {', '.join(map(str, swept))}"
        if swept
        else "the nominal placed on them"
    )
    begun = Note.info(
        f"start: each frame's board pose (OpenCV PnP) as a 6-DoF target, the model from "
        f"{how}; then the whole model fitted to every corner in pixels.",
        "camera-start",
    )
    kept = (n for n in result.notes if n.code == "never-alone")
    result = replace(result, notes=(begun, *notes, *kept))
    placement = placements.get(chosen) or placed_nominal(result, nominal, obs)
    result, fit = _pixel_stage(result, obs, T_cb, placement[1], (chosen, reason), options, progress)
    disagree = frames_disagree(obs, pnp_rms, use, fit.rms)
    if disagree is not None and not any(n.code == "camera-moved" for n in result.notes):
        result = result.said(Note.warning(disagree, "frames-disagree"))  # a cause not yet named
    placed_px = placement[0]
    if setup and nominal is not None and not placed_px < FAR_PX:
        # a set-up given wrongly fits by a free fit on sweeps, and shows only here
        said = (
            f"--camera-setup {setup}: the nominal, placed on the corners in that set-up, misses "
            f"them by {'over 10 000' if not placed_px < 1e4 else f'{placed_px:.1f}'} px RMS: is "
            "the set-up right? Leave --camera-setup out and it is decided from the data."
        )
        result = replace(result, notes=(Note.warning(said, "camera-setup"), *result.notes))
    if extra_cameras and chosen != "eye-to-hand":
        said = (
            f"the log has {len(observations)} cameras; several are fitted together fixed in the "
            f"cell (eye-to-hand) only: this calibration used {obs.camera} alone "
            f"({', '.join(extra_cameras)} not used)."
        )
        result = result.said(Note.warning(said, "cameras-unused"))
    elif extra_cameras:
        rest = [o if frames is None else of_frames(o, frames) for o in observations[1:]]
        result = _several_cameras(result, fit, [obs, *rest], holdout, progress)
    assert isinstance(result, Identification)
    return result


def _adopt(
    result: Identification, whole: WholeFit
) -> tuple[Identification, Extraction, Uncertainty, Extractor]:
    """``result`` with the pixel fit ``whole`` in it: its DH model read off as for a tracker,
    the covariance and what is fixed, the FK check against the PnP poses. Returns that result,
    the extraction, the uncertainty and the extraction's function."""
    from dhlog.identify.check.validate import validate_samples
    from dhlog.identify.joints.sweeps import samples_with_encoders

    nominal = result.nominal
    nominal_table = nominal.table if nominal is not None else None
    ref = result.reference_pose
    types = tuple(whole.model.types)

    def extract(axes: list[Line], target: FloatArray, plane: Plane | None) -> Extraction:
        return extract_dh(
            axes, types, target=target, reference_pose=ref, base_plane=plane, nominal=nominal_table
        )

    ex = extract(list(whole.model.axes), whole.model.target, None)
    found = whole_uncertainty(whole, None, extract, ex, ref, nominal_table)
    seg = result.segmentation
    rows, Q, P = samples_with_encoders(seg)
    # the table's joint values are the encoders' (no scales, no terms in a camera's fit)
    inl = np.ones(len(rows), dtype=bool)
    assert result.fit is not None  # a start is a whole-model fit of the poses
    adopted = replace(
        result,
        notes=(*result.notes, *found.notes),
        # in pixels: the camera block says so
        fit=replace(
            result.fit, whole=whole, selection=None, method="whole-model maximum likelihood"
        ),
        readout=replace(
            result.readout, extraction=ex, uncertainty=found, target=whole.model.target
        ),
        checks=replace(
            result.checks,
            validation=validate_samples(seg, rows, Q, P, ex, inl, ex.tool_point[None]),
        ),
    )
    return adopted, ex, found, extract


def _pixel_stage(
    result: Identification,
    obs: Observations,
    T_cb: FloatArray,
    placed: AxisModel | None,
    chosen: tuple[str, str],
    options: ProcessOptions,
    progress: Callable[[str, float], None] | None,
) -> tuple[Identification, PixelFit]:
    """Refit ``result``'s whole model in pixels (and from ``placed``, the nominal placed on
    the corners, when given) in the set-up ``chosen`` (its name and why), with the intrinsics
    refined and the frames cross-validated as ``options`` asks; returns the result with the DH
    model, σ and camera in it, and the fit."""
    (setup, reason), refine_intrinsics, holdout = chosen, options.refine_intrinsics, options.holdout
    assert result.whole is not None
    if progress is not None:
        progress("fitting pixels", 0.0)
    data = corners_of(obs, np.ones(obs.frames, dtype=bool))
    measurement = PixelModel(setup, obs.intrinsics, refine=refine_intrinsics)
    fit = fit_pixels(result.whole.model, measurement, data)
    # a second start, the nominal placed on the corners: the start fit's model can sit in
    # another basin of the pixels' cost (a poor seed-method start eye-in-hand); the better
    # optimum, by the truncated cost at the first fit's cut, is kept
    if placed is not None:
        other = fit_pixels(placed, measurement, data)
        if _cost(other, fit.whole.limit) < _cost(fit, fit.whole.limit):
            fit = other
    fit, clustered = frame_clustered(fit, data.frame)
    result = result.said(*clustered)
    nominal = result.nominal
    nominal_table = nominal.table if nominal is not None else None
    ref = result.reference_pose
    result, ex, found, extract = _adopt(result, fit.whole)
    T_fixed, T_mounted, fixed_std, mounted_std = hand_eye(fit, extract, setup, board_centre(obs))
    scaled = board_scale(ex, nominal_table, obs, set(found.fixed))
    if scaled is not None:  # the calibration is of a board of another size: implausible
        result = replace(result, implausible=(*result.implausible, scaled))
    moved = camera_moved(fit, data, obs, ex, ref)
    if moved is not None:
        result = replace(result, notes=(Note.warning(moved, "camera-moved"), *result.notes))
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
    said = (
        f"camera {obs.camera} ({setup}, {reason}): {cam.frames} frames, {cam.corners} corners "
        f"({cam.corners - cam.inlier_corners} held out as false detections); the whole model "
        f"fitted to the corners in pixels: σ {cam.sigma_px:.3f} px per coordinate. The FK "
        "check below is against the board's poses from PnP (mm), the fit's own is in pixels."
    )
    assert result.fit is not None
    shown = replace(
        result,
        camera=cam,
        fit=replace(result.fit, sigma=None),  # the pixels' σ is the camera block's
        notes=(*result.notes, Note.info(said, "camera")),
        cameras=(camera_view(fit, data, obs, cam, check),),
        camera_results=(cam,),
    )
    return shown, fit


def _cost(fit: PixelFit, limit: float) -> float:
    """The truncated sum of squares of ``fit``'s residuals at the cut ``limit`` (px)."""
    norms = np.sqrt(np.sum(fit.residuals**2, axis=1))
    return float(np.sum(np.minimum(np.nan_to_num(norms, nan=limit), limit) ** 2))


def _several_cameras(
    result: Identification,
    first: PixelFit,
    observations: list[Observations],
    holdout: int,
    progress: Callable[[str, float], None] | None,
) -> Identification:
    """``result`` with the whole model fitted to every camera's corners at once
    (:class:`CamerasModel`: M the first camera's frame, each further camera's pose fitted with
    it), starting from the first
    camera's fit and each further camera placed by its frames' PnP poses against where that
    fit puts the board; every camera's pose in the base frame with σ, the held-out check
    over all frames, a view per camera."""
    from dhlog.identify.fit.measure import fit_measured

    if progress is not None:
        progress("fitting cameras together", 0.0)
    model = first.whole.model
    centre = board_centre(observations[0])
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
        carried = np.zeros((p.shape[0], 4, 4))  # the board's frame in M at each frame
        carried[:, :3, :3] = np.moveaxis(R, 2, 0)
        carried[:, :3, 3] = p
        carried[:, 3, 3] = 1.0
        found = carried @ shift(-centre) @ np.linalg.inv(T[ok])  # one batch, not a copy a frame
        mean = Rotation.from_matrix(found[:, :3, :3]).mean().as_matrix()
        poses.append(transform(mean, np.median(found[:, :3, 3], axis=0)))
    data = stacked(observations)
    measurement = CamerasModel(tuple(o.intrinsics for o in observations), tuple(poses))
    # the further cameras placed first, the model held and every corner in (their PnP start
    # misses by px, which the joint fit's outlier cut, judged mostly on the first camera's
    # corners, would hold out whole), then everything together
    held = np.zeros((ParameterLayout.of(model.types, rotation=True).size, 0))
    placed = fit_measured(model, measurement, data, within=held, threshold=math.inf)
    # the first camera's design effect is replaced by the cameras' together
    kept = tuple(n for n in result.notes if n.code != "frame-clustered")
    fit, clustered = frame_clustered(fit_measured(model, placed.measurement, data), data.frame)
    result, ex, _, extract = _adopt(replace(result, notes=(*kept, *clustered)), fit.whole)
    _, T_mounted, _, mounted_std = hand_eye(fit, extract, "eye-to-hand", centre)
    cams_std = cameras_std(fit, extract)
    base: FloatArray = np.asarray(np.linalg.inv(ex.T_measurement_base), dtype=np.float64)
    check = None
    if holdout > 1:
        if progress is not None:
            progress("cross-validating", 0.0)
        check = cross_validate_cameras(fit, data, holdout, result.nominal, result.reference_pose)
    first_reason = result.camera.setup_reason if result.camera is not None else ""
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
            setup_reason=first_reason if k == 0 else "the first camera's",
            holdout=check,
        )
        results.append(cam)
        own = corners_of(o, np.ones(o.frames, dtype=bool))
        sub = replace(first, residuals=res, whole=replace(first.whole, model=fit.whole.model))
        views.append(camera_view(sub, own, o, cam, check, T_base_M=base))
    said = (
        f"{len(observations)} cameras fitted together ({', '.join(o.camera for o in observations)}"
        f"): {int(data.uv.shape[0])} corners, σ {fit.sigma:.3f} px per coordinate; each "
        "camera's pose in the base frame with its σ in the camera blocks."
    )
    return replace(
        result,
        camera=results[0],
        camera_results=tuple(results),
        cameras=tuple(views),
        notes=(*result.notes, Note.info(said, "cameras")),
    )
