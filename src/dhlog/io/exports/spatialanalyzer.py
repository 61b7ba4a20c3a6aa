"""SpatialAnalyzer's ASCII point list (``name x y z``, or ``collection, group, point, x, y, z``):
named points without joint values, which come from a joints file. A SpatialAnalyzer export
with a header is read as a table (:func:`is_table`)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dhlog.io.exports.options import ImportOptions
from dhlog.io.exports.source import MAX_COORDINATE_M
from dhlog.io.exports.table import (
    LENGTH_UNITS,
    ConversionError,
    cut,
    parse_header,
    read_table,
    read_text,
    unit_name,
)

_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def read_spatialanalyzer(
    path: str | Path, length_unit: str
) -> tuple[list[str], NDArray[np.float64]]:
    """Named points of a SpatialAnalyzer-style ASCII point list: per line a name (``A::B::C``,
    or collection, group and point as separate fields) and x, y, z as the last three fields,
    separated by commas, semicolons, tabs or spaces; a header line is skipped."""
    names, xyz, _, _ = spatialanalyzer_points(path, length_unit)
    return names, xyz


def header_unit(
    path: str | Path, fields: list[str], line: int, length_unit: str, where: str
) -> tuple[str, str]:
    """The length unit of a point list whose header line (``fields``) states one for x, y, z
    (``Name X[m] Y[m] Z[m]``), else ``length_unit``; x, y, z in different units, or a unit
    that contradicts ``--length-unit`` or a comment line (``where``), are refused."""
    heads = [parse_header(f) for f in fields]
    stated = [h for h in heads if h.key in ("x", "y", "z") and h.unit not in (None, "", "-", "1")]
    if not stated:
        return length_unit, where
    units = []
    for h in stated:
        try:
            units.append(unit_name(h.unit or "", "length"))
        except ValueError:
            raise ConversionError(
                path,
                f"the header '{h.text}' states the unit '{h.unit}'; dhlog reads "
                f"{', '.join(LENGTH_UNITS)} there; correct the header, or drop the unit and give "
                "--length-unit.",
                line,
            ) from None
    if len(set(units)) > 1 or len(stated) != 3:
        raise ConversionError(
            path,
            f"the header states the unit of {', '.join(h.text for h in stated)} only or not "
            "alike; state one unit for x, y and z (X [mm]), or give --length-unit.",
            line,
        )
    if where != "the default" and units[0] != length_unit:
        raise ConversionError(
            path,
            f"the header states {units[0]} but {where} states {length_unit}; correct the one "
            "that is wrong.",
            line,
        )
    return units[0], "the header"


def spatialanalyzer_points(
    path: str | Path, length_unit: str, where: str = "the default"
) -> tuple[list[str], NDArray[np.float64], list[int], tuple[str, str]]:
    """The points of a point list (``read_spatialanalyzer``) with their lines, and the unit
    they were read in and what stated it; a header line stating the unit (``Name X[m] Y[m]
    Z[m]``) is obeyed (:func:`header_unit`)."""
    names, xyz, lines = [], [], []
    for i, line in enumerate(read_text(path).splitlines()):
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
                    f"the point {cut('::'.join(fields[:-3]))} is at "
                    f"{', '.join(cut(v, 24) for v in fields[-3:])} ({length_unit}): out of "
                    f"range: dhlog reads coordinates within ±{MAX_COORDINATE_M:g} m; check the "
                    "value and --length-unit.",
                    i + 1,
                )
            names.append("::".join(fields[:-3]))
            xyz.append(point)
            lines.append(i + 1)
        elif not names and not any(numeric):
            length_unit, where = header_unit(path, fields, i + 1, length_unit, where)
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
    return names, np.asarray(xyz, dtype=np.float64), lines, (length_unit, where)


def is_table(path: Path, opts: ImportOptions) -> bool:
    """True when ``path`` is a delimited table whose header names x, y and z."""
    try:
        table = read_table(path)
    except ConversionError:
        return False
    return all(table.find(c) is not None for c in (opts.x, opts.y, opts.z))
