"""The text of a tracker program's export as a table: its encoding, separator and rows
(:func:`read_table`), each column header's key and unit (:func:`parse_header`: ``X [mm]``,
``X (mm)``, ``X[mm]``, ``X_mm``, ``U(95)  [mm]``), its columns as numbers (decimal commas in a
``;``-separated table), and the units (:func:`unit_name`, :func:`column_unit`: a header's unit
used, an error when it contradicts the option given). Every error names the file and line.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError

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
    **dict.fromkeys(("gon", "gons", "gradian", "gradians"), "gon"),
}
#: Unit spellings refused as ambiguous, with why: ``grad`` is a degree in German software
#: (``Grad``, ``Altgrad``) and a gon in English (grad, gradian).
AMBIGUOUS_UNITS = {
    "grad": "'grad' is a degree in German software (Grad) and a gon (gradian, 400 a turn) in "
    "English; write deg or gon",
}
#: Header units that say "no unit" (a quaternion's).
DIMENSIONLESS = ("", "-", "1")
_TRAILING_BRACKET = re.compile(r"^(?P<name>.*?)\s*[\[({]\s*(?P<unit>[^\[\](){}]*?)\s*[\])}]\s*$")
#: A unit after the name without brackets: ``X_m``, ``X/mm``, ``A1 deg``, ``X in m``.
_SUFFIX_UNIT = re.compile(r"^(?P<name>.*?\S)(?:\s*[_/]\s*|\s+in\s+|\s+)(?P<unit>[^\s_/]+)$")
#: The largest file ``dhlog import`` reads (bytes): a few hundred thousand rows of a table.
MAX_TABLE_BYTES = 128 * 2**20
_KEY_DROPS = re.compile(r"[\s_\-.()\[\]/]")


class ConversionError(InputError):
    """A source file that cannot be converted, with the file and line at fault."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        where = f"{path}" if line is None else f"{path}, line {line}"
        super().__init__(f"{where}: {message}")


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
    elif (s := _SUFFIX_UNIT.match(name)) and (
        s["unit"].lower() in UNIT_SPELLINGS or s["unit"].lower() in AMBIGUOUS_UNITS
    ):
        name, unit = s["name"], s["unit"].lower()
    return Header(text.strip(), _KEY_DROPS.sub("", name.lower()), unit)


@dataclass
class Table:
    """A delimited text table: header names, rows of strings and each row's line number."""

    path: str
    header: list[str]
    rows: list[list[str]]
    lines: list[int]
    sep: str = ","
    #: the comment lines skipped (``#``, ``//``): their line numbers and text
    comments: list[tuple[int, str]] = field(default_factory=list)
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
                    f"{what} '{cut(text)}' is not a number{comma}; {hint}",
                    self.lines[i],
                ) from None
            if not math.isfinite(out[i]):
                raise ConversionError(
                    self.path, f"{what} '{cut(text)}' is not finite; {hint}", self.lines[i]
                )
        return out

    def _decimal_commas(self, texts: list[str], what: str) -> list[str]:
        """``texts`` with decimal commas as points; a column that mixes decimal commas and
        points, or a value with a thousands separator, is refused (its line named)."""
        for i, text in enumerate(texts):
            if text.count(",") > 1 or ("," in text and "." in text):
                raise ConversionError(
                    self.path,
                    f"{what} '{cut(text)}' holds a thousands separator or more than one decimal "
                    "mark; export the numbers without thousands separators.",
                    self.lines[i],
                )
        points = [i for i, t in enumerate(texts) if "." in t]
        if points:
            i = points[0]
            raise ConversionError(
                self.path,
                f"{what} mixes decimal commas and decimal points ('{cut(texts[i])}' here); "
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
                f"{what} '{cut(self.texts(k)[i])}' is out of range: dhlog reads {lo:g} to "
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


def cut(text: str, size: int = 40) -> str:
    """``text`` cut to ``size`` characters for a message."""
    return text if len(text) <= size else text[: size - 1] + "…"


def read_text(path: str | Path, option: str = "the source") -> str:
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


def read_table(path: str | Path, *, header: bool = True, option: str = "the source") -> Table:
    """A CSV (``,``), semicolon (``;``, decimal commas allowed) or tab-separated table; blank
    lines and lines starting with ``#`` or ``//`` are skipped. A row with more fields than the
    header (beyond empty ones) is refused, naming its line."""
    text = read_text(path, option)
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
    comments = [
        (i + 1, line.strip())
        for i, line in enumerate(text.splitlines())
        if line.lstrip().startswith(("#", "//"))
    ]
    table = Table(str(path), names, body, lines, sep, comments)
    if not body:
        raise ConversionError(path, "has a header but no rows; export the points too.")
    return table


# ---------------------------------------------------------------------------------------------
# units


def unit_name(text: str, kind: str) -> str:
    """A length (``kind="length"``) or angle unit as spelled in an option or a header, by its
    name in ``LENGTH_UNITS``/``ANGLE_UNITS``; ValueError for any other."""
    name = UNIT_SPELLINGS.get(text.strip().lower())
    known = LENGTH_UNITS if kind == "length" else ANGLE_UNITS
    if name not in known:
        raise ValueError(AMBIGUOUS_UNITS.get(text.strip().lower(), ""))
    return name


def column_unit(
    table: Table, k: int, kind: str, given: str | None, fallback: str, *, option: str | None = None
) -> str:
    """The unit of column ``k``: its header's, else the option's (``given``), else ``fallback``;
    a header that contradicts the option is an error naming both (``option``: the option's
    name, by default ``--length-unit`` or ``--angle-unit``)."""
    option = option or ("--length-unit" if kind == "length" else "--angle-unit")
    written = table.heads[k].unit
    if written is None or written in DIMENSIONLESS:
        return given or fallback
    try:
        unit = unit_name(written, kind)
    except ValueError as exc:
        known = ", ".join(LENGTH_UNITS if kind == "length" else ANGLE_UNITS)
        why = f" ({exc})" if str(exc) else ""
        raise ConversionError(
            table.path,
            f"the header '{table.header[k]}' states the unit '{written}'{why}; dhlog reads "
            f"{known} there; correct the header (the unit in brackets), or drop the unit and "
            f"give {option}.",
        ) from None
    if given is not None and given != unit:
        raise ConversionError(
            table.path,
            f"the header '{table.header[k]}' states {unit} but {option} {given} was given; "
            f"leave {option} out (the header's unit is used) or correct the header.",
        )
    return unit


def without_unit(head: Header) -> str:
    """A header as written without its unit (``A1 [deg]``, ``A1_deg`` → ``A1``)."""
    if head.unit is None:
        return head.text
    m = _TRAILING_BRACKET.match(head.text) or _SUFFIX_UNIT.match(head.text)
    return m["name"].strip() if m else head.text


def stated_alike(
    table: Table,
    columns: list[int],
    kind: str,
    given: str | None,
    what: str,
    *,
    option: str | None = None,
) -> None:
    """Refuse a header that states the unit of some of ``columns`` (``X [m]``) and not of the
    others (``Y``, ``Z``), when no option gives it: the others would be read in the default."""
    if given is not None:
        return
    stated = [k for k in columns if table.heads[k].unit not in (None, *DIMENSIONLESS)]
    for k in stated:  # a unit dhlog does not know is the error to give first
        column_unit(table, k, kind, None, DEFAULT_LENGTH_UNIT)
    silent = [table.header[k] for k in columns if k not in stated]
    if stated and silent:
        option = option or ("--length-unit" if kind == "length" else "--angle-unit")
        raise ConversionError(
            table.path,
            f"the header states the unit of '{table.header[stated[0]]}' but not of "
            f"{', '.join(repr(h) for h in silent)}; state it for every {what} (X [mm]), or give "
            f"{option}.",
        )
