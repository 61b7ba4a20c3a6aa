"""The ``dhlog`` command line: a thin layer over the library.

Only this module catches :class:`~dhlog.errors.DhlogError`, printing its one-line message and
exiting with 2 (unreadable or unusable input); usage errors exit with 1 (``EXIT_CODES`` lists
them all, as ``dhlog --help`` prints them).
"""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, NoReturn, get_args, get_origin

import numpy as np
import typer
from rich.console import Console
from typer.core import TyperArgument, TyperCommand, TyperGroup

from dhlog import __version__
from dhlog.errors import DhlogError, OutputError

if TYPE_CHECKING:
    from dhlog.io.dhfile import DHModel
    from dhlog.io.pipeline import Pipeline

EXIT_USAGE, EXIT_INPUT, EXIT_PARTIAL = 1, 2, 3
EXIT_INTERRUPTED, EXIT_OUTPUT_CLOSED, EXIT_TERMINATED = 130, 141, 143

#: The epilog of ``dhlog --help``, ``process --help`` and ``batch --help`` (no square brackets:
#: the help is rich markup).
EXIT_CODES = (
    "Exit codes: 0 success; 1 usage error (a bad option or argument, an output that exists "
    "without --force, an output folder that does not exist); 2 unreadable or unusable input, or "
    "an output that cannot be written; 3 partial result (joints not identified; in a batch, "
    "logs that failed: the rest is written); 130 interrupted (Ctrl-C); 141 the standard output "
    "was closed (| head: the results were written first); 143 terminated (SIGTERM)."
)


class _Ended(BaseException):
    """The run ends here with ``code``, its message (if any) printed: no command-line library
    in between may turn it into another exit."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


class _Console(Console):
    """A console whose closed output (``dhlog process … | head -1``) ends the run quietly with
    ``EXIT_OUTPUT_CLOSED``; rich's own ending is exit 1 without a word, the code of a usage
    error."""

    def on_broken_pipe(self) -> None:
        self.quiet = True
        try:  # what Python still flushes at exit goes nowhere, without "Exception ignored"
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self.file.fileno())
            os.close(devnull)
        except (OSError, ValueError):  # a file without a descriptor (tests)
            pass
        raise _Ended(EXIT_OUTPUT_CLOSED)


def _type_metavar(param: Any) -> str | None:
    """click's name of a parameter's type (PATH, TEXT, INTEGER, FLOAT), from typer's own
    description of it; None where typer has none (older typer: click names it itself)."""
    desc = getattr(param, "type_descriptor", None)
    if desc is None:
        return None
    annotation = getattr(desc, "annotation", None)
    if get_origin(annotation) is list:
        annotation = get_args(annotation)[0]
    names: dict[Any, str] = {Path: "PATH", str: "TEXT", int: "INTEGER", float: "FLOAT"}
    return names.get(annotation, "VALUE")


class _Argument(TyperArgument):
    """An argument as click shows it: its metavar alone (``LOG``) in the usage line, ``[LOG]``
    when optional, ``LOG...`` when repeated, no type beside it in the help."""

    def display_type_rich(self, ctx: Any) -> str | None:
        return None

    def get_usage_pieces(self, ctx: Any) -> list[str]:
        name = self.metavar or (self.name or "").upper()
        if self.nargs != 1:
            name += "..."
        return [name if self.required else f"[{name}]"]


def _plain_help(params: list[Any]) -> list[Any]:
    """Metavars as a user reads them. typer 0.2x's rich help gives every parameter its Python
    type: flags show as ``--force <bool>`` (and ``--force true`` is then refused), arguments as
    ``{log}`` in the usage line, a repeated option as ``<list[Path]>``. Here a flag shows
    nothing after its name, an argument its name in capitals, an option its metavar or click's
    name of its type."""
    for p in params:
        if isinstance(p, TyperArgument):
            if type(p) is TyperArgument:
                p.__class__ = _Argument
            if p.metavar is None:
                p.metavar = (p.name or "").upper()
        elif getattr(p, "is_flag", False) or getattr(p, "count", False):
            if p.metavar is None:
                p.metavar = ""
        elif p.metavar is None:
            p.metavar = _type_metavar(p)
    return params


class _Command(TyperCommand):
    """A command whose help and usage line read as click's (:func:`_plain_help`)."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain_help(super().get_params(ctx))


class _Group(TyperGroup):
    """``dhlog`` itself, its help as :class:`_Command`'s."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain_help(super().get_params(ctx))


app = typer.Typer(
    name="dhlog",
    help="Exact Denavit-Hartenberg parameters from robot calibration logs (MCAP).",
    epilog=EXIT_CODES,
    cls=_Group,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
stderr = _Console(stderr=True, highlight=False, soft_wrap=True)
stdout = _Console(highlight=False)


def _fail(exc: DhlogError, code: int = EXIT_INPUT) -> None:
    """One line on stderr (the message is the log's text, never markup) and the exit code."""
    from rich.markup import escape

    stderr.print(f"[bold red]error:[/] {escape(str(exc))}", soft_wrap=True)
    raise typer.Exit(code)


def _check_folder(folder: Path) -> None:
    """A command's output folder must exist (only ``process --out`` creates one)."""
    _refuse_file(folder)
    if not folder.is_dir():
        from rich.markup import escape

        stderr.print(f"error: the folder {escape(str(folder))} does not exist; create it first.")
        raise typer.Exit(EXIT_USAGE)
    _check_writable(folder)


def _existing_above(folder: Path) -> Path:
    """``folder``, or the nearest of its parents that exists."""
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return probe


def _refuse_file(folder: Path) -> None:
    """Exit 2 (as every unwritable output) when an output folder, or the nearest existing path
    above it, is a file."""
    probe = _existing_above(folder)
    if probe.exists() and not probe.is_dir():
        from rich.markup import escape

        stderr.print(
            f"[bold red]error:[/] cannot write into {escape(str(folder))}: {escape(str(probe))} "
            "is a file, not a folder; choose a folder, or move the file away. Nothing was "
            "written."
        )
        raise typer.Exit(EXIT_INPUT)


def _check_writable(folder: Path) -> None:
    """Stop before any work when the output folder (or, if missing, the nearest existing folder
    above it) cannot be written, or is a file."""
    _refuse_file(folder)
    probe = _existing_above(folder)
    if not os.access(probe, os.W_OK | os.X_OK):
        _fail(OutputError(folder, PermissionError(13, "Permission denied")))


def _refuse_existing(path: Path, force: bool) -> None:
    """Exit 1 when an output exists and --force was not given."""
    if path.exists() and not force:
        from rich.markup import escape

        stderr.print(f"error: {escape(str(path))} exists; pass --force to overwrite it.")
        raise typer.Exit(EXIT_USAGE)


def _quiet_numerics() -> None:
    """Floating-point warnings of numpy on damaged data are not for the user: every result is
    checked for finiteness where it matters, and what is set aside is counted."""
    import warnings

    warnings.filterwarnings("ignore", category=RuntimeWarning)
    np.seterr(all="ignore")


def _version(value: bool) -> None:
    if value:
        stdout.print(f"dhlog {__version__}")
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


@app.command(cls=_Command)
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
    protocol: Annotated[
        str,
        typer.Option(
            help="sweeps (each joint alone), random-poses (--poses still poses within the "
            "limits, every joint changing) or coupled (each joint alone in --steps stops, "
            "except joint 2: only with joint 3 as q3 = -q2); the last two measure only at stops."
        ),
    ] = "sweeps",
    poses: Annotated[
        str,
        typer.Option(
            metavar="N|CSV",
            help="Still poses of --protocol random-poses: how many to draw, or a CSV of joint "
            "vectors to visit in order (one per row, a header row kept; what plan --select "
            "writes), in --angle-unit.",
        ),
    ] = "40",
    angle_unit: Annotated[
        str, typer.Option(metavar="rad|deg", help="The unit of --poses CSV's revolute joints.")
    ] = "rad",
    model_error_mm: Annotated[
        float,
        typer.Option(
            help="σ per coordinate of an unmodelled smooth error of the robot's position "
            "(what gravity and gears leave after a geometric model), mm."
        ),
    ] = 0.0,
    compliance: Annotated[
        str,
        typer.Option(
            metavar="J:C,…",
            help="Gravity compliance of the truth: joint J yields C rad per N·m of the gravity "
            "torque of the robot's lumped masses and payload (kr5, kr210), e.g. '2:2e-8,3:3e-8'.",
        ),
    ] = "",
    payload_kg: Annotated[
        float | None, typer.Option(help="Payload at the tool point for --compliance, kg.")
    ] = None,
    harmonic: Annotated[
        str,
        typer.Option(
            metavar="J:A:B,…",
            help="Transmission error of the truth: Δq_J = A sin q_J + B cos q_J, rad, e.g. "
            "'2:1e-4:5e-5'.",
        ),
    ] = "",
    six_dof: Annotated[
        bool,
        typer.Option(
            "--six-dof",
            help="A 6-DoF target: its frame, turned on the flange, written with its "
            "orientation (PoseStamped / PoseInFrame).",
        ),
    ] = False,
    orientation_noise_deg: Annotated[
        float, typer.Option(help="σ of the 6-DoF target's orientation noise, degrees.")
    ] = 0.0,
    extra_targets: Annotated[
        str,
        typer.Option(
            help="Further targets (SMRs) as 'x,y,z;x,y,z', mm in the flange frame, measured at "
            "the same instants on /tracker/point_2, /tracker/point_3, …"
        ),
    ] = "",
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
    skip_joints: Annotated[
        str,
        typer.Option(
            help="Joints (1-based, comma-separated) never swept, to make a partial session."
        ),
    ] = "",
    clock_offset_ms: Annotated[
        float,
        typer.Option(
            help="Joint-state stamps written this many ms early (the tracker's clock is right): "
            "the clock offset a pipeline would need."
        ),
    ] = 0.0,
    start_day: Annotated[
        float,
        typer.Option(help="Days after 2025-11-21 04:40 UTC the session starts (a series)."),
    ] = 0.0,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing outputs.")] = False,
) -> None:
    """Write a simulated calibration session and its ground truth."""
    from rich.markup import escape

    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import sha256_of, write_session, write_truth
    from dhlog.simulate import (
        PROTOCOLS,
        SIX_DOF_TOOL_ROTATION,
        SimulationConfig,
        config_problems,
        simulate_session,
        swept_joints,
        truth_document,
    )

    choices = {
        "encoding": (encoding, ("ros2", "json", "protobuf")),
        "noise-kind": (noise_kind, ("gaussian", "uniform")),
        "motion": (motion, ("continuous", "step")),
        "lock-poses": (lock_poses, ("home", "random")),
        "point-type": (point_type, ("point", "pose")),
        "protocol": (protocol, PROTOCOLS),
        "angle-unit": (angle_unit, ("rad", "deg")),
    }
    for option, (value, allowed) in choices.items():
        if value not in allowed:
            stderr.print(f"error: --{option} must be one of {', '.join(allowed)}, not '{value}'.")
            raise typer.Exit(EXIT_USAGE)
    extra_tools = _triples(extra_targets, "--extra-targets")
    compliant = [(int(j), c) for j, c in _tuples(compliance, "--compliance", 2)]
    harmonics = [(int(j), a, b) for j, a, b in _tuples(harmonic, "--harmonic", 3)]
    truth_path = output.with_name(output.stem + ".truth.json")
    urdf_path = output.with_name(output.stem + ".urdf") if compliant else None
    _check_folder(output.parent)
    for path in (output, truth_path, *([urdf_path] if urdf_path else [])):
        _refuse_existing(path, force)
    pose_file = None if poses.strip().isdigit() else Path(poses)
    if pose_file is not None and pose_file.resolve() in {
        p.resolve() for p in (output, truth_path, *([urdf_path] if urdf_path else []))
    }:
        stderr.print(f"error: --poses {escape(poses)} is an output; name another.")
        raise typer.Exit(EXIT_USAGE)
    try:
        rob = robot_or_dh_file(robot)
        pose_list: tuple[tuple[float, ...], ...] = ()
        if pose_file is not None:
            pose_list = _pose_file(pose_file, rob, angle_unit)
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
            protocol=protocol,  # type: ignore[arg-type]
            poses=len(pose_list) or int(poses),
            pose_list=pose_list,
            model_error=model_error_mm * 1e-3,
            tool_rotation=SIX_DOF_TOOL_ROTATION if six_dof else None,
            orientation_noise=math.radians(orientation_noise_deg),
            extra_tools=tuple((x * 1e-3, y * 1e-3, z * 1e-3) for x, y, z in extra_tools),
            base_points=base_points,
            outliers=outliers,
            dropouts=dropouts,
            encoders=not no_encoders,
            phase=phase or no_encoders,
            perturb_length=perturb_mm * 1e-3,
            perturb_angle=math.radians(perturb_deg),
            skip_joints=tuple(int(v) for v in _floats(skip_joints, "--skip-joints")),
            clock_offset=clock_offset_ms * 1e-3,
            start_day=start_day,
            compliance=tuple(compliant),
            payload=payload_kg,
            harmonic=tuple(harmonics),
            seed=seed,
        )
        problems = config_problems(rob, cfg)
        if problems:
            stderr.print(f"error: {escape(problems[0])}.")
            raise typer.Exit(EXIT_USAGE)
        session = simulate_session(rob, cfg)
        swept = swept_joints(rob, cfg)
        for k, (got, jt) in enumerate(zip(session.sweeps, rob.table.joint_types, strict=True)):
            asked = cfg.sweep if jt.value == "revolute" else cfg.travel
            if k + 1 in swept and got < asked - 1e-9:
                shown = (
                    f"sweep {math.degrees(got):.1f}° (asked {math.degrees(asked):g}°)"
                    if jt.value == "revolute"
                    else f"travel {got * 1e3:.1f} mm (asked {asked * 1e3:g} mm)"
                )
                stdout.print(f"note: joint {k + 1}: {shown}, as its limits allow.")
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
        if urdf_path is not None:  # the maker's description of the masses, for --masses
            from dhlog.io.writer import atomic_output
            from dhlog.simulate import masses_urdf

            with atomic_output(urdf_path) as f:
                f.write(masses_urdf(rob).encode())
    except DhlogError as exc:
        _fail(exc)
    stdout.print(
        f"wrote {output} ({session.point_xyz.shape[0]} target samples, "
        f"{session.joint_t_ns.size} joint states, {encoding}) and {truth_path}"
        + (
            f"; {urdf_path} (the nominal robot with its lumped masses, for --masses)"
            if urdf_path
            else ""
        )
    )
    if six_dof:
        stdout.print(
            "note: the target's orientation is in /tracker/point: read it with "
            "orientation = true in the pipeline's [streams.point].",
            markup=False,
        )
    if extra_tools:
        topics = ", ".join(f'"/tracker/point_{k + 2}"' for k in range(len(extra_tools)))
        stdout.print(
            f"note: read the further targets with extra_topics = [{topics}] in the pipeline's "
            "[streams.point].",
            markup=False,
        )


def _pose_file(path: Path, robot: Any, angle_unit: str) -> tuple[tuple[float, ...], ...]:
    """``simulate --poses CSV``: the joint vectors (rad or m) to visit, in the file's order."""
    from dhlog.cell.compensate import read_targets

    _, Q = read_targets(path, robot.n)
    if angle_unit == "deg":
        revolute = np.array([t.value == "revolute" for t in robot.table.joint_types])
        Q = np.where(revolute, np.radians(Q), Q)
    return tuple(tuple(float(v) for v in q) for q in Q)


def _triples(text: str, what: str) -> list[tuple[float, float, float]]:
    """``'x,y,z;x,y,z'`` as number triples (exit 1 naming the option otherwise)."""
    out = []
    for group in (g for g in text.split(";") if g.strip()):
        values = _floats(group, what)
        if len(values) != 3:
            stderr.print(
                f"error: {what} takes x,y,z triples separated by ';', not '{group.strip()}'.",
                markup=False,
            )
            raise typer.Exit(EXIT_USAGE)
        out.append((values[0], values[1], values[2]))
    return out


def _tuples(text: str, what: str, size: int) -> list[tuple[float, ...]]:
    """``'j:v,j:v'`` as tuples of ``size`` numbers, the first a whole joint number (exit 1
    naming the option otherwise)."""
    out = []
    for group in (g.strip() for g in text.split(",") if g.strip()):
        try:
            values = tuple(float(v) for v in group.split(":"))
        except ValueError:
            values = ()
        if len(values) != size or values[0] != int(values[0]):
            form = ":".join(["J", "C"] if size == 2 else ["J", "A", "B"])
            stderr.print(f"error: {what} takes {form} groups separated by ',', not '{group}'.")
            raise typer.Exit(EXIT_USAGE)
        out.append(values)
    return out


def _floats(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        stderr.print(f"error: {what} must be numbers separated by commas, not '{text}'.")
        raise typer.Exit(EXIT_USAGE) from None


PIPELINE_HELP = (
    "A shipped pipeline's name (dhlog pipelines lists them) or a pipeline file (default: "
    "the shipped one whose topics the log holds)."
)


def _pipeline(spec: str) -> Pipeline:
    """A pipeline file, or a shipped pipeline by name (``dhlog pipelines`` lists them)."""
    from dhlog.io.pipeline import pipeline_from

    return pipeline_from(spec)


def _viewer() -> str:
    """How to open a recording from here: ``rerun`` when it is on the PATH, else the viewer
    installed beside this Python (the README's venv flow)."""
    import shutil

    beside = Path(sys.executable).with_name("rerun")
    if shutil.which("rerun") == str(beside) or (shutil.which("rerun") and not beside.exists()):
        return "rerun"
    return str(beside) if beside.exists() else f"{sys.executable} -m rerun"


def _model(spec: str) -> DHModel:
    """A DH model from a DH file or a library robot name."""
    from dhlog.io.dhfile import dh_model_from

    return dh_model_from(spec)


@app.command(cls=_Command, epilog=EXIT_CODES)
def process(
    log: Annotated[
        Path, typer.Argument(metavar="LOG", help="The session log (.mcap, or a bag folder).")
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
) -> None:
    """Identify the DH parameters from a calibration log and write <stem>.dh.json, .dh.csv, .rrd."""
    _quiet_numerics()
    from rich.markup import escape
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from dhlog.fleet.batch import HOLDOUT_SUFFIX, TERMS_SUFFIX, write_results
    from dhlog.identify.run import process_log
    from dhlog.present.console import print_result

    if units not in ("mm", "m"):
        stderr.print(f"error: --units must be mm or m, not '{units}'.")
        raise typer.Exit(EXIT_USAGE)
    if angle_unit not in (None, "rad", "deg"):
        stderr.print(f"error: --angle-unit must be rad or deg, not '{angle_unit}'.")
        raise typer.Exit(EXIT_USAGE)
    if holdout == 1 or not 0 <= holdout <= 1000:
        stderr.print(
            f"error: --holdout must be 0 (none) or a fold count of 2 to 1000, not {holdout}."
        )
        raise typer.Exit(EXIT_USAGE)
    request = _model_request(model, gravity, harmonic_joints)
    if masses is not None:
        if not masses.is_file():
            stderr.print(f"error: --masses {masses}: no such file; give the robot's URDF.")
            raise typer.Exit(EXIT_USAGE)
        request = replace(request, masses=str(masses))
    folder = out if out is not None else log.parent
    stem = log.name.removesuffix(".zstd").removesuffix(".mcap")
    outputs = [folder / f"{stem}.dh.json", folder / f"{stem}.dh.csv"]
    if not no_rrd:
        outputs.append(folder / f"{stem}.rrd")
    if holdout or validate:
        outputs.append(folder / f"{stem}{HOLDOUT_SUFFIX}")
    if request.mode != "geometric" and not analytic_only:
        outputs.append(folder / f"{stem}{TERMS_SUFFIX}")
    inputs = {p.resolve() for p in [log, *(validate or [])]}
    clash = [str(p) for p in outputs if p.resolve() in inputs]
    if clash:
        stderr.print(f"error: {', '.join(clash)} is an input; choose another --out.")
        raise typer.Exit(EXIT_USAGE)
    existing = [str(p) for p in outputs if p.exists()]
    if existing and not force:
        stderr.print(f"error: {', '.join(existing)} exist(s); pass --force to overwrite.")
        raise typer.Exit(EXIT_USAGE)
    _check_writable(folder)
    ref = None if reference_pose is None else np.array(_floats(reference_pose, "--reference-pose"))
    try:
        pipe = _pipeline(pipeline) if pipeline is not None else None
        if ref is not None:
            unit = angle_unit or (pipe.angle_unit if pipe is not None else "rad")
            types = pipe.joint_types if pipe is not None and pipe.joint_types else None
            ref = _angles(ref, unit, types)
        nom = _model(nominal) if nominal is not None else None
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TimeElapsedColumn(),
            console=stderr,
            transient=True,
            disable=not stderr.is_terminal,
        ) as bar:
            task = bar.add_task(f"reading {escape(log.name)}", total=1.0)

            def advance(stage: str, fraction: float) -> None:
                bar.update(task, description=f"{stage} {escape(log.name)}", completed=fraction)

            result = process_log(
                log,
                pipeline=pipe,
                nominal=nom,
                reference_pose=ref,
                analytic_only=analytic_only,
                fit_scales=fit_encoder_scales,
                holdout=holdout,
                validate=list(validate or []),
                model=request,
                progress=advance,
            )
            if refine:
                result.info.append(
                    "--refine is a no-op: the fit of the whole model to every sample is the "
                    "default (--analytic-only gives the per-joint circle fits and line geometry "
                    "alone)."
                )
            advance("writing", 0.0)
            try:
                folder.mkdir(parents=True, exist_ok=True)  # --out is created when missing
                write_results(result, outputs, units, hold_signals=True, with_log=with_log)
            except OSError as exc:
                raise OutputError(folder, exc) from None
    except DhlogError as exc:
        _fail(exc)
    if result.log.pipeline_reason:
        stdout.print(escape(f"{log.name}: {result.log.pipeline_reason}"))
    print_result(stdout, result, units=units)
    stdout.print("wrote " + ", ".join(str(p) for p in outputs))
    if not no_rrd:
        stdout.print(f"open the recording with: {_viewer()} {outputs[2]}")
    if (holdout or validate) and not result.holdout:
        stderr.print(
            "held-out error: not computed (it needs the whole-model fit of a complete result)."
        )
    if not result.complete:
        names = ", ".join(f"joint {j.index} ({j.name})" for j in result.failed)
        stderr.print(f"partial result: {names} not identified; the rest was written.")
        raise typer.Exit(EXIT_PARTIAL)


def _model_request(model: str, gravity: str | None, harmonic_joints: str | None) -> Any:
    """``--model``, ``--gravity`` and ``--harmonic-joints`` as a request (exit 1 naming the
    option when one is wrong)."""
    from dhlog.identify.select import MODELS, ModelRequest

    if model not in MODELS:
        stderr.print(f"error: --model must be one of {', '.join(MODELS)}, not '{model}'.")
        raise typer.Exit(EXIT_USAGE)
    g = None
    if gravity is not None:
        values = _floats(gravity, "--gravity")
        if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
            stderr.print(
                f"error: --gravity takes three numbers x,y,z, not all zero, not '{gravity}'."
            )
            raise typer.Exit(EXIT_USAGE)
        g = (values[0], values[1], values[2])
    joints = None
    if harmonic_joints is not None:
        values = _floats(harmonic_joints, "--harmonic-joints")
        if not values or any(v != int(v) or not 1 <= v <= 64 for v in values):
            stderr.print(
                f"error: --harmonic-joints takes joint numbers (1, 2, …), not '{harmonic_joints}'."
            )
            raise typer.Exit(EXIT_USAGE)
        joints = tuple(sorted({int(v) - 1 for v in values}))
    return ModelRequest(model, g, joints)


def _angles(values: np.ndarray, unit: str, types: Sequence[object] | None) -> np.ndarray:
    """``values`` in radians: revolute entries (all but declared prismatic ones) from degrees
    when ``unit`` is deg."""
    if unit != "deg":
        return values
    prismatic = [str(getattr(t, "value", t)) == "prismatic" for t in (types or [])]
    prismatic += [False] * (values.size - len(prismatic))
    return np.where(prismatic[: values.size], values, np.radians(values))


@app.command(cls=_Command)
def fk(
    dh: Annotated[str, typer.Argument(help="A DH file, a result JSON, or a library robot name.")],
    q: Annotated[
        str,
        typer.Option(
            "--q", help="Joint values, comma-separated (in --angle-unit, m for prismatic)."
        ),
    ],
    units: Annotated[str, typer.Option(help="mm or m for the printed translation.")] = "m",
    angle_unit: Annotated[str, typer.Option(help="rad or deg: the unit of --q.")] = "rad",
) -> None:
    """Pose of the last frame and the spatial manipulator Jacobian at q."""
    from dhlog.model.fk import fk_frames, fk_point, spatial_jacobian

    try:
        model = _model(dh)
    except DhlogError as exc:
        _fail(exc)
    for option, value, allowed in (
        ("units", units, ("mm", "m")),
        ("angle-unit", angle_unit, ("rad", "deg")),
    ):
        if value not in allowed:
            stderr.print(f"error: --{option} must be {' or '.join(allowed)}, not '{value}'.")
            raise typer.Exit(EXIT_USAGE)
    values = np.array(_floats(q, "--q"))
    if values.size == model.table.n:
        values = _angles(values, angle_unit, model.table.joint_types)
    if values.size != model.table.n:
        stderr.print(f"error: --q has {values.size} values but {dh} has {model.table.n} joints.")
        raise typer.Exit(EXIT_USAGE)
    scale = 1e3 if units == "mm" else 1.0
    if model.terms is not None:  # the joints as they stand: deflected by the result's terms
        deflected = model.joint_values(values)
        shown_dq = ", ".join(f"{v:+.3g}" for v in deflected - values)
        stdout.print(f"joint deflection by the nongeometric terms (rad or m): {shown_dq}")
        values = deflected
    T = fk_frames(model.table, values, T_base=model.T_base)[-1]
    J = spatial_jacobian(model.table, values, T_base=model.T_base)
    np.set_printoptions(precision=6, suppress=True, linewidth=120)
    shown = T.copy()
    shown[:3, 3] *= scale
    stdout.print(f"T_base_last (translation in {units}):")
    stdout.print(str(shown))
    tool = fk_point(model.table, values, model.tool_point, T_base=model.T_base) * scale
    stdout.print(f"tool point ({units}): {tool}")
    stdout.print("spatial Jacobian [v; w] (rows vx vy vz wx wy wz, one column per joint):")
    stdout.print(str(J))


@app.command(cls=_Command)
def pipelines() -> None:
    """List the shipped pipelines (--pipeline takes their names, or a pipeline file)."""
    from rich.markup import escape

    from dhlog.io.pipeline import shipped_pipelines

    stdout.print(
        "Shipped pipelines (dhlog process LOG --pipeline NAME; or --pipeline FILE, a pipeline "
        "file of your own):"
    )
    for p in shipped_pipelines():
        stdout.print(
            f"  {escape(p.name)} ({', '.join(p.encodings)}; point topic "
            f"{escape(p.streams['point'].topic)}): {escape(p.description)}"
        )


EXPORT_FORMATS = ("urdf", "ur", "rtb", "dh-csv", "dh-json")


@app.command(cls=_Command)
def export(
    result: Annotated[Path, typer.Argument(help="A result <stem>.dh.json (or a DH JSON file).")],
    output: Annotated[Path, typer.Option("-o", "--output", help="The file to write.")],
    format: Annotated[
        str,
        typer.Option(
            "--format",
            help="urdf; ur (Universal Robots calibration YAML); rtb (a roboticstoolbox "
            "DHRobot in Python); dh-csv or dh-json (standard and modified DH tables).",
        ),
    ] = "urdf",
    limits_from: Annotated[
        str | None,
        typer.Option(help="A library robot (or DH file) whose joint limits the URDF gets."),
    ] = None,
    template: Annotated[
        Path | None,
        typer.Option(
            help="A URDF whose joints (matched by name) get the calibrated origins; its links, "
            "meshes, inertials and limits stay."
        ),
    ] = None,
    zero_offsets: Annotated[
        str,
        typer.Option(
            help="origins (joint zero = encoder zero) or calibration (offsets in each joint's "
            "<calibration rising>; URDF without --template)."
        ),
    ] = "origins",
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Write the identified model in a form a robot stack loads."""
    from rich.markup import escape

    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import atomic_output
    from dhlog.result import export as exports
    from dhlog.result.check import refuse_inputs_as_outputs

    if zero_offsets not in ("origins", "calibration") or (
        zero_offsets == "calibration" and (template is not None or format != "urdf")
    ):
        stderr.print(
            "error: --zero-offsets must be origins or calibration (calibration: a URDF "
            "without --template)."
        )
        raise typer.Exit(EXIT_USAGE)
    if template is not None and format != "urdf":
        stderr.print("error: --template is for --format urdf.")
        raise typer.Exit(EXIT_USAGE)
    if format not in EXPORT_FORMATS:
        stderr.print(
            f"error: --format must be one of {', '.join(EXPORT_FORMATS)}, not '{escape(format)}'."
        )
        raise typer.Exit(EXIT_USAGE)
    _check_folder(output.parent)
    inputs = [(result, "result"), *([(template, "URDF template")] if template else [])]
    if limits_from and Path(limits_from).exists():
        inputs.append((Path(limits_from), "DH file of --limits-from"))
    try:  # exit 2, with or without --force: the input stays as it is
        refuse_inputs_as_outputs(inputs, [output])
    except DhlogError as exc:
        _fail(exc)
    _refuse_existing(output, force)
    extra = ""
    try:
        if format == "urdf" and template is not None:
            text = exports.urdf_from_template(result, template)
        elif format == "urdf":
            limits = robot_or_dh_file(limits_from).limits if limits_from else None
            text = exports.urdf_document(result, limits=limits, zero_offsets=zero_offsets)
        elif format == "ur":
            text, tcp = exports.ur_calibration(result)
            extra = (
                "; set the TCP on the controller to "
                f"({tcp[0] * 1e3:.4f}, {tcp[1] * 1e3:.4f}, {tcp[2] * 1e3:.4f}) mm in tool0"
            )
        elif format == "rtb":
            text = exports.rtb_document(result)
        else:
            text = exports.dh_table_document(result, format)
        with atomic_output(output) as f:
            f.write(text.encode())
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(output.parent, exc))
    stdout.print(f"wrote {escape(str(output))}{extra}")
    _terms_not_exported(result, format)


def _terms_not_exported(result: Path, fmt: str) -> None:
    """Say so when the result carries terms beyond the geometry that ``fmt`` cannot carry."""
    from dhlog.io.dhfile import parse_dh
    from dhlog.result.check import load_result, printable

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


@app.command(cls=_Command, epilog=EXIT_CODES)
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
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Write a calibration certificate: one self-contained HTML page (robot, hashes, noise
    model, held-out error before and after, DH parameters with ±1σ, residuals, warnings)."""
    from rich.markup import escape

    from dhlog.io.writer import atomic_output
    from dhlog.present.certificate import Nominal, certificate_html, load_sources

    if output.resolve() in {result.resolve(), *([log.resolve()] if log else [])}:
        stderr.print(f"error: {escape(str(output))} is an input; name another with -o.")
        raise typer.Exit(EXIT_USAGE)
    _check_folder(output.parent)
    _refuse_existing(output, force)
    try:
        sources = load_sources(result, log=log)
        if output.resolve() in {p.resolve() for p in sources.inputs}:
            stderr.print(f"error: {escape(str(output))} is an input; name another with -o.")
            raise typer.Exit(EXIT_USAGE)
        nom = None if nominal is None else Nominal(nominal, _model(nominal).table)
        page = certificate_html(sources, robot=robot, nominal=nom)
        with atomic_output(output) as f:
            f.write(page.encode())
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(output.parent, exc))
    found = sources.log
    if found.sha256 is None:
        logged = f"log {found.name or '?'} not found: its hash not checked (give it with --log)"
    elif found.sha256 == found.recorded_sha256:
        logged = f"log {found.path} matches the recorded SHA-256"
    else:
        logged = f"log {found.path} DIFFERS from the SHA-256 the result records"
    stdout.print(f"wrote {escape(str(output))} ({escape(logged)})")


@app.command(cls=_Command, epilog=EXIT_CODES)
def compensate(
    result: Annotated[
        Path, typer.Argument(metavar="RESULT", help="A result JSON (<stem>.dh.json).")
    ],
    nominal: Annotated[
        str,
        typer.Option(
            metavar="NAME|FILE",
            help="The model the controller runs: a library robot or a DH file (its limits from "
            "the library, when it is one).",
        ),
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", metavar="CSV", help="The corrected targets.")
    ],
    joints: Annotated[
        Path | None,
        typer.Option(
            metavar="CSV",
            help="Joint targets as the controller would run them: one row per target, one "
            "column per joint (a header row is read and kept).",
        ),
    ] = None,
    poses: Annotated[
        Path | None,
        typer.Option(
            metavar="CSV",
            help="Cartesian targets of the last frame in the nominal's base frame: columns x, y, "
            "z (mm) and qw, qx, qy, qz or rx, ry, rz (degrees, fixed X, Y, Z), optionally the "
            "controller's configuration j1 … jn (--angle-unit). Written: the corrected joint "
            "targets and the pose to command instead.",
        ),
    ] = None,
    angle_unit: Annotated[
        str, typer.Option(metavar="rad|deg", help="The unit of the targets' revolute joints.")
    ] = "rad",
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Correct joint targets for a controller that keeps its nominal model: the calibrated robot
    (its terms beyond the geometry included) then reaches the pose the controller intended."""
    from rich.markup import escape

    from dhlog.cell.compensate import compensate as corrected
    from dhlog.cell.compensate import read_targets, targets_csv
    from dhlog.io.writer import atomic_output
    from dhlog.model.robots import load_robot, robot_names

    if angle_unit not in ("rad", "deg"):
        stderr.print(f"error: --angle-unit must be rad or deg, not '{angle_unit}'.")
        raise typer.Exit(EXIT_USAGE)
    if (joints is None) == (poses is None):
        stderr.print("error: give the targets once: --joints CSV or --poses CSV.")
        raise typer.Exit(EXIT_USAGE)
    targets = joints if joints is not None else poses
    assert targets is not None
    if output.resolve() in {targets.resolve(), result.resolve()}:
        stderr.print(f"error: {escape(str(output))} is an input; name another with -o.")
        raise typer.Exit(EXIT_USAGE)
    _refuse_existing(output, force)
    if poses is not None:
        _compensate_poses(result, nominal, poses, output, angle_unit)
        return
    assert joints is not None
    try:
        model, nom = _result_and_nominal(result, nominal)
        header, Q = read_targets(joints, model.table.n)
        revolute = np.array([t.value == "revolute" for t in model.table.joint_types])
        if angle_unit == "deg":
            Q = np.where(revolute, np.radians(Q), Q)
        limits = load_robot(nominal).limits if nominal in robot_names() else None
        done = corrected(model, nom, Q, limits=limits)
        shown = np.where(revolute, np.degrees(done.targets), done.targets)
        if angle_unit != "deg":
            shown = done.targets
        with atomic_output(output) as f:
            f.write(targets_csv(header, shown, done.problems).encode())
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(output.parent, exc))
    for row, why in sorted(done.problems.items()):
        stdout.print(escape(f"{joints.name} row {row + 1}: not corrected: {why}."))
    good = np.isfinite(done.targets[:, 0])
    largest = float(np.max(np.abs(done.targets[good] - Q[good]))) if np.any(good) else 0.0
    worst = float(np.max(done.error[good], initial=0.0))
    stdout.print(
        f"wrote {escape(str(output))}: {int(good.sum())} of {len(Q)} targets corrected (largest "
        f"change {largest:.6g} rad or m; each within {worst:.1e} m and rad of the pose the "
        "nominal gives the original)"
    )


def _result_and_nominal(result: Path, nominal: str) -> tuple[Any, Any]:
    """The calibrated model of ``result`` and the controller's nominal, of the same robot."""
    from dhlog.errors import InputError
    from dhlog.io.dhfile import load_dh

    model = load_dh(result)
    nom = _model(nominal)
    if nom.table.n != model.table.n:
        raise InputError(
            f"{nominal}: has {nom.table.n} joints but {result} has {model.table.n}; give the "
            "nominal of this robot."
        )
    return model, nom


def _compensate_poses(
    result: Path, nominal: str, poses: Path, output: Path, angle_unit: str
) -> None:
    """``dhlog compensate --poses CSV``: Cartesian targets to corrected joint targets."""
    from rich.markup import escape

    from dhlog.cell.compensate import compensate_poses, poses_csv, read_poses
    from dhlog.io.writer import atomic_output
    from dhlog.model.robots import load_robot, robot_names

    try:
        model, nom = _result_and_nominal(result, nominal)
        T, config = read_poses(poses, model.table.n)
        revolute = np.array([t.value == "revolute" for t in model.table.joint_types])
        scale = np.where(revolute & (angle_unit == "deg"), 180 / math.pi, 1.0)
        if config is not None:
            config = config / scale
        limits = load_robot(nominal).limits if nominal in robot_names() else None
        done, _ = compensate_poses(model, nom, T, configuration=config, limits=limits)
        with atomic_output(output) as f:
            f.write(poses_csv(nom, done, scale).encode())
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(output.parent, exc))
    for row, why in sorted(done.problems.items()):
        stdout.print(escape(f"{poses.name} row {row + 1}: not corrected: {why}."))
    good = np.isfinite(done.targets[:, 0])
    worst = float(np.max(done.error[good], initial=0.0))
    stdout.print(
        escape(
            f"wrote {output}: {int(good.sum())} of {len(T)} Cartesian targets reached by the "
            f"calibrated robot (each within {worst:.1e} m and rad), with the joint targets to "
            "run and the pose to command instead."
        )
    )


@app.command(cls=_Command, epilog=EXIT_CODES)
def plan(
    robot: Annotated[str, typer.Argument(metavar="ROBOT", help="A library robot or a DH file.")],
    protocol: Annotated[
        str, typer.Option(metavar="sweeps|random-poses|coupled", help="What the robot does.")
    ] = "random-poses",
    poses: Annotated[int, typer.Option(help="Still poses of --protocol random-poses.")] = 40,
    steps: Annotated[int, typer.Option(help="Stops per sweep (sweeps, coupled).")] = 12,
    sweep_deg: Annotated[float, typer.Option(help="Sweep of each revolute joint, degrees.")] = 90.0,
    noise_mm: Annotated[
        float, typer.Option(help="The tracker's σ per coordinate, mm (isotropic).")
    ] = 0.01,
    tracker_rate: Annotated[float, typer.Option(help="Tracker samples per second.")] = 100.0,
    six_dof: Annotated[
        bool, typer.Option("--six-dof", help="A 6-DoF probe: its orientation measured too.")
    ] = False,
    seed: Annotated[int, typer.Option(help="Seed of the poses drawn.")] = 0,
    station: Annotated[
        str | None,
        typer.Option(
            metavar="X,Y,Z",
            help="Where the tracker stands, mm in the robot's base frame: poses whose target "
            "is beyond --range-m are left out and counted, and --tracker-um's noise is along "
            "the line of sight from here.",
        ),
    ] = None,
    range_m: Annotated[
        str,
        typer.Option(metavar="MIN,MAX", help="The distances the tracker measures, m."),
    ] = "0.8,30",
    tracker_um: Annotated[
        str | None,
        typer.Option(
            metavar="RADIAL,TRANSVERSE,PER_M",
            help="With --station: the tracker's noise model in place of --noise-mm — radial "
            "and transverse σ (µm) and the transverse σ's growth (µm per m of distance), as "
            'in a pipeline\'s [noise] model = "tracker".',
        ),
    ] = None,
    candidates: Annotated[
        Path | None,
        typer.Option(
            metavar="CSV",
            help="Candidate joint vectors (one per row, a header row kept) to --select from.",
        ),
    ] = None,
    select: Annotated[
        int, typer.Option(metavar="N", help="With --candidates: the N most informative poses.")
    ] = 0,
    output: Annotated[
        Path | None,
        typer.Option(
            "-o",
            "--output",
            metavar="FILE",
            help="With --select: the chosen poses (CSV); else the prediction as JSON.",
        ),
    ] = None,
    angle_unit: Annotated[
        str, typer.Option(metavar="rad|deg", help="The unit of the candidates' revolute joints.")
    ] = "rad",
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Before the session: the σ of every DH parameter and the FK σ over the workspace that a
    protocol will give, and what it cannot determine; or, with --candidates and --select, the
    most informative poses (D-optimal)."""
    import json

    from rich import box
    from rich.markup import escape
    from rich.table import Table

    from dhlog.cell.plan import plan_session
    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import atomic_output
    from dhlog.simulate import SIX_DOF_TOOL_ROTATION, SimulationConfig, config_problems

    tracker = _tracker(station, range_m, tracker_um)
    if candidates is not None or select:
        _select_poses(robot, candidates, select, output, noise_mm, angle_unit, force, tracker)
        return
    if output is not None:
        _refuse_existing(output, force)
    try:
        rob = robot_or_dh_file(robot)
        cfg = SimulationConfig(
            noise=noise_mm * 1e-3,
            tracker_rate=tracker_rate,
            motion="step",
            sweep=math.radians(sweep_deg),
            steps=steps,
            protocol=protocol,  # type: ignore[arg-type]
            poses=poses,
            tool_rotation=SIX_DOF_TOOL_ROTATION if six_dof else None,
            base_points=12,
            seed=seed,
        )
        problems = config_problems(rob, cfg)
        if problems:
            stderr.print(f"error: {escape(problems[0])}.")
            raise typer.Exit(EXIT_USAGE)
        found = plan_session(rob, cfg, tracker)
        if output is not None:
            with atomic_output(output) as f:
                f.write(json.dumps(found.document(rob.name), indent=2).encode())
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        assert output is not None
        _fail(OutputError(output.parent, exc))
    t = Table(
        title=f"Predicted σ of {escape(rob.name)}'s parameters ({protocol}: {found.samples} "
        f"samples at {found.poses} poses, {found.noise_model})",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for head in ("#", "σ θ [°]", "σ d / β [mm or °]", "σ a [mm]", "σ α [°]"):
        t.add_column(escape(head), justify="right")
    for i, (row, form) in enumerate(zip(found.rows_std, found.forms, strict=True)):
        cells = []
        for k, v in enumerate(row):
            angular = k in (0, 3) or (k == 1 and form == "hayati")
            cells.append(
                "fixed" if not np.isfinite(v) else f"{v * (180 / math.pi if angular else 1e3):.5f}"
            )
        t.add_row(str(i + 1), *cells)
    stdout.print(t)
    sd = found.fk_sd * 1e3
    stdout.print(
        f"Predicted FK σ at {sd.size} random joint vectors within the limits: RMS "
        f"{math.sqrt(float(np.mean(sd**2))):.4f} mm, 95 % {float(np.percentile(sd, 95)):.4f} mm, "
        f"max {float(sd.max()):.4f} mm (3-D)."
    )
    for line in found.fixed:
        stdout.print(escape(f"Fixed: {line}"))
    if found.out_of_range:
        stdout.print(
            f"Left out: {found.out_of_range} of the drawn poses put the target beyond the "
            "tracker's range."
        )
    if output is not None:
        stdout.print(escape(f"wrote {output}"))


def _tracker(station: str | None, range_m: str, tracker_um: str | None) -> Any:
    """``plan``'s tracker options as a :class:`dhlog.cell.plan.Tracker` (None without a station)."""
    from dhlog.cell.plan import Tracker

    if station is None:
        if tracker_um is not None:
            stderr.print("error: --tracker-um needs --station (where the line of sight starts).")
            raise typer.Exit(EXIT_USAGE)
        return None
    xyz = _floats(station, "--station")
    reach = _floats(range_m, "--range-m")
    model = _floats(tracker_um, "--tracker-um") if tracker_um is not None else None
    if not all(math.isfinite(v) for v in [*xyz, *reach, *(model or [])]):
        stderr.print("error: --station, --range-m and --tracker-um take finite numbers.")
        raise typer.Exit(EXIT_USAGE)
    if len(xyz) != 3 or max(abs(v) for v in xyz) > 1e6:
        stderr.print("error: --station needs X,Y,Z in mm (within a km).")
        raise typer.Exit(EXIT_USAGE)
    if len(reach) != 2 or not 0 <= reach[0] < reach[1]:
        stderr.print("error: --range-m needs MIN,MAX in m with 0 ≤ MIN < MAX.")
        raise typer.Exit(EXIT_USAGE)
    if model is not None and (len(model) != 3 or min(model[:2]) <= 0 or model[2] < 0):
        stderr.print(
            "error: --tracker-um needs RADIAL,TRANSVERSE,PER_M: σ > 0 µm, growth ≥ 0 µm/m."
        )
        raise typer.Exit(EXIT_USAGE)
    return Tracker(
        (xyz[0] * 1e-3, xyz[1] * 1e-3, xyz[2] * 1e-3),
        (reach[0], reach[1]),
        None if model is None else (model[0] * 1e-6, model[1] * 1e-6, model[2] * 1e-6),
    )


def _select_poses(
    robot: str,
    candidates: Path | None,
    count: int,
    output: Path | None,
    noise_mm: float,
    angle_unit: str,
    force: bool,
    tracker: Any,
) -> None:
    """``dhlog plan --candidates CSV --select N -o CSV``."""
    from rich.markup import escape

    from dhlog.cell.compensate import read_targets, targets_csv
    from dhlog.cell.plan import select_poses
    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import atomic_output

    if candidates is None or count < 1 or output is None:
        stderr.print("error: --select N (N ≥ 1) needs --candidates CSV and -o CSV.")
        raise typer.Exit(EXIT_USAGE)
    if angle_unit not in ("rad", "deg"):
        stderr.print(f"error: --angle-unit must be rad or deg, not '{angle_unit}'.")
        raise typer.Exit(EXIT_USAGE)
    if noise_mm <= 0:
        stderr.print(f"error: --noise-mm must be > 0, not {noise_mm:g}.")
        raise typer.Exit(EXIT_USAGE)
    if output.resolve() == candidates.resolve():
        stderr.print(f"error: {output} is the input; name another with -o.")
        raise typer.Exit(EXIT_USAGE)
    _refuse_existing(output, force)
    try:
        rob = robot_or_dh_file(robot)
        header, Q = read_targets(candidates, rob.n)
        revolute = np.array([t.value == "revolute" for t in rob.table.joint_types])
        if angle_unit == "deg":
            Q = np.where(revolute, np.radians(Q), Q)
        found = select_poses(rob, Q, count, noise_mm * 1e-3, tracker)
        shown = np.where(revolute, np.degrees(Q), Q) if angle_unit == "deg" else Q
        left = {k: "not chosen" for k in range(len(Q)) if k not in set(found.chosen)}
        with atomic_output(output) as f:  # the chosen rows, numbered as in the candidates
            f.write(targets_csv(header, shown, left).encode())
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(output.parent, exc))
    stdout.print(
        escape(
            f"wrote {output}: {count} of {len(Q)} candidate poses, the most informative "
            f"(D-optimal: each adds the most to log det of the Fisher information); "
            f"{found.singular} near a singularity and {found.out_of_range} beyond the "
            f"tracker's range left out. Predicted FK σ over the workspace (RMS, 3-D, "
            f"σ {noise_mm:g} mm, one sample a pose): {found.fk_sd_chosen * 1e3:.4f} mm, against "
            f"{found.fk_sd_random * 1e3:.4f} mm for {count} drawn at random."
        )
    )


@app.command(cls=_Command, epilog=EXIT_CODES)
def batch(
    logs: Annotated[
        list[Path], typer.Argument(metavar="LOG", help="Session logs (.mcap, bag folders).")
    ],
    out: Annotated[
        Path,
        typer.Option(metavar="DIR", help="Folder for every log's results and the summary."),
    ],
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs", "-j", metavar="N", help="Logs processed at once (worker processes)."
        ),
    ] = 1,
    pipeline: Annotated[
        str | None,
        typer.Option(
            metavar="NAME|FILE",
            help="A shipped pipeline's name (dhlog pipelines lists them) or a pipeline file, for "
            "every log (default: chosen per log from its topics).",
        ),
    ] = None,
    nominal: Annotated[
        str | None,
        typer.Option(
            metavar="ROBOT|FILE", help="A nominal DH file (or library robot), for every log."
        ),
    ] = None,
    no_rrd: Annotated[
        bool, typer.Option("--no-rrd", help="Do not write the Rerun recordings.")
    ] = False,
    analytic_only: Annotated[
        bool,
        typer.Option(
            "--analytic-only",
            help="Only the per-joint circle fits and line geometry, for every log.",
        ),
    ] = False,
    units: Annotated[
        str, typer.Option(metavar="mm|m", help="Units of each log's CSV: mm or m.")
    ] = "mm",
    holdout: Annotated[
        int,
        typer.Option(
            metavar="K",
            help="K-fold cross-validation of every log (K ≥ 2; 0: none): held-out errors "
            "before and after in each result and in the summary.",
        ),
    ] = 0,
    model: Annotated[
        str,
        typer.Option(
            metavar="auto|geometric|compliance|harmonic|full",
            help="Terms beyond the geometry, as dhlog process --model.",
        ),
    ] = "auto",
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing results.")] = False,
) -> None:
    """Process many logs in --jobs workers into one summary table (a failing log is a row)."""
    import time

    from rich.markup import escape
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from dhlog.fleet.batch import (
        HOLDOUT_SUFFIX,
        TERMS_SUFFIX,
        BatchJob,
        check_paths,
        output_stamps,
        run_batch,
        stem_of,
        summary_frame,
        summary_paths,
        write_summary,
        written_logs,
    )
    from dhlog.identify.select import MODELS

    if jobs < 1 or jobs > 256:
        stderr.print(f"error: --jobs must be between 1 and 256, not {jobs}.")
        raise typer.Exit(EXIT_USAGE)
    if units not in ("mm", "m"):
        stderr.print(f"error: --units must be mm or m, not '{escape(units)}'.")
        raise typer.Exit(EXIT_USAGE)
    if model not in MODELS:  # said here: the value is the user's text, never markup
        stderr.print(f"error: --model must be one of {', '.join(MODELS)}, not '{escape(model)}'.")
        raise typer.Exit(EXIT_USAGE)
    if holdout == 1 or not 0 <= holdout <= 1000:
        stderr.print(f"error: --holdout must be 0 (none) or a fold count of 2-1000, not {holdout}.")
        raise typer.Exit(EXIT_USAGE)
    stems: dict[str, Path] = {}
    for log in logs:
        other = stems.setdefault(stem_of(log), log)
        if other != log:
            stderr.print(
                f"error: {escape(str(other))} and {escape(str(log))} would write the same "
                "results; rename one, or process them into different folders."
            )
            raise typer.Exit(EXIT_USAGE)
    work = [
        BatchJob(
            str(log), str(out), pipeline, nominal, no_rrd, analytic_only, units, holdout, model
        )
        for log in logs
    ]
    try:  # exit 2, with or without --force: no input is overwritten, no output is a folder
        check_paths(work, out)
    except DhlogError as exc:
        _fail(exc)
    suffixes = [".dh.json", ".dh.csv", *([] if no_rrd else [".rrd"])]
    suffixes += [HOLDOUT_SUFFIX] if holdout else []
    request = _model_request(model, None, None)
    suffixes += [TERMS_SUFFIX] if request.mode != "geometric" and not analytic_only else []
    wanted = [out / f"{s}{x}" for s in stems for x in suffixes] + summary_paths(out)
    clash = [str(p) for p in wanted if p.exists()]
    if clash and not force:
        stderr.print(f"error: {escape(clash[0])} (and {len(clash) - 1} more) exist; pass --force.")
        raise typer.Exit(EXIT_USAGE)
    _check_writable(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _fail(OutputError(out, exc))
    if pipeline is not None:  # a misspelt name fails here, not once per log
        try:
            _pipeline(pipeline)
        except DhlogError as exc:
            _fail(exc)
    before = output_stamps(work)
    try:
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=stderr,
            disable=not stderr.is_terminal,
        ) as bar:
            task = bar.add_task("logs", total=len(work))

            def done(row: dict[str, object]) -> None:
                bar.advance(task)
                if row["status"] != "ok":
                    bar.console.print(
                        f"{escape(str(row['log']))}: {row['status']}: {escape(str(row['reason']))}"
                    )

            start = time.perf_counter()
            try:
                rows = run_batch(work, jobs, done)
            except DhlogError as exc:
                _fail(exc)
            seconds = time.perf_counter() - start
        frame = summary_frame(rows)
        try:
            paths = write_summary(frame, out, hold_signals=True)
        except OSError as exc:
            _fail(OutputError(out, exc))
    except (KeyboardInterrupt, _Terminated) as exc:  # the workers are stopped already
        _batch_stopped(exc, written_logs(work, before), len(work))
    counts = {s: sum(1 for r in rows if r["status"] == s) for s in ("ok", "partial", "failed")}
    stdout.print(
        f"{len(rows)} log(s) in {seconds:.1f} s with {jobs} worker(s): {counts['ok']} ok, "
        f"{counts['partial']} partial, {counts['failed']} failed; wrote "
        + ", ".join(escape(str(p)) for p in paths)
    )
    if counts["partial"] or counts["failed"]:
        raise typer.Exit(EXIT_PARTIAL)


def _batch_stopped(cause: BaseException, written: list[str], total: int) -> NoReturn:
    """One line saying which logs' results an interrupted batch wrote (they are complete: each
    log's results are moved into place together), then exit 130 / 143."""
    from rich.markup import escape

    code, what = (
        (EXIT_INTERRUPTED, "interrupted")
        if isinstance(cause, KeyboardInterrupt)
        else (EXIT_TERMINATED, "terminated")
    )
    if not written:
        stderr.print(
            f"{what}: no log had finished: nothing was written (no results, no summary; files "
            "of earlier runs stay as they were)."
        )
    else:
        names = [Path(log).name for log in written]
        shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6 else "")
        rest = "the summary was not" if len(written) == total else "the others' and the summary not"
        stderr.print(
            f"{what}: the results of {len(written)} of {total} log(s) were written "
            f"({escape(shown)}); {rest}."
        )
    raise _Ended(code)


def _listed(text: str | None) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()] if text else []


@app.command(name="import", cls=_Command)
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
            "no unit (default mm; a header that states another is an error)."
        ),
    ] = None,
    angle_unit: Annotated[
        str | None,
        typer.Option(
            help="rad, deg or gon: revolute joints and rotation angles, where the header "
            "states no unit (default deg)."
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
        typer.Option("--no-u95", help="Leave the U95 columns out (the noise model applies)."),
    ] = False,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Convert a tracker export (CSV, SpatialAnalyzer, Leica) into a log dhlog process reads."""
    from rich.markup import escape

    from dhlog.io.importer import ImportOptions, import_source, same_file, write_imported

    out = output if output is not None else source.with_suffix(".mcap")
    for given, what in ((source, "the source"), (joints_file, "the --joints-file")):
        if given is not None and same_file(out, given):
            stderr.print(
                f"error: the output {escape(str(out))} would replace {what}; an output is never "
                "one of the inputs: name another with -o."
            )
            raise typer.Exit(EXIT_USAGE)
    _check_folder(out.parent)
    _refuse_existing(out, force)
    opts = ImportOptions(
        format=format,
        joints_file=joints_file,
        x=x,
        y=y,
        z=z,
        joint_columns=_listed(joint_columns),
        joint_names=_listed(joint_names),
        joint_types=_listed(joint_types),
        time=time,
        time_unit=time_unit,
        name_column=name_column,
        length_unit=length_unit,
        angle_unit=angle_unit,
        orientation_columns=_listed(orientation_columns),
        euler=euler,
        no_u95=no_u95,
    )
    try:
        imported = import_source(source, opts)
        write_imported(imported, out)
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(out.parent, exc))
    for w in imported.warnings:
        stderr.print(f"warning: {escape(w)}")
    for note in imported.notes:
        stdout.print(f"note: {escape(note)}", soft_wrap=True)
    kind = "stops (step and measure)" if imported.stepped else "timed samples"
    u95 = ", with per-point U95 as covariance" if imported.covariance is not None else ""
    rot = (
        f", with the target's orientation from {imported.provenance['orientation_columns']}"
        if imported.orientation is not None
        else ""
    )
    stdout.print(
        f"wrote {escape(str(out))}: {len(imported.xyz)} {kind}{u95}{rot}, joints "
        f"{', '.join(imported.joint_names)}; next: dhlog process {escape(str(out))}"
    )


@app.command(name="compare", cls=_Command)
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
) -> None:
    """Has the robot changed? Two results, or every parameter's trend over a batch summary."""
    from dhlog.fleet.compare import compare
    from dhlog.io.dhfile import robot_or_dh_file

    if second is None:
        if first.suffix not in (".csv", ".parquet"):
            stderr.print("error: give two results, or one batch summary (.csv or .parquet).")
            raise typer.Exit(EXIT_USAGE)
        _compare_trends(first, threshold, rrd)
        return
    try:
        limits = robot_or_dh_file(limits_from).limits if limits_from else None
        result = compare(first, second, limits=limits)
    except DhlogError as exc:
        _fail(exc)
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
    _print_values(
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
        stdout.print(f"changed beyond {threshold:g}σ: {', '.join(significant)} (marked *).")
    else:
        stdout.print(f"no parameter changed beyond {threshold:g}σ.")


#: The narrowest the parameter column of a value table may fold to (below it, a list).
NAME_FOLD = 8


def _print_values(
    console: Console, title: str, heads: Sequence[str], rows: Sequence[Sequence[str]]
) -> None:
    """Parameters (each row's first cell) and their values, never cut on a narrow terminal:
    a table when the values fit whole beside the parameter names (which fold, down to
    ``NAME_FOLD`` characters, when the names do not fit on one line); otherwise one line per
    parameter, ``name: head value, …``, wrapped between the values."""
    from rich import box
    from rich.cells import cell_len
    from rich.markup import escape
    from rich.table import Table

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
            table.add_row(escape(row[0]), *row[1:])
        console.print(table)
        return
    console.print(title, markup=False)
    for row in rows:
        cells = ", ".join(
            f"{' '.join(head.split())} {value}"
            for head, value in zip(heads, row[1:], strict=True)
            if value
        )
        console.print(f"  {row[0]}: {cells}", markup=False)


def _compare_trends(summary: Path, threshold: float, rrd: Path | None) -> None:
    """The console table (and optionally the recording) of a batch summary's trends."""
    from rich.markup import escape

    from dhlog.fleet.compare import read_summary, trends, write_trend_recording
    from dhlog.result.check import printable, refuse_inputs_as_outputs

    try:
        if rrd is not None:  # the summary stays as it is
            refuse_inputs_as_outputs([(summary, "batch summary")], [rrd])
        logs, times, found = trends(read_summary(summary), printable(str(summary)))
        if rrd is not None:
            _check_folder(rrd.parent)
            write_trend_recording(logs, times, found, rrd)
    except DhlogError as exc:
        _fail(exc)
    except OSError as exc:
        _fail(OutputError(rrd.parent if rrd else summary.parent, exc))
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
    _print_values(
        stdout,
        f"Trends over {len(logs)} sessions (first → last; σ combined)",
        ("first", "last", "change", "|change|\n/ σ", "largest\nstep / σ"),
        rows,
    )
    if moved:  # the names are the summary's columns: text, never markup
        stdout.print(f"moved beyond {threshold:g}σ: {escape(', '.join(moved))} (marked *).")
    else:
        stdout.print(f"no parameter moved beyond {threshold:g}σ over the sessions.")
    if rrd is not None:
        stdout.print(f"wrote {escape(str(rrd))}; open it with: {_viewer()} {escape(str(rrd))}")


@app.command(cls=_Command)
def show(
    dh: Annotated[
        str,
        typer.Argument(
            help="A DH file, a result JSON, or a library robot "
            "(elbow, scara, stanford, kr5, puma560, ur5)."
        ),
    ],
    output: Annotated[
        Path | None,
        typer.Option("-o", "--output", help="The .rrd to write (default: <name>.rrd)."),
    ] = None,
    steps: Annotated[int, typer.Option(help="Steps per joint sweep.")] = 60,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite an existing recording.")
    ] = False,
) -> None:
    """A Rerun recording of a robot from its DH table, each joint swept in turn."""
    from dhlog.model.robots import load_robot
    from dhlog.present.recording import write_robot_recording

    try:
        model = _model(dh)
        limits = None
        if not (Path(dh).suffix in (".json", ".toml") or Path(dh).exists()):
            limits = load_robot(dh).limits
        path = output if output is not None else Path(f"{Path(dh).stem}.rrd")
        _refuse_existing(path, force)
        write_robot_recording(
            model.table, path, T_base=model.T_base, limits=limits, title=Path(dh).stem, steps=steps
        )
    except DhlogError as exc:
        _fail(exc)
    stdout.print(f"wrote {path}; open it with: rerun {path}")


def _stdout_replaced() -> bool:
    """Whether the standard output was found closed and replaced (by /dev/null, or typer's
    wrapper that swallows its errors), as rich and typer do on a broken pipe."""
    if type(sys.stdout).__name__ == "PacifyFlushWrapper":
        return True
    try:
        out, null = os.fstat(1), os.stat(os.devnull)
    except OSError:
        return False
    return (out.st_dev, out.st_ino) == (null.st_dev, null.st_ino)


class _Terminated(BaseException):
    """SIGTERM, raised where the program is (temporary files are removed on the way out)."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise _Terminated()


def run() -> None:
    """Entry point: exit codes as ``EXIT_CODES`` lists them (0 success, 1 usage error,
    2 unusable input or output, 3 partial result, 130 interrupted (SIGINT), 141 the standard
    output closed, 143 terminated (SIGTERM))."""
    import signal

    _quiet_numerics()
    signal.signal(signal.SIGTERM, _on_sigterm)
    if len(sys.argv) <= 1:  # no arguments: the help, and success
        sys.argv.append("--help")
    try:
        code = app(standalone_mode=False)
    except _Ended as end:  # its message is printed
        sys.exit(end.code)
    except SystemExit as exc:  # rich and typer end a closed output (their help) with exit 1
        if exc.code == 1 and _stdout_replaced():
            sys.exit(EXIT_OUTPUT_CLOSED)
        raise
    except typer.Abort as exc:
        if isinstance(exc.__cause__ or exc.__context__, KeyboardInterrupt):
            stderr.print("interrupted: no output was written (finished files stay as they were).")
            sys.exit(EXIT_INTERRUPTED)
        sys.exit(EXIT_USAGE)
    except KeyboardInterrupt:
        stderr.print("interrupted: no output was written (finished files stay as they were).")
        sys.exit(EXIT_INTERRUPTED)
    except _Terminated:
        stderr.print("terminated: no output was written (finished files stay as they were).")
        sys.exit(EXIT_TERMINATED)
    except DhlogError as exc:  # pragma: no cover - commands catch their own
        stderr.print(f"error: {exc}")
        sys.exit(EXIT_INPUT)
    except Exception as exc:
        # usage errors of the command-line parser carry their own message and exit code
        if hasattr(exc, "format_message") and hasattr(exc, "exit_code"):
            stderr.print(f"error: {exc.format_message()} (see dhlog --help)")
            sys.exit(EXIT_USAGE)
        raise
    if code == EXIT_INTERRUPTED:  # typer's own ending of a KeyboardInterrupt
        stderr.print("interrupted: no output was written (finished files stay as they were).")
    # the work is done: a signal now (while the recording library shuts down) changes nothing
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sys.exit(code if isinstance(code, int) else 0)
