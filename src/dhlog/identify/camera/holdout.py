"""The camera calibration's error at frames not used to fit: K-fold over the frames' poses, in
pixels and, for one camera, in mm against each held-out frame's own PnP pose, the nominal placed
on the same training frames (:func:`cross_validate_pixels`, :func:`cross_validate_cameras`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.identify.camera.frames.observations import Observations
from dhlog.identify.camera.pixels import Corners, PixelFit, fit_pixels
from dhlog.identify.camera.poses import pnp_points, refined_poses
from dhlog.identify.fit.leaveout import fold_of_poses
from dhlog.identify.read.extract import extract_dh
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import StandardDH
from dhlog.vision.report import PixelHoldout


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
    from dhlog.identify.fit.leaveout import pose_groups

    groups = pose_groups(data.Q)
    fold = fold_of_poses(groups, folds, 0)
    placing = None
    if nominal is not None:
        placing = nominal_start(fit, nominal, ref)
    # the corners the fit held out as false detections, and every corner of a frame most of
    # whose corners it held out (its ids mis-assigned: a pose the board never had), are not
    # scored (decided on every frame, as the tracker's gross outliers are)
    false = np.bincount(data.frame, weights=~fit.inliers, minlength=data.frames)
    counted = np.bincount(data.frame, minlength=data.frames)
    bad_frame = false > 0.5 * np.maximum(counted, 1)
    scored = fit.inliers & ~bad_frame[data.frame]
    X_pnp, var_pnp = pnp_points(obs, refined_poses(obs, fit, data, scored), data, fit.sigma)
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
        if placing is not None:
            models["nominal"] = fit.measurement.place(*placing, train_c)
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
    notes = []
    if np.any(~scored):
        frames = ", ".join(str(int(obs.frame[f])) for f in np.flatnonzero(bad_frame)[:5])
        notes.append(
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
    notes.append(
        "each fold refits the whole model in pixels on the other folds' frames; the nominal is "
        "placed on the same frames (the camera's pose and the board's mount fitted, its "
        "geometry held). Pixels: the corners' reprojection (2-D norm); mm: the board's corners "
        "in the camera against each held-out frame's own PnP pose (from the fit's inlier "
        "corners), whose depth noise is in it: the PnP noise is that of independent corner "
        "errors, the in-sample figure what the frames' PnP poses give against the model "
        "fitted to them."
    )
    return replace(check, notes=tuple(notes))


def cross_validate_cameras(
    fit: PixelFit, data: Corners, folds: int, nominal: DHModel | None, ref: FloatArray
) -> PixelHoldout:
    """K-fold over the frames of every camera: the joint fit again on the other folds' frames,
    the nominal placed there (with the further cameras' poses), both scored in pixels at the
    fold's frames (no mm figure: the PnP floor is one camera's)."""
    from dhlog.identify.fit.leaveout import pose_groups
    from dhlog.identify.fit.measure import fit_measured
    from dhlog.identify.fit.measure import residuals as measured

    fold = fold_of_poses(pose_groups(data.Q), folds, 0)
    placing = None
    if nominal is not None:
        ex = extract_dh(
            list(fit.whole.model.axes),
            tuple(fit.whole.model.types),
            target=fit.whole.model.target,
            reference_pose=ref,
            nominal=nominal.table,
        )
        R_tool = ex.frames[-1][:3, :3].T @ fit.whole.model.tool_rotation
        placing = (nominal.table, ref, ex.T_measurement_base, ex.tool_point, R_tool)
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
        if placing is not None:
            m, meas = fit.measurement.place(*placing, train_c)
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
    said = (
        "the cameras together: each fold refits the model and the further cameras' poses on "
        "the other folds' frames of every camera; the nominal is placed on the same frames. "
        "Pixels only (the mm figure is a single camera's PnP)."
    )
    return replace(check, notes=(said,))


def nominal_start(
    fit: PixelFit, nominal: DHModel, ref: FloatArray
) -> tuple[StandardDH, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Where the nominal's placement starts: the table with the fitted model's base in M and
    carried frame on the flange (:meth:`~dhlog.identify.fit.measure.Measurement.place`'s first
    five arguments)."""
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
