"""``dhlog import``: measurement exports (CSV, SpatialAnalyzer, Leica Tracker Pilot) to an MCAP
log that ``dhlog process`` reads with the shipped ``ros2_tracker`` pipeline.

Three sources, one reading of their header (:func:`parse_header`):

* ``csv``: a table of target positions and joint values, one row per sample, with a time column
  (``--time``) or without one as one stop per row (step and measure).
* ``spatialanalyzer``: a SpatialAnalyzer export of named points — a table with a header (read as
  the other two), or the ASCII point list ``name x y z`` / ``collection, group, point, x, y, z``
  — with the joint values in a joints CSV (``--joints-file``).
* ``leica``: a Tracker-Pilot-style CSV of named points with per-point U95 columns (a 3D ``U95``,
  ``U(95)``, or ``U95 X/Y/Z``), kept as each sample's covariance.

Every format reads the same columns by what the header says they are: the point name, x, y, z,
U95, the orientation of a 6-DoF target (quaternion ``Q0 Q1 Q2 Q3`` scalar first as Leica writes
it, ``Qw Qx Qy Qz`` in any order, or rotation angles ``Rx Ry Rz`` about the fixed axes X, then Y,
then Z unless ``--euler`` says otherwise), the time, and the joints (``q1…``, ``j1…``, ``A1…``,
``joint_1…``, ``axis1…``; or ``--joint-columns``). A unit in a header (``X [mm]``, ``X (mm)``,
``X[mm]``, ``RX [deg]``) is used, and an error when it contradicts the option given. The joints
come from the source's own columns or from a joints file matched by point name or by row. A
column the header names (orientation, U95, time) is never taken as a joint.

The log is written as rosbag2 would (profile ``ros2``, CDR): the target on ``/tracker/point``
(``geometry_msgs/msg/PointStamped``; ``PoseStamped`` with the orientation;
``PoseWithCovarianceStamped`` with the uncertainties, its pose holding the orientation when
there is one), the joints on ``/joint_states`` (``sensor_msgs/msg/JointState``, SI units), with
the conversion's provenance in an MCAP metadata record ``dhlog.import`` — whose ``orientation =
true`` makes :func:`dhlog.io.reader.read_log` read the orientation without a pipeline saying so.
Discrete points become stops: 2 s per point, the target measured in the middle, three joint
states holding the point's joint values — at the stop's start, at the measurement and at its end
one 20 Hz period before the next stop: what the segmentation sees of a step-and-measure cell's
20 Hz stream (the motion between two stops, the stillness around the measurement) in 3 messages
a stop instead of 40, so that 200 000 stops write in seconds.

U95 to σ: a per-coordinate U95 is 1.96 σ; a single (3D) U95 is the radius of the 95 % sphere
of an isotropic normal distribution, 2.796 σ (√χ²₃(0.95)). A U95 the export rounded to 0 is
floored at the export's resolution (the last decimal written), and said in a note.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError
from dhlog.io import ros2
from dhlog.model.dh import JointType

FORMATS = ("csv", "spatialanalyzer", "leica")
#: σ = U95 / this, per coordinate (1.96) or from a 3D radius (√χ²₃(0.95)).
U95_PER_COORDINATE = 1.959963984540054
U95_SPHERE = 2.7954834829151074
#: A stop's length and its encoder rate (s, Hz), the target measured in its middle.
STOP_SECONDS, STOP_RATE = 2.0, 20.0
#: When in a stop its joint states are written (s): its start, the measurement, its end.
STOP_JOINT_TIMES = (0.0, STOP_SECONDS / 2, STOP_SECONDS - 1.0 / STOP_RATE)
#: The first stop's time (ns): 2020-01-01, so that stamps look like a real clock's.
EPOCH_NS = 1_577_836_800_000_000_000
TIME_UNITS = {"s": 1e9, "ms": 1e6, "us": 1e3, "ns": 1.0}
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "in": 0.0254}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0, "gon": math.pi / 200.0}
#: Defaults when neither the header nor an option gives the unit.
DEFAULT_LENGTH_UNIT, DEFAULT_ANGLE_UNIT = "mm", "deg"
#: How units are spelled in headers and options, to the names above.
UNIT_SPELLINGS = {
    **dict.fromkeys(("m", "meter", "metre", "meters", "metres"), "m"),
    **dict.fromkeys(("mm", "millimeter", "millimetre", "millimeters", "millimetres"), "mm"),
    **dict.fromkeys(("um", "µm", "μm", "micron", "microns", "micrometer", "micrometre"), "um"),
    **dict.fromkeys(("in", "inch", "inches", '"'), "in"),
    **dict.fromkeys(("rad", "radian", "radians"), "rad"),
    **dict.fromkeys(("deg", "°", "º", "degree", "degrees"), "deg"),
    **dict.fromkeys(("gon", "grad", "gons"), "gon"),
}
#: Header units that say "no unit" (a quaternion's).
DIMENSIONLESS = ("", "-", "1")
#: Orientation columns by their (normalised) header: quaternions, scalar first, and rotation
#: angles (X, Y, Z).
QUATERNION_HEADERS = (("qw", "qx", "qy", "qz"), ("q0", "q1", "q2", "q3"))
ANGLE_HEADERS = (
    ("rx", "ry", "rz"),
    ("rotx", "roty", "rotz"),
    ("rotationx", "rotationy", "rotationz"),
)
#: The default sequence of rotation angles: about the fixed (measurement) axes X, then Y, then Z,
#: R = Rz(rz)·Ry(ry)·Rx(rx) (scipy's ``"xyz"``; upper case would be moving axes).
EULER_DEFAULT = "xyz"
#: A quaternion is normalised when its norm is this close to 1, else refused.
QUATERNION_TOLERANCE = 1e-3
#: Point-name columns by their (normalised) header, in order of preference.
NAME_HEADERS = ("pointname", "name", "pointid", "point", "id", "ptid", "target", "label")
_JOINT_HEADER = re.compile(r"^(?:q|j|a|joint|axis)(\d{1,3})$")
_TRAILING_BRACKET = re.compile(r"^(?P<name>.*?)\s*[\[({]\s*(?P<unit>[^\[\](){}]*?)\s*[\])}]\s*$")
#: A unit after the name without brackets: ``X_m``, ``X/mm``, ``A1 deg``, ``X in m``.
_SUFFIX_UNIT = re.compile(r"^(?P<name>.*?\S)(?:\s*[_/]\s*|\s+in\s+|\s+)(?P<unit>[^\s_/]+)$")
#: The largest file ``dhlog import`` reads (bytes): a few hundred thousand rows of a table.
MAX_TABLE_BYTES = 128 * 2**20
#: The ranges of the values read, in SI units: a coordinate (m, any axis), a revolute joint
#: value or rotation angle (rad), a prismatic joint value (m), a U95 (m).
MAX_COORDINATE_M = 1000.0
MAX_ANGLE_RAD = 1000.0
MAX_TRAVEL_M = 1000.0
U95_RANGE_M = (1e-9, 1.0)
_KEY_DROPS = re.compile(r"[\s_\-.()\[\]/]")


class ConversionError(InputError):
    """A source file that cannot be converted, with the file and line at fault."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        where = f"{path}" if line is None else f"{path}, line {line}"
        super().__init__(f"{where}: {message}")


@dataclass
class ImportOptions:
    """How to read the source: column names, units, joint types (see ``dhlog import --help``).

    ``length_unit`` and ``angle_unit`` are None when not given: the header's unit, else mm and
    degrees. ``orientation_columns``: four (a quaternion, scalar first) or three (rotation angles
    in the ``euler`` sequence) columns, ``["none"]`` to leave the orientation out, or empty to
    recognise it from the header."""

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
    orientation_columns: list[str] = field(default_factory=list)
    euler: str = EULER_DEFAULT
    no_u95: bool = False


@dataclass
class Imported:
    """A converted source in SI units: target stamps and positions (with each sample's 3×3
    covariance columns ``cxx, cxy, cxz, cyy, cyz, czz`` in m² when known, and the target frame's
    orientation as unit quaternions ``x, y, z, w`` when measured), the joint stream, and the
    provenance written into the log; ``notes`` say what was done to the values."""

    point_t_ns: NDArray[np.int64]
    xyz: NDArray[np.float64]
    covariance: NDArray[np.float64] | None
    joint_names: list[str]
    joint_t_ns: NDArray[np.int64]
    joint_q: NDArray[np.float64]
    stepped: bool
    provenance: dict[str, str]
    warnings: list[str] = field(default_factory=list)
    orientation: NDArray[np.float64] | None = None
    notes: list[str] = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# headers and text tables


@dataclass(frozen=True)
class Header:
    """One column header: as written, its key (lower case, without spaces, ``_ - . ( ) [ ] /``
    and without its unit) and the unit in its trailing brackets, if any (``X [mm]`` → ``x``,
    ``mm``; ``U(95)  [mm]`` → ``u95``, ``mm``; ``U(95)`` → ``u95``, no unit)."""

    text: str
    key: str
    unit: str | None


def parse_header(text: str) -> Header:
    """The :class:`Header` of a column header; a bracket holding a number (``U(95)``) is part
    of the name, any other trailing bracket is the unit."""
    name, unit = text.strip(), None
    m = _TRAILING_BRACKET.match(name)
    if m and not re.fullmatch(r"[\d.,]+", m["unit"]):
        name, unit = m["name"], m["unit"].strip().lower() or None
    elif (s := _SUFFIX_UNIT.match(name)) and s["unit"].lower() in UNIT_SPELLINGS:
        name, unit = s["name"], s["unit"].lower()
    return Header(text.strip(), _KEY_DROPS.sub("", name.lower()), unit)


@dataclass
class _Table:
    """A delimited text table: header names, rows of strings and each row's line number."""

    path: str
    header: list[str]
    rows: list[list[str]]
    lines: list[int]
    sep: str = ","
    heads: list[Header] = field(init=False)

    def __post_init__(self) -> None:
        self.heads = [parse_header(h) for h in self.header]

    def find(self, name: str) -> int | None:
        """The index of the column called ``name`` (as written, or by its key), or None; two
        columns of that name are refused (which would be read?)."""
        exact = [k for k, h in enumerate(self.header) if h.strip() == name.strip()]
        if exact:
            return self._one(exact)
        want = parse_header(name).key
        return self._one([k for k, h in enumerate(self.heads) if h.key == want])

    def key(self, *keys: str) -> int | None:
        """The column whose key is the first of ``keys`` the header holds, or None."""
        for want in keys:
            found = [k for k, h in enumerate(self.heads) if h.key == want]
            if found:
                return self._one(found)
        return None

    def _one(self, found: list[int]) -> int | None:
        if len(found) > 1:
            shown = " and ".join(f"'{self.header[k]}' (column {k + 1})" for k in found[:2])
            raise ConversionError(
                self.path,
                f"has two columns that read alike, {shown}; rename or drop one of them (or "
                "name the one to read with its option).",
            )
        return found[0] if found else None

    def column(self, name: str, what: str, option: str) -> int:
        """The index of the column called ``name``; the error names the option to fix it."""
        k = self.find(name)
        if k is None:
            raise ConversionError(
                self.path,
                f"no column '{name}' for {what}; its columns are {', '.join(self.header)}; "
                f"name the right one with {option}.",
            )
        return k

    def numbers(self, k: int, what: str, hint: str) -> NDArray[np.float64]:
        """Column ``k`` as numbers (converted in one numpy call; only when that fails or meets
        a non-finite value are the rows walked, to name the first bad one's line). In a
        ``;``-separated table a decimal comma (``1,5``) is read as a decimal point when the
        column holds no decimal point and no value with two commas; anything else is refused."""
        texts = self.texts(k)
        if self.sep == ";" and any("," in t for t in texts):
            texts = self._decimal_commas(texts, what)
        try:
            out = np.asarray(texts, dtype=np.float64)
            if np.all(np.isfinite(out)):
                return out
        except (ValueError, OverflowError):
            pass
        out = np.empty(len(texts))
        for i, text in enumerate(texts):
            try:
                out[i] = float(text)
            except (ValueError, OverflowError):
                comma = (
                    " (a decimal comma: in a table separated by commas or tabs write decimal "
                    "points, or separate the fields with ';')"
                    if re.fullmatch(r"[+-]?\d+,\d+", text)
                    else ""
                )
                raise ConversionError(
                    self.path,
                    f"{what} '{_cut(text)}' is not a number{comma}; {hint}",
                    self.lines[i],
                ) from None
            if not math.isfinite(out[i]):
                raise ConversionError(
                    self.path, f"{what} '{_cut(text)}' is not finite; {hint}", self.lines[i]
                )
        return out

    def _decimal_commas(self, texts: list[str], what: str) -> list[str]:
        """``texts`` with decimal commas as points; a column that mixes decimal commas and
        points, or a value with a thousands separator, is refused (its line named)."""
        for i, text in enumerate(texts):
            if text.count(",") > 1 or ("," in text and "." in text):
                raise ConversionError(
                    self.path,
                    f"{what} '{_cut(text)}' holds a thousands separator or more than one decimal "
                    "mark; export the numbers without thousands separators.",
                    self.lines[i],
                )
        points = [i for i, t in enumerate(texts) if "." in t]
        if points:
            i = points[0]
            raise ConversionError(
                self.path,
                f"{what} mixes decimal commas and decimal points ('{_cut(texts[i])}' here); "
                "export every number with the same decimal mark.",
                self.lines[i],
            )
        return [t.replace(",", ".") for t in texts]

    def in_range(
        self, k: int, values: NDArray[np.float64], what: str, lo: float, hi: float, unit: str
    ) -> None:
        """Refuse the first of ``values`` (column ``k`` in SI units) outside ``[lo, hi]``."""
        bad = np.flatnonzero(~((values >= lo) & (values <= hi)))
        if bad.size:
            i = int(bad[0])
            raise ConversionError(
                self.path,
                f"{what} '{_cut(self.texts(k)[i])}' is out of range: dhlog reads {lo:g} to "
                f"{hi:g} {unit} there; check the value and the unit (in the header, X [mm], or "
                "--length-unit / --angle-unit).",
                self.lines[i],
            )

    def texts(self, k: int) -> list[str]:
        return [row[k].strip() if k < len(row) else "" for row in self.rows]

    def numeric(self, k: int) -> bool:
        """True when every value of column ``k`` reads as a number."""
        comma = self.sep == ";"
        try:
            np.asarray([t.replace(",", ".") if comma else t for t in self.texts(k)], np.float64)
        except (ValueError, OverflowError):
            return False
        return True


def _cut(text: str, size: int = 40) -> str:
    """``text`` cut to ``size`` characters for a message."""
    return text if len(text) <= size else text[: size - 1] + "…"


def _read_text(path: str | Path, option: str = "the source") -> str:
    """The text of an export: a regular file of at most :data:`MAX_TABLE_BYTES` (checked before
    reading, read with that cap), UTF-8, UTF-16 with a byte-order mark (spreadsheets' "Unicode
    text"), or else Windows-1252; NUL bytes refused."""
    from dhlog.io.textfile import line_of, read_capped

    def fail(problem: str) -> ConversionError:
        return ConversionError(path, problem)

    data = read_capped(
        path,
        MAX_TABLE_BYTES,
        fail,
        what=f"file for {option}" if option != "the source" else "tracker export",
        hint="split the export, or write the session as an MCAP log directly.",
        check=f"check the path of {option}.",
    )
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError as exc:
            raise ConversionError(
                path, f"is UTF-16 text with a bad byte at offset {exc.start}; export it again."
            ) from None
    nul = data.find(b"\x00")
    if nul >= 0:
        raise ConversionError(
            path,
            "holds a NUL byte: not a text export (UTF-16 without a byte-order mark, or binary); "
            f"export it as UTF-8 text, as {option}.",
            line_of(data, nul),
        )
    for encoding in ("utf-8-sig", "cp1252"):
        try:
            return data.decode(encoding)
        except UnicodeDecodeError:
            continue
    return data.decode("latin-1")  # cp1252 leaves five bytes undefined


def read_table(path: str | Path, *, header: bool = True, option: str = "the source") -> _Table:
    """A CSV (``,``), semicolon (``;``, decimal commas allowed) or tab-separated table; blank
    lines and lines starting with ``#`` or ``//`` are skipped. A row with more fields than the
    header (beyond empty ones) is refused, naming its line."""
    text = _read_text(path, option)
    numbered = [
        (i + 1, line)
        for i, line in enumerate(text.splitlines())
        if line.strip() and not line.lstrip().startswith(("#", "//"))
    ]
    if not numbered:
        raise ConversionError(
            path, f"holds no rows; give the export itself as {option} (see --format)."
        )
    first = numbered[0][1]
    sep = "\t" if "\t" in first else ";" if first.count(";") > first.count(",") else ","
    reader = csv.reader(io.StringIO("\n".join(line for _, line in numbered)), delimiter=sep)
    parsed: list[list[str]] = []
    try:
        for row in reader:
            parsed.append(row)
    except csv.Error as exc:
        at = min(max(reader.line_num, 1), len(numbered))
        raise ConversionError(
            path,
            f"cannot be read as a table ({exc}); export it as plain CSV (one row per line, "
            "fields separated by commas, semicolons or tabs).",
            numbered[at - 1][0],
        ) from None
    if len(parsed) != len(numbered):
        raise ConversionError(path, "has a quoted field across lines; export it without them.")
    names = [h.strip() for h in parsed[0]] if header else [str(k) for k in range(len(parsed[0]))]
    body, lines = (
        (parsed[1:], [n for n, _ in numbered[1:]]) if header else (parsed, [n for n, _ in numbered])
    )
    for row, line in zip(body, lines, strict=True):
        if len(row) < len(names) and any(c.strip() for c in row):
            raise ConversionError(
                path,
                f"has {len(row)} field(s), the header {len(names)}; check the separator "
                "(comma, semicolon or tab) and that --format fits the file.",
                line,
            )
        if len(row) > len(names) and any(c.strip() for c in row[len(names) :]):
            comma = (
                " — decimal commas in a comma-separated file? Export decimal points, or "
                "separate the fields with ';'"
                if sep == ","
                else ""
            )
            raise ConversionError(
                path,
                f"has {len(row)} fields, the header {len(names)}{comma}; every row must have "
                "the header's fields (check the separator and the export).",
                line,
            )
    table = _Table(str(path), names, body, lines, sep)
    if not body:
        raise ConversionError(path, "has a header but no rows; export the points too.")
    return table


def _resolution(texts: list[str]) -> float:
    """The smallest step the numbers are written with: 10⁻ᵈ for d decimals (``0.001`` for
    ``1.234``, ``1e-4`` for ``1.2e-3``), the finest over ``texts``."""
    finest = math.inf
    for text in texts:
        mantissa, _, exponent = text.strip().lower().replace(",", ".").partition("e")
        decimals = len(mantissa.partition(".")[2])
        try:
            shift = int(exponent) if exponent else 0
        except ValueError:
            continue
        finest = min(finest, 10.0 ** max(min(shift - decimals, 300), -300))
    return finest


# ---------------------------------------------------------------------------------------------
# units


def unit_name(text: str, kind: str) -> str:
    """A length (``kind="length"``) or angle unit as spelled in an option or a header, by its
    name in ``LENGTH_UNITS``/``ANGLE_UNITS``; ValueError for any other."""
    name = UNIT_SPELLINGS.get(text.strip().lower())
    known = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
    if name not in known:
        raise ValueError(text)
    return name


def _column_unit(table: _Table, k: int, kind: str, given: str | None, fallback: str) -> str:
    """The unit of column ``k``: its header's, else the option's (``given``), else ``fallback``;
    a header that contradicts the option is an error naming both."""
    option = "--length-unit" if kind == "length" else "--angle-unit"
    written = table.heads[k].unit
    if written is None or written in DIMENSIONLESS:
        return given or fallback
    try:
        unit = unit_name(written, kind)
    except ValueError:
        known = ", ".join(LENGTH_UNITS if kind == "length" else ANGLE_UNITS)
        raise ConversionError(
            table.path,
            f"the header '{table.header[k]}' states the unit '{written}'; dhlog reads {known} "
            f"there; correct the header (the unit in brackets), or drop the unit and give "
            f"{option}.",
        ) from None
    if given is not None and given != unit:
        raise ConversionError(
            table.path,
            f"the header '{table.header[k]}' states {unit} but {option} {given} was given; "
            f"leave {option} out (the header's unit is used) or correct the header.",
        )
    return unit


# ---------------------------------------------------------------------------------------------
# what each column is


@dataclass
class _Layout:
    """The columns of a table by what they hold (indices into its header)."""

    xyz: list[int]
    name: list[int]
    time: int | None
    u95: tuple[str, list[int]] | None  # ("axes", [x, y, z]) or ("sphere", [k])
    orientation: tuple[str, list[int]] | None  # ("quaternion", [w, x, y, z]) or ("angles", …)
    joints: list[int]
    recognised: dict[int, str]  # every column the header says is not a joint, and what it is
    notes: list[str] = field(default_factory=list)


def _without_unit(head: Header) -> str:
    """A header as written without its unit (``A1 [deg]``, ``A1_deg`` → ``A1``)."""
    if head.unit is None:
        return head.text
    m = _TRAILING_BRACKET.match(head.text) or _SUFFIX_UNIT.match(head.text)
    return m["name"].strip() if m else head.text


def _claim(table: _Table, claims: dict[int, str], k: int, option: str) -> None:
    """Column ``k`` taken by ``option``; a column that two options (or one option twice) name
    is refused."""
    if k in claims:
        other = claims[k]
        if other == option:
            raise ConversionError(
                table.path,
                f"{option} names the column '{table.header[k]}' twice; name each column once.",
            )
        raise ConversionError(
            table.path,
            f"{other} and {option} both name the column '{table.header[k]}'; give each its own "
            "column.",
        )
    claims[k] = option


def _joints_by_number(table: _Table, candidates: list[int], notes: list[str]) -> list[int]:
    """The joint columns the header names (``j2, j1, j3``), in the order of their numbers
    (``j1, j2, j3``, said in a note when it is not the header's); two columns for one joint, or
    a joint left out between others, are refused."""
    by_number: dict[int, int] = {}
    for k in candidates:
        m = _JOINT_HEADER.match(table.heads[k].key)
        assert m is not None
        number = int(m[1])
        if number in by_number:
            raise ConversionError(
                table.path,
                f"has two columns for joint {number}, '{table.header[by_number[number]]}' and "
                f"'{table.header[k]}'; name the joint columns in chain order with "
                "--joint-columns.",
            )
        by_number[number] = k
    if not by_number:
        return []
    numbers = sorted(by_number)
    missing = [n for n in range(numbers[0], numbers[-1] + 1) if n not in by_number]
    if missing:
        raise ConversionError(
            table.path,
            f"has joint columns {', '.join(table.header[by_number[n]] for n in numbers)} but none "
            f"for joint {missing[0]}; name the joint columns in chain order with --joint-columns.",
        )
    ordered = [by_number[n] for n in numbers]
    if ordered != candidates:
        notes.append(
            f"{table.path}: the joint columns were taken in the order of their numbers "
            f"({', '.join(table.header[k] for k in ordered)}), not the header's "
            f"({', '.join(table.header[k] for k in candidates)})."
        )
    return ordered


def _stated_alike(
    table: _Table, columns: list[int], kind: str, given: str | None, what: str
) -> None:
    """Refuse a header that states the unit of some of ``columns`` (``X [m]``) and not of the
    others (``Y``, ``Z``), when no option gives it: the others would be read in the default."""
    if given is not None:
        return
    stated = [k for k in columns if table.heads[k].unit not in (None, *DIMENSIONLESS)]
    for k in stated:  # a unit dhlog does not know is the error to give first
        _column_unit(table, k, kind, None, DEFAULT_LENGTH_UNIT)
    silent = [table.header[k] for k in columns if k not in stated]
    if stated and silent:
        option = "--length-unit" if kind == "length" else "--angle-unit"
        raise ConversionError(
            table.path,
            f"the header states the unit of '{table.header[stated[0]]}' but not of "
            f"{', '.join(repr(h) for h in silent)}; state it for every {what} (X [mm]), or give "
            f"{option}.",
        )


def _name_columns(table: _Table, opts: ImportOptions, *, required: bool) -> list[int]:
    """The point-name column(s): ``--name-column`` (which may name the joints file's instead,
    unless ``required``), else by the header (collection, group, point joined, or a name)."""
    if opts.name_column and (required or table.find(opts.name_column) is not None):
        return [table.column(opts.name_column, "the point name", "--name-column")]
    collection, group, point = table.key("collection"), table.key("group"), table.key("point")
    if point is not None and (collection is not None or group is not None):
        return [k for k in (collection, group, point) if k is not None]
    k = table.key(*NAME_HEADERS)
    return [] if k is None else [k]


def _orientation_columns(
    table: _Table, opts: ImportOptions, recognised: dict[int, str]
) -> tuple[str, list[int]] | None:
    """The orientation's columns (and ``recognised`` completed with every orientation set the
    header holds, used or not)."""
    found: list[tuple[str, list[int]]] = []
    for kind, sets in (("quaternion", QUATERNION_HEADERS), ("angles", ANGLE_HEADERS)):
        for keys in sets:
            hits = [table.key(key) for key in keys]
            if all(c is not None for c in hits):
                found.append((kind, [c for c in hits if c is not None]))
    # --joint-columns naming all of Q0…Q3: joints counted from 0, not a quaternion
    zero_based = set(QUATERNION_HEADERS[1]) <= {parse_header(c).key for c in opts.joint_columns}
    # Q0…Q3 beside Q4…: joints counted from 0, or a quaternion and more joints?
    leica = [f for f in found if [table.heads[c].key for c in f[1]] == list(QUATERNION_HEADERS[1])]
    if leica and not zero_based:
        more = [
            h.text
            for h in table.heads
            if (m := _JOINT_HEADER.match(h.key)) and h.key.startswith("q") and int(m[1]) >= 4
        ]
        if more and not opts.orientation_columns and not opts.joint_columns:
            raise ConversionError(
                table.path,
                f"has Q0…Q3 and {', '.join(more)}: a quaternion (Q0 scalar first, as Leica "
                "writes it) beside more joints, or joints counted from 0? Name the joints "
                "with --joint-columns, or the orientation with --orientation-columns "
                "(none to leave it out).",
            )
    if zero_based:
        found = [f for f in found if f not in leica]
    for _, used in found:
        for c in used:
            recognised.setdefault(c, "the orientation")
    if opts.orientation_columns:
        if [c.lower() for c in opts.orientation_columns] == ["none"]:
            return None
        cols = [
            table.column(c, "the orientation", "--orientation-columns")
            for c in opts.orientation_columns
        ]
        if len(cols) not in (3, 4):
            raise ConversionError(
                table.path,
                f"--orientation-columns names {len(cols)} column(s); give four (a quaternion, "
                "scalar first: w, x, y, z) or three (rotation angles, see --euler), or none.",
            )
        for c in cols:
            recognised[c] = "the orientation"
        return ("quaternion" if len(cols) == 4 else "angles", cols)
    return found[0] if found else None


def _layout(table: _Table, opts: ImportOptions, *, joints: bool) -> _Layout:
    """What each column of ``table`` holds; ``joints``: the joints are in this table. A column
    two options name (``--x X --y X``, ``--joint-columns A1,A1``) is refused."""
    recognised: dict[int, str] = {}
    claims: dict[int, str] = {}
    xyz = []
    for name, axis in zip((opts.x, opts.y, opts.z), "xyz", strict=True):
        k = table.column(name, f"the target's {axis}", f"--{axis}")
        _claim(table, claims, k, f"--{axis}")
        xyz.append(k)
        recognised[k] = f"the target's {axis}"
    time: int | None = None
    if opts.time:
        time = table.column(opts.time, "the time", "--time")
        _claim(table, claims, time, "--time")
        recognised[time] = "the time"
    names = _name_columns(table, opts, required=opts.joints_file is None)
    for k in names:
        _claim(table, claims, k, "--name-column" if opts.name_column else "the point name")
        recognised[k] = "the point name"
    axes = [table.key(f"u95{a}") for a in "xyz"]
    sphere = table.key("u95")
    u95: tuple[str, list[int]] | None = None
    if all(k is not None for k in axes):
        u95 = ("axes", [k for k in axes if k is not None])
    elif sphere is not None:
        u95 = ("sphere", [sphere])
    if u95 is not None and not opts.no_u95:
        for k in u95[1]:
            _claim(table, claims, k, f"the U95 '{table.header[k]}'")
    for u in [*axes, sphere]:
        if u is not None:
            recognised[u] = f"the U95 '{table.header[u]}'"
    orientation = _orientation_columns(table, opts, recognised)
    if orientation is not None:
        option = "--orientation-columns" if opts.orientation_columns else "the orientation"
        for k in orientation[1]:
            _claim(table, claims, k, option)
    cols: list[int] = []
    notes: list[str] = []
    if joints and opts.joint_columns:
        for c in opts.joint_columns:
            k = table.column(c, "a joint", "--joint-columns")
            if k in recognised:
                raise ConversionError(
                    table.path,
                    f"--joint-columns names '{table.header[k]}', which is "
                    f"{recognised[k]}, not a joint; name the joint columns only.",
                )
            _claim(table, claims, k, "--joint-columns")
            cols.append(k)
    elif joints:
        cols = _joints_by_number(
            table,
            [
                k
                for k, h in enumerate(table.heads)
                if k not in recognised and _JOINT_HEADER.match(h.key)
            ],
            notes,
        )
    return _Layout(xyz, names, time, u95, orientation, cols, recognised, notes)


# ---------------------------------------------------------------------------------------------
# values


def _joint_values(
    table: _Table, columns: list[int], opts: ImportOptions
) -> tuple[list[str], NDArray[np.float64]]:
    """Joint names and values in SI units (rad, m), each column in its header's unit."""
    n = len(columns)
    names = opts.joint_names or [_without_unit(table.heads[k]) for k in columns]
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
    _stated_alike(table, revolute, "angle", opts.angle_unit, "revolute joint column")
    _stated_alike(table, prismatic, "length", opts.length_unit, "prismatic joint column")
    q = np.empty((len(table.rows), n))
    for j, (k, t) in enumerate(zip(columns, types, strict=True)):
        what = f"joint {names[j]}"
        q[:, j] = table.numbers(k, what, "is it a joint column (--joint-columns)?")
        if t is JointType.PRISMATIC:
            unit = _column_unit(table, k, "length", opts.length_unit, DEFAULT_LENGTH_UNIT)
            q[:, j] *= LENGTH_UNITS[unit]
            table.in_range(k, q[:, j], what, -MAX_TRAVEL_M, MAX_TRAVEL_M, "m")
        else:
            unit = _column_unit(table, k, "angle", opts.angle_unit, DEFAULT_ANGLE_UNIT)
            q[:, j] *= ANGLE_UNITS[unit]
            table.in_range(k, q[:, j], what, -MAX_ANGLE_RAD, MAX_ANGLE_RAD, "rad")
    return names, q


@dataclass
class _Source:
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

    def take(self, rows: NDArray[np.int64]) -> _Source:
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
        )


def _u95_sigma(
    table: _Table, layout: _Layout, xyz_unit: str, opts: ImportOptions
) -> tuple[NDArray[np.float64], str | None]:
    """σ per coordinate (m, 3) from the U95 columns, and the note on values floored: a U95 the
    export rounded to 0 is floored at the column's resolution (its last decimal as written)."""
    assert layout.u95 is not None
    kind, cols = layout.u95
    hint = "fix the export, or leave U95 out with --no-u95."
    values, floored = [], []
    for k in cols:
        what = table.header[k]
        v = table.numbers(k, what, hint)
        negative = np.flatnonzero(v < 0)
        if negative.size:
            i = int(negative[0])
            raise ConversionError(
                table.path,
                f"{what} is {table.texts(k)[i]}: a U95 cannot be negative; {hint}",
                table.lines[i],
            )
        zero = v == 0
        unit = _column_unit(table, k, "length", opts.length_unit, xyz_unit)
        if np.all(zero):
            raise ConversionError(
                table.path,
                f"{what} is 0 at every point: the export holds no uncertainty; export U95 with "
                "more decimals, or leave it out with --no-u95.",
            )
        if np.any(zero):
            step = _resolution(table.texts(k))
            v = np.where(zero, step, v)
            floored.append((int(zero.sum()), step, unit, what))
        v = v * LENGTH_UNITS[unit]
        table.in_range(k, v, what, *U95_RANGE_M, "m")
        values.append(v)
    if kind == "axes":
        sd = np.column_stack(values) / U95_PER_COORDINATE
    else:
        sd = np.repeat(values[0][:, None], 3, axis=1) / U95_SPHERE
    note = None
    if floored:
        count = sum(n for n, *_ in floored)
        steps = sorted({f"{step:g} {unit}" for _, step, unit, _ in floored})
        columns = ", ".join(what for *_, what in floored)
        note = (
            f"{table.path}: {count} U95 value(s) read 0 (rounded by the export) and were floored "
            f"at the export's resolution, {' / '.join(steps)} (the last decimal written in "
            f"{columns})."
        )
    return sd, note


def _orientation(
    table: _Table, layout: _Layout, opts: ImportOptions
) -> tuple[NDArray[np.float64], str]:
    """The target frame's orientation in the measurement frame as unit quaternions (m, 4:
    x, y, z, w), and how it was read."""
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

    _stated_alike(table, cols, "angle", opts.angle_unit, "rotation angle")
    units = [_column_unit(table, k, "angle", opts.angle_unit, DEFAULT_ANGLE_UNIT) for k in cols]
    radians = values * np.array([ANGLE_UNITS[u] for u in units])
    for c, k in enumerate(cols):
        table.in_range(k, radians[:, c], table.header[k], -MAX_ANGLE_RAD, MAX_ANGLE_RAD, "rad")
    quat = Rotation.from_euler(seq, radians).as_quat()  # x, y, z, w
    axes = "fixed" if seq.islower() else "moving"
    return np.asarray(quat, dtype=np.float64), f"{named} (rotation angles, {axes} axes {seq})"


def _times(table: _Table, k: int, opts: ImportOptions) -> NDArray[np.int64]:
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


def _from_table(table: _Table, opts: ImportOptions) -> _Source:
    """The points (and joints, unless a joints file gives them) of a table with a header."""
    own_joints = opts.joints_file is None
    layout = _layout(table, opts, joints=own_joints)
    _stated_alike(table, layout.xyz, "length", opts.length_unit, "coordinate")
    units = [
        _column_unit(table, k, "length", opts.length_unit, DEFAULT_LENGTH_UNIT) for k in layout.xyz
    ]
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
    src = _Source(table.path, list(table.lines), names, xyz, notes=list(layout.notes))
    src.named_by_option = opts.name_column is not None and table.find(opts.name_column) is not None
    if layout.u95 is not None and not opts.no_u95:
        sd, note = _u95_sigma(table, layout, units[0], opts)
        src.cov = np.zeros((len(sd), 6))
        src.cov[:, 0], src.cov[:, 3], src.cov[:, 5] = sd[:, 0] ** 2, sd[:, 1] ** 2, sd[:, 2] ** 2
        src.provenance["u95_columns"] = ", ".join(table.header[k] for k in layout.u95[1])
        if note:
            src.notes.append(note)
    elif opts.format == "leica" and not opts.no_u95:
        raise ConversionError(
            table.path,
            "has no U95 column (U95, U(95), or U95 X, U95 Y, U95 Z, with a unit or not); its "
            f"columns are {', '.join(table.header)}; export the U95, or import it without "
            "with --no-u95 (or --format csv).",
        )
    if layout.orientation is not None:
        src.quat, how = _orientation(table, layout, opts)
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
        src.joint_names, src.q = _joint_values(table, layout.joints, opts)
    else:
        own = [
            h.text
            for k, h in enumerate(table.heads)
            if k not in layout.recognised and _JOINT_HEADER.match(h.key)
        ]
        if own:
            src.notes.append(
                f"{table.path}: its joint columns ({', '.join(own)}) were left out: the joints "
                "come from --joints-file."
            )
    return src


_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def read_spatialanalyzer(
    path: str | Path, length_unit: str
) -> tuple[list[str], NDArray[np.float64]]:
    """Named points of a SpatialAnalyzer-style ASCII point list: per line a name (``A::B::C``,
    or collection, group and point as separate fields) and x, y, z as the last three fields,
    separated by commas, semicolons, tabs or spaces; a header line is skipped."""
    names, xyz, _ = _spatialanalyzer_points(path, length_unit)
    return names, xyz


def _spatialanalyzer_points(
    path: str | Path, length_unit: str
) -> tuple[list[str], NDArray[np.float64], list[int]]:
    names, xyz, lines = [], [], []
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
            point = [float(v) * LENGTH_UNITS[length_unit] for v in fields[-3:]]
            if not all(abs(v) <= MAX_COORDINATE_M for v in point):  # inf and NaN too
                raise ConversionError(
                    path,
                    f"the point {_cut('::'.join(fields[:-3]))} is at "
                    f"{', '.join(_cut(v, 24) for v in fields[-3:])} ({length_unit}): out of "
                    f"range: dhlog reads coordinates within ±{MAX_COORDINATE_M:g} m; check the "
                    "value and --length-unit.",
                    i + 1,
                )
            names.append("::".join(fields[:-3]))
            xyz.append(point)
            lines.append(i + 1)
        elif not names and not any(numeric):
            continue  # a header
        else:
            raise ConversionError(
                path,
                "is not 'name x y z' (a name, then three numbers); export the points as a "
                "point list, or as a table with a header (X, Y, Z, …) for --format "
                "spatialanalyzer or csv.",
                i + 1,
            )
    if not names:
        raise ConversionError(path, "holds no points; check --format.")
    return names, np.asarray(xyz, dtype=np.float64), lines


def _is_table(path: Path, opts: ImportOptions) -> bool:
    """True when ``path`` is a delimited table whose header names x, y and z."""
    try:
        table = read_table(path)
    except ConversionError:
        return False
    return all(table.find(c) is not None for c in (opts.x, opts.y, opts.z))


# ---------------------------------------------------------------------------------------------
# joints from a file


def _joints_name_column(joints: _Table, opts: ImportOptions) -> int | None:
    if opts.name_column and joints.find(opts.name_column) is not None:
        return joints.find(opts.name_column)
    k = joints.key(*NAME_HEADERS)
    if k is None and not joints.numeric(0):
        k = 0  # a first column of names
    return k


def _with_joints_file(src: _Source, opts: ImportOptions) -> _Source:
    """``src`` with the joint values of ``opts.joints_file``, matched by point name (when both
    name points) or by row; by name, the points come in the joints file's order."""
    assert opts.joints_file is not None
    joints = read_table(opts.joints_file, option="--joints-file")
    nk = _joints_name_column(joints, opts)
    if opts.name_column and joints.find(opts.name_column) is None and not src.named_by_option:
        raise ConversionError(
            joints.path,
            f"has no column '{opts.name_column}' (--name-column), nor has {src.path}; its "
            f"columns are {', '.join(joints.header)}; name the point column with --name-column.",
        )
    claims: dict[int, str] = {} if nk is None else {nk: "the point name"}
    if opts.joint_columns:
        cols = []
        for c in opts.joint_columns:
            k = joints.column(c, "a joint", "--joint-columns")
            _claim(joints, claims, k, "--joint-columns")
            cols.append(k)
    else:
        cols = _joints_by_number(
            joints,
            [k for k, h in enumerate(joints.heads) if k != nk and _JOINT_HEADER.match(h.key)],
            src.notes,
        )
    if not cols:
        raise ConversionError(
            joints.path,
            "has no joint columns (q1…, j1…, A1…, joint_1…, axis1…); its columns are "
            f"{', '.join(joints.header)}; name them with --joint-columns.",
        )
    names, q = _joint_values(joints, cols, opts)
    by_name = nk is not None and src.names is not None
    if nk is not None and src.names is not None:
        p_idx, r_idx = _match_by_name(src, joints, nk)
    else:
        if len(joints.rows) != len(src.xyz):
            raise ConversionError(
                joints.path,
                f"has {len(joints.rows)} row(s), {src.path} {len(src.xyz)} point(s); without "
                "point names in both files to match them by, rows are matched in order and "
                "must be as many (name the point column with --name-column).",
            )
        p_idx = r_idx = np.arange(len(src.xyz))
        src.notes.append(
            f"{joints.path}: its rows were matched to the points of {src.path} in order (the "
            "points are not named in both files; --name-column names the column)."
        )
    if src.t_ns is not None:  # timed samples keep their time order
        order = np.argsort(p_idx, kind="stable")
        p_idx, r_idx = p_idx[order], r_idx[order]
    out = src.take(p_idx)
    out.joint_names, out.q = names, q[r_idx]
    out.provenance["joints_matched"] = "by point name" if by_name else "by row"
    return out


def _match_by_name(
    src: _Source, joints: _Table, nk: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Rows of the points and of the joints file that name the same point (the full name or
    its last ``::`` part), in the joints file's order."""
    assert src.names is not None
    by_name: dict[str, int] = {}
    for i, name in enumerate(src.names):
        for key in {name, name.split("::")[-1]}:
            if key in by_name and by_name[key] != i and key == name:
                raise ConversionError(
                    src.path,
                    f"names the point '{name}' twice; point names must be unique to match "
                    "--joints-file by name.",
                    src.lines[i],
                )
            by_name.setdefault(key, i)
    rows, missing = [], []
    for r, name in enumerate(joints.texts(nk)):
        if name in by_name:
            rows.append((r, by_name[name]))
        else:
            missing.append((joints.lines[r], name))
    if missing:
        line, name = missing[0]
        src.warnings.append(
            f"{joints.path}: {len(missing)} row(s) name a point that {Path(src.path).name} "
            f"does not hold (first: '{name}', line {line}); they were left out."
        )
    unused = len(src.names) - len({p for _, p in rows})
    if unused:
        src.warnings.append(
            f"{src.path}: {unused} point(s) have no joint values in {joints.path} and were "
            "left out."
        )
    if not rows:
        raise ConversionError(
            joints.path,
            f"names none of the points of {Path(src.path).name}; name its point column with "
            "--name-column.",
        )
    return (
        np.array([p for _, p in rows], dtype=np.int64),
        np.array([r for r, _ in rows], dtype=np.int64),
    )


# ---------------------------------------------------------------------------------------------
# the source as a whole


def _checked_options(opts: ImportOptions) -> None:
    if opts.format not in FORMATS:
        raise InputError(f"--format must be one of {', '.join(FORMATS)}, not '{opts.format}'.")
    for option, value, kind in (
        ("--length-unit", opts.length_unit, "length"),
        ("--angle-unit", opts.angle_unit, "angle"),
    ):
        if value is None:
            continue
        try:
            unit = unit_name(value, kind)
        except ValueError:
            known = ", ".join(LENGTH_UNITS if kind == "length" else ANGLE_UNITS)
            raise InputError(f"{option} must be one of {known}, not '{value}'.") from None
        if kind == "length":
            opts.length_unit = unit
        else:
            opts.angle_unit = unit
    if opts.time_unit not in TIME_UNITS:
        raise InputError(
            f"--time-unit must be one of {', '.join(TIME_UNITS)}, not '{opts.time_unit}'."
        )


def import_source(source: str | Path, opts: ImportOptions) -> Imported:
    """Read ``source`` (and ``opts.joints_file``) as ``opts.format`` into SI samples."""
    path = Path(source)
    _checked_options(opts)
    if opts.format == "spatialanalyzer" and not _is_table(path, opts):
        if opts.joints_file is None:
            raise InputError(
                f"{path}: a SpatialAnalyzer point list holds no joint values; give them with "
                "--joints-file (matched by point name, or by row)."
            )
        names, xyz, lines = _spatialanalyzer_points(path, opts.length_unit or DEFAULT_LENGTH_UNIT)
        src = _Source(str(path), lines, names, xyz)
    else:
        src = _from_table(read_table(path), opts)
    if opts.joints_file is not None:
        src = _with_joints_file(src, opts)
    assert src.q is not None
    xyz, q = src.xyz, src.q
    if src.t_ns is not None:
        point_t, joint_t, joint_q, stepped = src.t_ns, src.t_ns, q, False
    else:
        m = len(xyz)
        start = EPOCH_NS + np.round(np.arange(m) * STOP_SECONDS * 1e9).astype(np.int64)
        point_t = start + int(STOP_SECONDS * 1e9 / 2)
        per_stop = len(STOP_JOINT_TIMES)
        offsets = np.round(np.array(STOP_JOINT_TIMES) * 1e9).astype(np.int64)
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
        **src.provenance,
    }
    if opts.joints_file is not None:
        provenance["joints_file"] = str(Path(opts.joints_file).resolve())
        provenance["joints_file_sha256"] = _sha256(Path(opts.joints_file))
    return Imported(
        np.asarray(point_t, dtype=np.int64),
        np.asarray(xyz, dtype=np.float64),
        src.cov,
        list(src.joint_names),
        np.asarray(joint_t, dtype=np.int64),
        np.asarray(joint_q, dtype=np.float64),
        stepped,
        provenance,
        list(src.warnings),
        src.quat,
        list(src.notes),
    )


def same_file(a: str | Path, b: str | Path) -> bool:
    """True when ``a`` and ``b`` name one file: the same path once resolved (a symbolic-link
    loop resolves without an error), or the same file by device and inode (a hard link)."""
    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
        return os.path.samefile(a, b)
    except (OSError, ValueError, RuntimeError):
        return False


def _sha256(path: Path) -> str:
    from dhlog.io.writer import sha256_of

    return sha256_of(path)


# ---------------------------------------------------------------------------------------------
# the log


def _point_messages(imported: Imported) -> tuple[str, list[bytes]]:
    """The target's schema and CDR payloads: PointStamped, PoseStamped with the orientation,
    or PoseWithCovarianceStamped with the uncertainties (its pose holding the orientation when
    measured, the orientation block of the covariance then zero: not in the export)."""
    t, xyz, cov, quat = imported.point_t_ns, imported.xyz, imported.covariance, imported.orientation
    if cov is None and quat is None:
        return ros2.POINT_STAMPED, ros2.encode_point_stamped(t, xyz, "tracker")
    if cov is None:
        return ros2.POSE_STAMPED, ros2.encode_pose_stamped(t, xyz, "tracker", quat)
    if quat is None:
        return ros2.POSE_WITH_COVARIANCE, ros2.encode_pose_with_covariance(t, xyz, "tracker", cov)
    full = np.zeros((len(xyz), 6, 6), dtype="<f8")
    rows, cols = [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]
    full[:, rows, cols] = cov
    full[:, cols, rows] = cov
    poses = ros2.encode_pose_stamped(t, xyz, "tracker", quat)
    return ros2.POSE_WITH_COVARIANCE, [p + c.tobytes() for p, c in zip(poses, full, strict=True)]


def _joint_payloads(
    t_ns: NDArray[np.int64], names: list[str], q: NDArray[np.float64]
) -> list[bytes]:
    """CDR payloads of JointState messages, as :func:`ros2.encode_joint_state` writes them,
    built at once: with the same names every message has the same layout, so one encoded
    message is the template whose stamp (bytes 4–12) and positions (the 8·n bytes before the
    empty velocity and effort) are written in per message (checked against the encoder on
    the first and last message; the encoder itself where they differ)."""
    m, n = q.shape
    if m == 0:
        return []
    template = ros2.encode_joint_state(t_ns[:1], names, q[:1])[0]
    size = len(template)
    rows = np.tile(np.frombuffer(template, dtype=np.uint8), (m, 1))
    sec, nsec = np.divmod(np.asarray(t_ns, dtype=np.int64), 1_000_000_000)
    rows[:, 4:8] = sec.astype("<i4").view(np.uint8).reshape(m, 4)
    rows[:, 8:12] = nsec.astype("<i4").view(np.uint8).reshape(m, 4)
    end = size - 8
    rows[:, end - 8 * n : end] = np.ascontiguousarray(q, dtype="<f8").view(np.uint8)
    data = rows.tobytes()
    out = [data[i : i + size] for i in range(0, m * size, size)]
    if out[0] != template or out[-1] != ros2.encode_joint_state(t_ns[-1:], names, q[-1:])[0]:
        return ros2.encode_joint_state(t_ns, names, q)  # pragma: no cover - layout changed
    return out


def write_imported(imported: Imported, out: str | Path) -> None:
    """Write ``imported`` as a ROS 2 MCAP log (atomically), with its provenance; the messages
    in time order (points before joint states at the same stamp), ordered in one sort."""
    from mcap.writer import CompressionType, Writer

    from dhlog import __version__
    from dhlog.io.writer import atomic_output

    point_schema, points = _point_messages(imported)
    joints = _joint_payloads(imported.joint_t_ns, imported.joint_names, imported.joint_q)
    times = np.concatenate([imported.point_t_ns, imported.joint_t_ns]).astype(np.int64)
    stream = np.repeat([0, 1], [len(points), len(joints)])
    order = np.lexsort((stream, times))  # stable: each stream keeps its own order
    payloads = points + joints
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
        add = writer.add_message
        ordered = zip(order.tolist(), times[order].tolist(), stream[order].tolist(), strict=True)
        for i, t, s in ordered:
            add(channels[s], t, payloads[i], t)
        writer.add_metadata("dhlog.import", {**imported.provenance, "dhlog": __version__})
        writer.finish()  # type: ignore[no-untyped-call]
