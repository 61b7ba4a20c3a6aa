"""The certificate's acceptance-test section as HTML (:func:`iso9283_section`): the test (robot,
cube, cycles, date, the report's SHA-256), a table per pose (AP before | after, RP, stabilisation
time, overshoot, vAP), distance accuracy and repeatability, drift, a table per path (AT before |
after, RT), what was missing (the report's notes) and a plot. mm and s on the page; the file's SI
value of every figure in the cell's ``data-si``; every text from the file escaped."""

from __future__ import annotations

from dhlog.present.certificate.iso9283 import Iso9283Shown
from dhlog.present.certificate.plots import iso9283_svg
from dhlog.present.certificate.sections import bullet_list, escape, kv_table

DASH = '<span class="muted">—</span>'


def _cell(
    value: float | None,
    key: str,
    *,
    scale: float = 1e3,
    places: int = 4,
    sigma: float | None = None,
) -> str:
    """A figure in display units (mm by default) with its SI value in ``data-si`` (and its
    standard uncertainty under it, in ``data-std``); a dash when it was not computed."""
    if value is None:
        return f'<td class="num" data-key="{escape(key)}">{DASH}</td>'
    std = "" if sigma is None else f' data-std="{sigma!r}"'
    under = "" if sigma is None else f'<span class="sd">± {sigma * scale:.{places}f}</span>'
    return (
        f'<td class="num" data-key="{escape(key)}" data-si="{value!r}"{std}>'
        f"{value * scale:.{places}f}{under}</td>"
    )


def _test_table(iso: Iso9283Shown, robot: str | None) -> str:
    named = robot or iso.nominal
    items = [
        (
            "Robot",
            escape(named)
            if named
            else '<span class="muted">not named (no --nominal given to dhlog iso9283)</span>',
        ),
        ("Logs", ", ".join(f"<code>{escape(log)}</code>" for log in iso.logs)),
    ]
    if iso.cube is not None:
        c = iso.cube
        centre = ", ".join(f"{v * 1e3:.1f}" for v in c.centre)
        items.append(
            (
                "Test cube",
                f"edge {c.edge * 1e3:.1f} mm, centre ({centre}) mm in the robot's base frame "
                '<span class="muted">(from the commanded P1 … P5: clause 6.3)</span>',
            )
        )
    else:
        items.append(
            (
                "Test cube",
                '<span class="muted">not known (no commanded P1 … P5 in the base frame)</span>',
            )
        )
    items += [
        (
            "Cycles",
            f"{iso.cycles} per pose, {iso.visits} visits found, tracker at {iso.rate_hz:.0f} Hz",
        ),
        ("Frame", f"{escape(iso.frame)}: {escape(iso.registration)}"),
        ("Commanded poses", escape(iso.commanded_from)),
        (
            "After calibration",
            escape(iso.after)
            if iso.after
            else '<span class="muted">no calibration result given to dhlog iso9283</span>',
        ),
        (
            "Calibration result",
            f"<code>{escape(iso.result)}</code>" if iso.result else DASH,
        ),
        (
            "Report file",
            f"<code>{escape(iso.path.name)}</code>, written "
            f"{iso.modified.strftime('%Y-%m-%d %H:%M UTC')} (its modification time), dhlog "
            f"{escape(iso.version)}",
        ),
        ("Report SHA-256", f'<code class="hash" id="iso9283-sha256">{iso.sha256}</code>'),
    ]
    return kv_table(items, "iso9283-test")


def _poses_table(iso: Iso9283Shown) -> str:
    head = (
        '<tr><th>Pose</th><th class="num">n</th><th class="num">AP before [mm]</th>'
        '<th class="num">AP after [mm]</th><th class="num">RP [mm]</th>'
        '<th class="num">t<sub>stab</sub> mean [s]</th>'
        '<th class="num">t<sub>stab</sub> max [s]</th>'
        '<th class="num">Overshoot mean [mm]</th><th class="num">Overshoot max [mm]</th>'
        '<th class="num">vAP [mm]</th></tr>'
    )
    rows = []
    for p in iso.poses:
        n = escape(p.name)
        rows.append(
            f'<tr data-pose="{n}"><th>{n}</th><td class="num">{p.visits}</td>'
            + _cell(p.AP_before, f"{p.name}.AP_before", sigma=p.AP_before_sigma)
            + _cell(p.AP_after, f"{p.name}.AP_after", sigma=p.AP_after_sigma)
            + _cell(p.RP, f"{p.name}.RP")
            + _cell(p.stabilisation_time, f"{p.name}.stabilisation_time", scale=1.0, places=3)
            + _cell(
                p.stabilisation_time_max, f"{p.name}.stabilisation_time_max", scale=1.0, places=3
            )
            + _cell(p.overshoot, f"{p.name}.overshoot")
            + _cell(p.overshoot_max, f"{p.name}.overshoot_max")
            + _cell(p.vAP, f"{p.name}.vAP")
            + "</tr>"
        )
    if not rows:
        return '<p class="muted" id="iso9283-poses">No test pose was found in the log.</p>'
    return (
        f'<table class="grid tool" id="iso9283-poses"><thead>{head}</thead><tbody>'
        + "".join(rows)
        + "</tbody></table>"
    )


def _distance_drift(iso: Iso9283Shown) -> str:
    rows = []
    d = iso.distance
    if d is not None:
        a, b = (escape(x) for x in d.poses)
        rows.append(
            f'<tr data-row="distance"><th>Distance {a}–{b} ({d.cycles} cycles)</th>'
            + _cell(d.D_mean, "distance.D_mean")
            + _cell(d.D_commanded, "distance.D_commanded")
            + _cell(d.AD, "distance.AD")
            + _cell(d.AD_after, "distance.AD_after")
            + _cell(d.RD, "distance.RD")
            + "</tr>"
        )
    parts = []
    if rows:
        parts.append(
            '<table class="grid stats" id="iso9283-distance"><thead><tr><th>Clause 7.3</th>'
            '<th class="num">D̄ [mm]</th><th class="num">D<sub>c</sub> [mm]</th>'
            '<th class="num">AD before [mm]</th><th class="num">AD after [mm]</th>'
            '<th class="num">RD ±[mm]</th></tr></thead><tbody>' + "".join(rows) + "</tbody></table>"
        )
    else:
        parts.append(
            '<p class="muted" id="iso9283-distance">Distance accuracy and repeatability (AD, RD): '
            "not computed (see below).</p>"
        )
    t = iso.drift
    if t is not None:
        parts.append(
            '<table class="grid stats" id="iso9283-drift"><thead><tr><th>Clause 7.6</th>'
            '<th class="num">Groups</th><th class="num">Apart [h]</th><th class="num">dAP [mm]</th>'
            '<th class="num">dRP [mm]</th><th class="num">Shift [mm]</th>'
            '<th class="num">Rate [mm/h]</th></tr></thead><tbody>'
            f'<tr data-row="drift"><th>Drift at {escape(t.pose)}</th>'
            f'<td class="num">{t.group} cycles</td>'
            + _cell(t.hours, "drift.hours", scale=1.0, places=3)
            + _cell(t.dAP, "drift.dAP")
            + _cell(t.dRP, "drift.dRP")
            + _cell(t.shift, "drift.shift")
            + _cell(t.rate_per_hour, "drift.rate_per_hour")
            + "</tr></tbody></table>"
        )
    else:
        parts.append(
            '<p class="muted" id="iso9283-drift">Drift (dAP, dRP): not computed (see below).</p>'
        )
    return "\n".join(parts)


def _paths_table(iso: Iso9283Shown) -> str:
    if not iso.paths:
        return (
            '<p class="muted" id="iso9283-paths">Path accuracy and repeatability (AT, RT): not '
            "computed (see below).</p>"
        )
    rows = []
    for p in iso.paths:
        n = escape(p.name)
        rows.append(
            f'<tr data-path="{n}"><th>{n}</th><td class="num">{p.cycles}</td>'
            f'<td class="num">{p.points}</td>'
            + _cell(p.AT, f"{p.name}.AT")
            + _cell(p.AT_after, f"{p.name}.AT_after")
            + _cell(p.RT, f"{p.name}.RT")
            + "</tr>"
        )
    return (
        '<table class="grid stats" id="iso9283-paths"><thead><tr><th>Path (clause 8.2)</th>'
        '<th class="num">n</th><th class="num">Points</th><th class="num">AT before [mm]</th>'
        '<th class="num">AT after [mm]</th><th class="num">RT [mm]</th></tr></thead><tbody>'
        + "".join(rows)
        + "</tbody></table>"
    )


def iso9283_section(iso: Iso9283Shown, robot: str | None = None) -> str:
    """The section: the test, the poses, distance and drift, the paths, the notes, the plot."""
    parts = [
        '<p class="caption">ISO 9283:1998 performance characteristics from the tracker log(s) '
        "of the standard test, computed by <code>dhlog iso9283</code> (docs/iso9283.md). Before: "
        "the robot as it ran (the nominal's forward kinematics of the commanded joints); after: "
        "with this calibration applied, as the report's after line says. AP = |x̄ − x<sub>c</sub>| "
        "(7.2.1), RP = l̄ + 3 S<sub>l</sub> (7.2.2), t<sub>stab</sub> and overshoot over the "
        "arrivals (7.4, 7.5), vAP (7.2.3), AD = D̄ − D<sub>c</sub> and RD = 3 S<sub>D</sub> "
        "(7.3), dAP and dRP (7.6), AT and RT (8.2). ± under AP: its standard uncertainty from the "
        "barycentre's sampling (the visits' scatter over √n). A dash: not computed.</p>",
        _test_table(iso, robot),
        "<h3>Poses</h3>",
        _poses_table(iso),
        "<h3>Distance and drift</h3>",
        _distance_drift(iso),
        "<h3>Paths</h3>",
        _paths_table(iso),
    ]
    svg = iso9283_svg(iso.poses, "iso9283")
    if svg is not None:
        with_points = any(p.attained is not None and len(p.attained) for p in iso.poses)
        caption = (
            "Each pose's attained positions about their barycentre (x and y of the base frame, "
            "µm) with the circle of radius RP."
            if with_points
            else "Per pose: AP before and after calibration and RP (µm)."
            if any(p.AP_before is not None for p in iso.poses)
            else "Per pose: RP (µm; no model given to dhlog iso9283, so no AP)."
        )
        parts.append(
            f'<figure class="plot" id="iso9283-plot">{svg}'
            f"<figcaption>{caption}</figcaption></figure>"
        )
    parts += [
        "<h3>What the log did not give</h3>",
        '<div id="iso9283-notes">'
        + bullet_list(iso.notes, "notes", "Nothing: every characteristic was computed.")
        + "</div>",
    ]
    return "\n".join(parts)
