"""The DH table's cells: display units and decimals, each value above its σ line (``± σ``,
``fixed``, ``undetermined``), the table's title (Hayati rows named), joint names cut to
``NAME_WIDTH``, and user text made literal for rich (:func:`literal`)."""

from __future__ import annotations

import math

from rich.markup import escape

from dhlog.io.safetext import printable
from dhlog.result.document import DisplayRow, display_scales

#: A σ beyond these (m, rad) is not a measurement's: such a value is labelled undetermined.
UNDETERMINED_LENGTH = 1.0
UNDETERMINED_ANGLE = math.radians(30.0)


#: Widest joint name shown in full in the console (longer ones end in "…"; the JSON has them).
NAME_WIDTH = 18


def scales(units: str) -> tuple[float, float, str, str]:
    length, angle, lu, au = display_scales(units)
    return length, angle, lu, "°" if au == "deg" else au


def decimals(units: str) -> tuple[int, int]:
    """Decimals of lengths and angles: 0.1 µm and 0.0001° (10⁻⁷ m, 10⁻⁶ rad)."""
    return (7, 6) if units == "m" else (4, 4)


def _places(sigma: float | None, base: int) -> int:
    """Decimals that show ``sigma`` to two significant digits (at least ``base``, at most
    ``base + 3``)."""
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return base
    return max(base, min(base + 3, 1 - math.floor(math.log10(sigma))))


def value_sigma(
    value: float, sigma: float | None, held: bool, base: int, undetermined: float = math.inf
) -> tuple[str, str]:
    """The value and its σ line (``± σ``, ``fixed``, or empty when unknown); a σ beyond
    ``undetermined`` (the quantity's physical scale) is labelled so."""
    places = _places(None if held else sigma, base)
    shown = f"{value:.{places}f}"
    if held:
        return shown, "fixed"
    if sigma is None or not math.isfinite(sigma):
        return shown, ""
    if sigma > undetermined:
        return shown, f"undetermined ±{sigma:.3g}"
    return shown, f"± {sigma:.{places}f}"


def value_cells(row: DisplayRow, units: str) -> list[tuple[str, str]]:
    """Per parameter (θ, d or β, a, α): the value and its σ line, in display units."""
    lb, ab = decimals(units)
    length, angle, _, _ = scales(units)
    out = []
    for k in range(4):
        angular = k in (0, 3) or (k == 1 and row.form == "hayati")
        scale = UNDETERMINED_ANGLE * angle if angular else UNDETERMINED_LENGTH * length
        value, sigma = value_sigma(
            row.values[k], row.stds[k], row.held[k], ab if angular else lb, scale
        )
        if k == 1 and row.form == "hayati":
            value = f"β {value}"
        out.append((value, sigma))
    return out


def _hayati_rows(rows: list[DisplayRow]) -> list[int]:
    return [i + 1 for i, r in enumerate(rows) if r.form == "hayati"]


def table_title(rows: list[DisplayRow]) -> str:
    hayati = _hayati_rows(rows)
    if not hayati:
        return "Standard DH, ±1σ under each value (θ, d: offsets at encoder zero)"
    which = ", ".join(str(i) for i in hayati)
    return (
        f"Standard DH with Hayati–Mirmirani row(s) {which}: Rz(θ) Tx(a) Rx(α) Ry(β), β in place "
        "of the ill-conditioned d (nearly parallel axes); ±1σ under each value"
    )


def literal(text: object) -> str:
    """User text (a joint name, a path, a note) as rich markup that prints it as it is and on one
    line: markup escaped, controls and line breaks as ``\\xNN`` escapes
    (:func:`~dhlog.io.safetext.printable`). Where it is used no markup tag follows it, so the
    backslash rich's ``escape`` adds after a lone trailing backslash (which would print twice)
    is left off."""
    shown = printable(str(text))
    safe = escape(shown)
    if shown.endswith("\\") and not shown.endswith("\\\\"):
        return safe[:-1]
    return safe


def short_name(name: str) -> str:
    """A joint name for a table cell: literal, cut to ``NAME_WIDTH`` characters with "…"."""
    shown = printable(name)
    return literal(shown if len(shown) <= NAME_WIDTH else shown[: NAME_WIDTH - 1] + "…")
