"""``dhlog process``: one log identified, its results written, the result shown."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from dhlog.cli.common import (
    EXIT_IMPLAUSIBLE,
    EXIT_INPUT,
    EXIT_PARTIAL,
    EXIT_USAGE,
    check_writable,
    fail,
    plain,
    say_implausible,
    stderr,
    stdout,
    viewer,
)
from dhlog.cli.options import (
    PIPELINE_HELP,
    angles,
    floats,
    load_model,
    load_pipeline,
    model_request,
)
from dhlog.errors import DhlogError, OutputError


def process(
    log: Annotated[
        Path,
        typer.Argument(
            metavar="LOG", help="The session log (.mcap or .db3, or a rosbag2 bag folder)."
        ),
    ],
    pipeline: Annotated[
        str | None,
        typer.Option(metavar="NAME|FILE", help=PIPELINE_HELP),
    ] = None,
    nominal: Annotated[
        str | None,
        typer.Option(
            metavar="ROBOT|FILE",
            help="A nominal DH file (or library robot): ambiguous choices follow it, "
            "and measured - nominal is shown.",
        ),
    ] = None,
    reference_pose: Annotated[
        str | None,
        typer.Option(
            metavar="Q1,Q2,…",
            help="Joint values of the reference pose, comma-separated (in --angle-unit, m for "
            "prismatic); default: the locked pose most sweeps share.",
        ),
    ] = None,
    angle_unit: Annotated[
        str | None,
        typer.Option(
            metavar="rad|deg",
            help="The unit of --reference-pose (default: the pipeline's angle_unit).",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            metavar="DIR",
            help="Folder for the results (default: beside the log; created when missing).",
        ),
    ] = None,
    units: Annotated[
        str,
        typer.Option(
            metavar="mm|m",
            help="Units on the console and in the CSV: mm (mm, degrees) or m (m, rad).",
        ),
    ] = "mm",
    no_rrd: Annotated[
        bool, typer.Option("--no-rrd", help="Do not write the Rerun recording.")
    ] = False,
    with_log: Annotated[
        bool,
        typer.Option(
            "--with-log",
            help="Also import the log's own channels into the recording, for context.",
        ),
    ] = False,
    analytic_only: Annotated[
        bool,
        typer.Option(
            "--analytic-only",
            help="Only the per-joint circle fits and the line geometry of their axes, without "
            "the fit of the whole model to every sample.",
        ),
    ] = False,
    fit_encoder_scales: Annotated[
        bool,
        typer.Option(
            "--fit-encoder-scales",
            help="Also fit one scale per encoder (gear ratio errors), reported with σ.",
        ),
    ] = False,
    holdout: Annotated[
        int,
        typer.Option(
            metavar="K",
            help="K-fold cross-validation (K ≥ 2): the error at poses not used to fit, of the "
            "nominal and of the calibrated model (0: none).",
        ),
    ] = 0,
    validate: Annotated[
        list[Path] | None,
        typer.Option(
            metavar="LOG",
            help="A log of other poses of the same robot (repeat for several) scoring the "
            "result; placed on a third of its poses when the tracker moved.",
        ),
    ] = None,
    model: Annotated[
        str,
        typer.Option(
            metavar="auto|geometric|compliance|harmonic|full",
            help="Terms beyond the geometry: auto adds gravity compliance, then transmission "
            "harmonics, only where they lower both the K-fold held-out error and the BIC; the "
            "others force a choice.",
        ),
    ] = "auto",
    gravity: Annotated[
        str | None,
        typer.Option(
            metavar="X,Y,Z",
            help="The direction gravity pulls in the measurement frame, for compliance "
            "(default: along joint 1's axis, against M's z).",
        ),
    ] = None,
    harmonic_joints: Annotated[
        str | None,
        typer.Option(
            metavar="J,…", help="Joints given harmonic terms (default: every revolute joint)."
        ),
    ] = None,
    masses: Annotated[
        Path | None,
        typer.Option(
            metavar="URDF",
            help="The robot's URDF: gravity compliance from its links' <inertial> masses (one "
            "compliance per joint and the payload) instead of the lumped terms; gravity along "
            "its base's -z.",
        ),
    ] = None,
    refine: Annotated[
        bool,
        typer.Option(
            "--refine",
            hidden=True,
            help="No-op: the whole-model fit against every sample is the default.",
        ),
    ] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing results.")] = False,
    camera_setup: Annotated[
        str | None,
        typer.Option(
            "--camera-setup",
            metavar="eye-to-hand|eye-in-hand",
            help="A vision log: the camera fixed in the cell and the board on the flange "
            "(eye-to-hand), or the camera on the flange (eye-in-hand). Default: decided from "
            "the data (with --nominal).",
        ),
    ] = None,
    refine_intrinsics: Annotated[
        bool,
        typer.Option(
            "--refine-intrinsics",
            help="A vision log: fit the camera's intrinsics with the model (held as recorded "
            "by default).",
        ),
    ] = False,
    frames: Annotated[
        str | None,
        typer.Option(
            "--frames",
            metavar="FIRST:END",
            help="A vision log: calibrate from the frames FIRST (included) to END (excluded) "
            "of the image topic only, e.g. 0:212 or 230: (a camera that moved in between).",
        ),
    ] = None,
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs", "-j", min=1, max=256, help="A vision log: processes decoding and detecting."
        ),
    ] = 1,
) -> None:
    """Identify the DH parameters from a calibration log and write <stem>.dh.json, .dh.csv, .rrd."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from dhlog.api.operations import process as identify
    from dhlog.api.operations import with_info
    from dhlog.api.outputs import output_names, write_run
    from dhlog.present.console import print_result

    if units not in ("mm", "m"):
        stderr.print(f"error: --units must be mm or m, not '{plain(units)}'.")
        raise typer.Exit(EXIT_USAGE)
    for other in validate or []:  # a validation asked for and missing: refused before any work
        if not other.exists():
            stderr.print(
                f"[bold red]error:[/] --validate {plain(other)}: no such file or folder; give "
                "the held-out session's log (a tracker's export: convert it with dhlog import "
                "first). Nothing was written."
            )
            raise typer.Exit(EXIT_INPUT)
    if angle_unit not in (None, "rad", "deg"):
        stderr.print(f"error: --angle-unit must be rad or deg, not '{plain(angle_unit)}'.")
        raise typer.Exit(EXIT_USAGE)
    if camera_setup not in (None, "eye-to-hand", "eye-in-hand"):
        stderr.print(
            f"error: --camera-setup must be eye-to-hand or eye-in-hand, not "
            f"'{plain(camera_setup)}'."
        )
        raise typer.Exit(EXIT_USAGE)
    frame_range = None
    if frames is not None:
        first, sep, end = frames.partition(":")
        try:
            if not sep:
                raise ValueError
            frame_range = (
                int(first) if first.strip() else None,
                int(end) if end.strip() else None,
            )
        except ValueError:
            stderr.print(
                f"error: --frames must be FIRST:END (frame indices, either may be empty), not "
                f"'{plain(frames)}'."
            )
            raise typer.Exit(EXIT_USAGE) from None
    if holdout == 1 or not 0 <= holdout <= 1000:
        stderr.print(
            f"error: --holdout must be 0 (none) or a fold count of 2 to 1000, not {holdout}."
        )
        raise typer.Exit(EXIT_USAGE)
    request = model_request(model, gravity, harmonic_joints)
    if masses is not None:
        if not masses.is_file():
            stderr.print(f"error: --masses {plain(masses)}: no such file; give the robot's URDF.")
            raise typer.Exit(EXIT_USAGE)
        request = replace(request, masses=str(masses))
    folder = out if out is not None else log.parent
    stem = log.name.removesuffix(".zstd").removesuffix(".mcap").removesuffix(".db3")
    outputs = output_names(
        folder / f"{stem}.dh.json",
        recording=not no_rrd,
        heldout=bool(holdout or validate),
        terms=request.mode != "geometric" and not analytic_only,
    )
    inputs = {p.resolve() for p in [log, *(validate or [])]}
    clash = [plain(p) for p in outputs if p.resolve() in inputs]
    if clash:
        stderr.print(f"error: {', '.join(clash)} is an input; choose another --out.")
        raise typer.Exit(EXIT_USAGE)
    existing = [plain(p) for p in outputs if p.exists()]
    if existing and not force:
        stderr.print(f"error: {', '.join(existing)} exist(s); pass --force to overwrite.")
        raise typer.Exit(EXIT_USAGE)
    check_writable(folder)
    ref = None if reference_pose is None else np.array(floats(reference_pose, "--reference-pose"))
    try:
        pipe = load_pipeline(pipeline) if pipeline is not None else None
        if ref is not None:
            unit = angle_unit or (pipe.angle_unit if pipe is not None else "rad")
            types = pipe.joint_types if pipe is not None and pipe.joint_types else None
            ref = angles(ref, unit, types)
        nom = load_model(nominal) if nominal is not None else None  # named before the log
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TimeElapsedColumn(),
            console=stderr,
            transient=True,
            disable=not stderr.is_terminal,
        ) as bar:
            task = bar.add_task(f"reading {plain(log.name)}", total=1.0)

            def advance(stage: str, fraction: float) -> None:
                bar.update(task, description=f"{stage} {plain(log.name)}", completed=fraction)

            calibration = identify(
                log,
                nominal=nom,
                pipeline=pipe,
                reference_pose=ref,
                analytic_only=analytic_only,
                fit_encoder_scales=fit_encoder_scales,
                holdout=holdout,
                validate=list(validate or []),
                model=request.mode,
                gravity=request.gravity,
                harmonic_joints=None
                if request.harmonic_joints is None
                else [j + 1 for j in request.harmonic_joints],
                masses=request.masses,
                progress=advance,
                camera_setup=camera_setup,  # type: ignore[arg-type]
                refine_intrinsics=refine_intrinsics,
                jobs=jobs,
                frames=frame_range,
            )
            if refine:  # in the console's report and in the JSON the calibration writes
                said = (
                    "--refine is a no-op: the fit of the whole model to every sample is the "
                    "default (--analytic-only gives the per-joint circle fits and line geometry "
                    "alone)."
                )
                calibration = with_info(calibration, said, "refine-no-op")
            run = calibration.run
            assert run is not None  # a run's calibration carries its record
            result = run
            advance("writing", 0.0)
            try:
                folder.mkdir(parents=True, exist_ok=True)  # --out is created when missing
            except OSError as exc:
                raise OutputError(folder, exc) from None
            write_run(calibration, outputs, units, hold_signals=True, with_log=with_log)
    except DhlogError as exc:
        fail(exc)
    if result.log.pipeline_reason:
        stdout.print(plain(f"{log.name}: {result.log.pipeline_reason}"))
    print_result(stdout, result, units=units)
    stdout.print("wrote " + ", ".join(plain(p) for p in outputs))
    if not no_rrd:
        stdout.print(f"open the recording with: {plain(viewer())} {plain(outputs[2])}")
    if (
        (holdout or validate)
        and not result.holdout
        and (result.whole is None or not result.complete)
    ):
        stderr.print(
            "held-out error: not computed (it needs the whole-model fit of a complete result)."
        )
    if not result.complete:
        names = ", ".join(f"joint {j.index} ({plain(j.name)})" for j in result.failed)
        stderr.print(f"partial result: {names} not identified; the rest was written.")
    if not calibration.plausible:  # 4 wins over 3: what was written is not to be used
        say_implausible(calibration.implausible)
        raise typer.Exit(EXIT_IMPLAUSIBLE)
    if not result.complete:
        raise typer.Exit(EXIT_PARTIAL)
