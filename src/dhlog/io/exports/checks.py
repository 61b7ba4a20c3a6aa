"""What an export's numbers say about the units it was read in, checked before the log is written:
a length unit stated in a comment line (``# Units: inch``), one unit for x, y and z, and values no
tracker session can produce in the unit read (an uncertainty under a micrometre or over
millimetres; points within a few millimetres while the joints turn).

Each refusal is one line naming the file (the line or column where there is one) and the option
or header that fixes it.
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import NDArray

from dhlog.io.exports.table import (
    AMBIGUOUS_UNITS,
    LENGTH_UNITS,
    UNIT_SPELLINGS,
    ConversionError,
    Table,
    cut,
)

#: A comment line stating the length unit: ``# Units: inch``, ``// length unit = mm``,
#: ``# units mm`` (not an angle's, time's or temperature's unit).
_UNIT_COMMENT = re.compile(
    r"^(?:#|//)\s*(?P<key>(?:[a-z]+\s+)?units?)\s*(?P<sep>[:=])?\s*(?P<unit>[^\s,;]+)",
    re.IGNORECASE,
)
_NOT_LENGTH = ("angle", "angular", "time", "temp", "temperature", "rotation")
#: σ per coordinate no tracker reaches (m): a laser tracker's U95 (its uncertainty model: 15 µm
#: + 6 µm/m) is 15 µm or more, a σ of several µm; a median below :data:`MIN_SIGMA_M` from a U95
#: means the values are in a larger unit than read (inches or metres read as mm). A standard
#: deviation or uncertainty column (``std``, ``unc``) may be the spread of an averaged reading,
#: which can be well under a µm: its floor is :data:`MIN_SPREAD_M`. Beyond :data:`MAX_SIGMA_M`
#: either is in a smaller unit than read (mm read as m).
MIN_SIGMA_M = 1e-6
MIN_SPREAD_M = 1e-7
MAX_SIGMA_M = 5e-3
#: Points that all lie within this (m, the largest extent along x, y or z) while the revolute
#: joints turn by :data:`MIN_TURN_RAD` or more in all (the sum of their spans) are in a larger
#: unit than read: a robot turning its joints by a radian moves its tool by decimetres.
MIN_EXTENT_M = 5e-3
MIN_TURN_RAD = 1.0
#: Points spread beyond this (m) are in a smaller unit than read: no cell is 200 m across.
MAX_EXTENT_M = 200.0
#: Judged only over at least this many points.
MIN_POINTS = 10


def comment_length_unit(path: str, comments: list[tuple[int, str]]) -> tuple[str, int] | None:
    """The length unit a comment line of the export states (``# Units: inch``, ``# units mm``)
    and its line, or None; an unknown or ambiguous unit after ``:`` or ``=`` is refused, naming
    the line (without one, a word that is no unit is not a statement: ``# unit tests``)."""
    found: list[tuple[str, int]] = []
    for line, text in comments:
        m = _UNIT_COMMENT.match(text)
        if m is None or any(w in m["key"].lower() for w in _NOT_LENGTH):
            continue
        word = m["unit"].strip().lower().rstrip(".")
        unit = UNIT_SPELLINGS.get(word)
        if unit not in LENGTH_UNITS and not m["sep"]:
            continue  # "# unit tests …": no statement of a unit
        if unit not in LENGTH_UNITS:
            why = AMBIGUOUS_UNITS.get(word, "")
            raise ConversionError(
                path,
                f"the comment '{cut(text)}' states the unit '{cut(m['unit'], 20)}'"
                f"{f' ({why})' if why else ''}; dhlog reads lengths in "
                f"{', '.join(LENGTH_UNITS)}; export in one of them, or correct the comment and "
                "give --length-unit.",
                line,
            )
        found.append((unit, line))
    units = {u for u, _ in found}
    if len(units) > 1:
        raise ConversionError(
            path,
            f"its comment lines state the units {', '.join(sorted(units))} (lines "
            f"{', '.join(str(n) for _, n in found)}); export one unit, or give --length-unit "
            "after correcting the comments.",
        )
    return found[0] if found else None


def one_unit(table: Table, columns: list[int], units: list[str], what: str) -> None:
    """Refuse ``columns`` (x, y, z; or a U95 per axis) read in different units: the header
    states ``X [m]`` beside ``Y [mm]`` (an export writes one unit for all three)."""
    if len(set(units)) > 1:
        shown = ", ".join(f"'{table.header[k]}' ({u})" for k, u in zip(columns, units, strict=True))
        raise ConversionError(
            table.path,
            f"the {what} columns are in different units, {shown}; an export writes one unit for "
            "the three: correct the header (X [mm], Y [mm], Z [mm]).",
        )


def plausible_sigma(
    table: Table,
    columns: list[int],
    sd: NDArray[np.float64],
    unit: str,
    where: str,
    *,
    expanded: bool,
) -> None:
    """Refuse per-point σ (m, per coordinate) whose median no tracker gives: under
    :data:`MIN_SIGMA_M` from a U95 (``expanded``; :data:`MIN_SPREAD_M` from a σ column: inches
    or metres read as mm) or over :data:`MAX_SIGMA_M` (mm read as m). ``unit``: the unit the
    columns were read in, ``where``: what said so."""
    if sd.shape[0] < MIN_POINTS:
        return
    median = float(np.median(sd))
    if (MIN_SIGMA_M if expanded else MIN_SPREAD_M) <= median <= MAX_SIGMA_M:
        return
    names = ", ".join(table.header[k] for k in columns)
    slip = (
        "the export is in a larger unit than read (inches or metres)"
        if median < MAX_SIGMA_M
        else "the export is in a smaller unit than read (mm read as m)"
    )
    raise ConversionError(
        table.path,
        f"the uncertainty {names} read in {unit} ({where}) gives a median σ of "
        f"{median * 1e6:.3g} µm per coordinate; no tracker measures "
        f"{'that well' if median < MAX_SIGMA_M else 'that poorly'}: {slip}? State the unit in "
        "the header (X [in], U95 [in]) or give --length-unit; or leave the uncertainty out with "
        "--no-u95.",
    )


def plausible_extent(
    path: str,
    xyz: NDArray[np.float64],
    q: NDArray[np.float64] | None,
    revolute: list[int],
    unit: str,
    where: str,
) -> None:
    """Refuse points (m) that span under :data:`MIN_EXTENT_M` while the revolute joints turn
    by :data:`MIN_TURN_RAD` (in a larger unit than read: metres read as mm), or over
    :data:`MAX_EXTENT_M` (in a smaller one)."""
    if xyz.shape[0] < MIN_POINTS:
        return
    extent = float(np.max(np.ptp(xyz, axis=0)))
    turn = 0.0
    if q is not None and revolute:
        turn = float(np.sum(np.ptp(q[:, revolute], axis=0)))
    if extent < MIN_EXTENT_M and turn >= MIN_TURN_RAD:
        raise ConversionError(
            path,
            f"the points read in {unit} ({where}) lie within {extent * 1e3:.3g} mm while the "
            f"joints turn by {turn:.3g} rad in all: no arm moves its tool so little; the export "
            "is in a larger unit (metres read as mm?): state it in the header (X [m]) or give "
            "--length-unit.",
        )
    if extent > MAX_EXTENT_M:
        raise ConversionError(
            path,
            f"the points read in {unit} ({where}) span {extent:.4g} m: no cell is so large; the "
            "export is in a smaller unit (mm read as m?): state it in the header (X [mm]) or "
            "give --length-unit.",
        )
