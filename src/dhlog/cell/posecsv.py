"""Cartesian targets as CSV: read with their units and rotation convention, written with the
units in every column's name.

A target file has a header and one row per target: the position ``x, y, z`` (mm; ``x_mm`` or
``x_m`` say the unit), the orientation in a named convention (:mod:`dhlog.cell.rotations`) —
``qw, qx, qy, qz`` for ``quaternion``; ``rx, ry, rz`` for ``rotvec`` (rad unless ``rx_deg``);
three angles ``r1, r2, r3`` (or ``rx, ry, rz``, or ``a, b, c``) in the sequence's order for an
Euler convention (degrees unless ``r1_rad``) — and optionally the controller's configuration
``j1 … jn`` (or ``q1_rad …``, ``q1_deg …``). Without a convention named, ``qw, qx, qy, qz``
is a quaternion and ``rx, ry, rz`` fixed-axis X, Y, Z angles in degrees (``extrinsic-xyz``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dhlog.cell import rotations
from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray

_UNIT = re.compile(r"^(.*?)(?:_(mm|m|deg|rad))?$")
#: Names of an Euler convention's three angles, in the sequence's order.
EULER_NAMES = (("r1", "r2", "r3"), ("rx", "ry", "rz"), ("a", "b", "c"))


@dataclass(frozen=True)
class PoseTable:
    """Targets read from a CSV: ``poses`` (m, 4, 4: the TCP in the base frame, m), the
    configurations (m, n; rad or m) or None, the file's ``lines`` of each row, the
    ``convention``, whether its angles were in ``degrees`` and the orientation's column names
    (``names``, without units: ``a, b, c``)."""

    poses: FloatArray
    configuration: FloatArray | None
    lines: list[int]
    convention: str
    degrees: bool
    names: tuple[str, ...] = ()


def _split(cell: str) -> tuple[str, str | None]:
    match = _UNIT.match(cell)
    assert match is not None
    return match.group(1), match.group(2)


def _columns(
    name: str, header: list[str], line: int, rotation: str | None, n: int
) -> tuple[list[int], str, bool, float, list[int] | None, tuple[str, ...], str | None]:
    """Where the position, orientation and configuration are, the convention, whether its
    angles are degrees, the length scale to m and the configuration's unit scale columns."""
    split = [_split(c) for c in header]
    bare = [b for b, _ in split]
    unit = {b: u for b, u in split}
    if len(set(bare)) != len(bare):
        raise InputError(f"{name}, line {line}: a column is named twice; name each once.")
    if not all(c in bare for c in ("x", "y", "z")):
        raise InputError(
            f"{name}: its header ({', '.join(header)[:80]}) lacks x, y, z (mm, or x_m …); name "
            "the columns x, y, z and the orientation's (qw, qx, qy, qz; rx, ry, rz; …)."
        )
    lengths = {unit[c] for c in ("x", "y", "z")}
    if len(lengths) != 1 or not lengths <= {None, "mm", "m"}:
        raise InputError(f"{name}, line {line}: give x, y, z in one length unit (mm or m).")
    scale = 1.0 if lengths == {"m"} else 1e-3
    if rotation is None:
        if all(c in bare for c in ("qw", "qx", "qy", "qz")) and "rx" not in bare:
            rotation = "quaternion"
        elif all(c in bare for c in ("rx", "ry", "rz")) and "qw" not in bare:
            rotation = "extrinsic-xyz"
        else:
            raise InputError(
                f"{name}: give the orientation once, as qw, qx, qy, qz or as rx, ry, rz "
                "(fixed-axis degrees), or name its convention with --rotation."
            )
    if rotation == "quaternion":
        names: tuple[str, ...] = ("qw", "qx", "qy", "qz")
    elif rotation == "rotvec":
        names = ("rx", "ry", "rz")
    else:
        names = next((e for e in EULER_NAMES if all(c in bare for c in e)), EULER_NAMES[0])
    if not all(c in bare for c in names):
        raise InputError(
            f"{name}: --rotation {rotation} needs the columns {', '.join(names)}; its header "
            f"has {', '.join(header)[:80]}."
        )
    angle_units = {unit[c] for c in names}
    if rotation == "quaternion" and angle_units != {None}:
        raise InputError(f"{name}, line {line}: a quaternion's columns take no unit.")
    if len(angle_units) != 1 or not angle_units <= {None, "deg", "rad"}:
        raise InputError(f"{name}, line {line}: give {', '.join(names)} in one unit (deg or rad).")
    default_deg = rotation != "rotvec"
    degrees = angle_units == {"deg"} or (angle_units == {None} and default_deg)
    where = [bare.index(c) for c in ("x", "y", "z", *names)]
    config = None
    config_unit: str | None = None
    for prefix in ("j", "q"):
        wanted = [f"{prefix}{j + 1}" for j in range(n)]
        if any(c in bare for c in wanted):
            if not all(c in bare for c in wanted):
                raise InputError(f"{name}: the configuration needs all of {', '.join(wanted)}.")
            config = [bare.index(c) for c in wanted]
            said = {unit[c] for c in wanted}
            if len(said) != 1 or not said <= {None, "deg", "rad", "m"}:
                raise InputError(f"{name}, line {line}: give {', '.join(wanted)} in one unit.")
            config_unit = said.pop()
            break
    known = {*where, *(config or [])}
    extra = [header[k] for k in range(len(header)) if k not in known and bare[k] != "row"]
    if extra:
        raise InputError(
            f"{name}: column '{extra[0][:40]}' is not a position, {rotation} orientation or "
            "configuration column."
        )
    return where, rotation, degrees, scale, config, tuple(names), config_unit


def read_pose_table(
    path: str | Path, n: int, *, rotation: str | None = None, joint_scale: FloatArray | None = None
) -> PoseTable:
    """The Cartesian targets of the CSV at ``path`` (see the module docstring); ``rotation``:
    the orientation's convention (None: from the header); ``joint_scale`` (n,): the
    configuration's values × this are rad or m (default 1). One-line errors name the file,
    line or column. A configuration column's unit (``q1_deg``) wins over ``joint_scale``."""
    name = str(path)
    if rotation is not None:
        rotations.check_convention(rotation)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(
            f"{name}: cannot be read ({exc}); give a CSV of Cartesian targets."
        ) from None
    lines = [
        (k, line)
        for k, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError(
            f"{name}: holds no target; give a header (x, y, z, qw, qx, qy, qz) and rows."
        )
    header = [c.strip().lower() for c in lines[0][1].replace(";", ",").split(",")]
    where, convention, degrees, scale, config, names, config_unit = _columns(
        name, header, lines[0][0], rotation, n
    )
    rows, numbers = [], []
    for number, line in lines[1:]:
        cells = [c.strip() for c in line.replace(";", ",").split(",")]
        if len(cells) != len(header):
            raise InputError(
                f"{name}, line {number}: has {len(cells)} values for {len(header)} columns."
            )
        try:
            values = [float(cells[i]) for i in [*where, *(config or [])]]
        except ValueError:
            raise InputError(
                f"{name}, line {number}: '{line.strip()[:60]}' is not {len(header)} numbers."
            ) from None
        if not all(math.isfinite(v) for v in values):
            raise InputError(f"{name}, line {number}: a value is not finite (NaN or inf).")
        if max(abs(v) for v in values[:3]) * scale > 1e3:
            raise InputError(f"{name}, line {number}: a position beyond 1 km; check the unit.")
        rows.append(values)
        numbers.append(number)
    if not rows:
        raise InputError(f"{name}: holds no target under its header.")
    A = np.array(rows)
    k = rotations.width(convention)
    if convention == "quaternion":
        norm = np.linalg.norm(A[:, 3:7], axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > 1e-3)
        if bad.size:
            raise InputError(
                f"{name}, line {numbers[int(bad[0])]}: the quaternion has norm "
                f"{norm[bad[0]]:.6g}, not 1."
            )
    T = np.repeat(np.eye(4)[None], len(A), 0)
    T[:, :3, :3] = rotations.matrices(A[:, 3 : 3 + k], convention, degrees=degrees)
    T[:, :3, 3] = A[:, :3] * scale
    configuration = None
    if config is not None:
        # the columns' own unit (q1_deg) wins over the caller's (--angle-unit)
        given = 1.0 if joint_scale is None else joint_scale
        if config_unit == "deg":
            given = np.where(np.asarray(given) == 1.0, math.pi / 180, given)
        elif config_unit in ("rad", "m"):
            given = np.ones(A.shape[1] - 3 - k)
        configuration = A[:, 3 + k :] * given
    return PoseTable(T, configuration, numbers, convention, degrees, names)


def orientation_names(convention: str, degrees: bool, names: tuple[str, ...] = ()) -> list[str]:
    """The output's orientation columns (the input's ``names``, else the convention's), their
    unit in the name."""
    if convention == "quaternion":
        return ["qw", "qx", "qy", "qz"]
    unit = "deg" if degrees else "rad"
    base = names or (("rx", "ry", "rz") if convention == "rotvec" else ("r1", "r2", "r3"))
    return [f"{c}_{unit}" for c in base]


def poses_table_csv(
    table: PoseTable,
    joints: FloatArray,
    commanded: FloatArray,
    problems: dict[int, str],
    joint_names: list[str],
) -> str:
    """Per target corrected: its ``row`` (1-based, as read), the corrected joints (named with
    their units: ``joint_names``, values already in those units), and the TCP pose to command
    instead (``x_mm, y_mm, z_mm`` and the orientation in the input's convention, the unit in
    each name, the representation nearest the input's). Targets not corrected are left out."""
    old = rotations.values(table.poses[:, :3, :3], table.convention, degrees=table.degrees)
    head = ["row", *joint_names, "x_mm", "y_mm", "z_mm"]
    head += orientation_names(table.convention, table.degrees, table.names)
    out = [",".join(head)]
    for k in range(len(joints)):
        if k in problems or not np.isfinite(joints[k, 0]):
            continue
        r = rotations.values(commanded[k : k + 1, :3, :3], table.convention, degrees=table.degrees)
        r = rotations.near(r, old[k : k + 1], table.convention, degrees=table.degrees)[0]
        cells = [*joints[k], *(commanded[k, :3, 3] * 1e3), *r]
        out.append(",".join([str(k + 1), *(f"{v:.15g}" for v in cells)]))
    return "\n".join(out) + "\n"
