"""The certificate page (:func:`certificate_html`): one self-contained HTML page of a result,
its sections (:mod:`~dhlog.present.certificate.sections`) under inline CSS, no script and no
external resource."""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime

from dhlog._version import __version__
from dhlog.errors import InputError
from dhlog.present.certificate.camera_section import (
    camera_accuracy,
    camera_cards,
    camera_frame_caption,
    camera_section,
)
from dhlog.present.certificate.holdout import read_holdout_csv
from dhlog.present.certificate.iso9283 import Iso9283Shown
from dhlog.present.certificate.iso9283_section import iso9283_section
from dhlog.present.certificate.read import read_result
from dhlog.present.certificate.sections import (
    accuracy_section,
    bullet_list,
    escape,
    identification_table,
    kv_table,
    parameter_table,
    residual_section,
    summary_cards,
    terms_section,
    tool_table,
)
from dhlog.present.certificate.shown import nominal_deltas
from dhlog.present.certificate.sources import Nominal, Sources

CSS = """
:root { --ink: #1d2733; --muted: #5f6b7a; --rule: #d5dbe1; --head: #1f3a5f; --bg: #f6f7f9;
  --good: #1e7a46; --warn: #9a6700; --bad: #b42318; --nom: #c8553d; --cal: #2a6f97; }
* { box-sizing: border-box; }
html { background: #e9ecef; }
body { margin: 0; color: var(--ink); font: 13px/1.45 "Helvetica Neue", Helvetica, Arial,
  "Liberation Sans", "DejaVu Sans", sans-serif; }
.sheet { max-width: 1120px; margin: 24px auto; background: #fff; padding: 36px 48px 28px;
  box-shadow: 0 1px 4px rgba(0,0,0,.12); }
header { display: flex; justify-content: space-between; align-items: flex-end; gap: 24px;
  border-bottom: 3px solid var(--head); padding-bottom: 10px; margin-bottom: 14px; }
h1 { font-size: 24px; margin: 0; color: var(--head); letter-spacing: .01em; }
header .sub { margin: 2px 0 0; color: var(--muted); }
header .robot { text-align: right; font-size: 15px; font-weight: 600; max-width: 45%;
  overflow-wrap: anywhere; }
header .robot small { display: block; font-weight: 400; color: var(--muted); font-size: 12px; }
h2 { font-size: 15px; color: var(--head); margin: 22px 0 8px; padding-bottom: 3px;
  border-bottom: 1px solid var(--rule); break-after: avoid; }
h2 .n { color: var(--muted); font-weight: 400; margin-right: 6px; }
h3 { font-size: 13px; margin: 14px 0 4px; color: var(--head); }
p { margin: 6px 0; }
code { font: 12px/1.3 "DejaVu Sans Mono", "Liberation Mono", Menlo, Consolas, monospace; }
code.hash { word-break: break-all; }
.cards { display: flex; gap: 10px; margin: 10px 0 4px; flex-wrap: wrap; }
.card { flex: 1 1 150px; border: 1px solid var(--rule); border-left: 4px solid var(--rule);
  padding: 6px 10px; background: var(--bg); }
.card .k { font-size: 11px; color: var(--muted); text-transform: uppercase; letter-spacing: .04em; }
.card .v { font-size: 18px; font-weight: 600; font-variant-numeric: tabular-nums; }
.card.good { border-left-color: var(--good); } .card.warn { border-left-color: var(--warn); }
.card.bad { border-left-color: var(--bad); } .card.bad .v { color: var(--bad); }
table { border-collapse: collapse; }
table.kv { width: 100%; }
table.kv th { text-align: left; font-weight: 600; width: 190px; vertical-align: top;
  padding: 3px 12px 3px 0; color: var(--muted); }
table.kv td { padding: 3px 0; overflow-wrap: anywhere; }
table.kv tr + tr > * { border-top: 1px solid #eef0f3; }
table.grid { margin: 6px 0; font-variant-numeric: tabular-nums; width: 100%; }
table.grid th, table.grid td { padding: 4px 10px; border-bottom: 1px solid #e6e9ed;
  text-align: left; vertical-align: top; }
table.grid thead th { border-bottom: 1.5px solid var(--head); font-size: 12px; color: var(--head);
  white-space: nowrap; vertical-align: bottom; }
table.grid .num, table.grid td.p { text-align: right; white-space: nowrap; }
table.grid .c { text-align: center; width: 2em; }
table.stats { width: auto; min-width: 70%; }
table.stats td.num, table.stats th.num { min-width: 6.5em; }
table.params td.p { padding-top: 5px; padding-bottom: 5px; }
td.p span { display: block; }
td.p .v { font-size: 13.5px; }
td.p .sd { font-size: 11.5px; color: var(--muted); }
td.p .dn { font-size: 11.5px; color: var(--nom); }
td.p.held .v { color: var(--muted); }
td.jn { font-weight: 600; overflow-wrap: anywhere; }
.jt { display: block; font-weight: 400; color: var(--muted); font-size: 11px; }
td.form { color: var(--muted); font-size: 12px; width: 9em; white-space: nowrap; }
table.params td.jn { width: 12em; }
.held { font-style: italic; }
sup { font-size: 9px; font-style: normal; }
ol.footnotes { margin: 4px 0 0; padding-left: 22px; color: var(--muted); font-size: 12px; }
tr.insample th, tr.insample td { border-top: 1.5px solid var(--rule); }
tr.calibrated td { font-weight: 600; color: var(--cal); }
tr.nominal td:nth-child(2) { color: var(--nom); } tr.chosen td { font-weight: 600; }
table.tool td .sd { display: block; color: var(--muted); font-size: 11px; }
.caption, figcaption { color: var(--muted); font-size: 12px; }
figure.plot { margin: 10px 0 4px; }
svg.plot { width: 100%; height: auto; display: block; }
.muted { color: var(--muted); } .good { color: var(--good); } .warn { color: var(--warn); }
.bad { color: var(--bad); font-weight: 600; }
.alert { border: 1px solid #f1b8b3; background: #fdf1f0; border-left: 5px solid var(--bad);
  padding: 10px 14px; margin: 8px 0; font-size: 14px; }
ul.warnings li { border-left: 4px solid var(--warn); background: #fff8e6; padding: 6px 10px;
  margin: 6px 0; list-style: none; }
ul.warnings, ul.notes { padding: 0; margin: 6px 0; }
ul.notes li { list-style: none; padding: 3px 0 3px 14px; position: relative; color: #3b4654; }
ul.notes li::before { content: "–"; position: absolute; left: 0; color: var(--muted); }
footer { margin-top: 24px; padding-top: 8px; border-top: 1px solid var(--rule);
  color: var(--muted); font-size: 11px; display: flex; justify-content: space-between; gap: 16px; }
@page { size: A4; margin: 14mm; }
@media print {
  html { background: #fff; } .sheet { box-shadow: none; margin: 0; padding: 0; max-width: none; }
  figure, table, .alert, .cards, tr, .keep { break-inside: avoid; }
  h2, h3 { break-after: avoid; }
  table.grid thead th { white-space: normal; }
}
"""


def certificate_html(
    sources: Sources,
    *,
    robot: str | None = None,
    nominal: Nominal | None = None,
    now: datetime | None = None,
    iso9283: Iso9283Shown | None = None,
) -> str:
    """The certificate of ``sources`` as one HTML page (no script, no external resource).
    ``robot``: the robot as the certificate names it (the result does not record it);
    ``nominal``: the table given to ``dhlog process``, for measured − nominal;
    ``iso9283``: an acceptance test's report (``dhlog iso9283``), shown as its own section
    after the DH parameters. Raises
    :class:`ResultFileError` (or :class:`~dhlog.errors.InputError`) naming the field at fault."""
    name = str(sources.result_path)
    result = read_result(sources.document, name)
    if sources.holdout_text is not None and result.checks:
        checks = read_holdout_csv(sources.holdout_text, str(sources.holdout_path), result.checks)
        result = replace(result, checks=checks)
    rows = result.rows
    if nominal is not None:
        if nominal.table.n != result.n_joints:
            raise InputError(
                f"{nominal.name}: has {nominal.table.n} joints but {name} has "
                f"{result.n_joints}; give the nominal of this robot (the one given to dhlog "
                "process)."
            )
        rows = nominal_deltas(rows, nominal.table, result.reference_pose)
    now = now or datetime.now(UTC)
    title = robot or result.log_name or sources.result_path.name
    hayati = [r.joint for r in rows if r.form == "hayati"]
    partial = [r for r in result.residuals if r.error]
    intro = (
        "Standard (distal) Denavit–Hartenberg parameters, A = Rz(θ) Tz(d) Tx(a) Rx(α); θ and d "
        "are the offsets at encoder zero. ±1σ from the fit of the whole model to every sample."
    )
    if hayati:
        intro += (
            f" Row(s) {', '.join(map(str, hayati))}: the Hayati–Mirmirani form Rz(θ) Tx(a) Rx(α) "
            "Ry(β), β in place of the ill-conditioned d of a nearly parallel pair (same forward "
            "kinematics; the JSON has both)."
        )
    intro += (
        " Parameters marked fixed are held by a convention, a gauge freedom or a relation the "
        "data cannot reject, or are not determined by the poses: they are not measurements."
    )
    if nominal is None:
        intro += (
            " Measured − nominal is not shown: the result JSON does not record the nominal "
            "(pass --nominal to dhlog report)."
        )
    camera = result.camera
    instrument = "a laser-tracker log" if camera is None else "a camera log (a board's corners)"
    body = [
        '<main class="sheet">',
        "<header><div><h1>Robot calibration certificate</h1>"
        f'<p class="sub">Kinematic (Denavit–Hartenberg) calibration from {instrument}, '
        "identified by dhlog</p></div>"
        f'<div class="robot" id="robot">{escape(title)}<small>{result.n_joints} joints · report '
        f"{now.strftime('%Y-%m-%d')}</small></div></header>",
    ]
    if result.implausible:
        body.append(
            '<div class="alert" id="implausible"><strong>Implausible result.</strong> dhlog '
            "judges this calibration implausible (dhlog process exited 4): "
            + " ".join(escape(r) for r in result.implausible)
            + "</div>"
        )
    if partial:
        body.append(
            '<div class="alert" id="partial"><strong>Partial result.</strong> Joint(s) '
            + ", ".join(str(r.joint) for r in partial)
            + " could not be identified; see the per-joint section.</div>"
        )
    # a camera calibration's held-out check is the camera's (pixels and mm), not validation's
    held = camera.holdout if camera is not None and not result.checks else None
    sections: list[tuple[str, str, list[str]]] = [
        (
            "identification",
            "Identification",
            [identification_table(sources, result, robot, nominal, now)],
        ),
        (
            "accuracy",
            "Accuracy at held-out poses" if held is None else "Accuracy at held-out frames",
            [accuracy_section(result) if held is None else camera_accuracy(held)],
        ),
        (
            "parameters",
            "DH parameters",
            [
                f'<p class="caption">{escape(intro)}</p>',
                parameter_table(rows, nominal)
                if rows
                else '<p class="alert">The result holds no DH parameters.</p>',
                tool_table(result.tool, None if camera is None else camera_frame_caption(camera)),
            ],
        ),
    ]
    if iso9283 is not None:
        sections.append(
            ("iso9283", "Acceptance test (ISO 9283)", [iso9283_section(iso9283, robot)])
        )
    if camera is not None:
        sections.append(("camera", "Camera and board", [camera_section(camera)]))
    sections += [
        (
            "measurement",
            "Tracker and noise model" if camera is None else "Noise model and fit",
            [
                kv_table([(k, escape(v)) for k, v in result.measurement], "measurement")
                if result.measurement
                else '<p class="muted">The result records no noise model.</p>'
            ],
        ),
        ("joints", "Per-joint residuals", [residual_section(result)]),
        ("terms", "Beyond the geometry", [terms_section(result.nongeometric)]),
        (
            "warnings",
            "Warnings and notes",
            [
                bullet_list(result.warnings, "warnings", "No warnings."),
                bullet_list(result.notes, "notes", "No notes."),
            ],
        ),
    ]
    body.append(summary_cards(result, None if camera is None else camera_cards(camera)))
    for n, (key, heading, parts) in enumerate(sections, start=1):
        body.append(f'<section id="s-{key}"><h2><span class="n">{n}</span>{heading}</h2>')
        body += parts
        body.append("</section>")
    body += [
        f"<footer><span>Written by dhlog {escape(__version__)} (dhlog report) from "
        f"<code>{escape(sources.result_path.name)}</code>. Lengths in mm, angles in degrees, "
        "±1σ.</span><span>SHA-256 "
        f"<code>{sources.result_sha256[:16]}…</code></span></footer>",
        "</main>",
    ]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f'<meta name="generator" content="dhlog {escape(__version__)}">\n'
        f"<title>Calibration certificate — {escape(title)}</title>\n"
        f"<style>{CSS}</style>\n</head>\n<body>\n" + "\n".join(body) + "\n</body>\n</html>\n"
    )
