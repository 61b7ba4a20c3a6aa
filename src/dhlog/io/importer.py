"""``dhlog import``: measurement exports (CSV, SpatialAnalyzer, Leica Tracker Pilot) to an MCAP
log that ``dhlog process`` reads with the shipped ``ros2_tracker`` pipeline.

Three sources:

* ``csv``: a generic table of target positions and joint values, one row per sample (columns
  named by options, units declared), with a time column, or without one as one stop per row
  (step and measure).
* ``spatialanalyzer``: a SpatialAnalyzer-style ASCII export of named points (``name x y z`` or
  ``collection, group, point, x, y, z``) and a joint-value CSV whose rows name the point measured
  at those joint values; the joints file's order is the measurement order.
* ``leica``: a Leica-Tracker-Pilot-style CSV of named points with per-point U95 columns (one 3D
  ``U95`` or ``U95 X/Y/Z``), kept as each sample's covariance; joint values in its own columns or
  in a joints CSV matched by point name.

The log is written as rosbag2 would (profile ``ros2``, CDR): the target on ``/tracker/point``
(``geometry_msgs/msg/PointStamped``, or ``PoseWithCovarianceStamped`` with the uncertainties),
the joints on ``/joint_states`` (``sensor_msgs/msg/JointState``, SI units), with the conversion's
provenance in an MCAP metadata record ``dhlog.import``. Discrete points become stops: 2 s per
point, the joint states at 20 Hz holding the point's joint values, the target measured in the
middle — as a step-and-measure cell logs them.

U95 to σ: a per-coordinate U95 is 1.96 σ; a single (3D) U95 is the radius of the 95 % sphere
of an isotropic normal distribution, 2.796 σ (√χ²₃(0.95)).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dhlog.dh import JointType
from dhlog.errors import InputError
from dhlog.io import ros2

FORMATS = ("csv", "spatialanalyzer", "leica")
#: σ = U95 / this, per coordinate (1.96) or from a 3D radius (√χ²₃(0.95)).
U95_PER_COORDINATE = 1.959963984540054
U95_SPHERE = 2.7954834829151074
#: A stop's length and its encoder rate (s, Hz), the target measured in its middle.
STOP_SECONDS, STOP_RATE = 2.0, 20.0
#: The first stop's time (ns): 2020-01-01, so that stamps look like a real clock's.
EPOCH_NS = 1_577_836_800_000_000_000
TIME_UNITS = {"s": 1e9, "ms": 1e6, "us": 1e3, "ns": 1.0}
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "gon": math.pi / 200.0}
_JOINT_COLUMN = re.compile(r"^(q|j|a|joint|axis)[ _]?(\d+)(\s*[\[(].*[\])])?$", re.IGNORECASE)
_UNIT_IN_HEADER = re.compile(r"\s*[\[(]\s*([^\])]*)\s*[\])]\s*$")


class ConversionError(InputError):
    """A source file that cannot be converted, with the file and line at fault."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        where = f"{path}" if line is None else f"{path}, line {line}"
        super().__init__(f"{where}: {message}")


@dataclass
class ImportOptions:
    """How to read the source: column names, units, joint types (see ``dhlog import --help``)."""

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
    length_unit: str = "mm"
    angle_unit: str = "deg"


@dataclass
class Imported:
    """A converted source in SI units: target stamps and positions (with each sample's 3×3
    covariance columns ``cxx, cxy, cxz, cyy, cyz, czz`` in m² when known), the joint stream, and
    the provenance written into the log."""

    point_t_ns: NDArray[np.int64]
    xyz: NDArray[np.float64]
    covariance: NDArray[np.float64] | None
    joint_names: list[str]
    joint_t_ns: NDArray[np.int64]
    joint_q: NDArray[np.float64]
    stepped: bool
    provenance: dict[str, str]
    warnings: list[str] = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# text tables


@dataclass
class _Table:
    """A delimited text table: header names, rows of strings and each row's line number."""

    path: str
    header: list[str]
    rows: list[list[str]]
    lines: list[int]
    sep: str = ","

    def column(self, name: str, what: str) -> int:
        """The index of the column called ``name`` (case, spaces and a trailing unit ignored)."""
        want = _plain(name)
        for k, h in enumerate(self.header):
            if _plain(h) == want:
                return k
        raise ConversionError(
            self.path,
            f"no column '{name}' for {what}; its columns are {', '.join(self.header)} "
            "(name the right one with the options of dhlog import).",
        )

    def numbers(self, k: int, what: str) -> NDArray[np.float64]:
        """Column ``k`` as numbers (converted in one numpy call; only when that fails or meets
        a non-finite value are the rows walked, to name the first bad one's line)."""
        texts = self.texts(k)
        if self.sep == ";":  # decimal commas
            texts = [t.replace(",", ".") for t in texts]
        try:
            out = np.asarray(texts, dtype=np.float64)
            if np.all(np.isfinite(out)):
                return out
        except ValueError:
            pass
        out = np.empty(len(texts))
        for i, text in enumerate(texts):
            try:
                out[i] = float(text)
            except ValueError:
                raise ConversionError(
                    self.path, f"{what} '{text}' is not a number.", self.lines[i]
                ) from None
            if not math.isfinite(out[i]):
                raise ConversionError(self.path, f"{what} '{text}' is not finite.", self.lines[i])
        return out

    def texts(self, k: int) -> list[str]:
        return [row[k].strip() if k < len(row) else "" for row in self.rows]


def _plain(header: str) -> str:
    return _UNIT_IN_HEADER.sub("", header).strip().lower().replace(" ", "").replace("_", "")


def _unit_of(header: str) -> str | None:
    m = _UNIT_IN_HEADER.search(header)
    return m.group(1).strip().lower() if m else None


def _read_text(path: str | Path) -> str:
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ConversionError(path, f"cannot be read ({exc.strerror}).") from None
    for encoding in ("utf-8-sig", "cp1252"):
        try:
            return data.decode(encoding)
        except UnicodeDecodeError:
            continue
    raise ConversionError(path, "is not text.")  # pragma: no cover - cp1252 decodes nearly all


def read_table(path: str | Path, *, header: bool = True) -> _Table:
    """A CSV (``,``), semicolon (``;``, decimal commas allowed) or tab-separated table; blank
    lines and lines starting with ``#`` or ``//`` are skipped."""
    text = _read_text(path)
    numbered = [
        (i + 1, line)
        for i, line in enumerate(text.splitlines())
        if line.strip() and not line.lstrip().startswith(("#", "//"))
    ]
    if not numbered:
        raise ConversionError(path, "holds no rows.")
    first = numbered[0][1]
    sep = "\t" if "\t" in first else ";" if first.count(";") > first.count(",") else ","
    parsed = list(csv.reader(io.StringIO("\n".join(line for _, line in numbered)), delimiter=sep))
    if len(parsed) != len(numbered):
        raise ConversionError(path, "has a quoted field across lines; export it without them.")
    names = [h.strip() for h in parsed[0]] if header else [str(k) for k in range(len(parsed[0]))]
    body, lines = (
        (parsed[1:], [n for n, _ in numbered[1:]]) if header else (parsed, [n for n, _ in numbered])
    )
    for row, line in zip(body, lines, strict=True):
        if len(row) < len(names) and any(c.strip() for c in row):
            raise ConversionError(path, f"has {len(row)} field(s), the header {len(names)}.", line)
    table = _Table(str(path), names, body, lines, sep)
    if not body:
        raise ConversionError(path, "has a header but no rows.")
    return table


# ---------------------------------------------------------------------------------------------
# the joints


def _joint_columns(table: _Table, opts: ImportOptions) -> list[int]:
    if opts.joint_columns:
        return [table.column(c, "a joint") for c in opts.joint_columns]
    found = [k for k, h in enumerate(table.header) if _JOINT_COLUMN.match(h.strip())]
    if not found:
        raise ConversionError(
            table.path,
            "has no joint columns (q1…, j1…, a1…, joint_1…, axis1…); name them with "
            "--joint-columns.",
        )
    return found


def _joint_values(
    table: _Table, columns: list[int], opts: ImportOptions
) -> tuple[list[str], NDArray[np.float64], list[JointType]]:
    """Joint names, values in SI units (rad, m) and types."""
    n = len(columns)
    names = opts.joint_names or [_UNIT_IN_HEADER.sub("", table.header[k]).strip() for k in columns]
    if len(names) != n:
        raise ConversionError(table.path, f"--joint-names gives {len(names)} names for {n} joints.")
    try:
        types = [JointType.parse(t) for t in opts.joint_types] or [JointType.REVOLUTE] * n
    except ValueError as exc:
        raise ConversionError(table.path, f"--joint-types: {exc}") from None
    if len(types) != n:
        raise ConversionError(table.path, f"--joint-types gives {len(types)} types for {n} joints.")
    q = np.column_stack([table.numbers(k, f"joint {names[j]}") for j, k in enumerate(columns)])
    for j, t in enumerate(types):
        q[:, j] *= (
            LENGTH_UNITS[opts.length_unit]
            if t is JointType.PRISMATIC
            else ANGLE_UNITS[opts.angle_unit]
        )
    return names, q, types


# ---------------------------------------------------------------------------------------------
# the sources


def _points(table: _Table, opts: ImportOptions) -> NDArray[np.float64]:
    cols = [
        table.column(c, f"the target's {a}")
        for c, a in zip((opts.x, opts.y, opts.z), "xyz", strict=True)
    ]
    xyz = np.column_stack([table.numbers(k, table.header[k]) for k in cols])
    return xyz * LENGTH_UNITS[opts.length_unit]


def _from_csv(path: Path, opts: ImportOptions) -> dict[str, Any]:
    table = read_table(path)
    names, q, _ = _joint_values(table, _joint_columns(table, opts), opts)
    out: dict[str, Any] = {"xyz": _points(table, opts), "names": names, "q": q}
    if opts.time:
        k = table.column(opts.time, "the time")
        with np.errstate(over="ignore"):  # an absurd value becomes inf, refused below
            t = table.numbers(k, "time") * TIME_UNITS[opts.time_unit]
        step = np.diff(t)
        bad = np.flatnonzero(step <= 0)
        if bad.size:
            raise ConversionError(
                path, "time does not increase; sort the export by time.", table.lines[bad[0] + 1]
            )
        if not t[-1] - t[0] <= 1e15:  # over 11 days (or infinite): the wrong unit
            raise ConversionError(
                path,
                f"the time column spans {(t[-1] - t[0]) / 86.4e12:.3g} days; check --time-unit.",
            )
        out["t_ns"] = np.round(t - t[0]).astype(np.int64) + EPOCH_NS
    return out


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def read_spatialanalyzer(
    path: str | Path, length_unit: str
) -> tuple[list[str], NDArray[np.float64]]:
    """Named points of a SpatialAnalyzer-style ASCII export: per line a name (``A::B::C``, or
    collection, group and point as separate fields) and x, y, z as the last three fields,
    separated by commas, semicolons, tabs or spaces; a header line is skipped."""
    names, xyz = [], []
    for i, line in enumerate(_read_text(path).splitlines()):
        text = line.strip()
        if not text or text.startswith(("#", "//")):
            continue
        fields = [
            f.strip() for f in re.split(r"[,;\t]" if re.search(r"[,;\t]", text) else r"\s+", text)
        ]
        fields = [f for f in fields if f]
        numeric = [bool(_NUMBER.match(f)) for f in fields]
        if len(fields) >= 4 and all(numeric[-3:]) and not all(numeric):
            names.append("::".join(fields[:-3]))
            xyz.append([float(v) for v in fields[-3:]])
        elif not names and not any(numeric):
            continue  # a header
        else:
            raise ConversionError(path, "is not 'name x y z' (a name, then three numbers).", i + 1)
    if not names:
        raise ConversionError(path, "holds no points.")
    return names, np.asarray(xyz) * LENGTH_UNITS[length_unit]


def _match_by_name(
    point_names: list[str],
    xyz: NDArray[np.float64],
    joints: _Table,
    opts: ImportOptions,
    covariance: NDArray[np.float64] | None,
    source: Path,
) -> dict[str, Any]:
    """The points measured at each row of the joints file (in its order), matched by name: the
    full name or its last ``::`` part."""
    k = joints.column(opts.name_column, "the point name") if opts.name_column else 0
    wanted = joints.texts(k)
    by_name: dict[str, int] = {}
    for i, name in enumerate(point_names):
        for key in {name, name.split("::")[-1]}:
            if key in by_name and by_name[key] != i and key == name:
                raise ConversionError(source, f"names the point '{name}' twice.")
            by_name.setdefault(key, i)
    cols = [c for c in _joint_columns(joints, opts) if c != k]
    names, q, _ = _joint_values(joints, cols, opts)
    rows, missing = [], []
    for r, name in enumerate(wanted):
        if name in by_name:
            rows.append((r, by_name[name]))
        else:
            missing.append((joints.lines[r], name))
    warnings = []
    if missing:
        line, name = missing[0]
        warnings.append(
            f"{joints.path}: {len(missing)} row(s) name a point that {source.name} does not hold "
            f"(first: '{name}', line {line}); they were left out."
        )
    unused = len(point_names) - len({p for _, p in rows})
    if unused:
        warnings.append(
            f"{source}: {unused} point(s) have no joint values in {joints.path} and were left out."
        )
    if not rows:
        raise ConversionError(joints.path, f"names none of the points of {source.name}.")
    r_idx = np.array([r for r, _ in rows])
    p_idx = np.array([p for _, p in rows])
    return {
        "xyz": xyz[p_idx],
        "names": names,
        "q": q[r_idx],
        "cov": None if covariance is None else covariance[p_idx],
        "warnings": warnings,
    }


def _leica(path: Path, opts: ImportOptions) -> dict[str, Any]:
    """Named points with U95 columns; joints in the same file or matched by name."""
    table = read_table(path)
    plain = [_plain(h) for h in table.header]
    name_k = next(
        (k for k, h in enumerate(plain) if h in ("name", "pointname", "pointid", "point", "id")),
        None,
    )
    if opts.name_column:
        name_k = table.column(opts.name_column, "the point name")
    unit = opts.length_unit
    header_units = {
        _unit_of(table.header[table.column(c, a)])
        for c, a in zip((opts.x, opts.y, opts.z), "xyz", strict=True)
    }
    header_units.discard(None)
    if len(header_units) == 1:
        unit = next(iter(header_units))  # type: ignore[assignment]
        if unit not in LENGTH_UNITS:
            raise ConversionError(
                path, f"states the unit '{unit}' for x, y, z; dhlog reads m or mm."
            )
    xyz = _points(table, dataclasses.replace(opts, length_unit=unit))
    u95_cols = {
        axis: next((k for k, h in enumerate(plain) if h == f"u95{axis}"), None) for axis in "xyz"
    }
    single = next((k for k, h in enumerate(plain) if h == "u95"), None)
    scale = LENGTH_UNITS[unit]
    if all(k is not None for k in u95_cols.values()):
        sd = np.column_stack(
            [table.numbers(k, f"U95 {a}") for a, k in u95_cols.items() if k is not None]
        ) * (scale / U95_PER_COORDINATE)
    elif single is not None:
        sd = np.repeat(table.numbers(single, "U95")[:, None], 3, axis=1) * (scale / U95_SPHERE)
    else:
        raise ConversionError(
            path, "has no U95 column (U95, or U95 X, U95 Y, U95 Z); use --format csv for it."
        )
    if np.any(sd <= 0):
        line = table.lines[int(np.flatnonzero(np.any(sd <= 0, axis=1))[0])]
        raise ConversionError(path, "U95 must be positive.", line)
    cov = np.zeros((len(sd), 6))
    cov[:, 0], cov[:, 3], cov[:, 5] = sd[:, 0] ** 2, sd[:, 1] ** 2, sd[:, 2] ** 2
    if opts.joints_file is None:
        names, q, _ = _joint_values(table, _joint_columns(table, opts), opts)
        return {"xyz": xyz, "names": names, "q": q, "cov": cov}
    if name_k is None:
        raise ConversionError(path, "has no point name column (Name, Point ID); name it.")
    point_names = table.texts(name_k)
    return _match_by_name(point_names, xyz, read_table(opts.joints_file), opts, cov, path)


def import_source(source: str | Path, opts: ImportOptions) -> Imported:
    """Read ``source`` (and ``opts.joints_file``) as ``opts.format`` into SI samples."""
    path = Path(source)
    if opts.format not in FORMATS:
        raise InputError(f"--format must be one of {', '.join(FORMATS)}, not '{opts.format}'.")
    for what, value, known in (
        ("--length-unit", opts.length_unit, LENGTH_UNITS),
        ("--angle-unit", opts.angle_unit, ANGLE_UNITS),
        ("--time-unit", opts.time_unit, TIME_UNITS),
    ):
        if value not in known:
            raise InputError(f"{what} must be one of {', '.join(known)}, not '{value}'.")
    if opts.format == "csv":
        got = _from_csv(path, opts)
    elif opts.format == "spatialanalyzer":
        if opts.joints_file is None:
            raise InputError(
                f"{path}: a SpatialAnalyzer export holds no joint values; give the joints CSV "
                "with --joints-file."
            )
        names, xyz = read_spatialanalyzer(path, opts.length_unit)
        got = _match_by_name(names, xyz, read_table(opts.joints_file), opts, None, path)
    else:
        got = _leica(path, opts)
    xyz, q = got["xyz"], got["q"]
    if "t_ns" in got:
        t = got["t_ns"]
        point_t, joint_t, joint_q, stepped = t, t, q, False
    else:
        m = len(xyz)
        start = EPOCH_NS + np.round(np.arange(m) * STOP_SECONDS * 1e9).astype(np.int64)
        point_t = start + int(STOP_SECONDS * 1e9 / 2)
        per_stop = int(STOP_SECONDS * STOP_RATE)
        offsets = np.round(np.arange(per_stop) * 1e9 / STOP_RATE).astype(np.int64)
        joint_t = (start[:, None] + offsets[None, :]).reshape(-1)
        joint_q = np.repeat(q, per_stop, axis=0)
        stepped = True
    provenance = {
        "source": str(path.resolve()),
        "source_sha256": _sha256(path),
        "format": opts.format,
        "options": json.dumps(
            {k: (str(v) if isinstance(v, Path) else v) for k, v in opts.__dict__.items()}
        ),
        "samples": str(len(xyz)),
        "timing": "step and measure: one stop per point, 2 s apart"
        if stepped
        else "from the source",
    }
    if opts.joints_file is not None:
        provenance["joints_file"] = str(Path(opts.joints_file).resolve())
        provenance["joints_file_sha256"] = _sha256(Path(opts.joints_file))
    return Imported(
        np.asarray(point_t, dtype=np.int64),
        np.asarray(xyz, dtype=np.float64),
        got.get("cov"),
        list(got["names"]),
        np.asarray(joint_t, dtype=np.int64),
        np.asarray(joint_q, dtype=np.float64),
        stepped,
        provenance,
        list(got.get("warnings", [])),
    )


def _sha256(path: Path) -> str:
    from dhlog.io.writer import sha256_of

    return sha256_of(path)


def write_imported(imported: Imported, out: str | Path) -> None:
    """Write ``imported`` as a ROS 2 MCAP log (atomically), with its provenance."""
    from mcap.writer import CompressionType, Writer

    from dhlog import __version__
    from dhlog.io.writer import atomic_output

    with_cov = imported.covariance is not None
    point_schema = ros2.POSE_WITH_COVARIANCE if with_cov else ros2.POINT_STAMPED
    if with_cov:
        assert imported.covariance is not None
        points = ros2.encode_pose_with_covariance(
            imported.point_t_ns, imported.xyz, "tracker", imported.covariance
        )
    else:
        points = ros2.encode_point_stamped(imported.point_t_ns, imported.xyz, "tracker")
    joints = ros2.encode_joint_state(imported.joint_t_ns, imported.joint_names, imported.joint_q)
    events = [(int(t), 0, k) for k, t in enumerate(imported.point_t_ns.tolist())]
    events += [(int(t), 1, k) for k, t in enumerate(imported.joint_t_ns.tolist())]
    events.sort()
    with atomic_output(out) as f:
        writer = Writer(f, compression=CompressionType.ZSTD, enable_crcs=False)
        writer.start(profile="ros2", library=f"dhlog import {__version__}")
        pid = writer.register_schema(point_schema, "ros2msg", ros2.MSGDEFS[point_schema].encode())
        jid = writer.register_schema(
            ros2.JOINT_STATE, "ros2msg", ros2.MSGDEFS[ros2.JOINT_STATE].encode()
        )
        channels = (
            writer.register_channel("/tracker/point", "cdr", pid),
            writer.register_channel("/joint_states", "cdr", jid),
        )
        payloads = (points, joints)
        for t, stream, k in events:
            writer.add_message(channels[stream], t, payloads[stream][k], t)
        writer.add_metadata("dhlog.import", {**imported.provenance, "dhlog": __version__})
        writer.finish()  # type: ignore[no-untyped-call]
