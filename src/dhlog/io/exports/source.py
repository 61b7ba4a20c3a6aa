"""An export's points in SI units (:class:`Source`): coordinates in their header's unit (else
``--length-unit``, else a comment line's ``# Units: …``, else mm; x, y, z in one unit), U95 or
standard-uncertainty columns as each point's covariance, the orientation as unit quaternions,
the time, and the joint values when the export holds them.

U95 to σ (:data:`UNCERTAINTY_KINDS`): a per-coordinate U95 is 1.96 σ; a single (3D) U95 is the
radius of the 95 % sphere of an isotropic normal distribution, 2.796 σ (√χ²₃(0.95)); a standard
uncertainty or deviation per coordinate (``unc X``, ``std x``, ``sigma_x``,
``measurement_std_x``) is σ; a single 3-D one (``leica_unc_m``, ``Uncertainty``) is the radial
figure √(σx² + σy² + σz²): σ = u / √3. A value of 0 or below is refused naming its line, and so
is a median σ no tracker gives in the unit read (:mod:`dhlog.io.exports.checks`). Uncertainty
columns that cannot be used (an orientation's σ: the log carries the position's covariance
only; a second set beside the one read) are named in a warning as left out.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dhlog.io.exports.checks import comment_length_unit, one_unit, plausible_sigma
from dhlog.io.exports.layout import JOINT_HEADER, Layout, column_layout
from dhlog.io.exports.options import ImportOptions, joint_angle_unit
from dhlog.io.exports.slips import joint_unit_slip, orientation_unit_slip
from dhlog.io.exports.table import (
    ANGLE_UNITS,
    DEFAULT_ANGLE_UNIT,
    DEFAULT_LENGTH_UNIT,
    DIMENSIONLESS,
    LENGTH_UNITS,
    TIME_UNITS,
    ConversionError,
    Table,
    column_unit,
    cut,
    stated_alike,
    without_unit,
)
from dhlog.model.dh import JointType

#: σ = U95 / this, per coordinate (1.96) or from a 3D radius (√χ²₃(0.95)).
U95_PER_COORDINATE = 1.959963984540054
U95_SPHERE = 2.7954834829151074
#: Each kind of uncertainty column (:class:`~dhlog.io.exports.layout.Layout`'s ``u95``): the
#: value over σ per coordinate, and what it is. A 3-D standard uncertainty (``unc``, ``std``,
#: ``sigma`` alone) is the radial figure √(σx² + σy² + σz²) of an isotropic σ: σ = u / √3.
UNCERTAINTY_KINDS = {
    "axes": (U95_PER_COORDINATE, "U95 per axis: σ = U95 / 1.96"),
    "sphere": (U95_SPHERE, "a 3-D U95 (the 95 % sphere's radius): σ = U95 / 2.796"),
    "std": (1.0, "a standard uncertainty per axis: σ as written"),
    "std3d": (math.sqrt(3.0), "a 3-D standard uncertainty (radial): σ = u / √3"),
}
#: The first stop's time (ns): 2020-01-01, so that stamps look like a real clock's.
EPOCH_NS = 1_577_836_800_000_000_000
#: A quaternion is normalised when its norm is this close to 1, else refused.
QUATERNION_TOLERANCE = 1e-3
#: The ranges of the values read, in SI units: a coordinate (m, any axis), a revolute joint
#: value or rotation angle (rad), a prismatic joint value (m), a U95 (m).
MAX_COORDINATE_M = 1000.0
MAX_ANGLE_RAD = 1000.0
MAX_TRAVEL_M = 1000.0
U95_RANGE_M = (1e-9, 1.0)


def joint_values(
    table: Table, columns: list[int], opts: ImportOptions, warnings: list[str] | None = None
) -> tuple[list[str], NDArray[np.float64]]:
    """Joint names and values in SI units (rad, m), each column in its header's unit, else
    ``--joint-angle-unit`` / ``--angle-unit`` (revolute) or ``--length-unit`` (prismatic). A
    unit slip the revolute values show (:func:`~dhlog.io.exports.slips.joint_unit_slip`) is
    refused, or appended to ``warnings`` where the header stated the unit."""
    n = len(columns)
    names = opts.joint_names or [without_unit(table.heads[k]) for k in columns]
    if len(names) != n:
        raise ConversionError(
            table.path, f"--joint-names gives {len(names)} names for {n} joint columns."
        )
    try:
        types = [JointType.parse(t) for t in opts.joint_types] or [JointType.REVOLUTE] * n
    except ValueError as exc:
        raise ConversionError(table.path, f"--joint-types: {exc}") from None
    if len(types) != n:
        raise ConversionError(
            table.path, f"--joint-types gives {len(types)} types for {n} joint columns."
        )
    if len(set(names)) != n:
        twice = next(name for name in names if names.count(name) > 1)
        raise ConversionError(
            table.path,
            f"two joints are named '{twice}'; name each joint once (--joint-names).",
        )
    revolute = [k for k, t in zip(columns, types, strict=True) if t is JointType.REVOLUTE]
    prismatic = [k for k, t in zip(columns, types, strict=True) if t is JointType.PRISMATIC]
    angle_unit, angle_option = joint_angle_unit(opts)
    stated_alike(table, revolute, "angle", angle_unit, "revolute joint column", option=angle_option)
    stated_alike(table, prismatic, "length", opts.length_unit, "prismatic joint column")
    q = np.empty((len(table.rows), n))
    read: dict[tuple[str, str], list[int]] = {}  # revolute columns by (unit, where it came from)
    for j, (k, t) in enumerate(zip(columns, types, strict=True)):
        what = f"joint {names[j]}"
        q[:, j] = table.numbers(k, what, "is it a joint column (--joint-columns)?")
        if t is JointType.PRISMATIC:
            unit = column_unit(table, k, "length", opts.length_unit, DEFAULT_LENGTH_UNIT)
            q[:, j] *= LENGTH_UNITS[unit]
            table.in_range(k, q[:, j], what, -MAX_TRAVEL_M, MAX_TRAVEL_M, "m")
        else:
            unit = column_unit(
                table, k, "angle", angle_unit, DEFAULT_ANGLE_UNIT, option=angle_option
            )
            where = (
                "the header"
                if table.heads[k].unit not in (None, *DIMENSIONLESS)
                else angle_option
                if angle_unit is not None
                else "the default"
            )
            read.setdefault((unit, where), []).append(j)
            q[:, j] *= ANGLE_UNITS[unit]
            table.in_range(k, q[:, j], what, -MAX_ANGLE_RAD, MAX_ANGLE_RAD, "rad")
    for (unit, where), js in read.items():
        as_read = q[:, js] / ANGLE_UNITS[unit]
        slip = joint_unit_slip([names[j] for j in js], as_read, unit, where)
        if slip is not None:
            message, refuse = slip
            if refuse:
                raise ConversionError(table.path, message)
            if warnings is not None:
                warnings.append(f"{table.path}: {message}")
    return names, q


@dataclass
class Source:
    """The points of a source in SI units, before the joints are attached: per point its line,
    name (when the source names points), position, covariance, orientation (x, y, z, w) and
    time, and the joints when the source holds them."""

    path: str
    lines: list[int]
    names: list[str] | None
    xyz: NDArray[np.float64]
    cov: NDArray[np.float64] | None = None
    quat: NDArray[np.float64] | None = None
    t_ns: NDArray[np.int64] | None = None
    joint_names: list[str] = field(default_factory=list)
    q: NDArray[np.float64] | None = None
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    provenance: dict[str, str] = field(default_factory=dict)
    named_by_option: bool = False
    #: rotation angles as written (m, 3), and their columns, unit and where the unit came from
    #: (``"the header"``, ``"--angle-unit"``, ``"--angle-unit (shared)"``, ``"the default"``)
    angles: NDArray[np.float64] | None = None
    angles_read: tuple[str, str, str] | None = None
    #: further targets' positions (k, m, 3), m (``--targets``)
    further: NDArray[np.float64] | None = None
    #: the positions' unit as read and what stated it (``"the header"``, ``"--length-unit"``,
    #: ``"line 2"``, ``"the default"``)
    length_read: tuple[str, str] | None = None

    def take(self, rows: NDArray[np.int64]) -> Source:
        """The points at ``rows``, in that order."""
        at = rows.tolist()
        return dataclasses.replace(
            self,
            lines=[self.lines[i] for i in at],
            names=None if self.names is None else [self.names[i] for i in at],
            xyz=self.xyz[rows],
            cov=None if self.cov is None else self.cov[rows],
            quat=None if self.quat is None else self.quat[rows],
            t_ns=None if self.t_ns is None else self.t_ns[rows],
            q=None if self.q is None else self.q[rows],
            angles=None if self.angles is None else self.angles[rows],
            further=None if self.further is None else self.further[:, rows],
        )

    def unit_slips(self, types: list[JointType] | None = None) -> None:
        """Refuse (or warn of) rotation angles read in the wrong unit, judged against the
        revolute joints (:func:`~dhlog.io.exports.slips.orientation_unit_slip`); ``types``:
        the joints' (default revolute)."""
        if self.angles is None or self.angles_read is None or self.quat is None or self.q is None:
            return
        revolute = [
            j
            for j in range(self.q.shape[1])
            if types is None or j >= len(types) or types[j] is JointType.REVOLUTE
        ]
        columns, unit, where = self.angles_read
        slip = orientation_unit_slip(
            columns, self.angles, unit, where, self.quat, self.q[:, revolute]
        )
        if slip is not None:
            message, refuse = slip
            if refuse:
                raise ConversionError(self.path, message)
            self.warnings.append(f"{self.path}: {message}")


def _u95_sigma(
    table: Table, layout: Layout, xyz_unit: str, xyz_where: str, opts: ImportOptions
) -> NDArray[np.float64]:
    """σ per coordinate (m, 3) from the uncertainty columns (:data:`UNCERTAINTY_KINDS`), each
    in its header's unit, else the position's (``xyz_unit``, stated by ``xyz_where``). A value
    of 0 or below is refused naming its line (no instrument measures without uncertainty: a
    0.000 is a value the export lost); per-axis columns in different units, and a median σ no
    tracker gives (:func:`~dhlog.io.exports.checks.plausible_sigma`), are refused."""
    assert layout.u95 is not None
    kind, cols = layout.u95
    hint = "fix the export, or leave the uncertainty out with --no-u95."
    name = "a U95" if kind in ("axes", "sphere") else "an uncertainty"
    values, units = [], []
    for k in cols:
        what = table.header[k]
        v = table.numbers(k, what, hint)
        bad = np.flatnonzero(~(v > 0))
        if bad.size:
            i = int(bad[0])
            count = f" (and at {bad.size - 1} other row(s))" if bad.size > 1 else ""
            raise ConversionError(
                table.path,
                f"{what} is {cut(table.texts(k)[i])}{count}: {name} must be above 0 (no "
                "instrument measures without uncertainty; 0.000 is a value the export rounded "
                "away or lost); export it with more decimals, or leave it out with --no-u95.",
                table.lines[i],
            )
        unit = column_unit(table, k, "length", opts.length_unit, xyz_unit)
        units.append(unit)
        v = v * LENGTH_UNITS[unit]
        table.in_range(k, v, what, *U95_RANGE_M, "m")
        values.append(v)
    one_unit(table, cols, units, "uncertainty")
    sd = np.column_stack(values) / UNCERTAINTY_KINDS[kind][0]
    if sd.shape[1] == 1:
        sd = np.repeat(sd, 3, axis=1)
    stated = table.heads[cols[0]].unit not in (None, *DIMENSIONLESS)
    expanded = kind in ("axes", "sphere")
    where = "the header" if stated else xyz_where
    plausible_sigma(table, cols, sd, units[0], where, expanded=expanded)
    return np.asarray(sd, dtype=np.float64)


def _orientation(
    table: Table, layout: Layout, opts: ImportOptions, src: Source
) -> tuple[NDArray[np.float64], str]:
    """The target frame's orientation in the measurement frame as unit quaternions (m, 4:
    x, y, z, w), and how it was read; rotation angles as written go to ``src.angles`` (their
    unit and where it came from to ``src.angles_read``), for :meth:`Source.unit_slips`."""
    assert layout.orientation is not None
    kind, cols = layout.orientation
    hint = "is it an orientation column (--orientation-columns)?"
    values = np.column_stack([table.numbers(k, table.header[k], hint) for k in cols])
    named = ", ".join(table.header[k] for k in cols)
    if kind == "quaternion":
        norm = np.linalg.norm(values, axis=1)
        bad = np.flatnonzero(np.abs(norm - 1.0) > QUATERNION_TOLERANCE)
        if bad.size:
            i = int(bad[0])
            raise ConversionError(
                table.path,
                f"the quaternion {named} has norm {norm[i]:.6g}, not 1 (within "
                f"{QUATERNION_TOLERANCE:g}); check that these are the orientation's columns, "
                "scalar first (--orientation-columns), and that the export writes enough "
                "decimals.",
                table.lines[i],
            )
        wxyz = values / norm[:, None]
        return np.ascontiguousarray(wxyz[:, [1, 2, 3, 0]]), f"{named} (quaternion, scalar first)"
    seq = opts.euler
    if not re.fullmatch(r"[xyz]{3}|[XYZ]{3}", seq) or seq[0] == seq[1] or seq[1] == seq[2]:
        raise ConversionError(
            table.path,
            f"--euler must be three axes, lower case for fixed axes (xyz: about X, then Y, "
            f"then Z) or upper case for moving ones (ZYX), not '{seq}'.",
        )
    from scipy.spatial.transform import Rotation

    stated_alike(table, cols, "angle", opts.angle_unit, "rotation angle")
    units = [column_unit(table, k, "angle", opts.angle_unit, DEFAULT_ANGLE_UNIT) for k in cols]
    radians = values * np.array([ANGLE_UNITS[u] for u in units])
    stated = table.heads[cols[0]].unit not in (None, *DIMENSIONLESS)
    where = (
        "the header"
        if stated
        else "the default"
        if opts.angle_unit is None
        else "--angle-unit"
        if opts.joint_angle_unit is not None
        else "--angle-unit (shared)"
    )
    src.angles, src.angles_read = values, (named, units[0], where)
    for c, k in enumerate(cols):
        table.in_range(k, radians[:, c], table.header[k], -MAX_ANGLE_RAD, MAX_ANGLE_RAD, "rad")
    quat = Rotation.from_euler(seq, radians).as_quat()  # x, y, z, w
    axes = "fixed" if seq.islower() else "moving"
    return np.asarray(quat, dtype=np.float64), f"{named} (rotation angles, {axes} axes {seq})"


def _times(table: Table, k: int, opts: ImportOptions) -> NDArray[np.int64]:
    with np.errstate(over="ignore"):  # an absurd value becomes inf, refused below
        t = table.numbers(k, "time", "is --time the right column?") * TIME_UNITS[opts.time_unit]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise ConversionError(
            table.path,
            "time does not increase; sort the export by time, or leave --time out to import "
            "the rows as stops.",
            table.lines[bad[0] + 1],
        )
    if not t[-1] - t[0] <= 1e15:  # over 11 days (or infinite): the wrong unit
        raise ConversionError(
            table.path,
            f"the time column spans {(t[-1] - t[0]) / 86.4e12:.3g} days; check --time-unit.",
        )
    return np.asarray(np.round(t - t[0]).astype(np.int64) + EPOCH_NS, dtype=np.int64)


def file_length_unit(
    path: str, opts: ImportOptions, commented: tuple[str, int] | None
) -> tuple[str, str]:
    """The length unit of a file's columns that state none, and what says so: ``--length-unit``,
    else a comment line (``# Units: inch``; a contradiction with the option is refused), else
    mm."""
    if commented is not None:
        if opts.length_unit is not None and opts.length_unit != commented[0]:
            raise ConversionError(
                path,
                f"states {commented[0]} but --length-unit {opts.length_unit} was given; leave "
                "--length-unit out (the file's unit is used) or correct the file.",
                commented[1],
            )
        return commented[0], f"line {commented[1]}"
    if opts.length_unit is not None:
        return opts.length_unit, "--length-unit"
    return DEFAULT_LENGTH_UNIT, "the default"


def from_table(table: Table, opts: ImportOptions) -> Source:
    """The points (and joints, unless a joints file gives them) of a table with a header."""
    own_joints = opts.joints_file is None
    layout = column_layout(table, opts, joints=own_joints)
    commented = comment_length_unit(table.path, table.comments)
    fallback, where = file_length_unit(table.path, opts, commented)
    if commented is not None:
        for k in layout.xyz:
            written = table.heads[k].unit
            if (
                written not in (None, *DIMENSIONLESS)
                and column_unit(table, k, "length", None, fallback) != commented[0]
            ):
                raise ConversionError(
                    table.path,
                    f"the header '{table.header[k]}' contradicts line {commented[1]}, which "
                    f"states {commented[0]}; correct the one that is wrong.",
                )
    else:
        stated_alike(table, layout.xyz, "length", opts.length_unit, "coordinate")
    units = [column_unit(table, k, "length", opts.length_unit, fallback) for k in layout.xyz]
    one_unit(table, layout.xyz, units, "position")
    if any(table.heads[k].unit not in (None, *DIMENSIONLESS) for k in layout.xyz):
        where = "the header"
    xyz = np.column_stack(
        [
            table.numbers(k, table.header[k], f"is --{a} the right column?") * LENGTH_UNITS[u]
            for k, u, a in zip(layout.xyz, units, "xyz", strict=True)
        ]
    )
    for c, k in enumerate(layout.xyz):
        table.in_range(k, xyz[:, c], table.header[k], -MAX_COORDINATE_M, MAX_COORDINATE_M, "m")
    names = None
    if layout.name:
        columns = [table.texts(k) for k in layout.name]
        names = ["::".join(parts) for parts in zip(*columns, strict=True)]
    src = Source(table.path, list(table.lines), names, xyz, notes=list(layout.notes))
    src.length_read = (units[0], where)
    src.named_by_option = opts.name_column is not None and table.find(opts.name_column) is not None
    if layout.u95 is not None and not opts.no_u95:
        sd = _u95_sigma(table, layout, units[0], where, opts)
        src.cov = np.zeros((len(sd), 6))
        src.cov[:, 0], src.cov[:, 3], src.cov[:, 5] = sd[:, 0] ** 2, sd[:, 1] ** 2, sd[:, 2] ** 2
        kind = layout.u95[0]
        read = "sigma_columns" if kind in ("std", "std3d") else "u95_columns"
        read_columns = ", ".join(table.header[k] for k in layout.u95[1])
        src.provenance[read] = read_columns
        src.provenance["uncertainty"] = UNCERTAINTY_KINDS[kind][1]
        src.notes.append(
            f"{table.path}: each point's σ was read from {read_columns} "
            f"({UNCERTAINTY_KINDS[kind][1]}) into its covariance."
        )
    elif opts.format == "leica" and not opts.no_u95:
        raise ConversionError(
            table.path,
            "has no U95 column (U95, U(95), or U95 X, U95 Y, U95 Z, with a unit or not; or an "
            "uncertainty per axis: unc X…, std x…, sigma_x…); its "
            f"columns are {', '.join(table.header)}; export the U95, or import it without "
            "with --no-u95 (or --format csv).",
        )
    if layout.unread and not opts.no_u95:
        unread = ", ".join(table.header[k] for k in layout.unread)
        read_from = src.provenance.get("sigma_columns") or src.provenance.get("u95_columns")
        src.warnings.append(
            f"{table.path}: the uncertainty column(s) {unread} were left out: dhlog reads "
            "one set of the position's uncertainty (U95 X/Y/Z, a 3-D U95, or σ: unc X…, "
            "std x…, sigma_x…, a 3-D unc) into each sample's covariance"
            f"{f', here {read_from}' if read_from else ' (none was read)'}; an orientation's σ "
            "is not carried (its noise is estimated from the data, or the pipeline's [noise] "
            "orientation)."
        )
    if layout.orientation is not None:
        src.quat, how = _orientation(table, layout, opts, src)
        src.provenance["orientation"] = "true"
        src.provenance["orientation_columns"] = how
    if layout.time is not None:
        src.t_ns = _times(table, layout.time, opts)
    if own_joints:
        if not layout.joints:
            raise ConversionError(
                table.path,
                "has no joint columns (q1…, j1…, A1…, joint_1…, axis1…); its columns are "
                f"{', '.join(table.header)}; name them with --joint-columns, or give the "
                "joint values in a file with --joints-file.",
            )
        src.joint_names, src.q = joint_values(table, layout.joints, opts, src.warnings)
    else:
        own = [
            h.text
            for k, h in enumerate(table.heads)
            if k not in layout.recognised and JOINT_HEADER.match(h.key)
        ]
        if own:
            src.notes.append(
                f"{table.path}: its joint columns ({', '.join(own)}) were left out: the joints "
                "come from --joints-file."
            )
    return src
