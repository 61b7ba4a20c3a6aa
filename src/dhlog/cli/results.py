"""Results out and side by side: ``dhlog export`` (a form a robot stack loads), ``dhlog report``
(the certificate) and ``dhlog compare`` (two results, or a batch summary's trends)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console

from dhlog.cli.common import (
    EXIT_CHANGED,
    EXIT_USAGE,
    check_folder,
    fail,
    plain,
    refuse_existing,
    stderr,
    stdout,
    viewer,
)
from dhlog.cli.options import load_model
from dhlog.errors import DhlogError, OutputError

if TYPE_CHECKING:
    from dhlog.fleet.compare import Comparison

EXPORT_FORMATS = ("urdf", "ur", "rtb", "dh-csv", "dh-json", "tf")


def export(
    result: Annotated[Path, typer.Argument(help="A result <stem>.dh.json (or a DH JSON file).")],
    output: Annotated[Path, typer.Option("-o", "--output", help="The file to write.")],
    format: Annotated[
        str,
        typer.Option(
            "--format",
            help="urdf; ur (Universal Robots calibration YAML); rtb (a roboticstoolbox "
            "DHRobot in Python); dh-csv or dh-json (standard and modified DH tables); tf (a ROS "
            "2 launch file: the tracker's frame and the target as static transforms, the "
            "calibrated URDF through robot_state_publisher; a camera's hand-eye poses).",
        ),
    ] = "urdf",
    limits_from: Annotated[
        str | None,
        typer.Option(
            help="A library robot (or DH file) whose name, joint names and limits the URDF "
            "gets (default: --nominal's)."
        ),
    ] = None,
    template: Annotated[
        Path | None,
        typer.Option(
            help="A URDF or xacro description whose joints (matched by name) get the "
            "calibrated origins; its links, meshes, inertials and limits stay. A xacro is "
            "expanded; -o NAME.xacro writes the xacro back with only joint origins changed."
        ),
    ] = None,
    xacro_arg: Annotated[
        list[str] | None,
        typer.Option(
            "--xacro-arg",
            metavar="NAME:=VALUE",
            help="An argument of the xacro template (as xacro takes it: ur_type:=ur5e); "
            "repeat for each.",
        ),
    ] = None,
    zero_offsets: Annotated[
        str,
        typer.Option(
            help="origins (joint zero = encoder zero) or calibration (offsets in each joint's "
            "<calibration rising>; URDF without --template)."
        ),
    ] = "origins",
    nominal: Annotated[
        str | None,
        typer.Option(
            help="The robot's nominal (a library robot or DH file): ur: its d6 places the "
            "flange (a target point cannot); urdf, tf: a library robot's name, joint names "
            "and limits."
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Write the identified model in a form a robot stack loads."""
    from dhlog.api import load
    from dhlog.io.paths import refuse_inputs_as_outputs
    from dhlog.io.writer import atomic_output
    from dhlog.result import export as exports

    if zero_offsets not in ("origins", "calibration") or (
        zero_offsets == "calibration" and (template is not None or format != "urdf")
    ):
        stderr.print(
            "error: --zero-offsets must be origins or calibration (calibration: a URDF "
            "without --template)."
        )
        raise typer.Exit(EXIT_USAGE)
    if template is not None and format not in ("urdf", "tf"):
        stderr.print("error: --template is for --format urdf and tf.")
        raise typer.Exit(EXIT_USAGE)
    xacro_args: dict[str, str] = {}
    for given in xacro_arg or []:
        key, sep, value = given.partition(":=")
        if not sep or not key.strip():
            stderr.print(
                f"error: --xacro-arg takes NAME:=VALUE (ur_type:=ur5e), not '{plain(given)}'."
            )
            raise typer.Exit(EXIT_USAGE)
        xacro_args[key.strip()] = value
    if format not in EXPORT_FORMATS:
        stderr.print(
            f"error: --format must be one of {', '.join(EXPORT_FORMATS)}, not '{plain(format)}'."
        )
        raise typer.Exit(EXIT_USAGE)
    check_folder(output.parent)
    inputs = [(result, "result"), *([(template, "URDF template")] if template else [])]
    if limits_from and Path(limits_from).exists():
        inputs.append((Path(limits_from), "DH file of --limits-from"))
    if nominal and Path(nominal).exists():
        inputs.append((Path(nominal), "DH file of --nominal"))
    try:  # exit 2, with or without --force: the input stays as it is
        if template is not None:
            from dhlog.result.export.expand import files_read

            inputs += [
                (Path(f), "file the xacro template includes")
                for f in files_read(template, xacro_args)
            ]
        refuse_inputs_as_outputs(inputs, [output])
    except DhlogError as exc:
        fail(exc)
    refuse_existing(output, force)
    extra = ""
    try:
        loaded = load(result, nominal=nominal)
        text = loaded.export(
            format,  # type: ignore[arg-type]
            limits_from=limits_from,
            template=template,
            zero_offsets=zero_offsets,  # type: ignore[arg-type]
            xacro_args=xacro_args,
            keep_xacro=output.name.endswith(".xacro"),
        )
        if format == "ur":
            flange = None if loaded.nominal is None else loaded.nominal.table
            tcp = exports.ur_calibration(result, flange)[1]
            extra = (
                "; set the TCP on the controller to "
                f"({tcp[0] * 1e3:.4f}, {tcp[1] * 1e3:.4f}, {tcp[2] * 1e3:.4f}) mm in tool0"
            )
        with atomic_output(output) as f:
            f.write(text.encode())
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        fail(OutputError(output.parent, exc))
    stdout.print(f"wrote {plain(output)}{extra}", soft_wrap=True)  # a path never broken
    _terms_not_exported(result, format)
    _camera_not_exported(result, format)
    if not loaded.plausible:  # exported as asked, but not silently
        _said_implausible(result, "exported")


def _terms_not_exported(result: Path, fmt: str) -> None:
    """Say so when the result carries terms beyond the geometry that ``fmt`` cannot carry."""
    from dhlog.io.dhfile import parse_dh
    from dhlog.io.safetext import printable
    from dhlog.result.check import load_result

    try:
        terms = parse_dh(load_result(result), str(result)).terms
    except DhlogError:
        return
    if terms is None:
        return
    stdout.print(
        f"note: {printable(result.name)} carries {terms.size} joint-value terms beyond the "
        f"geometry ({', '.join(terms.families())}); {fmt} cannot carry them, so the export is the "
        "geometric part (the robot as it would stand without gravity and gear errors): apply "
        "the JSON's nongeometric block for compensation (dhlog fk, DHModel.joint_values).",
        markup=False,
    )


def _camera_not_exported(result: Path, fmt: str) -> None:
    """Say so when the result has a camera's hand-eye poses that ``fmt`` does not carry."""
    from dhlog.result.check import load_result

    if fmt in ("tf", "urdf"):
        return
    try:
        data = load_result(result)
    except DhlogError:
        return
    if data.get("camera") is None:
        return
    stdout.print(
        f"note: the result has a camera's hand-eye poses, which {fmt} does not carry; export "
        "them with --format tf (ROS 2 static transforms) or --format urdf (fixed links).",
        markup=False,
    )


def report(
    result: Annotated[
        Path, typer.Argument(metavar="RESULT", help="A result JSON (<stem>.dh.json).")
    ],
    output: Annotated[
        Path,
        typer.Option("-o", "--output", metavar="HTML", help="The certificate to write."),
    ],
    robot: Annotated[
        str | None,
        typer.Option(
            metavar="TEXT",
            help="The robot as the certificate names it (model, serial number); the result "
            "does not record it.",
        ),
    ] = None,
    nominal: Annotated[
        str | None,
        typer.Option(
            metavar="ROBOT|FILE",
            help="The nominal given to dhlog process (a library robot or a DH file), for "
            "measured - nominal; the result does not record it.",
        ),
    ] = None,
    log: Annotated[
        Path | None,
        typer.Option(
            metavar="LOG",
            help="The session log, when it is neither beside the result nor in the current "
            "folder: hashed and compared with the SHA-256 the result records.",
        ),
    ] = None,
    iso9283: Annotated[
        Path | None,
        typer.Option(
            "--iso9283",
            metavar="FILE",
            help="An acceptance test's <stem>.iso9283.json (dhlog iso9283): shown as the "
            "section 'Acceptance test (ISO 9283)'.",
        ),
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Write a calibration certificate: one self-contained HTML page (robot, hashes, noise
    model, held-out error before and after, DH parameters with ±1σ, residuals, warnings)."""
    from dhlog.io.writer import atomic_output
    from dhlog.present.certificate import Nominal, certificate_html, load_sources

    given = [result, *([log] if log else []), *([iso9283] if iso9283 else [])]
    if output.resolve() in {p.resolve() for p in given}:
        stderr.print(f"error: {plain(output)} is an input; name another with -o.")
        raise typer.Exit(EXIT_USAGE)
    check_folder(output.parent)
    refuse_existing(output, force)
    try:
        sources = load_sources(result, log=log)
        if output.resolve() in {p.resolve() for p in sources.inputs}:
            stderr.print(f"error: {plain(output)} is an input; name another with -o.")
            raise typer.Exit(EXIT_USAGE)
        nom = None if nominal is None else Nominal(nominal, load_model(nominal).table)
        iso = None
        if iso9283 is not None:
            from dhlog.present.certificate.iso9283 import load_iso9283

            iso = load_iso9283(iso9283)
        page = certificate_html(sources, robot=robot, nominal=nom, iso9283=iso)
        with atomic_output(output) as f:
            f.write(page.encode())
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        fail(OutputError(output.parent, exc))
    found = sources.log
    if found.sha256 is None:
        logged = f"log {found.name or '?'} not found: its hash not checked (give it with --log)"
    elif found.sha256 == found.recorded_sha256:
        logged = f"log {found.path} matches the recorded SHA-256"
    else:
        logged = f"log {found.path} DIFFERS from the SHA-256 the result records"
    stdout.print(f"wrote {plain(output)} ({plain(logged)})")


def compare_results(
    first: Annotated[
        Path,
        typer.Argument(
            help="The earlier result <stem>.dh.json, or a batch summary (.csv, .parquet)."
        ),
    ],
    second: Annotated[
        Path | None, typer.Argument(help="The later result of the same robot.")
    ] = None,
    limits_from: Annotated[
        str | None,
        typer.Option(help="A library robot (or DH file) whose joint range the FK check covers."),
    ] = None,
    threshold: Annotated[
        float, typer.Option(help="A change beyond this many combined σ is significant.")
    ] = 3.0,
    rrd: Annotated[
        Path | None,
        typer.Option(help="With a batch summary: write the trends as a Rerun recording here."),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite an existing recording.")
    ] = False,
    as_json: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Two results: print one JSON document (dhlog.compare/1, SI units; docs/cli.md).",
        ),
    ] = False,
    fail_beyond: Annotated[
        float | None,
        typer.Option(
            "--fail-beyond",
            metavar="SIGMA",
            help="Two results: exit 5 when a parameter changed beyond SIGMA combined σ.",
        ),
    ] = None,
) -> None:
    """Has the robot changed? Two results, or every parameter's trend over a batch summary."""
    from dhlog.fleet.compare import compare
    from dhlog.io.dhfile import robot_or_dh_file

    if fail_beyond is not None and not (math.isfinite(fail_beyond) and fail_beyond > 0):
        stderr.print(f"error: --fail-beyond must be a positive number of σ, not {fail_beyond:g}.")
        raise typer.Exit(EXIT_USAGE)
    if second is None:
        if first.suffix not in (".csv", ".parquet"):
            stderr.print("error: give two results, or one batch summary (.csv or .parquet).")
            raise typer.Exit(EXIT_USAGE)
        if as_json or fail_beyond is not None:
            stderr.print(
                "error: --json and --fail-beyond compare two results; a batch summary's trends "
                "are in the console and its --rrd recording."
            )
            raise typer.Exit(EXIT_USAGE)
        _compare_trends(first, threshold, rrd, force)
        return
    try:
        limits = robot_or_dh_file(limits_from).limits if limits_from else None
        result = compare(first, second, limits=limits)
    except DhlogError as exc:
        fail(exc)
    if as_json:
        stdout.out(json.dumps(compare_document(result, first, second, threshold), indent=2))
    else:
        _print_comparison(result, threshold)
    for path in (first, second):
        _said_implausible(path, "compared")
    beyond = [
        c.name
        for c in result.changes
        if fail_beyond is not None and c.significance is not None and c.significance > fail_beyond
    ]
    if beyond:
        stderr.print(
            f"changed beyond --fail-beyond {fail_beyond:g}σ: {plain(', '.join(beyond))}; exit "
            f"{EXIT_CHANGED}."
        )
        raise typer.Exit(EXIT_CHANGED)


def compare_document(
    result: Comparison, first: Path, second: Path, threshold: float
) -> dict[str, object]:
    """``dhlog compare --json``: the comparison as one JSON document (``dhlog.compare/1``, SI
    units; docs/cli.md)."""
    changes = [
        {
            "name": c.name,
            "unit": "rad" if c.angular else "m",
            "a": c.a,
            "b": c.b,
            "change": c.diff,
            "sigma": c.sigma,
            "significance": c.significance,
            "significant": c.significance is not None and c.significance > threshold,
        }
        for c in result.changes
    ]
    return {
        "schema": "dhlog.compare/1",
        "a": plain(first),
        "b": plain(second),
        "threshold": threshold,
        "changes": changes,
        "significant": [c["name"] for c in changes if c["significant"]],
        "fk": {
            "samples": result.samples,
            "rms": result.fk_rms,
            "max": result.fk_max,
            "max_at": [float(v) for v in result.fk_max_at],
        },
        "units": {"length": "m", "angle": "rad"},
    }


def _print_comparison(result: Comparison, threshold: float) -> None:
    """The console's account of a comparison: the changes table and the FK difference."""
    rows = []
    significant = []
    for c in result.changes:
        f, unit = (180 / math.pi, "°") if c.angular else (1e3, "mm")
        z = c.significance
        mark = "" if z is None else f"{z:.1f}" + (" *" if z > threshold else "")
        if z is not None and z > threshold:
            significant.append(c.name)
        rows.append(
            (
                c.name,
                f"{c.a * f:.4f}",
                f"{c.b * f:.4f}",
                f"{c.diff * f:+.4f} {unit}",
                "fixed" if c.sigma is None else f"{c.sigma * f:.4f}",
                mark,
            )
        )
    print_values(
        stdout,
        "Changes (B − A; σ: both sessions combined)",
        ("A", "B", "B − A", "σ", "|B − A|\n/ σ"),
        rows,
    )
    at = ", ".join(f"{v:.3f}" for v in result.fk_max_at)
    stdout.print(
        f"FK difference over {result.samples} joint vectors in the joint range: RMS "
        f"{result.fk_rms * 1e3:.4f} mm, max {result.fk_max * 1e3:.4f} mm at q = ({at})."
    )
    if significant:
        stdout.print(f"changed beyond {threshold:g}σ: {plain(', '.join(significant))} (marked *).")
    else:
        stdout.print(f"no parameter changed beyond {threshold:g}σ.")


def _said_implausible(path: Path, done: str) -> None:
    """A warning when the result at ``path`` is one dhlog judged implausible (``done``: what
    the command did with it all the same)."""
    from dhlog.result.check import implausible_reasons, load_result

    try:
        reasons = implausible_reasons(load_result(path))
    except DhlogError:
        return
    if reasons:
        stderr.print(
            f"warning: {plain(path.name)} is a result dhlog judged implausible (dhlog process "
            f"exited 4), {done} as asked: " + " ".join(plain(r) for r in reasons)
        )


#: The narrowest the parameter column of a value table may fold to (below it, a list).
NAME_FOLD = 8


def print_values(
    console: Console, title: str, heads: Sequence[str], rows: Sequence[Sequence[str]]
) -> None:
    """Parameters (each row's first cell) and their values, never cut on a narrow terminal:
    a table when the values fit whole beside the parameter names (which fold, down to
    ``NAME_FOLD`` characters, when the names do not fit on one line); otherwise one line per
    parameter, ``name: head value, …``, wrapped between the values."""
    from rich import box
    from rich.cells import cell_len
    from rich.table import Table

    from dhlog.io.safetext import printable

    def width(texts: Sequence[str]) -> int:
        return max(cell_len(line) for text in texts for line in text.split("\n"))

    values = [width([head, *(r[k + 1] for r in rows)]) for k, head in enumerate(heads)]
    names = width(["parameter", *(r[0] for r in rows)])
    chrome = 2 + len(heads) + 2 * len(heads)  # edges, separators, padding (none at the edges)
    if chrome + min(names, NAME_FOLD) + sum(values) <= console.width:
        table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
        table.add_column("parameter", overflow="fold")
        for head in heads:
            table.add_column(head, justify="right", no_wrap=True)
        for row in rows:
            table.add_row(plain(row[0]), *row[1:])
        console.print(table)
        return
    console.print(title, markup=False)
    for row in rows:
        cells = ", ".join(
            f"{' '.join(head.split())} {value}"
            for head, value in zip(heads, row[1:], strict=True)
            if value
        )
        console.print(f"  {printable(row[0])}: {cells}", markup=False)


def _compare_trends(summary: Path, threshold: float, rrd: Path | None, force: bool) -> None:
    """The console table (and optionally the recording) of a batch summary's trends."""
    from dhlog.fleet.compare import read_summary, trends, write_trend_recording
    from dhlog.io.paths import refuse_inputs_as_outputs
    from dhlog.io.safetext import printable

    try:
        if rrd is not None:  # before any work; the summary stays as it is, even with --force
            check_folder(rrd.parent)
            refuse_inputs_as_outputs([(summary, "batch summary")], [rrd])
            refuse_existing(rrd, force)
        logs, times, found = trends(read_summary(summary), printable(str(summary)))
        if rrd is not None:
            write_trend_recording(logs, times, found, rrd)
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        fail(OutputError(rrd.parent if rrd else summary.parent, exc))
    rows = []
    moved = []
    for t in found:
        f, unit = (180 / math.pi, "°") if t.angular else (1e3, "mm")
        z, step = t.significance, t.largest_step
        if (z is not None and z > threshold) or (step is not None and step > threshold):
            moved.append(t.name)
        rows.append(
            (
                t.name,
                f"{t.values[0] * f:.4f}",
                f"{t.values[-1] * f:.4f}",
                f"{t.change * f:+.4f} {unit}",
                "fixed" if z is None else f"{z:.1f}" + (" *" if z > threshold else ""),
                "fixed" if step is None else f"{step:.1f}" + (" *" if step > threshold else ""),
            )
        )
    print_values(
        stdout,
        f"Trends over {len(logs)} sessions (first → last; σ combined)",
        ("first", "last", "change", "|change|\n/ σ", "largest\nstep / σ"),
        rows,
    )
    if moved:  # the names are the summary's columns: text, never markup
        stdout.print(f"moved beyond {threshold:g}σ: {plain(', '.join(moved))} (marked *).")
    else:
        stdout.print(f"no parameter moved beyond {threshold:g}σ over the sessions.")
    if rrd is not None:
        stdout.print(f"wrote {plain(rrd)}; open it with: {plain(viewer())} {plain(rrd)}")
