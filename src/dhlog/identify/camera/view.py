"""What the recording shows of a camera calibration (:class:`dhlog.vision.view.CameraView`):
:func:`camera_view`.
"""

from __future__ import annotations

import math

from dhlog.geometry._checks import FloatArray
from dhlog.identify.camera.frames.observations import Observations
from dhlog.identify.camera.pixels import Corners, PixelFit
from dhlog.identify.camera.poses import board_centre, shift, transform
from dhlog.identify.fit.axismodel import ParameterLayout
from dhlog.identify.fit.prediction import predict as predict_points
from dhlog.identify.fit.prediction import predict_orientation
from dhlog.vision.report import CameraResult, PixelHoldout
from dhlog.vision.view import CameraView, FrameView


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

    model = fit.whole.model
    kept = {index: (fmt, blob) for index, fmt, blob in obs.kept}
    frames: list[FrameView] = []
    centre = board_centre(obs)
    # the carried frame in M at each frame, then in the base
    layout = ParameterLayout.of(model.types, rotation=True)
    p, _ = predict_points(model, data.Q)
    R, _ = predict_orientation(model, data.Q, layout, model.bases())
    if T_base_M is None:
        T_base_M = (
            cam.T_base_fixed if cam.setup == "eye-to-hand" else cam.T_base_fixed @ shift(centre)
        )
    uv_pred = data.uv + fit.residuals
    spans = data.frame_slices()
    for f in range(data.frames):
        index = int(obs.frame[f])
        at = spans[f]
        T_M_carried = transform(R[:, :, f], p[f])
        if cam.setup == "eye-to-hand":
            T_base_camera = cam.T_base_fixed
            T_base_board = T_base_M @ T_M_carried @ shift(-centre)
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
        notes=holdout_lines(check),
    )


def holdout_lines(check: PixelHoldout | None) -> tuple[str, ...]:
    """The held-out check as the recording's camera text shows it (markdown lines)."""
    if check is None:
        return ("No held-out check: run dhlog process with --holdout 5.",)

    def mm(value: float | None) -> str:
        return "—" if value is None or not math.isfinite(value) else f"{value:.4f} mm"

    nominal = "—" if check.nominal_px is None else f"{check.nominal_px:.4f} px"
    return (
        f"**Held-out** ({check.folds}-fold over {check.frames} frames): reprojection RMS "
        f"nominal {nominal}, calibrated {check.calibrated_px:.4f} px (in sample "
        f"{check.fit_px:.4f} px); board corners nominal {mm(check.nominal_mm)}, calibrated "
        f"{mm(check.calibrated_mm)} (in sample {mm(check.fit_mm)}, PnP noise "
        f"{mm(check.pnp_noise_mm)}).",
        *check.notes,
    )
