"""The ``dhlog`` command line: a thin layer over the library.

Only this module catches :class:`~dhlog.errors.DhlogError`, printing its one-line message and
exiting with 2 (unreadable or unusable input); usage errors exit with 1.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated, Literal

import typer
from rich.console import Console

from dhlog import __version__
from dhlog.errors import DhlogError

app = typer.Typer(
    name="dhlog",
    help="Exact Denavit-Hartenberg parameters from robot calibration logs (MCAP).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
err = Console(stderr=True, highlight=False)
out = Console(highlight=False)

EXIT_USAGE, EXIT_INPUT, EXIT_PARTIAL = 1, 2, 3


def _fail(exc: DhlogError) -> None:
    err.print(f"[bold red]error:[/] {exc}", soft_wrap=True)
    raise typer.Exit(EXIT_INPUT)


def _version(value: bool) -> None:
    if value:
        out.print(f"dhlog {__version__}")
        raise typer.Exit(0)


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Exact Denavit-Hartenberg parameters from robot calibration logs (MCAP)."""


@app.command()
def simulate(
    robot: Annotated[
        str,
        typer.Argument(
            help="A library robot (kr5, puma560, ur5, elbow, scara, stanford) or a DH file."
        ),
    ],
    output: Annotated[
        Path,
        typer.Option(
            "-o",
            "--output",
            help="The MCAP file to write; the truth goes beside it as <stem>.truth.json.",
        ),
    ],
    encoding: Annotated[
        str, typer.Option(help="ros2 (as rosbag2 writes it), json or protobuf.")
    ] = "ros2",
    noise_mm: Annotated[
        float, typer.Option(help="Tracker noise: σ (gaussian) or half-width (uniform), mm.")
    ] = 0.01,
    noise_kind: Annotated[str, typer.Option(help="gaussian or uniform.")] = "gaussian",
    motion: Annotated[
        str, typer.Option(help="continuous, or step (step-and-measure).")
    ] = "continuous",
    tracker_rate: Annotated[float, typer.Option(help="Tracker samples per second.")] = 100.0,
    joint_rate: Annotated[
        float, typer.Option(help="Joint-state samples per second (own clock).")
    ] = 250.0,
    sweep_deg: Annotated[float, typer.Option(help="Sweep of each revolute joint, degrees.")] = 90.0,
    travel_mm: Annotated[float, typer.Option(help="Travel of each prismatic joint, mm.")] = 100.0,
    steps: Annotated[int, typer.Option(help="Stops per sweep in step mode.")] = 12,
    lock_poses: Annotated[
        str, typer.Option(help="home (all sweeps from one pose) or random.")
    ] = "home",
    base_points: Annotated[int, typer.Option(help="Points probed on the mounting plane.")] = 12,
    outliers: Annotated[float, typer.Option(help="Fraction of gross outliers (mm-sized).")] = 0.0,
    dropouts: Annotated[
        float, typer.Option(help="Fraction of tracker samples lost in bursts.")
    ] = 0.0,
    no_encoders: Annotated[
        bool, typer.Option("--no-encoders", help="Write no joint states (phase markers instead).")
    ] = False,
    phase: Annotated[bool, typer.Option("--phase", help="Write phase markers.")] = False,
    point_type: Annotated[
        str, typer.Option(help="ROS 2 target message: point (PointStamped) or pose (PoseStamped).")
    ] = "point",
    perturb_mm: Annotated[
        float, typer.Option(help="σ of length errors of the simulated robot against its table, mm.")
    ] = 0.0,
    perturb_deg: Annotated[
        float, typer.Option(help="σ of angle errors of the simulated robot, degrees.")
    ] = 0.0,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing outputs.")] = False,
) -> None:
    """Write a simulated calibration session and its ground truth."""
    from dhlog.dhfile import robot_or_dh_file
    from dhlog.io.writer import sha256_of, write_session, write_truth
    from dhlog.simulate import SimulationConfig, simulate_session, truth_document

    choices = {
        "encoding": (encoding, ("ros2", "json", "protobuf")),
        "noise-kind": (noise_kind, ("gaussian", "uniform")),
        "motion": (motion, ("continuous", "step")),
        "lock-poses": (lock_poses, ("home", "random")),
        "point-type": (point_type, ("point", "pose")),
    }
    for option, (value, allowed) in choices.items():
        if value not in allowed:
            err.print(f"error: --{option} must be one of {', '.join(allowed)}, not '{value}'.")
            raise typer.Exit(EXIT_USAGE)
    truth_path = output.with_name(output.stem + ".truth.json")
    for path in (output, truth_path):
        if path.exists() and not force:
            err.print(f"error: {path} exists; pass --force to overwrite it.")
            raise typer.Exit(EXIT_USAGE)
    try:
        rob = robot_or_dh_file(robot)
        cfg = SimulationConfig(
            noise=noise_mm * 1e-3,
            noise_kind=noise_kind,  # type: ignore[arg-type]
            tracker_rate=tracker_rate,
            joint_rate=joint_rate,
            motion=motion,  # type: ignore[arg-type]
            sweep=math.radians(sweep_deg),
            travel=travel_mm * 1e-3,
            steps=steps,
            lock_poses=lock_poses,  # type: ignore[arg-type]
            base_points=base_points,
            outliers=outliers,
            dropouts=dropouts,
            encoders=not no_encoders,
            phase=phase or no_encoders,
            perturb_length=perturb_mm * 1e-3,
            perturb_angle=math.radians(perturb_deg),
            seed=seed,
        )
        session = simulate_session(rob, cfg)
        kind: Literal["point", "pose"] = "pose" if point_type == "pose" else "point"
        write_session(session, output, encoding, point_type=kind)  # type: ignore[arg-type]
        pipeline = (
            "phase_markers"
            if no_encoders
            else {"ros2": "ros2_tracker", "json": "foxglove_json", "protobuf": "foxglove_protobuf"}[
                encoding
            ]
        )
        doc = truth_document(
            session,
            source_path=output.name,
            sha256=sha256_of(output),
            pipeline=pipeline,
            version=__version__,
        )
        write_truth(doc, truth_path)
    except DhlogError as exc:
        _fail(exc)
    out.print(
        f"wrote {output} ({session.point_xyz.shape[0]} target samples, "
        f"{session.joint_t_ns.size} joint states, {encoding}) and {truth_path}"
    )


def run() -> None:
    """Entry point: run the app, mapping stray DhlogErrors to exit code 2."""
    try:
        app()
    except DhlogError as exc:  # pragma: no cover - commands catch their own
        err.print(f"error: {exc}")
        sys.exit(EXIT_INPUT)
