"""``dhlog iso9283``: the ISO 9283 acceptance report from tracker logs (thin: the options
parsed, :func:`dhlog.iso9283.run.run_logs` called, the tables printed, the JSON and the
recording (:func:`dhlog.present.recording.iso9283.write_iso9283_recording`) written)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from dhlog.cli.common import (
    EXIT_USAGE,
    check_writable,
    fail,
    plain,
    refuse_existing,
    stderr,
    stdout,
)
from dhlog.cli.options import PIPELINE_HELP, load_model, load_pipeline
from dhlog.errors import DhlogError, OutputError


def iso9283(
    logs: Annotated[
        list[Path],
        typer.Argument(
            metavar="LOG", help="The test's log(s) (.mcap or bag folder), read as one test."
        ),
    ],
    nominal: Annotated[
        str | None,
        typer.Option(
            metavar="ROBOT|FILE",
            help="The model the controller runs (library robot or DH file): its FK of the "
            "commanded joints is the commanded position (accuracy AP, AD).",
        ),
    ] = None,
    result: Annotated[
        Path | None,
        typer.Option(
            metavar="R.dh.json",
            help="A calibration result of this robot: its placement gives the base frame, and "
            "each accuracy figure is given after the calibration too.",
        ),
    ] = None,
    pipeline: Annotated[str | None, typer.Option(metavar="NAME|FILE", help=PIPELINE_HELP)] = None,
    commanded: Annotated[
        Path | None,
        typer.Option(
            metavar="CSV",
            help="The test program dhlog plan --iso9283 wrote: it names the poses and gives "
            "the paths (AT, RT); the commanded targets where the log has no commanded stream.",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            metavar="DIR",
            help="Where <stem>.iso9283.json goes (default: beside the log; created when missing).",
        ),
    ] = None,
    stops: Annotated[
        bool,
        typer.Option(
            "--stops",
            help="The log is a tracker's static measurements, one point per stop (as tracker "
            "software exports them; detected when its samples are too sparse for a dwell): "
            "each stop is a visit, grouped into poses by its joints.",
        ),
    ] = False,
    no_rrd: Annotated[
        bool, typer.Option("--no-rrd", help="Do not write the Rerun recording.")
    ] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the outputs.")] = False,
) -> None:
    """The ISO 9283 characteristics (AP, RP, vAP, AD/RD, stabilisation, overshoot, drift; AT,
    RT with the test program) of a robot's test from tracker logs (a time series, or static
    measurements one per stop: --stops), before and after a calibration; written as
    <stem>.iso9283.json and the recording <stem>.iso9283.rrd (the cube, each pose's attained
    positions and RP sphere, the paths' deviations)."""
    from dhlog.api import acceptance_test
    from dhlog.iso9283.report import report_document, write_report
    from dhlog.present.console.iso9283 import print_iso9283

    if result is not None and nominal is None:
        stderr.print(
            "error: --result needs --nominal (the model the controller runs: the commanded "
            "positions are its forward kinematics)."
        )
        raise typer.Exit(EXIT_USAGE)
    first = logs[0]
    folder = out if out is not None else first.resolve().parent
    check_writable(folder)  # a file in the way, or no permission: refused before any work
    stem = first.name.removesuffix(".zstd").removesuffix(".mcap").removesuffix(".db3")
    target = folder / f"{stem}.iso9283.json"
    recording = None if no_rrd else folder / f"{stem}.iso9283.rrd"
    outputs = [target] if recording is None else [target, recording]
    inputs = [*logs, *(p for p in (result, commanded) if p is not None)]
    for output in outputs:
        if any(output.resolve() == p.resolve() for p in inputs):
            stderr.print(f"error: {plain(output)} is an input; choose another --out.")
            raise typer.Exit(EXIT_USAGE)
        refuse_existing(output, force)
    try:
        report = acceptance_test(
            logs,
            nominal=None if nominal is None else load_model(nominal),
            result=result,
            pipeline=None if pipeline is None else load_pipeline(pipeline),
            commanded=commanded,
            stops=True if stops else None,
        )
        source = {
            "logs": [str(p) for p in logs],
            "nominal": nominal,
            "result": None if result is None else str(result),
            "commanded": None if commanded is None else str(commanded),
            "pipeline": pipeline,
        }
        try:
            folder.mkdir(parents=True, exist_ok=True)  # --out is created when missing
        except OSError as exc:
            raise OutputError(folder, exc) from None
        write_report(report_document(report, source), target)
        if recording is not None:
            from dhlog.present.recording.iso9283 import write_iso9283_recording

            write_iso9283_recording(report, recording)
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        fail(OutputError(folder, exc))
    print_iso9283(stdout, report)
    for output in outputs:
        stdout.print(f"wrote {plain(output)}", soft_wrap=True)
