"""The Markdown of a result for the recording's text view (``report/dh_table``): the DH tables
with ±1σ, measured − nominal, the fits, method, clock, FK check, the terms beyond the geometry,
the modified (Craig) table, what is held, notes and warnings."""

from __future__ import annotations

import math

from dhlog.identify.model.beyond import determined
from dhlog.identify.run import Identification
from dhlog.present.console.layout import decimals, scales, table_title, value_cells
from dhlog.present.console.notes import clock_line, held_lines, method_line
from dhlog.result.document import display_rows, frame_1_origin, nominal_difference


def _terms_markdown(result: Identification, length: float, lu: str) -> list[str]:
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
        target, sd = result.deflection_target, result.deflection_target_std
        said = f"{target * length:.4f}" + (f" ± {sd * length:.4f}" if math.isfinite(sd) else "")
        lines += [
            "",
            f"The terms move the target by up to {said} {lu} at the session's samples"
            + ("." if determined(target, sd) else ": not determined (within 2σ of zero)."),
        ]
    return lines


def _markdown_cell(value: str, sigma: str) -> str:
    return f"{value} {sigma}".strip()


def result_markdown(result: Identification, *, units: str = "mm") -> str:
    """The DH tables and fit summary as Markdown (for the recording's text view)."""
    length, angle, lu, au = scales(units)
    rows = display_rows(result, units)
    lines = [f"# {result.path.split('/')[-1]}", "", f"## {table_title(rows)}", ""]
    head = ["joint", "name", "type", f"θ offset [{au}]", f"d [{lu}]", f"a [{lu}]", f"α [{au}]"]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for i, row in enumerate(rows):
        cells = [str(i + 1), result.joints[i].name, row.type[0].upper()]
        cells += [_markdown_cell(v, s) for v, s in value_cells(row, units)]
        lines.append("| " + " | ".join(cells) + " |")
    diff = nominal_difference(result, shown=True)
    if diff is not None and result.nominal is not None:
        lb, ab = decimals(units)
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
    lines += ["", f"Method: {method_line(result, length, lu)}."]
    if clock_line(result):
        lines += ["", f"Clock: {clock_line(result)}."]
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
