"""Logs in: ``dhlog pipelines`` (the shipped ways of reading a log) and ``dhlog import`` (a
tracker's export converted into a log)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dhlog.cli.common import (
    EXIT_USAGE,
    check_folder,
    fail,
    plain,
    refuse_existing,
    stderr,
    stdout,
)
from dhlog.cli.options import listed
from dhlog.errors import DhlogError, OutputError


def pipelines() -> None:
    """List the shipped pipelines (--pipeline takes their names, or a pipeline file)."""
    from dhlog.io.pipeline import shipped_pipelines

    stdout.print(
        "Shipped pipelines (dhlog process LOG --pipeline NAME; or --pipeline FILE, a pipeline "
        "file of your own):"
    )
    for p in shipped_pipelines():
        topic = (
            f"image topic {plain(p.image.topic)}"
            if p.image is not None
            else f"point topic {plain(p.streams['point'].topic)}"
        )
        stdout.print(
            f"  {plain(p.name)} ({', '.join(p.encodings)}; {topic}): {plain(p.description)}"
        )


def import_(
    source: Annotated[
        Path,
        typer.Argument(
            help="The export: a CSV, a SpatialAnalyzer point list or table, a Leica CSV."
        ),
    ],
    output: Annotated[
        Path | None,
        typer.Option("-o", "--output", help="The MCAP log to write (default: <source>.mcap)."),
    ] = None,
    format: Annotated[str, typer.Option("--format", help="csv, spatialanalyzer or leica.")] = "csv",
    joints_file: Annotated[
        Path | None,
        typer.Option(
            help="A CSV of joint values, matched to the points by name (a name column, or "
            "--name-column) or else by row."
        ),
    ] = None,
    x: Annotated[str, typer.Option(help="The column of the target's x.")] = "x",
    y: Annotated[str, typer.Option(help="The column of the target's y.")] = "y",
    z: Annotated[str, typer.Option(help="The column of the target's z.")] = "z",
    targets: Annotated[
        str | None,
        typer.Option(
            metavar="PREFIX,…",
            help="Several targets (reflectors) per row: the prefixes of their x, y, z columns, "
            "comma-separated, the first the primary target (mA,mB,mC reads mA_x_m … mC_z_m); "
            "the others go to /tracker/point_2, … and are read without a pipeline file.",
        ),
    ] = None,
    joint_columns: Annotated[
        str | None,
        typer.Option(
            help="Joint columns in chain order, comma-separated, of the joints file if given "
            "(default: q1…, j1…, a1…, joint_1…, axis1…)."
        ),
    ] = None,
    joint_names: Annotated[
        str | None, typer.Option(help="Joint names, comma-separated (default: the columns').")
    ] = None,
    joint_types: Annotated[
        str | None,
        typer.Option(help="revolute/prismatic per joint, comma-separated (default: revolute)."),
    ] = None,
    time: Annotated[
        str | None,
        typer.Option(help="The time column (default: none — one stop per row, step and measure)."),
    ] = None,
    time_unit: Annotated[str, typer.Option(help="s, ms, us or ns.")] = "s",
    name_column: Annotated[
        str | None,
        typer.Option(
            help="The point-name column, of the source and of the joints file (default: "
            "Point Name, Name, Point ID, Point, …)."
        ),
    ] = None,
    length_unit: Annotated[
        str | None,
        typer.Option(
            help="m, mm, um or in: positions, U95, prismatic joints, where the header states "
            "no unit (default: a comment line's '# Units: …', else mm; a header or comment "
            "that states another is an error)."
        ),
    ] = None,
    angle_unit: Annotated[
        str | None,
        typer.Option(
            help="rad, deg or gon: rotation angles (and revolute joints unless "
            "--joint-angle-unit is given), where the header states no unit (default deg)."
        ),
    ] = None,
    joint_angle_unit: Annotated[
        str | None,
        typer.Option(
            help="rad, deg or gon: revolute joints, where the header states no unit (default: "
            "--angle-unit, else deg)."
        ),
    ] = None,
    orientation_columns: Annotated[
        str | None,
        typer.Option(
            help="The 6-DoF target's orientation: four columns (a quaternion, scalar first) or "
            "three (rotation angles, see --euler), or none (default: Q0…Q3, Qw…Qz, Rx Ry Rz "
            "from the header)."
        ),
    ] = None,
    euler: Annotated[
        str,
        typer.Option(
            help="The rotation angles' sequence: lower case about fixed axes (xyz: X, then Y, "
            "then Z), upper case about moving ones (ZYX)."
        ),
    ] = "xyz",
    no_u95: Annotated[
        bool,
        typer.Option(
            "--no-u95",
            help="Leave the uncertainty columns (U95, unc, σ) out (the noise model applies).",
        ),
    ] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Convert a tracker export (CSV, SpatialAnalyzer, Leica) into a log dhlog process reads."""
    from dhlog.io.importer import ImportOptions, import_source, same_file, write_imported

    out = output if output is not None else source.with_suffix(".mcap")
    for given, what in ((source, "the source"), (joints_file, "the --joints-file")):
        if given is not None and same_file(out, given):
            stderr.print(
                f"error: the output {plain(out)} would replace {what}; an output is never "
                "one of the inputs: name another with -o."
            )
            raise typer.Exit(EXIT_USAGE)
    check_folder(out.parent)
    refuse_existing(out, force)
    opts = ImportOptions(
        format=format,
        joints_file=joints_file,
        x=x,
        y=y,
        z=z,
        joint_columns=listed(joint_columns),
        joint_names=listed(joint_names),
        joint_types=listed(joint_types),
        time=time,
        time_unit=time_unit,
        name_column=name_column,
        length_unit=length_unit,
        angle_unit=angle_unit,
        joint_angle_unit=joint_angle_unit,
        orientation_columns=listed(orientation_columns),
        euler=euler,
        no_u95=no_u95,
        targets=listed(targets),
    )
    try:
        imported = import_source(source, opts)
        write_imported(imported, out)
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        fail(OutputError(out.parent, exc))
    for w in imported.warnings:
        stderr.print(f"warning: {plain(w)}")
    for note in imported.notes:
        stdout.print(f"note: {plain(note)}", soft_wrap=True)
    kind = "stops (step and measure)" if imported.stepped else "timed samples"
    u95 = (
        ""
        if imported.covariance is None
        else ", with per-point σ as covariance"
        if "sigma_columns" in imported.provenance
        else ", with per-point U95 as covariance"
    )
    rot = (
        f", with the target's orientation from {plain(imported.provenance['orientation_columns'])}"
        if imported.orientation is not None
        else ""
    )
    if imported.further is not None:
        rot += f", {1 + len(imported.further)} targets"
    stdout.print(
        f"wrote {plain(out)}: {len(imported.xyz)} {kind}{u95}{rot}, joints "
        f"{plain(', '.join(imported.joint_names))}; next: dhlog process {plain(out)}"
    )
