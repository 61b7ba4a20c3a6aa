"""``dhlog compensate``: targets corrected for a controller that keeps its nominal model —
joint targets, Cartesian targets (a CSV in a named rotation convention, at a TCP) or a whole
robot program, its text kept but for the targets' numbers.

A target not corrected is named on stderr (the file and its row or line, and why) and makes
the exit :data:`~dhlog.cli.common.EXIT_PARTIAL` (3); the targets corrected are written all the
same (in a program, the others keep their numbers)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from dhlog.cli.common import EXIT_PARTIAL, EXIT_USAGE, fail, plain, refuse_existing, stderr, stdout
from dhlog.cli.options import floats
from dhlog.errors import DhlogError, OutputError


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
        Path,
        typer.Option(
            "-o", "--output", metavar="FILE", help="The corrected targets (CSV) or program."
        ),
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
            help="Cartesian targets of the TCP in the nominal's base frame, in order: x, y, z "
            "(mm, or x_m …), the orientation in --rotation's convention, optionally the "
            "controller's configuration j1 … jn (--angle-unit). Written: the corrected joint "
            "targets and the pose to command instead.",
        ),
    ] = None,
    program: Annotated[
        Path | None,
        typer.Option(
            metavar="FILE",
            help="A robot program (URScript .script/.urscript, ABB RAPID .mod/.modx/.prg): "
            "written with only its targets' numbers corrected.",
        ),
    ] = None,
    program_format: Annotated[
        str | None,
        typer.Option(
            metavar="urscript|rapid", help="The program's format (default: by its suffix)."
        ),
    ] = None,
    rotation: Annotated[
        str | None,
        typer.Option(
            metavar="CONVENTION",
            help="With --poses: the orientation's convention — quaternion (qw first), rotvec "
            "(rad, as URScript and the UR pendant), extrinsic-SEQ or intrinsic-SEQ (an Euler "
            "sequence: xyz, zyx, zyz …; KUKA A, B, C = intrinsic-zyx). Default: qw … a "
            "quaternion, rx, ry, rz fixed-axis X, Y, Z degrees.",
        ),
    ] = None,
    tcp: Annotated[
        str | None,
        typer.Option(
            metavar="X,Y,Z[,RX,RY,RZ]|tool",
            help="The TCP in the flange (last) frame: mm, and a rotation vector in rad (as "
            "URScript's set_tcp and the pendant); tool: the result's tool point. Default: the "
            "flange (a program's own set_tcp, or a RAPID tooldata, applies where it is used).",
        ),
    ] = None,
    angle_unit: Annotated[
        str, typer.Option(metavar="rad|deg", help="The unit of the targets' revolute joints.")
    ] = "rad",
    force: Annotated[bool, typer.Option("--force", help="Overwrite the output.")] = False,
) -> None:
    """Correct a robot's targets for a controller that keeps its nominal model: the calibrated
    robot (its terms beyond the geometry included) then reaches the pose the controller
    intended. Cartesian targets are solved in order, each from the previous one, so the arm
    keeps its configuration; a target not corrected is named and the exit is 3."""
    if angle_unit not in ("rad", "deg"):
        stderr.print(f"error: --angle-unit must be rad or deg, not '{plain(angle_unit)}'.")
        raise typer.Exit(EXIT_USAGE)
    given = [p for p in (joints, poses, program) if p is not None]
    if len(given) != 1:
        stderr.print("error: give the targets once: --joints CSV, --poses CSV or --program FILE.")
        raise typer.Exit(EXIT_USAGE)
    for option, value, needs in (
        ("--rotation", rotation, poses),
        ("--program-format", program_format, program),
        ("--tcp", tcp, poses or program),
    ):
        if value is not None and needs is None:
            kind = "--poses" if option == "--rotation" else "--program"
            kind = "--poses or --program" if option == "--tcp" else kind
            stderr.print(f"error: {option} applies to {kind} only.")
            raise typer.Exit(EXIT_USAGE)
    if output.resolve() in {given[0].resolve(), result.resolve()}:
        stderr.print(f"error: {plain(output)} is an input; name another with -o.")
        raise typer.Exit(EXIT_USAGE)
    refuse_existing(output, force)
    try:
        if rotation is not None:
            from dhlog.cell.rotations import check_convention

            check_convention(rotation)
        calibration = _result_and_nominal(result, nominal)
        tcp_T = _tcp(tcp, calibration)
        if joints is not None:
            problems = _joints(calibration, joints, output, angle_unit)
        elif poses is not None:
            problems = _poses(calibration, poses, output, angle_unit, rotation, tcp_T)
        else:
            assert program is not None
            problems = _program(calibration, program, program_format, output, tcp_T)
    except DhlogError as exc:
        fail(exc)
    except OSError as exc:
        fail(OutputError(output.parent, exc))
    if problems:
        raise typer.Exit(EXIT_PARTIAL)


def _result_and_nominal(result: Path, nominal: str) -> Any:
    """The calibration of ``result`` with the controller's nominal, of the same robot."""
    from dhlog.api import load
    from dhlog.errors import InputError

    calibration = load(result, nominal=nominal)
    nom = calibration.nominal
    if nom is not None and nom.table.n != calibration.n:
        raise InputError(
            f"{nominal}: has {nom.table.n} joints but {result} has {calibration.n}; give the "
            "nominal of this robot."
        )
    return calibration


def _tcp(text: str | None, calibration: Any) -> Any:
    """``--tcp`` as a 4 × 4 transform in the flange frame (None: not given)."""
    if text is None:
        return None
    T = np.eye(4)
    if text.strip() == "tool":
        T[:3, 3] = calibration.tool_point
        return T
    values = floats(text, "--tcp")
    if len(values) not in (3, 6) or max(abs(v) for v in values[:3]) > 1e4:
        stderr.print(
            "error: --tcp takes X,Y,Z (mm, within 10 m) and optionally RX,RY,RZ (a rotation "
            "vector, rad), or tool."
        )
        raise typer.Exit(EXIT_USAGE)
    from dhlog.cell.rotations import matrices

    T[:3, 3] = np.array(values[:3]) * 1e-3
    if len(values) == 6:
        T[:3, :3] = matrices(np.array([values[3:]]), "rotvec", degrees=False)[0]
    return T


def _say_problems(name: str, problems: list[tuple[str, str]]) -> None:
    """One line on stderr per target not corrected (``where``: ``row 3`` or ``line 12``)."""
    for where, why in problems:
        stderr.print(plain(f"{name} {where}: not corrected: {why}."))


def _reached(calibration: Any, joints: Any, goal: Any, tcp: Any) -> tuple[float, float]:
    """The largest position (m) and rotation (rad) error of the calibrated model's TCP at the
    corrected ``joints`` (m, n) from the targets ``goal`` (m, 4, 4)."""
    from scipy.spatial.transform import Rotation

    from dhlog.model.fk import fk_frames

    if not len(joints):
        return 0.0, 0.0
    model = calibration.identified()
    T = fk_frames(model.table, model.joint_values(joints))[:, -1] @ tcp
    dp = float(np.max(np.linalg.norm(T[:, :3, 3] - goal[:, :3, 3], axis=1)))
    E = np.einsum("mij,mkj->mik", T[:, :3, :3], goal[:, :3, :3])
    return dp, float(np.max(Rotation.from_matrix(E).magnitude()))


def _units(calibration: Any, angle_unit: str) -> tuple[Any, list[str]]:
    """The joints' display scale (× rad or m) and unit names."""
    revolute = np.array([t.value == "revolute" for t in calibration.table.joint_types])
    scale = np.where(revolute & (angle_unit == "deg"), 180 / math.pi, 1.0)
    return scale, [angle_unit if r else "m" for r in revolute]


def _joints(calibration: Any, joints: Path, output: Path, angle_unit: str) -> list[Any]:
    """``--joints CSV``: each joint target corrected (Newton on the calibrated model)."""
    from dhlog.cell.compensate import read_targets, targets_csv
    from dhlog.io.writer import atomic_output

    header, Q = read_targets(joints, calibration.n)
    scale, units = _units(calibration, angle_unit)
    Q = Q / scale
    done = calibration.compensate(Q)
    with atomic_output(output) as f:
        f.write(targets_csv(header, done.targets * scale, done.problems, units).encode())
    problems = [(f"row {k + 1}", why) for k, why in sorted(done.problems.items())]
    _say_problems(joints.name, problems)
    good = np.isfinite(done.targets[:, 0])
    largest = float(np.max(np.abs(done.targets[good] - Q[good]))) if np.any(good) else 0.0
    worst = float(np.max(done.error[good], initial=0.0))
    stdout.print(
        plain(
            f"wrote {output}: {int(good.sum())} of {len(Q)} targets corrected (largest change "
            f"{largest:.6g} rad or m; each within {worst:.1e} m and rad of the pose the nominal "
            "gives the original)"
        )
    )
    return problems


def _poses(
    calibration: Any,
    poses: Path,
    output: Path,
    angle_unit: str,
    rotation: str | None,
    tcp: Any,
) -> list[Any]:
    """``--poses CSV``: Cartesian targets corrected in order (:mod:`dhlog.cell.sequence`)."""
    from dhlog.cell.posecsv import poses_table_csv, read_pose_table
    from dhlog.cell.sequence import Target, filter_targets
    from dhlog.io.writer import atomic_output

    scale, units = _units(calibration, angle_unit)
    table = read_pose_table(poses, calibration.n, rotation=rotation, joint_scale=1 / scale)
    tcp = np.eye(4) if tcp is None else tcp
    targets = [
        Target(
            f"line {line}",
            pose=table.poses[k],
            tcp=tcp,
            hint=None if table.configuration is None else table.configuration[k],
        )
        for k, line in enumerate(table.lines)
    ]
    done = filter_targets(
        calibration.identified(), calibration.nominal, targets, limits=calibration.limits
    )
    names = [f"q{j + 1}_{u}" for j, u in enumerate(units)]
    text = poses_table_csv(table, done.joints * scale, done.commanded, done.problems, names)
    with atomic_output(output) as f:
        f.write(text.encode())
    problems = [
        (f"line {table.lines[k]} (row {k + 1})", why) for k, why in sorted(done.problems.items())
    ]
    _say_problems(poses.name, problems)
    for note in done.notes:
        stdout.print(plain(f"note: {poses.name} {note}."))
    good = np.flatnonzero(np.isfinite(done.joints[:, 0]))
    _summary(output, calibration, done, good, table.poses[good], tcp, len(targets), "targets")
    return problems


def _summary(
    output: Path, calibration: Any, done: Any, good: Any, goal: Any, tcp: Any, total: int, what: str
) -> None:
    """The last line: how many were corrected, how close, the largest joint step."""
    tcps = tcp if np.ndim(tcp) == 3 else np.repeat(np.asarray(tcp)[None], len(good), 0)
    dp, dr = _reached(calibration, done.joints[good], goal, tcps)
    stdout.print(
        plain(
            f"wrote {output}: {len(good)} of {total} {what} corrected; under the calibrated "
            f"model each reaches its target within {dp * 1e6:.3g} µm and {dr * 1e6:.3g} µrad; "
            f"largest joint step between neighbours {math.degrees(done.largest_step):.3g}° "
            "(the configuration kept throughout)"
            + ("" if len(good) == total else f"; {total - len(good)} not corrected (above)")
        )
    )


def _program(calibration: Any, program: Path, fmt: str | None, output: Path, tcp: Any) -> list[Any]:
    """``--program FILE``: the program rewritten with its targets corrected."""
    from dhlog.cell.programs import filtered, format_of, read
    from dhlog.io.writer import atomic_output

    name = format_of(program, fmt)
    read_in = read(program, name, calibration.n, tcp)
    done = filtered(
        read_in, calibration.identified(), calibration.nominal, limits=calibration.limits
    )
    with atomic_output(output) as f:
        f.write(done.text.encode())
    problems = [(f"line {line}", why) for line, why in done.problems]
    _say_problems(program.name, problems)
    for note in done.notes:
        stdout.print(plain(f"note: {program.name} {note}."))
    runs = [m for m in read_in.motions if m.literal is not None]
    goal, tcps = [], []
    good = np.flatnonzero(np.isfinite(done.filtered.joints[:, 0]))
    for k in good.tolist():
        motion = runs[k]
        assert motion.literal is not None
        lit = read_in.literals[motion.literal]
        if lit.kind == "pose":
            goal.append(read_in.units.pose(lit.values))
        else:
            from dhlog.model.fk import fk_frames

            nom = calibration.nominal
            q = read_in.units.joints(lit.values)
            goal.append(fk_frames(nom.table, q[None], T_base=nom.T_base)[0, -1] @ motion.tcp)
        tcps.append(motion.tcp)
    G = np.array(goal).reshape(-1, 4, 4)
    _summary(
        output,
        calibration,
        done.filtered,
        good,
        G,
        np.array(tcps).reshape(-1, 4, 4),
        len(read_in.motions),
        "targets",
    )
    return problems
