"""The console tables of ``dhlog iso9283``: per pose (visits, AP before | after with σ below, RP,
stabilisation time and overshoot — not for stops, which do not determine them —, vAP), distance
accuracy and repeatability, drift (per target where the log has several), then the frame, the
commanded targets' source, what the log does not determine and the notes, one line each. mm,
µm, degrees and s; 80 columns."""

from __future__ import annotations

import math

from rich import box
from rich.console import Console
from rich.table import Table

from dhlog.iso9283.poses import DRIFT_HOURS
from dhlog.iso9283.report import Accuracy, Iso9283Report
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


def _pose_table(report: Iso9283Report, title: str) -> Table:
    """The per-pose table (stops: no stabilisation columns, the figures are not determined;
    several targets: RP of each target beside the primary one's, by pose name)."""
    after = any(p.after is not None for p in report.poses)
    rp_of = [{p.name: p.RP for p in other.poses} for other in report.further]
    stops = report.stops is not None
    table = Table(title=title, box=box.SIMPLE_HEAD, title_justify="left", pad_edge=False)
    table.add_column("pose")
    table.add_column("n", justify="right")
    table.add_column("AP before", justify="right")
    if after:
        table.add_column("AP after", justify="right")
    table.add_column("RP" if not rp_of else "RP 1", justify="right")
    for other in report.further:
        table.add_column(f"RP {other.target}", justify="right")
    if not stops:
        table.add_column("t_stab", justify="right")
        table.add_column("overshoot", justify="right")
    table.add_column("vAP", justify="right")
    for p in report.poses:
        row = [p.name, str(p.visits), _ap(p.before)]
        if after:
            row.append(_ap(p.after))
        row.append(_mm(p.RP))
        row += [_mm(rp.get(p.name)) for rp in rp_of]
        if not stops:
            row += [_s(p.stabilisation_time), _mm(p.overshoot)]
        row.append(_mm(p.vAP))
        table.add_row(*row)
    return table


def _distance_drift(report: Iso9283Report) -> list[tuple[str, str]]:
    """The distance and drift lines."""
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
        apart = (
            f"{f.hours * 60:.1f} min apart" if math.isfinite(f.hours) else "(time apart unknown)"
        )
        text = f"{f.pose}, first and last {f.group} cycles {apart}: dRP {_mm(f.dRP)} mm"
        if f.dAP is not None:
            text += f", dAP {_mm(f.dAP)} mm"
        text += f", barycentre moved {_mm(f.shift)} mm"
        if math.isfinite(f.hours) and f.hours >= DRIFT_HOURS:  # minutes: an extrapolation
            text += f" ({_mm(f.rate)} mm/h)"
        lines.append(("drift", text))
    return lines


def _orientation_table(console: Console, report: Iso9283Report) -> None:
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


def _path_table(console: Console, report: Iso9283Report) -> None:
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


def print_iso9283(console: Console, report: Iso9283Report) -> None:
    """The report's tables and lines (see the module docstring); several targets: each further
    target's pose table, distance and drift after the primary one's."""
    what = "stops, mm" if report.stops is not None else "mm, s"
    console.print(_pose_table(report, f"ISO 9283 pose characteristics ({what})"))
    _orientation_table(console, report)
    _path_table(console, report)
    lines = _distance_drift(report)
    if report.further:
        lines = [(f"{label} 1", text) for label, text in lines]
        for other in report.further:
            lines += [(f"{label} {other.target}", text) for label, text in _distance_drift(other)]
    if report.further:
        lines.append(
            (
                "targets",
                f"{1 + len(report.further)}: RP k is target k's; AP, the orientation RP and "
                "the frame are target 1's (each target's in the JSON's further_targets)",
            )
        )
    lines.append(("frame", f"{report.frame}: {report.registration}"))
    lines.append(("commanded", report.commanded_from))
    if report.after_basis is not None:
        lines.append(("after", report.after_basis))
    if report.stops is not None:
        lines.append(("log", f"{report.visits} visit(s): {report.stops}"))
    else:
        lines.append(("log", f"{report.visits} visit(s), tracker at {report.rate_hz:.0f} Hz"))
    for missing in report.not_determined:
        lines.append(("not determined", missing))
    for note in report.notes:
        lines.append(("note", note))
    said = set(report.notes)
    for other in report.further:
        for note in other.notes:
            if note not in said:
                said.add(note)
                lines.append(("note", f"target {other.target}: {note}"))
    prose(console, lines)
