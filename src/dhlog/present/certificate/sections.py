"""The sections of the certificate page as HTML: the summary cards, the identification
(robot, files, SHA-256s), the accuracy at held-out poses, the DH parameters (±1σ, measured −
nominal, fixed ones with their reason), tool and base, per-joint residuals, the terms beyond the
geometry; every text from the files escaped. Lengths in mm and angles in degrees, as the
console shows them."""

from __future__ import annotations

import html
import math
from datetime import datetime
from typing import Any

from dhlog._version import __version__
from dhlog.present.certificate.plots import histogram_svg, residual_bars_svg
from dhlog.present.certificate.shown import Parameter, Result, ShownRow, Stats, Triple
from dhlog.present.certificate.sources import Nominal, Sources

#: A σ beyond these (m, rad) is not a measurement's: the parameter is shown as undetermined
#: (as on the console).
UNDETERMINED_LENGTH = 1.0
UNDETERMINED_ANGLE = math.radians(30.0)

PARAMETER_SYMBOLS = {"theta": "θ", "d": "d", "beta": "β", "a": "a", "alpha": "α", "scale": "s"}


def escape(text: object) -> str:
    """``text`` safe in HTML text and attribute values."""
    return html.escape(str(text), quote=True)


def _places(sigma: float | None, base: int) -> int:
    """Decimals that show ``sigma`` to two significant digits (``base`` to ``base + 3``), as
    the console does."""
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return base
    return max(base, min(base + 3, 1 - math.floor(math.log10(sigma))))


def _fixed(value: float, places: int, *, sign: bool = False) -> str:
    text = f"{value:+.{places}f}" if sign else f"{value:.{places}f}"
    if set(text.lstrip("+-")) <= set("0."):
        text = text.lstrip("+-")
        return f"+{text}" if sign else text
    return text


def _display(p: Parameter) -> tuple[float, str, float]:
    """Display factor, unit and the σ beyond which the parameter is undetermined (display
    units)."""
    if p.name == "scale":
        return 1.0, "", math.inf
    if p.angular:
        return 180.0 / math.pi, "°", math.degrees(UNDETERMINED_ANGLE)
    return 1e3, "mm", UNDETERMINED_LENGTH * 1e3


def _parameter_cell(p: Parameter, joint: int, notes: dict[str, list[str]]) -> str:
    """One parameter: its value, ±1σ (or ``fixed`` with the footnote of its reason, or
    ``undetermined``) and measured − nominal, each on its own line; SI values in ``data-*``."""
    factor, unit, undetermined = _display(p)
    base = 6 if p.name == "scale" else 4
    sd = None if p.std is None else p.std * factor
    places = _places(None if p.fixed else sd, base)
    value = _fixed(p.value * factor, places) + (unit if unit == "°" else "")
    if p.name == "beta":
        value = f"β {value}"
    data = f' data-parameter="{p.name}" data-si="{p.value!r}"'
    lines = [f'<span class="v">{value}</span>']
    if p.fixed is not None:
        held = notes.setdefault(p.fixed, [])
        held.append(f"{PARAMETER_SYMBOLS[p.name]}{joint}")
        mark = list(notes).index(p.fixed) + 1
        data += ' data-fixed="true"'
        lines.append(f'<span class="sd held">fixed <sup>{mark}</sup></span>')
    elif sd is None:
        lines.append('<span class="sd">σ unknown</span>')
    elif sd > undetermined:
        lines.append(f'<span class="sd bad">undetermined ± {sd:.3g}</span>')
    else:
        data += f' data-std="{p.std!r}"'
        lines.append(f'<span class="sd">± {_fixed(sd, places)}</span>')
    if p.delta is not None:
        data += f' data-delta="{p.delta!r}"'
        lines.append(f'<span class="dn">Δ {_fixed(p.delta * factor, places, sign=True)}</span>')
    cls = "p held" if p.fixed is not None else "p"
    return f'<td class="{cls}"{data}>{"".join(lines)}</td>'


def parameter_table(rows: list[ShownRow], nominal: Nominal | None) -> str:
    """The DH table: one row per joint, each parameter's value with ±1σ and measured − nominal
    under it; the reasons of fixed parameters as footnotes."""
    scales = any(p.name == "scale" for r in rows for p in r.parameters)
    heads = ["θ [°]", "d [mm]", "a [mm]", "α [°]"] + (["encoder scale"] if scales else [])
    out = [
        '<table id="parameters" class="grid params"><thead><tr><th class="c">#</th>'
        "<th>Joint</th><th>Form</th>"
        + "".join(f'<th class="num">{h}</th>' for h in heads)
        + "</tr></thead><tbody>"
    ]
    notes: dict[str, list[str]] = {}
    for row in rows:
        form = "Hayati–Mirmirani" if row.form == "hayati" else "DH"
        cells = [_parameter_cell(p, row.joint, notes) for p in row.parameters]
        if scales and len(cells) == 4:
            cells.append("<td></td>")
        out.append(
            f'<tr data-joint="{row.joint}" data-form="{row.form}"><td class="c">{row.joint}</td>'
            f'<td class="jn">{escape(row.name)}<span class="jt">{escape(row.type)}</span></td>'
            f'<td class="form">{form}</td>{"".join(cells)}</tr>'
        )
    out.append("</tbody></table>")
    legend = "Under each value: ±1σ"
    legend += (
        f", then Δ = measured − nominal ({escape(nominal.name)})." if nominal is not None else "."
    )
    if any(r.form == "hayati" for r in rows):
        legend += " On a Hayati–Mirmirani row, β [°] stands in place of d."
    out.append(f'<p class="caption">{legend}</p>')
    if notes:
        out.append('<ol class="footnotes" id="fixed-reasons">')
        for reason, held in notes.items():
            out.append(f"<li>{', '.join(held)} fixed: {escape(reason)}</li>")
        out.append("</ol>")
    return "\n".join(out)


def kv_table(items: list[tuple[str, str]], table_id: str) -> str:
    """A key–value table; values are HTML already escaped by the caller."""
    body = "".join(f"<tr><th>{escape(k)}</th><td>{v}</td></tr>" for k, v in items)
    return f'<table class="kv" id="{table_id}">{body}</table>'


def _stat_cells(s: Stats | None) -> str:
    if s is None:
        return '<td class="num" colspan="5">no nominal given to dhlog process</td>'
    return f'<td class="num">{s.n_poses}</td>' + "".join(
        f'<td class="num" data-si="{v!r}">{v * 1e3:.4f}</td>' for v in (s.mean, s.rms, s.p95, s.max)
    )


def accuracy_section(result: Result) -> str:
    if not result.checks:
        fit = (
            f" The in-sample FK RMS, {result.fk_rms * 1e3:.4f} mm over the fitted samples, says "
            "how well the model fits the session, not how well it predicts the robot."
            if result.fk_rms is not None
            else ""
        )
        return (
            '<div class="alert" id="no-holdout"><strong>No held-out validation.</strong> This '
            "result was not checked at poses left out of the fit, so its accuracy on the robot "
            f"is not shown.{escape(fit)} Run <code>dhlog process LOG --holdout 5</code> (or "
            "<code>--validate OTHER_LOG</code>) and report again.</div>"
        )
    parts = [
        '<table class="grid stats" id="holdout"><thead><tr><th>Check</th><th>Model</th>'
        '<th class="num">Poses</th><th class="num">Mean [mm]</th><th class="num">RMS [mm]</th>'
        '<th class="num">95 % [mm]</th><th class="num">Max [mm]</th></tr></thead><tbody>'
    ]
    for check in result.checks:
        parts.append(
            f'<tr class="nominal"><th rowspan="2">{escape(check.label)}</th><td>nominal</td>'
            f"{_stat_cells(check.nominal)}</tr>"
        )
        parts.append(
            f'<tr class="calibrated"><td>calibrated</td>{_stat_cells(check.calibrated)}</tr>'
        )
    rms = "—" if result.fk_rms is None else f"{result.fk_rms * 1e3:.4f}"
    top = "—" if result.fk_max is None else f"{result.fk_max * 1e3:.4f}"
    parts.append(
        f'<tr class="insample"><th>in-sample fit</th><td>calibrated</td>'
        f'<td class="num">{result.fk_points} samples</td><td class="num">—</td>'
        f'<td class="num">{rms}</td><td class="num">—</td><td class="num">{top}</td></tr>'
    )
    parts.append("</tbody></table>")
    parts.append(
        '<p class="caption">3-D distance [mm] between the measured target and the model\'s '
        "prediction at poses not used to fit it (held out), before (the nominal, its base and "
        "tool placed on the poses the calibration was fitted on, never on the poses scored) and "
        "after calibration; in a K-fold check each fold's calibration is made again from its "
        "training poses alone, the model's choice of terms and the pairs held parallel "
        "included, and the nominal placed on the same poses; at another session's log both "
        "models are then given the same freedom, placed on the same poses (the base where the "
        "tracker moved, the tool where the probe was re-mounted, as its note says); the "
        "in-sample row is the FK "
        "residual at the fitted samples. A held-out error far above the in-sample one means the "
        "model fits the session better than it predicts the robot.</p>"
    )
    for k, check in enumerate(result.checks):
        for note in check.notes:
            parts.append(f'<p class="caption">{escape(check.label)}: {escape(note)}</p>')
        svg = histogram_svg(check, result.fk_rms, f"h{k}")
        if svg is None:
            parts.append(
                f'<p class="muted">{escape(check.label)}: no per-pose errors (the '
                "&lt;stem&gt;.holdout.csv that dhlog process writes is not beside the result), "
                "so no histogram.</p>"
            )
        else:
            parts.append(
                f'<figure class="plot">{svg}<figcaption>Held-out error per pose, '
                f"{escape(check.label)}: nominal and calibrated (log scale).</figcaption></figure>"
            )
    return "\n".join(parts)


def summary_cards(result: Result, held: list[tuple[str, str, str]] | None = None) -> str:
    """The cards at the top; ``held``: the held-out cards of a result without
    ``validation.holdout`` (a camera calibration's, in pixels and mm)."""
    cards = []
    if result.checks:
        c = result.checks[0]
        cards.append(("Held-out RMS, calibrated", f"{c.calibrated.rms * 1e3:.4f} mm", "good"))
        if c.nominal is not None:
            cards.append(("Held-out RMS, nominal", f"{c.nominal.rms * 1e3:.4f} mm", ""))
            if c.calibrated.rms > 0:
                cards.append(
                    ("Improvement", f"{c.nominal.rms / c.calibrated.rms:.1f}× lower", "good")
                )
    elif held is not None:
        cards += held
    else:
        cards.append(("Held-out validation", "none: run --holdout 5", "bad"))
    if result.fk_rms is not None:
        cards.append(("In-sample FK RMS", f"{result.fk_rms * 1e3:.4f} mm", ""))
    cards.append(("Warnings", str(len(result.warnings)), "warn" if result.warnings else "good"))
    return (
        '<div class="cards">'
        + "".join(
            f'<div class="card {cls}"><div class="k">{escape(k)}</div>'
            f'<div class="v">{escape(v)}</div></div>'
            for k, v, cls in cards
        )
        + "</div>"
    )


def tool_table(tool: list[Triple], frame: str | None = None) -> str:
    """The tool point and frame 1 in M ±1σ; ``frame``: what M is (HTML), where not the tracker's
    measurement frame (the caption's first sentences)."""
    if not tool:
        return ""
    rows = []
    held_by = []
    for triple in tool:
        label, values, stds, fixed = triple.label, triple.values, triple.stds, triple.fixed
        if fixed:
            held_by.append(f"{label.split(' [')[0]} {', '.join(fixed)} fixed: {triple.reason}")
        angular = "rotation" in label
        factor = 180.0 / math.pi if angular else 1e3
        cells = []
        for k, (v, s) in enumerate(zip(values, stds, strict=True)):
            held = "xyz"[k] in fixed
            sd = None if s is None else s * factor
            places = _places(None if held else sd, 4)
            under = "fixed" if held else ("" if sd is None else f"± {_fixed(sd, places)}")
            cells.append(
                f'<td class="num">{_fixed(v * factor, places)}<span class="sd">{under}</span></td>'
            )
        rows.append(f"<tr><th>{escape(label)}</th>{''.join(cells)}</tr>")
    return (
        '<div class="keep"><h3>Tool and base</h3><table class="grid tool" id="tool"><thead>'
        "<tr><th></th>"
        '<th class="num">x</th><th class="num">y</th><th class="num">z</th>'
        "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>"
        '<p class="caption">'
        + (
            frame
            or "M: the tracker's measurement frame. The rotation's σ is that of a small rotation "
            "about x, y, z."
        )
        + "".join(f" {escape(h)}." for h in held_by)
        + "</p></div>"
    )


def residual_section(result: Result) -> str:
    svg = residual_bars_svg(result.residuals, "r")
    failed = [r for r in result.residuals if r.error]
    parts = []
    if svg is None:
        parts.append(
            '<p class="muted" id="no-joint-residuals">The result carries no per-joint residuals: '
            "no joint was swept alone (random static poses or coupled moves), so there are no "
            "per-joint fits; the held-out errors above are the check per pose.</p>"
        )
    else:
        rows = []
        for r in result.residuals:

            def cell(v: float | None) -> str:
                return "—" if v is None else f"{v * 1e3:.4f}"

            rows.append(
                f"<tr><td>{r.joint}</td><td>{escape(r.name)}</td>"
                f'<td class="num">{"—" if r.fit_points is None else r.fit_points}</td>'
                f'<td class="num">{cell(r.fit_rms)}</td><td class="num">{cell(r.fk_rms)}</td>'
                f'<td class="num">{cell(r.fk_max)}</td></tr>'
            )
        parts.append(
            f'<figure class="plot">{svg}<figcaption>Per joint: the RMS of its own circle (or '
            "line) fit, and the RMS and max of the table's FK residual at its samples.</figcaption>"
            "</figure>"
        )
        parts.append(
            '<table class="grid" id="joint-residuals"><thead><tr><th>#</th><th>Joint</th>'
            "<th>Samples</th><th>Fit RMS [mm]</th><th>FK RMS [mm]</th><th>FK max [mm]</th></tr>"
            "</thead><tbody>" + "".join(rows) + "</tbody></table>"
        )
    for r in failed:
        parts.append(
            f'<p class="alert">Joint {r.joint} ({escape(r.name)}) was not identified: '
            f"{escape(r.error)}</p>"
        )
    return "\n".join(parts)


def terms_section(block: dict[str, Any] | None) -> str:
    if block is None:
        return (
            '<p class="muted">No search beyond the geometry (dhlog process --model geometric): '
            "the model is the DH table alone.</p>"
        )
    parts = []
    mode, chosen = block["mode"], block["chosen"]
    parts.append(
        f"<p>Model asked: <strong>{escape(mode or '?')}</strong>; chosen: "
        f"<strong>{escape(chosen or '?')}</strong>.</p>"
    )
    if block["candidates"]:
        rows = []
        for c in block["candidates"]:
            held = "—" if c["holdout_rms"] is None else f"{c['holdout_rms'] * 1e3:.4f}"
            rng = "—" if c["range_sd"] is None else f"{c['range_sd'] * 1e3:.4f}"
            bic = "—" if c["bic"] is None else f"{c['bic']:.1f}"
            mark = ' class="chosen"' if c["chosen"] else ""
            rows.append(
                f'<tr{mark}><td>{escape(c["model"])}</td><td class="num">{c["parameters"]}</td>'
                f'<td class="num">{bic}</td><td class="num">{held}</td><td class="num">{rng}</td>'
                f"<td>{'chosen' if c['chosen'] else ''}</td><td>{escape(c['why'])}</td></tr>"
            )
        parts.append(
            '<table class="grid" id="candidates"><thead><tr><th>Model</th><th>Parameters</th>'
            "<th>BIC</th><th>Held-out RMS [mm]</th><th>σ over the ranges [mm]</th><th></th>"
            "<th>Why</th></tr></thead><tbody>" + "".join(rows) + "</tbody></table>"
        )
    if block["terms"]:
        rows = []
        for t in block["terms"]:
            sd = "—" if t["std"] is None else f"{t['std']:.4g}"
            rows.append(
                f"<tr><td>{escape(t['name'])}</td><td>{escape(t['kind'])}</td>"
                f'<td class="num">{t["joint"]}</td><td>{escape(t["lump"])}</td>'
                f'<td class="num" data-si="{t["value"]!r}">{t["value"]:.6g}</td>'
                f'<td class="num">± {sd}</td><td>{escape(t["unit"])}</td></tr>'
            )
        parts.append(
            '<table class="grid" id="terms"><thead><tr><th>Term</th><th>Kind</th><th>Joint</th>'
            "<th>Lump</th><th>Value</th><th>±1σ</th><th>Unit</th></tr></thead><tbody>"
            + "".join(rows)
            + "</tbody></table>"
        )
        if block["max_target_displacement"] is not None:
            parts.append(
                '<p class="caption">The terms move the target by up to '
                f"{block['max_target_displacement'] * 1e3:.4f} mm at the session's poses. Every "
                "FK of this result adds Δq = Σ value · b(q) to the table's joint values.</p>"
            )
    else:
        parts.append(
            '<p class="muted" id="no-terms">No terms beyond the geometry were kept: the '
            "session does not show them above the noise.</p>"
        )
    return "\n".join(parts)


def bullet_list(items: list[str], cls: str, empty: str) -> str:
    if not items:
        return f'<p class="muted">{escape(empty)}</p>'
    return f'<ul class="{cls}">' + "".join(f"<li>{escape(t)}</li>" for t in items) + "</ul>"


def identification_table(
    sources: Sources, result: Result, robot: str | None, nominal: Nominal | None, now: datetime
) -> str:
    log = sources.log
    items: list[tuple[str, str]] = []
    robot_text = (
        escape(robot)
        if robot
        else '<span class="muted">not named (the result JSON does not record it: pass '
        "--robot)</span>"
    )
    items.append(("Robot", robot_text))
    joints = ", ".join(
        f"{escape(n)} ({escape(t or 'not identified')})"
        for n, t in zip(result.joint_names, result.joint_types, strict=True)
    )
    items.append(("Joints", f"{result.n_joints}: {joints}"))
    items.append(
        (
            "Nominal",
            escape(nominal.name)
            if nominal is not None
            else '<span class="muted">not recorded in the result JSON; pass --nominal (the one '
            "given to dhlog process) for measured − nominal</span>",
        )
    )
    items.append(("Result file", f"<code>{escape(sources.result_path.name)}</code>"))
    items.append(
        ("Result SHA-256", f'<code class="hash" id="result-sha256">{sources.result_sha256}</code>')
    )
    stamp = "%Y-%m-%d %H:%M UTC"
    items.append(
        (
            "Result date",
            f"{sources.result_modified.strftime(stamp)} (the file's modification time; the "
            "result JSON records no date)",
        )
    )
    items.append(("Report date", now.strftime(stamp)))
    items.append(
        (
            "Log",
            f"<code>{escape(result.log_name or '—')}</code>, "
            f"pipeline {escape(result.pipeline or '—')}",
        )
    )
    recorded = result.log_sha256 or "—"
    items.append(
        (
            "Log SHA-256, recorded",
            f'<code class="hash" id="log-sha256-recorded">{escape(recorded)}</code> (when the '
            "result was computed)",
        )
    )
    if log.sha256 is None:
        computed = '<span class="warn" id="log-sha256">log not found, hash not computed</span>'
        if log.searched:
            computed += (
                ' <span class="muted">(looked for '
                + ", ".join(f"<code>{escape(p)}</code>" for p in log.searched)
                + ")</span>"
            )
    else:
        same = log.sha256 == result.log_sha256
        verdict = (
            '<span class="good">matches the recorded hash</span>'
            if same
            else '<span class="bad">differs from the recorded hash: not the log this result was '
            "computed from</span>"
        )
        computed = (
            f'<code class="hash" id="log-sha256">{log.sha256}</code> {verdict} '
            f'<span class="muted">({escape(log.path)})</span>'
        )
    items.append(("Log SHA-256, now", computed))
    versions = f"result {escape(result.version)}, report {escape(__version__)}"
    items.append(("dhlog version", versions))
    if result.method:
        items.append(("Method", escape(result.method)))
    return kv_table(items, "identification")
