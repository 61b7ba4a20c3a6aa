"""The robot's cell before a session: ``dhlog plan`` (the σ a protocol will give, the most
informative poses, the ISO 9283 test program); ``dhlog compensate`` is
:mod:`dhlog.cli.compensate`."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from dhlog.cli.common import EXIT_USAGE, fail, plain, refuse_existing, stderr, stdout
from dhlog.cli.options import floats
from dhlog.errors import DhlogError, OutputError


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
            help="With --select: the chosen poses (CSV); with --iso9283: the test's cycle "
            "program (CSV); else the prediction as JSON.",
        ),
    ] = None,
    angle_unit: Annotated[
        str, typer.Option(metavar="rad|deg", help="The unit of the candidates' revolute joints.")
    ] = "rad",
    iso9283: Annotated[
        bool,
        typer.Option(
            "--iso9283",
            help="The ISO 9283 test program instead: the largest test cube the workspace "
            "allows, the poses P1–P5 and the test paths with their joint targets; -o writes "
            "the cycle program (CSV, docs/iso9283.md).",
        ),
    ] = False,
    cube_size: Annotated[
        float | None,
        typer.Option(metavar="MM", help="With --iso9283: the test cube's edge, mm."),
    ] = None,
    cube_centre: Annotated[
        str | None,
        typer.Option(
            metavar="X,Y,Z",
            help="With --iso9283: the test cube's centre, mm in the robot's base frame.",
        ),
    ] = None,
    plane: Annotated[
        str,
        typer.Option(
            metavar="PLANE",
            help="With --iso9283: the cube's diagonal plane the poses and paths lie in: "
            "C1-C2-C7-C8, C2-C3-C8-C5, C3-C4-C5-C6 or C4-C1-C6-C7 (docs/iso9283.md).",
        ),
    ] = "C1-C2-C7-C8",
    cycles: Annotated[
        int, typer.Option(help="With --iso9283: cycles of the pose test (P1 → … → P5).")
    ] = 30,
    path_cycles: Annotated[
        int, typer.Option(help="With --iso9283: cycles of the path test (line, circles).")
    ] = 10,
    dwell: Annotated[
        float, typer.Option(metavar="S", help="With --iso9283: the dwell at each pose, s.")
    ] = 2.0,
    path_speed: Annotated[
        float, typer.Option(metavar="MM/S", help="With --iso9283: the commanded path speed, mm/s.")
    ] = 250.0,
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Before the session: the σ of every DH parameter and the FK σ over the workspace that a
    protocol will give, and what it cannot determine; or, with --candidates and --select, the
    most informative poses (D-optimal); or, with --iso9283, the ISO 9283 test program."""
    import json

    from rich import box
    from rich.table import Table

    from dhlog.api import plan as plan_protocol
    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import atomic_output

    if iso9283:
        _iso9283_program(
            robot,
            output,
            force,
            cube_size,
            cube_centre,
            plane,
            cycles,
            path_cycles,
            dwell,
            path_speed,
        )
        return
    tracker = _tracker(station, range_m, tracker_um)
    if candidates is not None or select:
        _select_poses(robot, candidates, select, output, noise_mm, angle_unit, force, tracker)
        return
    if output is not None:
        refuse_existing(output, force)
    try:
        rob = robot_or_dh_file(robot)
        found = plan_protocol(
            rob,
            protocol=protocol,  # type: ignore[arg-type]
            poses=poses,
            steps=steps,
            sweep=math.radians(sweep_deg),
            noise=noise_mm * 1e-3,
            tracker_rate=tracker_rate,
            six_dof=six_dof,
            seed=seed,
            tracker=tracker,
        )
        if output is not None:
            with atomic_output(output) as f:
                f.write(json.dumps(found.document(rob.name), indent=2).encode())
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        assert output is not None
        fail(OutputError(output.parent, exc))
    t = Table(
        title=f"Predicted σ of {plain(rob.name)}'s parameters ({plain(protocol)}: {found.samples} "
        f"samples at {found.poses} poses, {found.noise_model})",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    for head in ("#", "σ θ [°]", "σ d / β [mm or °]", "σ a [mm]", "σ α [°]"):
        t.add_column(plain(head), justify="right")
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
        stdout.print(plain(f"Fixed: {line}"))
    if found.out_of_range:
        stdout.print(
            f"Left out: {found.out_of_range} of the drawn poses put the target beyond the "
            "tracker's range."
        )
    if output is not None:
        stdout.print(plain(f"wrote {output}"))


def _iso9283_program(
    robot: str,
    output: Path | None,
    force: bool,
    cube_size: float | None,
    cube_centre: str | None,
    plane: str,
    cycles: int,
    path_cycles: int,
    dwell: float,
    path_speed: float,
) -> None:
    """``dhlog plan ROBOT --iso9283``: the test program's tables, and its CSV with -o."""
    from rich import box
    from rich.table import Table

    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import atomic_output
    from dhlog.iso9283.program import program_csv
    from dhlog.iso9283.program import test_program as iso9283_program

    centre = None
    if cube_centre is not None:
        centre = floats(cube_centre, "--cube-centre")
        if len(centre) != 3 or max(abs(v) for v in centre) > 1e5:
            stderr.print("error: --cube-centre needs X,Y,Z in mm (within 100 m).")
            raise typer.Exit(EXIT_USAGE)
    for what, value, unit in (
        ("--cube-size", cube_size, "mm"),
        ("--path-speed", path_speed, "mm/s"),
    ):
        if value is not None and not (math.isfinite(value) and 0 < value <= 1e5):
            stderr.print(f"error: {what} must be a positive number of {unit}, not {value:g}.")
            raise typer.Exit(EXIT_USAGE)
    if output is not None:
        refuse_existing(output, force)
    try:
        rob = robot_or_dh_file(robot)
        program = iso9283_program(
            rob,
            cube_size=None if cube_size is None else cube_size * 1e-3,
            cube_centre=None if centre is None else np.array(centre) * 1e-3,
            plane=plane,
            cycles=cycles,
            path_cycles=path_cycles,
            dwell=dwell,
            speed=path_speed * 1e-3,
        )
        if output is not None:
            with atomic_output(output) as f:
                f.write(program_csv(program).encode())
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        assert output is not None
        fail(OutputError(output.parent, exc))
    cube = program.cube
    xyz = ", ".join(f"{v * 1e3:.1f}" for v in cube.centre)
    stdout.print(
        plain(
            f"ISO 9283 test cube of {rob.name}: centre ({xyz}) mm in the base frame, edge "
            f"{cube.size * 1e3:.0f} mm, poses and paths in the plane {cube.plane}."
        )
    )
    revolute = np.array([t.value == "revolute" for t in rob.table.joint_types])
    t = Table(
        title="Test poses: the tool point in the base frame (mm), the joint targets (° or mm)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        padding=(0, 1),
        collapse_padding=True,
    )
    for head in ("pose", "x", "y", "z", *(f"j{j + 1}" for j in range(rob.n))):
        t.add_column(head, justify="right", no_wrap=True)
    for pose in program.poses:
        joints = np.where(revolute, np.degrees(pose.q), pose.q * 1e3)
        t.add_row(
            pose.name,
            *(f"{v * 1e3:.1f}" for v in pose.T[:3, 3]),
            *(f"{v:.2f}" for v in joints),
        )
    stdout.print(t)
    t = Table(title="Test paths", title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    for head in ("path", "length [mm]", "points", "speed [mm/s]"):
        t.add_column(plain(head), justify="right")
    for path in program.paths:
        length = float(np.sum(np.linalg.norm(np.diff(path.points, axis=0), axis=1)))
        t.add_row(
            path.name, f"{length * 1e3:.1f}", str(len(path.points)), f"{path.speed * 1e3:.0f}"
        )
    stdout.print(t)
    for note in program.notes:
        stdout.print(plain(f"Note: {note}."))
    rows = program.cycles * len(program.poses) + program.path_cycles * sum(
        len(p.points) for p in program.paths
    )
    if output is not None:
        stdout.print(
            plain(
                f"wrote {output}: {rows} commanded targets ({program.cycles} pose cycles, "
                f"{program.path_cycles} path cycles, dwell {program.dwell:g} s)"
            )
        )
    else:
        stdout.print("Give -o CSV to write the cycle program.")


def _tracker(station: str | None, range_m: str, tracker_um: str | None) -> Any:
    """``plan``'s tracker options as a :class:`dhlog.cell.plan.Tracker` (None without a station)."""
    from dhlog.cell.plan import Tracker

    if station is None:
        if tracker_um is not None:
            stderr.print("error: --tracker-um needs --station (where the line of sight starts).")
            raise typer.Exit(EXIT_USAGE)
        return None
    xyz = floats(station, "--station")
    reach = floats(range_m, "--range-m")
    model = floats(tracker_um, "--tracker-um") if tracker_um is not None else None
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
    from dhlog.cell.compensate import read_targets, targets_csv
    from dhlog.cell.plan import select_poses
    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.io.writer import atomic_output

    if candidates is None or count < 1 or output is None:
        stderr.print("error: --select N (N ≥ 1) needs --candidates CSV and -o CSV.")
        raise typer.Exit(EXIT_USAGE)
    if angle_unit not in ("rad", "deg"):
        stderr.print(f"error: --angle-unit must be rad or deg, not '{plain(angle_unit)}'.")
        raise typer.Exit(EXIT_USAGE)
    if noise_mm <= 0:
        stderr.print(f"error: --noise-mm must be > 0, not {noise_mm:g}.")
        raise typer.Exit(EXIT_USAGE)
    if output.resolve() == candidates.resolve():
        stderr.print(f"error: {plain(output)} is the input; name another with -o.")
        raise typer.Exit(EXIT_USAGE)
    refuse_existing(output, force)
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
        fail(exc)
    except OSError as exc:
        fail(OutputError(output.parent, exc))
    stdout.print(
        plain(
            f"wrote {output}: {count} of {len(Q)} candidate poses, the most informative "
            f"(D-optimal: each adds the most to log det of the Fisher information); "
            f"{found.singular} near a singularity and {found.out_of_range} beyond the "
            f"tracker's range left out. Predicted FK σ over the workspace (RMS, 3-D, "
            f"σ {noise_mm:g} mm, one sample a pose): {found.fk_sd_chosen * 1e3:.4f} mm, against "
            f"{found.fk_sd_random * 1e3:.4f} mm for {count} drawn at random."
        )
    )
