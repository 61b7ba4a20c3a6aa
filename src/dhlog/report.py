"""Human-facing views of a result: the console tables and the Markdown of the recording.

Lengths in mm and angles in degrees (or m and rad with ``units="m"``); ±1σ beside each value;
measured − nominal when a nominal table was given.
"""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from dhlog.process import ProcessResult
from dhlog.result import display_rows, display_scales, nominal_difference

NAMES = ("θ", "d", "a", "α")


def _scales(units: str) -> tuple[float, float, str, str]:
    length, angle, lu, au = display_scales(units)
    return length, angle, lu, "°" if au == "deg" else au


def _rows(result: ProcessResult, units: str) -> list[list[str]]:
    length, angle, _, _ = _scales(units)
    diff = nominal_difference(result)
    factors = [angle, length, length, angle]
    out = []
    for i, (kind, values, stds, held) in enumerate(display_rows(result, units)):
        cells = [str(i + 1), escape(result.joints[i].name), kind[0].upper()]
        for k in range(4):
            sd = " fixed" if held[k] else ("" if stds[k] is None else f" ± {stds[k]:.4f}")
            cells.append(f"{values[k]:.4f}{sd}")
        if diff is not None:
            cells += [f"{diff[i][k] * factors[k]:+.4f}" for k in range(4)]
        out.append(cells)
    return out


def print_result(console: Console, result: ProcessResult, *, units: str = "mm") -> None:
    """The DH table (±1σ, and measured − nominal), the fit summary, validation and warnings."""
    _, _, lu, au = _scales(units)
    dh = Table(title="Standard DH (θ is the offset at encoder zero)", title_justify="left")
    for col in ("joint", "name", "type", f"θ [{au}]", f"d [{lu}]", f"a [{lu}]", f"α [{au}]"):
        dh.add_column(escape(col), justify="right" if "[" in col else "left")
    if result.nominal is not None:
        for col in (f"Δθ [{au}]", f"Δd [{lu}]", f"Δa [{lu}]", f"Δα [{au}]"):
            dh.add_column(escape(col), justify="right", style="cyan")
    for cells in _rows(result, units):
        dh.add_row(*cells)
    if dh.row_count:
        console.print(dh)
    fits = Table(title="Fits", title_justify="left")
    for col in (
        "joint",
        "type",
        "method",
        "samples",
        "outliers",
        f"RMS [{lu}]",
        "sweep",
        f"FK RMS [{lu}]",
        "status",
    ):
        right = col in ("samples", "outliers") or "[" in col
        fits.add_column(escape(col), justify="right" if right else "left")
    length, angle, _, _ = _scales(units)
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
            f"{j.index} {j.name}",
            j.type.value[0].upper() if j.type else "?",
            f.method if f else "",
            str(j.rows.size) if f else "0",
            str(j.n_outliers) if f else "",
            f"{f.rms * length:.4f}" if f else "",
            sweep,
            fk,
            "ok" if j.ok else f"[red]not identified: {escape(str(j.reason))}[/]",
        )
    console.print(fits)
    console.print(_method_line(result, length, lu))
    if val is not None:
        console.print(
            f"FK check: RMS {val.rms * length:.4f} {lu}, max {val.max * length:.4f} {lu} "
            f"over {val.n_points} samples."
        )
    aside = result.segmentation.set_aside
    if aside:
        console.print("Set aside: " + ", ".join(f"{k} {v}" for k, v in sorted(aside.items())))
    for w in result.warnings:
        console.print(f"[yellow]warning:[/] {escape(w)}", soft_wrap=True)


def _method_line(result: ProcessResult, length: float, lu: str) -> str:
    """How the table was found: the whole-model fit (samples, noise model, χ²/dof) or the seed
    method."""
    w = result.whole
    if w is None:
        return "Method: the seed method (per-joint fits + line geometry)."
    noise = result.noise.described
    if result.noise.model == "isotropic" and result.sigma is not None:
        noise = f"isotropic, σ {result.sigma * length:.4f} {lu} per coordinate"
    return (
        f"Method: whole-model maximum likelihood over {w.n_points} samples "
        f"({noise}; χ²/dof {w.chi2_dof:.2f})."
    )


def result_markdown(result: ProcessResult, *, units: str = "mm") -> str:
    """The DH tables and fit summary as Markdown (for the recording's text view)."""
    _, _, lu, au = _scales(units)
    lines = [f"# {result.path.split('/')[-1]}", "", "## Standard DH (±1σ)", ""]
    head = ["joint", "name", "type", f"θ offset [{au}]", f"d [{lu}]", f"a [{lu}]", f"α [{au}]"]
    if result.nominal is not None:
        head += [f"Δθ [{au}]", f"Δd [{lu}]", f"Δa [{lu}]", f"Δα [{au}]"]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for cells in _rows(result, units):
        lines.append("| " + " | ".join(cells) + " |")
    ex = result.extraction
    if ex is not None and result.complete:
        length, angle, _, _ = _scales(units)
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
    if result.hayati:
        length, angle, _, _ = _scales(units)
        lines += [
            "",
            "## Nearly parallel pairs (Hayati–Mirmirani, β in place of d)",
            "",
            f"| joints | θ [{au}] | a [{lu}] | α [{au}] | β [{au}] |",
            "|---|---|---|---|---|",
        ]
        for h in result.hayati:
            lines.append(
                f"| {h.joints[0]}–{h.joints[1]} | {h.theta * angle:.4f} | {h.a * length:.4f} | "
                f"{h.alpha * angle:.5f} | {h.beta * angle:.5f} |"
            )
    lines += [
        "",
        "## Fits",
        "",
        f"| joint | method | samples | outliers | RMS [{lu}] | status |",
        "|---|---|---|---|---|---|",
    ]
    length = _scales(units)[0]
    for j in result.joints:
        f = j.fit
        lines.append(
            f"| {j.index} {j.name} | {f.method if f else ''} | {j.rows.size if f else 0} | "
            f"{j.n_outliers if f else ''} | {f'{f.rms * length:.4f}' if f else ''} | "
            f"{'ok' if j.ok else 'not identified: ' + str(j.reason)} |"
        )
    lines += ["", _method_line(result, length, lu)]
    if result.validation is not None:
        v = result.validation
        lines += [
            "",
            f"FK check: RMS {v.rms * length:.4f} {lu}, max {v.max * length:.4f} {lu} "
            f"over {v.n_points} samples.",
        ]
    if result.warnings:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in result.warnings]
    return "\n".join(lines) + "\n"
