"""The camera calibration's parts of the certificate page as HTML: the summary cards and the
held-out check in pixels and mm (:func:`camera_cards`, :func:`camera_accuracy`, shown in the
accuracy section) and the camera section (:func:`camera_section`: the set-up, the
detections, the hand-eye poses ±1σ, the intrinsics, the corners). Every text from the file is
escaped; SI values in ``data-si``."""

from __future__ import annotations

import math

from dhlog.present.certificate.camera import LENS, SETUPS, CameraHoldout, CameraPose, CameraShown
from dhlog.present.certificate.sections import _fixed, _places, escape, kv_table


def _px(value: float | None) -> str:
    return "—" if value is None else f"{value:.4f}"


def camera_cards(cam: CameraShown) -> list[tuple[str, str, str]]:
    """The summary cards of a camera calibration's held-out check: (key, value, class)."""
    h = cam.holdout
    if h is None:
        return [("Held-out validation", "none: run --holdout 5", "bad")]
    cards = [
        ("Held-out RMS, calibrated", f"{h.calibrated_px:.4f} px · {h.calibrated_mm:.4f} mm", "good")
    ]
    if h.nominal_px is not None and h.nominal_mm is not None:
        cards.append(
            ("Held-out RMS, nominal", f"{h.nominal_px:.4f} px · {h.nominal_mm:.4f} mm", "")
        )
    cards.append(("Corners' σ", f"{cam.corner_sigma_px:.3f} px", ""))
    return cards


def camera_accuracy(h: CameraHoldout) -> str:
    """The held-out check of a camera calibration: the nominal and the result at the held-out
    frames in pixels and mm, the in-sample fit and the PnP noise beside them, and its notes."""

    def cell(v: float | None) -> str:
        data = "" if v is None else f' data-value="{v!r}"'
        return f'<td class="num"{data}>{_px(v)}</td>'

    def row(cls: str, head: str, model: str, px: float | None, mm: float | None) -> str:
        return f'<tr class="{cls}"><th>{head}</th><td>{model}</td>{cell(px)}{cell(mm)}</tr>'

    check = escape(f"{h.folds}-fold cross-validation, {h.frames} frames")
    rows = [
        row("nominal", check, "nominal", h.nominal_px, h.nominal_mm)
        if h.nominal_px is not None or h.nominal_mm is not None
        else '<tr class="nominal"><th>' + check + '</th><td>nominal</td><td class="num" '
        'colspan="2">no nominal given to dhlog process</td></tr>',
        row("calibrated", "", "calibrated", h.calibrated_px, h.calibrated_mm),
        row("insample", "in-sample fit", "calibrated", h.in_sample_px, h.in_sample_mm),
        row("noise", "PnP noise", "—", None, h.pnp_noise_mm),
    ]
    parts = [
        '<table class="grid stats" id="camera-holdout"><thead><tr><th>Check</th><th>Model</th>'
        '<th class="num">Reprojection RMS [px]</th><th class="num">Board corners RMS [mm]</th>'
        "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>",
        '<p class="caption">At frames not used to fit (held out), before (the nominal placed on '
        "the frames the calibration was fitted on: its camera pose and board mount fitted, its "
        "geometry held; never on the frames scored) and after calibration (each fold's "
        "calibration made again in pixels from its training frames alone). Pixels: the RMS "
        "distance between each detected corner and the model's reprojection of it. mm: the RMS "
        "3-D distance of the board's corners in the camera between the model's prediction and "
        "the held-out frame's own PnP pose (the result's triangulation). A single camera's "
        "depth is its weak direction and the PnP poses' own error is in that figure: the PnP "
        "noise row is what independent corner errors give it, the in-sample row what the "
        "frames' PnP poses give against the model fitted to all of them. A held-out error far "
        "above the in-sample one means the model fits the session better than it predicts the "
        "robot.</p>",
    ]
    if h.beyond_noise_mm is not None:
        parts.append(
            f'<p id="camera-beyond-noise">Calibrated, the PnP noise taken out (in quadrature): '
            f"<strong>{h.beyond_noise_mm:.4f} mm</strong>.</p>"
        )
    for note in h.notes:
        parts.append(f'<p class="caption">Held out: {escape(note)}</p>')
    return "\n".join(parts)


def _pose_cells(pose: CameraPose) -> list[str]:
    """x, y, z (mm) and roll, pitch, yaw (°), each with ±1σ under it."""
    out = []
    values = [*pose.translation, *pose.rpy]
    stds = [*pose.translation_std, *pose.rotation_std]
    for k, (v, s) in enumerate(zip(values, stds, strict=True)):
        factor = 1e3 if k < 3 else 180.0 / math.pi
        sd = None if s is None else s * factor
        places = _places(sd, 4)
        under = "σ unknown" if sd is None else f"± {_fixed(sd, places)}"
        data = f' data-si="{v!r}"' + ("" if s is None else f' data-std="{s!r}"')
        shown = _fixed(v * factor, places)
        out.append(f'<td class="num"{data}>{shown}<span class="sd">{under}</span></td>')
    return out


def _intrinsics(cam: CameraShown) -> list[tuple[str, str]]:
    std = cam.intrinsics_std if cam.refined else None

    def value(v: float, k: int, unit: str = "") -> str:
        s = None if std is None else std[k]
        if s is None:
            shown = f"{v:.6g}"
            return shown + unit + (" (σ unknown)" if cam.refined else "")
        places = max(2, 1 - math.floor(math.log10(s))) if s > 0 else 6
        return f"{v:.{places}f} ± {s:.{places}f}{unit}"

    K = cam.K
    names = LENS[cam.distortion_model]
    lens = ", ".join(
        f"{names[k] if len(cam.D) == len(names) else f'D[{k}]'} {value(d, 4 + k)}"
        for k, d in enumerate(cam.D)
    )
    how = (
        "refined with the model (dhlog process --refine-intrinsics), ±1σ"
        if cam.refined
        else "held as the log's CameraInfo (or the pipeline's calibration file) gives them, "
        "not fitted"
    )
    return [
        ("Held or refined", escape(how)),
        ("Image", f"{cam.width} × {cam.height} px"),
        (
            "Focal length",
            f"f<sub>x</sub> {value(K[0][0], 0, ' px')}, f<sub>y</sub> {value(K[1][1], 1, ' px')}",
        ),
        (
            "Principal point",
            f"c<sub>x</sub> {value(K[0][2], 2, ' px')}, c<sub>y</sub> {value(K[1][2], 3, ' px')}",
        ),
        ("Lens", f"{escape(cam.distortion_model)}: {lens or 'none'}"),
    ]


def camera_section(cam: CameraShown) -> str:
    """The camera section: the set-up and why, the topic, the detections, the fixed part's
    pose in the robot's base frame and the mounted part's on the flange ±1σ, the intrinsics
    and the corners' σ and RMS."""
    fixed, mounted = cam.fixed, cam.mounted
    held_out = cam.corners - cam.inlier_corners
    setup = [
        ("Camera", f"<code>{escape(cam.topic)}</code>"),
        (
            "Set-up",
            f"{escape(SETUPS[cam.setup])}"
            + (
                f' <span class="muted">({escape(cam.setup_reason)})</span>'
                if cam.setup_reason
                else ""
            ),
        ),
        (
            "Detections",
            f"{escape(cam.detections)}; {cam.frames} frames, {cam.corners} corners"
            + (f" ({held_out} held out as false detections)" if held_out else ""),
        ),
        (
            "Corners",
            f"σ {cam.corner_sigma_px:.3f} px per coordinate (the data's own), reprojection RMS "
            f"{cam.reprojection_rms_px:.3f} px over {cam.inlier_corners} of {cam.corners} "
            f"corners",
        ),
    ]
    labels = ("x [mm]", "y [mm]", "z [mm]", "roll [°]", "pitch [°]", "yaw [°]")
    cols = [_pose_cells(fixed), _pose_cells(mounted)]
    body = "".join(
        f"<tr><th>{label}</th>{cols[0][k]}{cols[1][k]}</tr>" for k, label in enumerate(labels)
    )
    camera_frame = (
        "The camera's frame is its optical one (x right, y down in the image, z along the line "
        "of sight); the board's is OpenCV's, in which its corners are given"
    )
    return "\n".join(
        [
            kv_table(setup, "camera-setup"),
            '<div class="keep"><h3>The camera and the board (hand-eye calibration)</h3>'
            '<table class="grid tool" id="camera-poses"><thead><tr><th></th>'
            f'<th class="num" data-pose="{fixed.name}">{fixed.name}<span class="jt">'
            f"{escape(fixed.what)}</span></th>"
            f'<th class="num" data-pose="{mounted.name}">{mounted.name}<span class="jt">'
            f"{escape(mounted.what)}</span></th></tr></thead><tbody>{body}</tbody></table>",
            '<p class="caption">These poses are in the DH table\'s base frame, with its '
            "conventions (frame 1 as the parameters' footnotes above say: x₁ and d₁ follow the "
            "nominal unless the log has base points), and on its flange (frame "
            "n+1 of the table); their σ is relative to that frame. roll, pitch, yaw: R = "
            "Rz(yaw) Ry(pitch) Rx(roll); a rotation's σ is that of a small rotation about the "
            f"parent frame's x, y, z. {camera_frame}.</p></div>",
            "<h3>Intrinsics</h3>",
            kv_table(_intrinsics(cam), "camera-intrinsics"),
        ]
    )


def camera_frame_caption(cam: CameraShown) -> str:
    """What M, the tool point and frame 1 in M are for a camera (the tool table's caption)."""
    if cam.setup == "eye-to-hand":
        return (
            "M: the camera's frame; the tool point is the board's centre. The rotation's σ is "
            "that of a small rotation about x, y, z."
        )
    return (
        "M: the board's frame moved to the board's centre; the tool point is the camera's "
        "centre. The rotation's σ is that of a small rotation about x, y, z."
    )
