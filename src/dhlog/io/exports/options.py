"""How ``dhlog import`` reads a source: the formats and the options (``dhlog import --help``),
checked before any file is opened."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from dhlog.errors import InputError
from dhlog.io.exports.table import ANGLE_UNITS, LENGTH_UNITS, TIME_UNITS, unit_name

FORMATS = ("csv", "spatialanalyzer", "leica")
#: The default sequence of rotation angles: about the fixed (measurement) axes X, then Y, then Z,
#: R = Rz(rz)·Ry(ry)·Rx(rx) (scipy's ``"xyz"``; upper case would be moving axes).
EULER_DEFAULT = "xyz"


@dataclass
class ImportOptions:
    """How to read the source: column names, units, joint types (see ``dhlog import --help``).

    ``length_unit`` and ``angle_unit`` are None when not given: the header's unit, else mm and
    degrees. ``joint_angle_unit``: the revolute joints' unit where the header states none
    (``--joint-angle-unit``); when not given, ``angle_unit`` covers the joints and the rotation
    angles alike (:func:`joint_angle_unit`). ``orientation_columns``: four (a quaternion,
    scalar first) or three (rotation angles in the ``euler`` sequence) columns, ``["none"]`` to
    leave the orientation out, or empty to recognise it from the header. ``targets``: the
    column prefixes of several targets' positions (:mod:`dhlog.io.exports.targets`)."""

    format: str = "csv"
    joints_file: Path | None = None
    x: str = "x"
    y: str = "y"
    z: str = "z"
    joint_columns: list[str] = field(default_factory=list)
    joint_names: list[str] = field(default_factory=list)
    joint_types: list[str] = field(default_factory=list)
    time: str | None = None
    time_unit: str = "s"
    name_column: str | None = None
    length_unit: str | None = None
    angle_unit: str | None = None
    joint_angle_unit: str | None = None
    orientation_columns: list[str] = field(default_factory=list)
    euler: str = EULER_DEFAULT
    no_u95: bool = False
    #: several targets: the prefixes of their x, y, z columns, the primary first (``--targets``)
    targets: list[str] = field(default_factory=list)


def checked_options(opts: ImportOptions) -> None:
    """Refuse an unknown format, unit or time unit (naming the option); the units given are
    set to their names in ``LENGTH_UNITS`` / ``ANGLE_UNITS``."""
    if opts.format not in FORMATS:
        raise InputError(f"--format must be one of {', '.join(FORMATS)}, not '{opts.format}'.")
    for option, value, kind in (
        ("--length-unit", opts.length_unit, "length"),
        ("--angle-unit", opts.angle_unit, "angle"),
        ("--joint-angle-unit", opts.joint_angle_unit, "angle"),
    ):
        if value is None:
            continue
        try:
            unit = unit_name(value, kind)
        except ValueError as exc:
            known = ", ".join(LENGTH_UNITS if kind == "length" else ANGLE_UNITS)
            why = f" ({exc})" if str(exc) else ""
            raise InputError(f"{option} must be one of {known}, not '{value}'{why}.") from None
        if kind == "length":
            opts.length_unit = unit
        elif option == "--angle-unit":
            opts.angle_unit = unit
        else:
            opts.joint_angle_unit = unit
    if opts.time_unit not in TIME_UNITS:
        raise InputError(
            f"--time-unit must be one of {', '.join(TIME_UNITS)}, not '{opts.time_unit}'."
        )


def joint_angle_unit(opts: ImportOptions) -> tuple[str | None, str]:
    """The revolute joints' unit given by an option (None: the header's, else degrees) and the
    option that gives it: ``--joint-angle-unit``, else ``--angle-unit`` (which then covers the
    joints and the rotation angles alike, as before the joints had their own)."""
    if opts.joint_angle_unit is not None:
        return opts.joint_angle_unit, "--joint-angle-unit"
    return opts.angle_unit, "--angle-unit"
