"""The console report of a result (:func:`print_result`): the DH table (±1σ under each value),
measured − nominal, the per-joint fits, tool and base, held-out errors, the models tried beyond
the geometry, then the labelled lines (method, frame 1, clock, FK check, what is fixed, notes,
warnings). Every user text (joint names, paths, notes) is printed literally, on one line."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from dhlog.geometry._checks import FloatArray, roll_pitch_yaw
from dhlog.identify.model.beyond import determined
from dhlog.identify.run import Identification
from dhlog.present.console.layout import (
    NAME_WIDTH,
    decimals,
    literal,
    scales,
    short_name,
    table_title,
    value_cells,
    value_sigma,
)
from dhlog.present.console.notes import clock_line, held_lines, method_line, prose
from dhlog.result.document import DisplayRow, display_rows, frame_1_origin, nominal_difference


def print_result(console: Console, result: Identification, *, units: str = "mm") -> None:
    """The DH table (±1σ), measured − nominal, the fits, tool and base, how the table was found,
    the FK check, what is held by convention, notes and warnings."""
    length, _, lu, au = scales(units)
    rows = display_rows(result, units)
    if rows:
        dh = Table(
            title=table_title(rows), title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False
        )
        dh.add_column("#", justify="right", no_wrap=True)
        dh.add_column("joint", no_wrap=True, max_width=NAME_WIDTH)
        dh.add_column("type", no_wrap=True)
        heads = (f"θ [{au}]", f"d [{lu}]", f"a [{lu}]", f"α [{au}]")
        for head in heads:
            dh.add_column(escape(head), justify="right", no_wrap=True)
        for i, row in enumerate(rows):
            cells = value_cells(row, units)
            name = short_name(result.joints[i].name)
            dh.add_row(str(i + 1), name, row.type[0].upper(), *(f"{v}\n{s}" for v, s in cells))
        console.print(dh)
        _print_nominal(console, result, rows, units)
    _print_fits(console, result, units)
    _print_tool_and_base(console, result, units)
    _print_holdout(console, result, units)
    _print_camera(console, result, units)
    _print_terms(console, result, units)
    lines = [("Method", method_line(result, length, lu))]
    if result.extraction is not None:
        lines.append(("Frame 1", f"origin at {frame_1_origin(result)}"))
    clock = clock_line(result)
    if clock:
        lines.append(("Clock", clock))
    val = result.validation
    if val is not None:
        lines.append(
            (
                "FK check",
                f"RMS {val.rms * length:.4f} {lu}, max {val.max * length:.4f} {lu} "
                f"(3-D distance of each of {val.n_points} samples from the FK of the table)",
            )
        )
    aside = result.segmentation.set_aside
    if aside:
        lines.append(("Set aside", ", ".join(f"{k} {v}" for k, v in sorted(aside.items()))))
    lines += [("Fixed", line) for line in held_lines(result, rows)]
    lines += [("Note", note) for note in result.info]
    prose(console, lines)
    prose(console, [("[yellow]Warning[/]", w) for w in result.warnings], markup=True)


def _print_nominal(
    console: Console, result: Identification, rows: list[DisplayRow], units: str
) -> None:
    diff = nominal_difference(result, shown=True)
    if diff is None or result.nominal is None:
        return
    length, angle, lu, au = scales(units)
    lb, ab = decimals(units)
    t = Table(
        title=f"Measured − nominal ({literal(result.nominal.source)})",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    t.add_column("#", justify="right", no_wrap=True)
    t.add_column("joint", no_wrap=True, max_width=NAME_WIDTH)
    for head in (f"Δθ [{au}]", f"Δd [{lu}]", f"Δa [{lu}]", f"Δα [{au}]"):
        t.add_column(escape(head), justify="right", no_wrap=True)
    for i, d in enumerate(diff):
        hayati = i < len(rows) and rows[i].form == "hayati"
        cells = []
        for k in range(4):
            angular = k in (0, 3) or (k == 1 and hayati)
            v = d[k] * (angle if angular else length)
            text = "–" if not math.isfinite(v) else f"{v:+.{ab if angular else lb}f}"
            cells.append(f"Δβ {text}" if k == 1 and hayati else text)
        t.add_row(str(i + 1), short_name(result.joints[i].name), *cells)
    console.print(t)


def _print_fits(console: Console, result: Identification, units: str) -> None:
    if all(j.fit is None for j in result.joints) and all(j.ok for j in result.joints):
        return  # no sweep (random static poses): nothing but the whole-model fit to show
    length, angle, lu, au = scales(units)
    fits = Table(
        title="Per-joint fits (RMS: 3-D distance of each sample from its circle or line; "
        "FK RMS: from the FK of the table)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    fits.add_column("#", justify="right", no_wrap=True)
    fits.add_column("joint", no_wrap=True, max_width=NAME_WIDTH)
    for head in ("samples", "outliers", f"RMS [{lu}]", "sweep", f"FK RMS [{lu}]"):
        fits.add_column(escape(head), justify="right", no_wrap=True)
    fits.add_column("status", no_wrap=True)
    val = result.validation
    for j in result.joints:
        f = j.fit
        sweep = ""
        if f is not None:
            sweep = (
                f"{f.sweep * angle:.1f} {au}"
                if f.kind == "circle"
                else f"{f.sweep * length:.1f} {lu}"
            )
        fk = ""
        if val is not None and j.index in val.per_joint:
            fk = f"{val.per_joint[j.index][0] * length:.4f}"
        fits.add_row(
            str(j.index),
            short_name(j.name),
            str(j.rows.size) if f else "0",
            str(j.n_outliers) if f else "",
            f"{f.rms * length:.4f}" if f else "",
            sweep,
            fk,
            "ok" if j.ok else "[red]failed[/]",
        )
    console.print(fits)
    for j in result.failed:
        console.print(
            f"[red]joint {j.index} ({literal(j.name)}) not identified:[/] {literal(j.reason)}"
        )


def _print_tool_and_base(console: Console, result: Identification, units: str) -> None:
    """The tool point in the last frame and frame 1 in the measurement frame, with σ."""
    ex, std = result.extraction, result.std
    if ex is None or not result.complete:
        return
    length, angle, lu, au = scales(units)
    lb, ab = decimals(units)
    n = ex.standard.n
    s = np.full(9, np.nan) if std is None else std[4 * n : 4 * n + 9]
    t = Table(
        title="Tool and base, ±1σ under each value (M: the measurement frame)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    t.add_column("")
    for head in ("x", "y", "z"):
        t.add_column(head, justify="right", no_wrap=True)

    def row(label: str, values: FloatArray, stds: FloatArray, factor: float, base: int) -> None:
        cells = []
        for v, sd in zip(values, stds, strict=True):
            value, sigma = value_sigma(float(v) * factor, float(sd) * factor, False, base)
            cells.append(f"{value}\n{sigma or 'fixed'}")
        t.add_row(escape(label), *cells)

    row(f"tool point in frame {n + 1} [{lu}]", ex.tool_point, s[0:3], length, lb)
    T = ex.T_measurement_base
    row(f"frame 1 origin in M [{lu}]", T[:3, 3], s[3:6], length, lb)
    row(
        f"frame 1 rotation in M [{au}]\n(roll, pitch, yaw; σ of a small\nrotation about x, y, z)",
        np.array(roll_pitch_yaw(T[:3, :3])),
        s[6:9],
        angle,
        ab,
    )
    console.print(t)


def _print_camera(console: Console, result: Identification, units: str) -> None:
    """A camera calibration's product: the camera's (or board's) pose in the base frame and
    the mounted part's on the flange with σ, the corners' σ, and the held-out check in pixels
    and in the unit of length."""
    cams = result.camera_results or ([] if result.camera is None else [result.camera])
    for cam in cams:
        _print_one_camera(console, cam, units)
    if cams:
        _print_camera_holdout(console, cams[0], units)


def _print_one_camera(console: Console, cam: Any, units: str) -> None:
    """One camera's poses ±σ and its corners."""
    length, _, lu, _ = scales(units)
    t = Table(
        title=escape(f"Camera {cam.name} ({cam.setup}): poses [{lu}, deg] ±1σ"),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    from scipy.spatial.transform import Rotation

    t.add_column("")
    cols = []
    for name, T, std in (
        (cam.fixed_name, cam.T_base_fixed, cam.fixed_std),
        (cam.mounted_name, cam.T_flange_mounted, cam.mounted_std),
    ):
        t.add_column(name, justify="right", no_wrap=True)
        rot = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
        cells = [f"{T[k, 3] * length:.4f} ± {std[3 + k] * length:.4f}" for k in range(3)]
        cells += [f"{rot[k]:.4f} ± {math.degrees(std[k]):.4f}" for k in range(3)]
        cols.append(cells)
    for k, label in enumerate(
        (f"x [{lu}]", f"y [{lu}]", f"z [{lu}]", "roll [°]", "pitch [°]", "yaw [°]")
    ):
        t.add_row(escape(label), *(c[k] for c in cols))
    console.print(t)
    console.print(
        f"corners: σ {cam.sigma_px:.3f} px per coordinate, reprojection RMS {cam.rms_px:.3f} px "
        f"over {cam.inlier_corners} of {cam.corners} corners in {cam.frames} frames; "
        f"{escape(cam.tally)}"
    )


def _print_camera_holdout(console: Console, cam: Any, units: str) -> None:
    """The camera calibration's held-out check: pixels and, for one camera, mm."""
    length, _, lu, _ = scales(units)
    h = cam.holdout
    if h is None:
        return
    t = Table(
        title=escape(
            f"Held-out error of the camera calibration ({h.folds}-fold over {h.frames} frames)"
        ),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for head in ("model", "reprojection RMS [px]", f"board corners RMS [{lu}]"):
        t.add_column(head, justify="left" if head == "model" else "right")

    def mm(value: float | None) -> str:
        return "—" if value is None or not math.isfinite(value) else f"{value * 1e-3 * length:.4f}"

    if h.nominal_px is not None:
        t.add_row("nominal", f"{h.nominal_px:.4f}", mm(h.nominal_mm))
    t.add_row("calibrated", f"{h.calibrated_px:.4f}", mm(h.calibrated_mm))
    t.add_row("(in sample)", f"{h.fit_px:.4f}", mm(h.fit_mm))
    t.add_row("(PnP noise)", "", mm(h.pnp_noise_mm))
    console.print(t)


def _print_holdout(console: Console, result: Identification, units: str) -> None:
    """Per held-out check, the position error of the nominal and of the calibrated model at
    poses not used to fit: mean, RMS, 95th percentile, max."""
    if not result.holdout:
        return
    length, _, lu, _ = scales(units)
    digits = 4 if units == "mm" else 7
    t = Table(
        title=escape(f"Held-out error: 3-D distance at poses not used to fit [{lu}]"),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for head in ("check", "model", "poses", "mean", "RMS", "95 %", "max"):
        t.add_column(head, justify="left" if head in ("check", "model") else "right")
    for h in result.holdout:
        what = f"{h.folds}-fold" if h.kind == "cross-validation" else Path(h.path or "").name
        if h.registered or getattr(h, "tool_replaced", False):
            what += " (placed)"
        for label, stats in (("nominal", h.nominal), ("calibrated", h.calibrated)):
            if stats is None:
                continue
            t.add_row(
                literal(what) if label == "nominal" or h.nominal is None else "",
                label,
                str(stats.n_poses),
                *(
                    f"{v * length:.{digits}f}"
                    for v in (stats.mean, stats.rms, stats.p95, stats.max)
                ),
            )
    console.print(t)
    in_sample = result.validation
    notes = [note for h in result.holdout for note in h.notes]
    if in_sample is not None:
        notes.insert(
            0,
            f"in-sample FK RMS {in_sample.rms * length:.{digits}f} {lu} over "
            f"{in_sample.n_points} samples (the fitted ones, each sample's error); a held-out "
            "error far above it means the model fits the session better than it predicts the "
            "robot. A held-out pose's error is that of its samples' mean, which keeps σ/√n of "
            "the noise: where poses hold many samples, it can lie below the in-sample figure.",
        )
    prose(console, [("Held out", n) for n in dict.fromkeys(notes)])


def deflection_lines(
    result: Identification, length: float, lu: str, digits: int
) -> list[tuple[str, str]]:
    """The "Deflection" line: the terms' largest move per joint and of the target at the
    samples, each with its σ there; one within 2σ of zero (or depending on an undetermined
    term) is said not to be determined, not printed as a measurement
    (:func:`dhlog.identify.model.beyond.determined`)."""
    stds = result.deflection_max_std
    moved: list[str] = []
    unseen: list[str] = []
    for i, v in enumerate(result.deflection_max):
        if v <= 0:
            continue
        sd = float(stds[i]) if i < stds.size else math.nan
        arc = math.degrees(v) * 3600
        shown = (
            f"{arc:.1f}″"
            if not math.isfinite(sd)
            else f"{arc:.1f} ± {math.degrees(sd) * 3600:.1f}″"
        )
        (moved if determined(v, sd) else unseen).append(f"joint {i + 1} {shown}")
    target, sd = result.deflection_target, result.deflection_target_std
    said = f"{target * length:.{digits}f}" + (
        f" ± {sd * length:.{digits}f}" if math.isfinite(sd) else ""
    )
    parts = [
        f"largest at the samples (σ where each is largest): {', '.join(moved) or 'none determined'}"
    ]
    if unseen:
        parts.append(f"not determined (within 2σ of zero): {', '.join(unseen)}")
    if determined(target, sd):
        parts.append(f"the target {said} {lu}")
    else:
        parts.append(
            f"the target's move is not determined ({said} {lu}, within 2σ of zero or of an "
            "undetermined term: the poses do not tell it from the geometry)"
        )
    text = "; ".join(parts) + (
        " (DH tables, URDF and the UR file cannot carry these terms: the JSON's nongeometric "
        "block does)"
    )
    return [("Deflection", text)]


def _print_terms(console: Console, result: Identification, units: str) -> None:
    """The models tried beyond the geometry (``--model``): terms, parameters, BIC, held-out
    RMS, which was chosen and why; then the chosen terms with σ and what they move."""
    selection = result.selection
    if selection is None:
        return
    length, _, lu, _ = scales(units)
    digits = 4 if units == "mm" else 7
    t = Table(
        title=escape(
            f"Model beyond the geometry (--model {selection.mode}): held-out RMS and the σ the "
            f"model predicts over the session's joint ranges [{lu}]"
        ),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for head in ("model", "params", "BIC", "held out", "σ range", ""):
        t.add_column(
            escape(head), justify="left" if head in ("model", "") else "right", no_wrap=True
        )
    for c in selection.candidates:
        t.add_row(
            literal(c.name),
            str(c.parameters),
            f"{c.bic:.1f}",
            "—" if c.holdout_rms is None else f"{c.holdout_rms * length:.{digits}f}",
            f"{c.range_sd * length:.{digits}f}",
            "chosen" if c.chosen else "",
        )
    console.print(t)
    lines = [("Model", f"{c.name}: {c.why}") for c in selection.candidates if c.why]
    terms = result.terms
    if terms is not None:
        doc = terms.document(result.terms_std)
        for item in doc["terms"]:
            sd = item["std"]
            shown = "not determined" if sd is None or not math.isfinite(sd) else f"± {sd:.3g}"
            lines.append(("Term", f"{item['name']} = {item['value']:.4g} {shown} {item['unit']}"))
        lines += deflection_lines(result, length, lu, digits)
    prose(console, lines)
