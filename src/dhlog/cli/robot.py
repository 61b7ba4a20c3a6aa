"""A robot's DH table on its own: ``dhlog fk`` (the pose and Jacobian at joint values),
``dhlog show`` (a recording of each joint swept in turn) and ``dhlog robots`` (the library)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from dhlog.cli.common import EXIT_USAGE, fail, plain, refuse_existing, stderr, stdout
from dhlog.cli.options import angles, floats, load_model
from dhlog.errors import DhlogError


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
    as_json: Annotated[
        bool,
        typer.Option("--json", help="Print one JSON document (dhlog.fk/1, SI units; docs/cli.md)."),
    ] = False,
) -> None:
    """Pose of the last frame, the tool point and the spatial manipulator Jacobian at q."""
    from dhlog.model.fk import fk_frames, fk_point, spatial_jacobian

    try:
        model = load_model(dh)
    except DhlogError as exc:
        fail(exc)
    for option, value, allowed in (
        ("units", units, ("mm", "m")),
        ("angle-unit", angle_unit, ("rad", "deg")),
    ):
        if value not in allowed:
            stderr.print(f"error: --{option} must be {' or '.join(allowed)}, not '{plain(value)}'.")
            raise typer.Exit(EXIT_USAGE)
    values = np.array(floats(q, "--q"))
    if values.size == model.table.n:
        values = angles(values, angle_unit, model.table.joint_types)
    if values.size != model.table.n:
        stderr.print(
            f"error: --q has {values.size} values but {plain(dh)} has {model.table.n} joints."
        )
        raise typer.Exit(EXIT_USAGE)
    scale = 1e3 if units == "mm" else 1.0
    given = values
    if model.terms is not None:  # the joints as they stand: deflected by the result's terms
        deflected = model.joint_values(values)
        if not as_json:  # the JSON gives both: q and joint_values
            shown_dq = ", ".join(f"{v:+.3g}" for v in deflected - values)
            stdout.print(f"joint deflection by the nongeometric terms (rad or m): {shown_dq}")
        values = deflected
    T = fk_frames(model.table, values, T_base=model.T_base)[-1]
    J = spatial_jacobian(model.table, values, T_base=model.T_base)
    if as_json:
        import json

        tool_m = fk_point(model.table, values, model.tool_point, T_base=model.T_base)
        document = {
            "schema": "dhlog.fk/1",
            "model": plain(model.source or dh),
            "joint_names": list(model.joint_names),
            "q": given.tolist(),
            "joint_values": values.tolist(),
            "T_base_last": T.tolist(),
            "tool_point": tool_m.tolist(),
            "jacobian": J.tolist(),
            "units": {"length": "m", "angle": "rad"},
        }
        stdout.out(json.dumps(document, indent=2), highlight=False)
        return
    np.set_printoptions(precision=6, suppress=True, linewidth=120)
    shown = T.copy()
    shown[:3, 3] *= scale
    stdout.print(f"T_base_last (translation in {units}):")
    stdout.print(str(shown))
    tool = fk_point(model.table, values, model.tool_point, T_base=model.T_base) * scale
    stdout.print(f"tool point ({units}): {tool}")
    stdout.print("spatial Jacobian [v; w] (rows vx vy vz wx wy wz, one column per joint):")
    stdout.print(str(J))


def show(
    dh: Annotated[
        str,
        typer.Argument(
            help="A DH file, a result JSON, or a library robot (dhlog robots lists them)."
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
        model = load_model(dh)
        limits = None
        if not (Path(dh).suffix in (".json", ".toml") or Path(dh).exists()):
            limits = load_robot(dh).limits
        path = output if output is not None else Path(f"{Path(dh).stem}.rrd")
        refuse_existing(path, force)
        write_robot_recording(
            model.table, path, T_base=model.T_base, limits=limits, title=Path(dh).stem, steps=steps
        )
    except DhlogError as exc:
        fail(exc)
    stdout.print(f"wrote {plain(path)}; open it with: rerun {plain(path)}")


def robots(
    names: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="[ROBOT]...",
            help="Robots to show whole (their source and the check of their FK); none: the list.",
        ),
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="The list as JSON (one object per robot).")
    ] = False,
) -> None:
    """The robot library: each robot's name (for --nominal and simulate), title, joints and
    whether its FK is tested against the vendor's description; with names, each one's source and
    check in full."""
    from dhlog.model.robots import library_robots, load_robot

    try:
        chosen = [load_robot(n) for n in names] if names else library_robots()
    except DhlogError as exc:
        fail(exc)
    entries = [
        {
            "name": r.name,
            "title": r.title,
            "joints": r.n,
            "joint_types": "".join(t.value[0].upper() for t in r.table.joint_types),
            "joint_names": list(r.joint_names),
            "source": r.source,
            "checked": r.checked or None,
        }
        for r in chosen
    ]
    if as_json:
        stdout.print_json(json.dumps(entries))
        return
    from rich.table import Table
    from rich.text import Text

    if not names:
        table = Table(box=None, pad_edge=False, show_edge=False)
        for column in ("robot", "title", "joints", "FK checked against"):
            table.add_column(column, overflow="fold")
        for e in entries:
            # the description's package or repository: its first word, without the owner
            checked = str(e["checked"]).split()[0].split("/")[-1] if e["checked"] else "-"
            joints = f"{e['joints']} {e['joint_types']}"
            table.add_row(Text(str(e["name"])), Text(str(e["title"])), joints, Text(checked))
        stdout.print(table)
        stdout.print("dhlog robots NAME: a robot's source and check in full; --json: as data.")
        return
    grid = Table.grid(padding=(0, 2))
    grid.add_column("robot", no_wrap=True)
    grid.add_column("entry", overflow="fold")
    for e in entries:
        names_said = ", the driver's joint names" if e["joint_names"] else ""
        said = e["checked"] or "not checked against a vendor description"
        entry = (
            f"{e['title']}: {e['joints']} joints ({e['joint_types']}){names_said}\n"
            f"source: {e['source']}\nFK checked: {said}"
        )
        grid.add_row(Text(str(e["name"])), Text(entry))
    stdout.print(grid)
