"""The console tables of ``dhlog iso9283``: per pose (visits, AP before | after with σ below, RP,
stabilisation time and overshoot, vAP), distance accuracy and repeatability, drift, then the
frame, the commanded targets' source and the notes, one line each. mm, µm, degrees and s; 80
columns."""

from __future__ import annotations

import math

from rich import box
from rich.console import Console
from rich.table import Table

from dhlog.iso9283.run import DRIFT_HOURS, Accuracy, Iso9283Report
from dhlog.present.console.notes import prose


def _mm(value: float | None, places: int = 3) -> str:
    return "—" if value is None or not math.isfinite(value) else f"{value * 1e3:.{places}f}"


def _s(value: float | None) -> str:
    return "—" if value is None or not math.isfinite(value) else f"{value:.3f}"


def _ap(accuracy: Accuracy | None) -> str:
    """AP (mm) above its σ line, as the house shows a value and its σ."""
    if accuracy is None:
        return "—"
    if accuracy.sigma is None:
        return _mm(accuracy.AP)
    return f"{_mm(accuracy.AP)}\n± {_mm(accuracy.sigma)}"


def print_iso9283(console: Console, report: Iso9283Report) -> None:
    """The report's tables and lines (see the module docstring)."""
    after = any(p.after is not None for p in report.poses)
    table = Table(
        title="ISO 9283 pose characteristics (mm, s)",
        box=box.SIMPLE_HEAD,
        title_justify="left",
        pad_edge=False,
    )
    table.add_column("pose")
    table.add_column("n", justify="right")
    table.add_column("AP before", justify="right")
    if after:
        table.add_column("AP after", justify="right")
    table.add_column("RP", justify="right")
    table.add_column("t_stab", justify="right")
    table.add_column("overshoot", justify="right")
    table.add_column("vAP", justify="right")
    for p in report.poses:
        row = [p.name, str(p.visits), _ap(p.before)]
        if after:
            row.append(_ap(p.after))
        row += [_mm(p.RP), _s(p.stabilisation_time), _mm(p.overshoot), _mm(p.vAP)]
        table.add_row(*row)
    console.print(table)
    if any(p.RP_abc is not None for p in report.poses):
        ori = Table(
            title="orientation repeatability ±3 S (degrees)",
            box=box.SIMPLE_HEAD,
            title_justify="left",
            pad_edge=False,
        )
        for name in ("pose", "RP_a", "RP_b", "RP_c"):
            ori.add_column(name, justify="right" if name != "pose" else "left")
        for p in report.poses:
            if p.RP_abc is not None:
                ori.add_row(p.name, *(f"{math.degrees(v):.4f}" for v in p.RP_abc))
        console.print(ori)
    if report.paths:
        after_p = any(p.AT_after is not None for p in report.paths)
        paths = Table(
            title="ISO 9283 path characteristics (mm)",
            box=box.SIMPLE_HEAD,
            title_justify="left",
            pad_edge=False,
        )
        paths.add_column("path")
        paths.add_column("n", justify="right")
        paths.add_column("points", justify="right")
        paths.add_column("AT before", justify="right")
        if after_p:
            paths.add_column("AT after", justify="right")
        paths.add_column("RT", justify="right")
        for path in report.paths:
            row = [path.path, str(path.cycles), str(path.points), _mm(path.AT)]
            if after_p:
                row.append(_mm(path.AT_after))
            row.append(_mm(path.RT))
            paths.add_row(*row)
        console.print(paths)
    lines: list[tuple[str, str]] = []
    d = report.distance
    if d is not None:
        text = f"{d.poses[0]}–{d.poses[1]}, {d.cycles} cycle(s): mean D {_mm(d.D_mean, 4)} mm"
        if d.AD is not None:
            text += f", AD {_mm(d.AD)} mm"
            if d.AD_after is not None:
                text += f" (after {_mm(d.AD_after)} mm)"
        if d.RD is not None:
            text += f", RD ±{_mm(d.RD)} mm"
        lines.append(("distance", text))
    if report.drift is not None:
        f = report.drift
        text = (
            f"{f.pose}, first and last {f.group} cycles {f.hours * 60:.1f} min apart: "
            f"dRP {_mm(f.dRP)} mm"
        )
        if f.dAP is not None:
            text += f", dAP {_mm(f.dAP)} mm"
        text += f", barycentre moved {_mm(f.shift)} mm"
        if f.hours >= DRIFT_HOURS:  # a rate per hour from minutes would be an extrapolation
            text += f" ({_mm(f.rate)} mm/h)"
        lines.append(("drift", text))
    lines.append(("frame", f"{report.frame}: {report.registration}"))
    lines.append(("commanded", report.commanded_from))
    if report.after_basis is not None:
        lines.append(("after", report.after_basis))
    lines.append(("log", f"{report.visits} visit(s), tracker at {report.rate_hz:.0f} Hz"))
    for note in report.notes:
        lines.append(("note", note))
    prose(console, lines)
