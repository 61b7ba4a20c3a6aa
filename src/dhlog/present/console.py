"""Human-facing views of a result: the console tables and the Markdown of the recording.

Lengths in mm and angles in degrees (or m and rad with ``units="m"``); ±1σ with each value;
measured − nominal when a nominal table was given. The console tables fit an 80-column terminal,
a pipe or a file without a wrapped cell: each value stands above its σ, and the differences to
the nominal are a table of their own. Values are printed to 0.1 µm and 0.0001° (10⁻⁷ m and
10⁻⁶ rad in SI units), or finer where the σ needs it to show two significant digits.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from dhlog.geometry._checks import FloatArray, roll_pitch_yaw
from dhlog.identify.run import ProcessResult
from dhlog.result.document import (
    DisplayRow,
    display_rows,
    display_scales,
    frame_1_origin,
    nominal_difference,
)

#: A σ beyond these (m, rad) is not a measurement's: such a value is labelled undetermined.
UNDETERMINED_LENGTH = 1.0
UNDETERMINED_ANGLE = math.radians(30.0)
#: Widest joint name shown in full in the console (longer ones end in "…"; the JSON has them).
NAME_WIDTH = 18


def _scales(units: str) -> tuple[float, float, str, str]:
    length, angle, lu, au = display_scales(units)
    return length, angle, lu, "°" if au == "deg" else au


def _decimals(units: str) -> tuple[int, int]:
    """Decimals of lengths and angles: 0.1 µm and 0.0001° (10⁻⁷ m, 10⁻⁶ rad)."""
    return (7, 6) if units == "m" else (4, 4)


def _places(sigma: float | None, base: int) -> int:
    """Decimals that show ``sigma`` to two significant digits (at least ``base``, at most
    ``base + 3``)."""
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return base
    return max(base, min(base + 3, 1 - math.floor(math.log10(sigma))))


def _value_sigma(
    value: float, sigma: float | None, held: bool, base: int, undetermined: float = math.inf
) -> tuple[str, str]:
    """The value and its σ line (``± σ``, ``fixed``, or empty when unknown); a σ beyond
    ``undetermined`` (the quantity's physical scale) is labelled so."""
    places = _places(None if held else sigma, base)
    shown = f"{value:.{places}f}"
    if held:
        return shown, "fixed"
    if sigma is None or not math.isfinite(sigma):
        return shown, ""
    if sigma > undetermined:
        return shown, f"undetermined ±{sigma:.3g}"
    return shown, f"± {sigma:.{places}f}"


def _cells(row: DisplayRow, units: str) -> list[tuple[str, str]]:
    """Per parameter (θ, d or β, a, α): the value and its σ line, in display units."""
    lb, ab = _decimals(units)
    length, angle, _, _ = _scales(units)
    out = []
    for k in range(4):
        angular = k in (0, 3) or (k == 1 and row.form == "hayati")
        scale = UNDETERMINED_ANGLE * angle if angular else UNDETERMINED_LENGTH * length
        value, sigma = _value_sigma(
            row.values[k], row.stds[k], row.held[k], ab if angular else lb, scale
        )
        if k == 1 and row.form == "hayati":
            value = f"β {value}"
        out.append((value, sigma))
    return out


def _hayati_rows(rows: list[DisplayRow]) -> list[int]:
    return [i + 1 for i, r in enumerate(rows) if r.form == "hayati"]


def _table_title(rows: list[DisplayRow]) -> str:
    hayati = _hayati_rows(rows)
    if not hayati:
        return "Standard DH, ±1σ under each value (θ, d: offsets at encoder zero)"
    which = ", ".join(str(i) for i in hayati)
    return (
        f"Standard DH with Hayati–Mirmirani row(s) {which}: Rz(θ) Tx(a) Rx(α) Ry(β), β in place "
        "of the ill-conditioned d (nearly parallel axes); ±1σ under each value"
    )


def _name(name: str) -> str:
    return escape(name if len(name) <= NAME_WIDTH else name[: NAME_WIDTH - 1] + "…")


def print_result(console: Console, result: ProcessResult, *, units: str = "mm") -> None:
    """The DH table (±1σ), measured − nominal, the fits, tool and base, how the table was found,
    the FK check, what is held by convention, notes and warnings."""
    length, _, lu, au = _scales(units)
    rows = display_rows(result, units)
    if rows:
        dh = Table(
            title=_table_title(rows), title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False
        )
        dh.add_column("#", justify="right", no_wrap=True)
        dh.add_column("joint", no_wrap=True, max_width=NAME_WIDTH)
        dh.add_column("type", no_wrap=True)
        heads = (f"θ [{au}]", f"d [{lu}]", f"a [{lu}]", f"α [{au}]")
        for head in heads:
            dh.add_column(escape(head), justify="right", no_wrap=True)
        for i, row in enumerate(rows):
            cells = _cells(row, units)
            name = _name(result.joints[i].name)
            dh.add_row(str(i + 1), name, row.type[0].upper(), *(f"{v}\n{s}" for v, s in cells))
        console.print(dh)
        _print_nominal(console, result, rows, units)
    _print_fits(console, result, units)
    _print_tool_and_base(console, result, units)
    _print_holdout(console, result, units)
    _print_terms(console, result, units)
    lines = [("Method", _method_line(result, length, lu))]
    if result.extraction is not None:
        lines.append(("Frame 1", f"origin at {frame_1_origin(result)}"))
    clock = _clock_line(result)
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
    _prose(console, lines)
    _prose(console, [("[yellow]Warning[/]", w) for w in result.warnings], markup=True)


def _print_holdout(console: Console, result: ProcessResult, units: str) -> None:
    """Per held-out check, the position error of the nominal and of the calibrated model at
    poses not used to fit: mean, RMS, 95th percentile, max."""
    if not result.holdout:
        return
    length, _, lu, _ = _scales(units)
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
        if h.registered:
            what += " (placed)"
        for label, stats in (("nominal", h.nominal), ("calibrated", h.calibrated)):
            if stats is None:
                continue
            t.add_row(
                escape(what) if label == "nominal" or h.nominal is None else "",
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
            f"{in_sample.n_points} samples (the fitted ones); a held-out error far above it "
            "means the model fits the session better than it predicts the robot.",
        )
    _prose(console, [("Held out", n) for n in dict.fromkeys(notes)])


def _print_terms(console: Console, result: ProcessResult, units: str) -> None:
    """The models tried beyond the geometry (``--model``): terms, parameters, BIC, held-out
    RMS, which was chosen and why; then the chosen terms with σ and what they move."""
    selection = result.selection
    if selection is None:
        return
    length, _, lu, _ = _scales(units)
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
            escape(c.name),
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
        moved = ", ".join(
            f"joint {i + 1} {math.degrees(v) * 3600:.1f}″"
            for i, v in enumerate(result.deflection_max)
            if v > 0
        )
        lines.append(
            (
                "Deflection",
                f"largest at the samples: {moved}; the target "
                f"{result.deflection_target * length:.{digits}f} {lu} (DH tables, URDF and the UR "
                "file cannot carry these terms: the JSON's nongeometric block does)",
            )
        )
    _prose(console, lines)


def _terms_markdown(result: ProcessResult, length: float, lu: str) -> list[str]:
    """The models tried beyond the geometry and the chosen terms with σ, as Markdown."""
    selection = result.selection
    if selection is None:
        return []
    lines = [
        "",
        f"## Beyond the geometry (--model {selection.mode})",
        "",
        f"| model | terms | parameters | BIC | held-out RMS [{lu}] | σ over the ranges [{lu}] | "
        "chosen | why |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in selection.candidates:
        held = "" if c.holdout_rms is None else f"{c.holdout_rms * length:.4f}"
        lines.append(
            f"| {c.name} | {c.terms} | {c.parameters} | {c.bic:.1f} | {held} | "
            f"{c.range_sd * length:.4f} | {'yes' if c.chosen else ''} | {c.why} |"
        )
    if result.terms is not None:
        lines += ["", "| term | value | σ | unit |", "|---|---|---|---|"]
        for item in result.terms.document(result.terms_std)["terms"]:
            sd = item["std"]
            shown = "not determined" if sd is None or not math.isfinite(sd) else f"{sd:.3g}"
            lines.append(f"| {item['name']} | {item['value']:.4g} | {shown} | {item['unit']} |")
        lines += [
            "",
            f"The terms move the target by up to {result.deflection_target * length:.4f} {lu} "
            "at the session's samples.",
        ]
    return lines


def _prose(console: Console, lines: list[tuple[str, str]], *, markup: bool = False) -> None:
    """Labelled lines of text; long ones wrap under their text, not under the label."""
    if not lines:
        return
    grid = Table.grid(padding=(0, 1))
    grid.add_column(no_wrap=True)
    grid.add_column(overflow="fold")
    for label, text in lines:
        grid.add_row((label if markup else escape(label)) + ":", escape(text))
    console.print(grid)


def _print_nominal(
    console: Console, result: ProcessResult, rows: list[DisplayRow], units: str
) -> None:
    diff = nominal_difference(result, shown=True)
    if diff is None or result.nominal is None:
        return
    length, angle, lu, au = _scales(units)
    lb, ab = _decimals(units)
    t = Table(
        title=f"Measured − nominal ({escape(result.nominal.source)})",
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
        t.add_row(str(i + 1), _name(result.joints[i].name), *cells)
    console.print(t)


def _print_fits(console: Console, result: ProcessResult, units: str) -> None:
    if all(j.fit is None for j in result.joints) and all(j.ok for j in result.joints):
        return  # no sweep (random static poses): nothing but the whole-model fit to show
    length, angle, lu, au = _scales(units)
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
            _name(j.name),
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
            f"[red]joint {j.index} ({escape(j.name)}) not identified:[/] {escape(str(j.reason))}"
        )


def _print_tool_and_base(console: Console, result: ProcessResult, units: str) -> None:
    """The tool point in the last frame and frame 1 in the measurement frame, with σ."""
    ex, std = result.extraction, result.std
    if ex is None or not result.complete:
        return
    length, angle, lu, au = _scales(units)
    lb, ab = _decimals(units)
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
            value, sigma = _value_sigma(float(v) * factor, float(sd) * factor, False, base)
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


def held_lines(result: ProcessResult, rows: list[DisplayRow]) -> list[str]:
    """One line per reason: the parameters held by it (the names of the shown ``rows``)."""
    fixed = result.conditioned.fixed if result.conditioned is not None else result.fixed
    if not fixed or result.extraction is None:
        return []
    n = result.extraction.standard.n
    by_reason: dict[str, list[str]] = {}
    for idx in sorted(fixed):
        if idx < 4 * n:
            row, p = divmod(idx, 4)
            hayati = row < len(rows) and rows[row].form == "hayati"
            name = ("θ", "β" if hayati else "d", "a", "α")[p] + str(row + 1)
        else:
            name = (
                "tool " + "xyz"[idx - 4 * n]
                if idx < 4 * n + 3
                else "base " + ("x", "y", "z", "rx", "ry", "rz")[min(idx - 4 * n - 3, 5)]
            )
        by_reason.setdefault(fixed[idx], []).append(name)
    return [f"{', '.join(names)}: {why}" for why, names in by_reason.items()]


def _clock_line(result: ProcessResult) -> str:
    """The clock offset of the joint states against the tracker, and where it comes from."""
    t = result.timing
    if t is None:
        return ""
    ms = f"{t.offset * 1e3:+.4f} ms"
    if t.source == "estimated" and t.std is not None:
        return (
            f"joint-state stamps {ms} ± {t.std * 1e3:.4f} ms onto the tracker's clock "
            f"(estimated from the data; the pipeline's clock_offset: {t.pipeline * 1e3:+.4f} ms)"
        )
    why = {
        "fixed": "clock_offset_fixed in the pipeline",
        "step-and-measure": "not estimated: samples taken while still (step-and-measure)",
    }.get(t.reason, t.reason)
    return f"joint-state stamps {ms} (the pipeline's clock_offset; {why})"


def _method_line(result: ProcessResult, length: float, lu: str) -> str:
    """How the table was found: the whole-model fit (samples, noise model, χ²/dof) or the seed
    method."""
    w = result.whole
    if w is None:
        return "the seed method (per-joint fits + line geometry)"
    noise = result.noise.described
    if result.noise.model == "isotropic" and result.sigma is not None:
        noise = f"isotropic, σ {result.sigma * length:.4f} {lu} per coordinate"
    return (
        f"whole-model maximum likelihood over {w.n_points} samples; noise {noise}, "
        f"χ²/dof {w.chi2_dof:.2f}"
    )


def _markdown_cell(value: str, sigma: str) -> str:
    return f"{value} {sigma}".strip()


def result_markdown(result: ProcessResult, *, units: str = "mm") -> str:
    """The DH tables and fit summary as Markdown (for the recording's text view)."""
    length, angle, lu, au = _scales(units)
    rows = display_rows(result, units)
    lines = [f"# {result.path.split('/')[-1]}", "", f"## {_table_title(rows)}", ""]
    head = ["joint", "name", "type", f"θ offset [{au}]", f"d [{lu}]", f"a [{lu}]", f"α [{au}]"]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for i, row in enumerate(rows):
        cells = [str(i + 1), result.joints[i].name, row.type[0].upper()]
        cells += [_markdown_cell(v, s) for v, s in _cells(row, units)]
        lines.append("| " + " | ".join(cells) + " |")
    diff = nominal_difference(result, shown=True)
    if diff is not None and result.nominal is not None:
        lb, ab = _decimals(units)
        lines += ["", f"## Measured − nominal ({result.nominal.source})", ""]
        lines.append(f"| joint | Δθ [{au}] | Δd or Δβ | Δa [{lu}] | Δα [{au}] |")
        lines.append("|---|---|---|---|---|")
        for i, d in enumerate(diff):
            hayati = i < len(rows) and rows[i].form == "hayati"
            second = (
                f"Δβ {d[1] * angle:+.{ab}f} {au}" if hayati else f"{d[1] * length:+.{lb}f} {lu}"
            )
            lines.append(
                f"| {i + 1} | {d[0] * angle:+.{ab}f} | {second} | {d[2] * length:+.{lb}f} | "
                f"{d[3] * angle:+.{ab}f} |"
            )
    per_joint = result.validation.per_joint if result.validation is not None else {}
    lines += [
        "",
        "## Fits",
        "",
        "| joint | method | samples | outliers | sweep | "
        f"fit RMS [{lu}] | FK RMS [{lu}] | status |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for j in result.joints:
        f = j.fit
        sweep = ""
        if f is not None:
            prismatic = j.type is not None and j.type.value == "prismatic"
            sweep = f"{f.sweep * length:.1f} {lu}" if prismatic else f"{math.degrees(f.sweep):.1f}°"
        fk = f"{per_joint[j.index][0] * length:.4f}" if j.index in per_joint else ""
        lines.append(
            f"| {j.index} {j.name} | {f.method if f else ''} | {j.rows.size if f else 0} | "
            f"{j.n_outliers if f else ''} | {sweep} | {f'{f.rms * length:.4f}' if f else ''} | "
            f"{fk} | {'ok' if j.ok else 'not identified: ' + str(j.reason)} |"
        )
    aside = result.segmentation.set_aside
    lines += [
        "",
        "Set aside: "
        + (", ".join(f"{k} {v}" for k, v in sorted(aside.items())) if aside else "none")
        + ".",
        "",
        "Nominal: "
        + (result.nominal.source if result.nominal is not None else "none (conventions)")
        + ".",
    ]
    lines += ["", f"Method: {_method_line(result, length, lu)}."]
    if _clock_line(result):
        lines += ["", f"Clock: {_clock_line(result)}."]
    if result.validation is not None:
        v = result.validation
        lines += [
            "",
            f"FK check: RMS {v.rms * length:.4f} {lu}, max {v.max * length:.4f} {lu} "
            f"over {v.n_points} samples (3-D).",
        ]
    if result.extraction is not None:
        lines += ["", f"Frame 1: origin at {frame_1_origin(result)}."]
    lines += _terms_markdown(result, length, lu)
    ex = result.extraction
    if ex is not None and result.complete:
        m, q = ex.modified, ex.reference_pose
        lines += [
            "",
            "## Modified DH (Craig)",
            "",
            f"| joint | α [{au}] | a [{lu}] | θ [{au}] | d [{lu}] |",
            "|---|---|---|---|---|",
        ]
        for i in range(m.n):
            lines.append(
                f"| {i + 1} | {m.alpha[i] * angle:.4f} | {m.a[i] * length:.4f} | "
                f"{m.theta(q)[i] * angle:.4f} | {m.d(q)[i] * length:.4f} |"
            )
        tool = ex.tool_point * length
        shown = ", ".join(f"{v:.4f}" for v in tool)
        lines += ["", f"Tool point (frame {m.n + 1}): ({shown}) {lu}"]
    held = held_lines(result, rows)
    if held:
        lines += ["", "## Held by convention or gauge (not measured)", ""]
        lines += [f"- {line}" for line in held]
    if result.info:
        lines += ["", "## Notes", ""] + [f"- {w}" for w in result.info]
    if result.warnings:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in result.warnings]
    return "\n".join(lines) + "\n"
