"""The Rerun recording of an ISO 9283 acceptance test (``<stem>.iso9283.rrd``,
:func:`write_iso9283_recording`), written atomically through
:func:`~dhlog.present.recording.stream.recording_file`.

Everything is static, in the report's frame (``world``: the robot's base frame, z up; the
tracker's when the report has no model, said in the text panel):

* ``world/cube/edges`` the test cube's 12 edges and ``world/cube/plane`` the measuring plane's
  outline and diagonals
  (clause 6.3; found from the commanded P1 … P5 by
  :func:`~dhlog.present.certificate.iso9283.cube_of`);
* ``world/poses/<P>/commanded`` each pose's commanded point;
* ``world/poses/<P>/AP_before``, ``.../AP_after`` the AP vector from the commanded point,
  magnified × ``k`` (the view's name says ``k``: a 1-2-5 number making the largest AP or AT
  about 10 % of the cube's edge);
* ``world/poses/<P>/attained`` the attained positions and ``world/poses/<P>/RP`` a sphere
  (Ellipsoids3D) of radius RP about their barycentre, both drawn about the magnified barycentre
  (commanded + k × AP) and magnified about it × ``k_RP`` (RP about 3 % of the edge);
* ``world/paths/<path>/commanded`` each path's commanded line, ``.../passes`` the attained
  passes, ``.../deviation`` each pass's crossing of the plane normal to the command path at
  each commanded point (clause 8.2) drawn from the commanded point, magnified × ``k``;
* ``report/iso9283`` the report's tables (Markdown).

The attained positions and the passes are the report's (its poses' ``attained`` (n, 3), its
paths' ``commanded`` (m, 3) and ``passes`` [(k, 3)], in the report's frame) unless ``attained``
and ``paths`` are given; without them the poses show their barycentre's sphere and the paths
only their figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import ArrayLike

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.present.certificate.iso9283 import Cube, cube_of
from dhlog.present.recording.scene import _nice
from dhlog.present.recording.stream import recording_file

if TYPE_CHECKING:
    from dhlog.iso9283.report import Iso9283Report

#: The application id of the acceptance test's recording.
APPLICATION = "dhlog iso9283"
#: Colours: commanded, before (the nominal's: as the certificate), after, attained, the cube.
COMMANDED = np.array([30, 30, 30], dtype=np.uint8)
BEFORE = np.array([200, 85, 61], dtype=np.uint8)
AFTER = np.array([42, 111, 151], dtype=np.uint8)
ATTAINED = np.array([60, 160, 90], dtype=np.uint8)
SPHERE = np.array([60, 160, 90, 70], dtype=np.uint8)
CUBE = np.array([120, 130, 145], dtype=np.uint8)
PLANE = np.array([190, 150, 60], dtype=np.uint8)
#: The magnified AP (and AT) and RP as fractions of the cube's edge.
AP_FRACTION, RP_FRACTION = 0.10, 0.03


def _array(value: Any) -> FloatArray | None:
    if value is None:
        return None
    a = np.asarray(value, dtype=np.float64)
    return a if a.size else None


def _extent(report: Iso9283Report, cube: Cube | None) -> float:
    """The scene's size (m): the cube's edge, else the poses' spread, at least 10 mm."""
    if cube is not None:
        return cube.edge
    bary = np.array([p.barycentre for p in report.poses]) if report.poses else np.zeros((1, 3))
    return max(float(np.max(np.ptp(bary, axis=0))) if len(bary) > 1 else 0.0, 0.01)


def magnifications(report: Iso9283Report, extent: float) -> tuple[float, float]:
    """``k`` (the largest AP or AT about 10 % of ``extent``) and ``k_RP`` (the largest RP about
    3 %), 1-2-5 numbers (1 when there is nothing to magnify)."""
    worst = max(
        [p.before.AP for p in report.poses if p.before is not None]
        + [p.after.AP for p in report.poses if p.after is not None]
        + [p.AT for p in report.paths]
        + [0.0]
    )
    rp = max([p.RP for p in report.poses if p.RP is not None] + [0.0])
    k = _nice(AP_FRACTION * extent / worst) if worst > 0 else 1.0
    k_rp = _nice(RP_FRACTION * extent / rp) if rp > 0 else 1.0
    return k, k_rp


def _mm(v: float | None, places: int = 4) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v * 1e3:.{places}f}"


def _s(v: float | None) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:.3f}"


def report_markdown(report: Iso9283Report, k: float, k_rp: float) -> str:
    """The text panel: the frame, the magnifications, the tables (mm, s) and the notes."""
    lines = [
        "# ISO 9283 acceptance test",
        "",
        f"Logs: {', '.join(f'`{log}`' for log in report.logs)}; {report.cycles} cycle(s) per "
        f"pose, {report.visits} visits, tracker at {report.rate_hz:.0f} Hz.",
        "",
        f"Frame: {report.frame} — {report.registration}. Commanded: {report.commanded_from}.",
        "",
        f"In the 3D view: AP and the paths' deviations × {k:g}; each pose's attained positions "
        f"and RP sphere about the magnified barycentre × {k_rp:g}.",
        "",
        "## Poses (mm, s)",
        "",
        "| pose | n | AP before | AP after | RP | t_stab | overshoot | vAP |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for p in report.poses:
        lines.append(
            f"| {p.name} | {p.visits} | {_mm(None if p.before is None else p.before.AP)} | "
            f"{_mm(None if p.after is None else p.after.AP)} | {_mm(p.RP)} | "
            f"{_s(p.stabilisation_time)} | {_mm(p.overshoot)} | {_mm(p.vAP)} |"
        )
    if report.paths:
        lines += [
            "",
            "## Paths (mm)",
            "",
            "| path | n | points | AT before | AT after | RT |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for t in report.paths:
            lines.append(
                f"| {t.path} | {t.cycles} | {t.points} | {_mm(t.AT)} | {_mm(t.AT_after)} | "
                f"{_mm(t.RT)} |"
            )
    d = report.distance
    if d is not None:
        lines += [
            "",
            f"Distance {d.poses[0]}–{d.poses[1]} ({d.cycles} cycles): mean D {_mm(d.D_mean)} mm, "
            f"AD {_mm(d.AD)} mm (after {_mm(d.AD_after)} mm), RD ±{_mm(d.RD)} mm.",
        ]
    dr = report.drift
    if dr is not None:
        lines += [
            "",
            f"Drift at {dr.pose} (first and last {dr.group} cycles, {dr.hours:.3f} h apart): dAP "
            f"{_mm(dr.dAP)} mm, dRP {_mm(dr.dRP)} mm, barycentre moved {_mm(dr.shift)} mm.",
        ]
    if report.notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in report.notes]
    return "\n".join(lines) + "\n"


def _path_deviation(
    commanded: FloatArray, passes: Sequence[FloatArray], used: tuple[int, int] | None = None
) -> tuple[FloatArray, FloatArray] | None:
    """The crossings (m', n, 3) of each pass with the planes normal to the command path and the
    commanded points they belong to (m', 3): ``used`` (first point, count: the report's), else
    the ends a pass stops short of left out as ``dhlog iso9283`` does; None when none works."""
    from dhlog.iso9283.formulas.paths import path_accuracy
    from dhlog.iso9283.paths import PATH_TRIMS

    m = len(commanded)
    trims = list(PATH_TRIMS)
    if used is not None and 0 <= used[0] and used[0] + used[1] <= m:
        trims.insert(0, (used[0], m - used[0] - used[1]))
    for a, b in trims:
        if m - a - b < 3:
            break
        try:
            got = path_accuracy(list(passes), commanded[a : m - b])
        except DhlogError:
            continue
        return np.asarray(got.crossings, dtype=np.float64), commanded[a : m - b]
    return None


def write_iso9283_recording(
    report: Iso9283Report,
    path: str | Path,
    *,
    attained: Mapping[str, ArrayLike] | None = None,
    paths: Mapping[str, tuple[ArrayLike, Sequence[ArrayLike]]] | None = None,
) -> None:
    """Write the recording of ``report`` to ``path`` (atomically; see the module docstring).
    ``attained``: each pose's attained positions (n, 3) by name; ``paths``: each path's
    commanded points (m, 3) and attained passes [(k, 3)] by name; all in the report's frame
    (default: the report's own)."""
    by_name = {p.name: _array(p.commanded) for p in report.poses}
    cube = cube_of(by_name) if report.frame == "base" else None
    extent = _extent(report, cube)
    k, k_rp = magnifications(report, extent)
    size = 0.004 * extent
    middle = (
        np.asarray(cube.centre)
        if cube is not None
        else np.mean([p.barycentre for p in report.poses], axis=0)
        if report.poses
        else np.zeros(3)
    )
    towards = np.array([1.0, -1.3, 0.8])  # from the front-right, above
    eye = rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital,
        position=middle + 2.2 * extent * towards / np.linalg.norm(towards),
        look_target=middle,
        eye_up=[0.0, 0.0, 1.0],
    )
    blueprint = rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                name=f"ISO 9283 test [{report.frame} frame; AP, AT ×{k:g}, RP ×{k_rp:g}]",
                origin="world",
                eye_controls=eye,
            ),
            rrb.TextDocumentView(name="ISO 9283 report", origin="report/iso9283"),
            column_shares=[2, 1],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )
    with recording_file(path, APPLICATION, blueprint) as rec:
        rec.log(
            "report/iso9283",
            rr.TextDocument(report_markdown(report, k, k_rp), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        if cube is not None:
            rec.log(
                "world/cube/edges",
                rr.LineStrips3D(list(cube.edges()), colors=CUBE, radii=0.25 * size),
                static=True,
            )
            quad = np.asarray(cube.plane, dtype=np.float64)
            rec.log(  # its outline and diagonals (through P2, P1, P4 and P3, P1, P5)
                "world/cube/plane",
                rr.LineStrips3D(
                    [np.vstack([quad, quad[:1]]), quad[[0, 2]], quad[[1, 3]]],
                    colors=PLANE,
                    radii=0.4 * size,
                ),
                static=True,
            )
        for p in report.poses:
            base = f"world/poses/{p.name}"
            bary = np.asarray(p.barycentre, dtype=np.float64)
            commanded = _array(p.commanded)
            # the magnified barycentre: where the cluster is drawn
            centre = bary if commanded is None else commanded + k * (bary - commanded)
            if commanded is not None:
                rec.log(
                    f"{base}/commanded",
                    rr.Points3D([commanded], colors=COMMANDED, radii=size),
                    static=True,
                )
                label = f"{p.name} AP " + " | ".join(  # before | after, on the first arrow
                    f"{acc.AP * 1e3:.3f}" for acc in (p.before, p.after) if acc is not None
                )
                for key, acc, colour in (
                    ("AP_before", p.before, BEFORE),
                    ("AP_after", p.after, AFTER),
                ):
                    if acc is None:
                        continue
                    rec.log(
                        f"{base}/{key}",
                        rr.Arrows3D(
                            origins=[commanded],
                            vectors=[k * np.asarray(acc.components, dtype=np.float64)],
                            colors=colour,
                            radii=0.5 * size,
                            labels=[f"{label} mm"] if key == "AP_before" else None,
                        ),
                        static=True,
                    )
            points = _array(attained.get(p.name) if attained is not None else p.attained)
            if points is not None:
                points = points.reshape(-1, 3)
                rec.log(
                    f"{base}/attained",
                    rr.Points3D(
                        centre + k_rp * (points - points.mean(axis=0)),
                        colors=ATTAINED,
                        radii=0.5 * size,
                    ),
                    static=True,
                )
            if p.RP is not None:
                rec.log(
                    f"{base}/RP",
                    rr.Ellipsoids3D(
                        centers=[centre],
                        half_sizes=[[k_rp * p.RP] * 3],
                        colors=SPHERE,
                        fill_mode=rr.components.FillMode.Solid,
                        labels=[f"RP {p.RP * 1e3:.3f} mm"],
                    ),
                    static=True,
                )
        for t in report.paths:
            given = paths.get(t.path) if paths is not None else None
            if given is not None:
                commanded_path, passes = (
                    _array(given[0]),
                    [np.asarray(x, np.float64) for x in given[1]],
                )
            else:
                commanded_path = _array(t.commanded)
                passes = [np.asarray(x, np.float64) for x in t.passes]
            if commanded_path is None:
                continue
            base = f"world/paths/{t.path}"
            rec.log(
                f"{base}/commanded",
                rr.LineStrips3D([commanded_path], colors=COMMANDED, radii=0.3 * size),
                static=True,
            )
            if not passes:
                continue
            rec.log(
                f"{base}/passes",
                rr.LineStrips3D(passes, colors=ATTAINED, radii=0.15 * size),
                static=True,
            )
            used = (t.first_point, t.points)
            found = _path_deviation(commanded_path, passes, used) if len(passes) >= 2 else None
            if found is None:
                continue
            crossings, points = found
            starts = np.repeat(points, crossings.shape[1], axis=0)
            ends = starts + k * (crossings.reshape(-1, 3) - starts)
            rec.log(
                f"{base}/deviation",
                rr.LineStrips3D(
                    np.stack([starts, ends], axis=1),
                    colors=BEFORE,
                    radii=0.1 * size,
                ),
                static=True,
            )
            rec.log(
                f"{base}/deviation_barycentre",
                rr.LineStrips3D(
                    [points + k * (crossings.mean(axis=1) - points)],
                    colors=BEFORE,
                    radii=0.3 * size,
                    labels=[f"{t.path} AT {t.AT * 1e3:.3f} mm"],
                ),
                static=True,
            )
