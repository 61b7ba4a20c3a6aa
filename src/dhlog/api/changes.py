"""Measured − nominal as a table (:meth:`dhlog.Calibration.changes`): each DH parameter's change
from the nominal with its σ and whether it is fixed, in the form the console's "Measured −
nominal" table shows (β in place of d on a nearly parallel pair), SI units named in the columns."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from dhlog.errors import UsageError
from dhlog.geometry._checks import wrap_angle

if TYPE_CHECKING:
    import polars as pl

    from dhlog.io.dhfile import DHModel
    from dhlog.model.dh import StandardDH

#: The columns of :func:`changes_table`, in order.
COLUMNS = (
    "joint",
    "name",
    "form",
    "parameter",
    "unit",
    "change_m",
    "change_rad",
    "sigma_m",
    "sigma_rad",
    "fixed",
)

#: The nominal's DH value a parameter's change is taken from.
_NOMINAL = {"theta": "theta_offset", "d": "d_offset", "a": "a", "alpha": "alpha", "beta": "beta"}


def changes_table(
    params: pl.DataFrame, nominal: DHModel | None, document: dict[str, Any], result: Any
) -> pl.DataFrame:
    """A calibration's measured − nominal from its :attr:`~dhlog.Calibration.parameters`
    (``params``), ``nominal``, result ``document`` and run record (``result``; None: loaded),
    one row per parameter as
    :attr:`~dhlog.Calibration.parameters` has them: ``joint``, ``name``, ``form``,
    ``parameter``, ``unit`` (m or rad), the change in its unit's column (``change_m`` or
    ``change_rad``, the other null; angles wrapped to ±π; null where the nominal has no such
    parameter), its σ likewise (``sigma_m`` / ``sigma_rad``; null where fixed) and ``fixed``.
    A calibration without a nominal raises a :class:`~dhlog.UsageError`."""
    import polars as pl

    if nominal is None:
        raise UsageError(
            "changes: this calibration has no nominal to subtract; pass nominal= to "
            "dhlog.process or dhlog.load (a library robot name, a DH file or dhlog.robot(...))."
        )
    shown = None
    if result is not None:
        from dhlog.result.document import nominal_difference

        shown = nominal_difference(result, shown=True)  # what the console's table prints
    table, unknown = _nominal_in_form(nominal.table, document, params)
    order = ("theta", "d", "a", "alpha")
    rows: list[dict[str, Any]] = []
    for row in params.iter_rows(named=True):
        i, key = int(row["joint"]) - 1, str(row["parameter"])
        k = 1 if key == "beta" else order.index(key)
        change: float | None
        if shown is not None:
            change = float(shown[i, k]) if i < shown.shape[0] else None
        elif i >= table.n or i in unknown:
            change = None
        else:
            change = float(row["value"]) - _nominal_value(table, key, i)
            if row["unit"] == "rad":
                change = wrap_angle(change)
        if change is not None and not math.isfinite(change):
            change = None
        metres = row["unit"] == "m"
        rows.append(
            {
                "joint": row["joint"],
                "name": row["name"],
                "form": row["form"],
                "parameter": key,
                "unit": row["unit"],
                "change_m": change if metres else None,
                "change_rad": None if metres else change,
                "sigma_m": row["sigma"] if metres else None,
                "sigma_rad": None if metres else row["sigma"],
                "fixed": row["fixed"],
            }
        )
    schema = {
        "joint": pl.Int64,
        "name": pl.String,
        "form": pl.String,
        "parameter": pl.String,
        "unit": pl.String,
        "change_m": pl.Float64,
        "change_rad": pl.Float64,
        "sigma_m": pl.Float64,
        "sigma_rad": pl.Float64,
        "fixed": pl.Boolean,
    }
    return pl.DataFrame(rows, schema=schema, orient="row")


def _nominal_in_form(
    nominal: StandardDH, document: dict[str, Any], params: pl.DataFrame
) -> tuple[StandardDH, set[int]]:
    """A loaded calibration's ``nominal`` in the form of its rows (the rows of nearly parallel
    pairs in the Hayati form, at the result's reference pose, as the run took it), and the rows
    whose change is unknown: those rows and the next when the nominal has no such form."""
    import numpy as np

    from dhlog.identify.read.conditioning import nominal_rows

    hayati = frozenset(int(j) - 1 for j in params.filter(form="hayati")["joint"].unique().to_list())
    if not hayati:
        return nominal, set()
    ref = np.asarray(document.get("reference_pose") or np.zeros(nominal.n), dtype=np.float64)
    if ref.shape != (nominal.n,):
        ref = np.zeros(nominal.n)
    in_form = nominal_rows(nominal, ref, hayati)
    if in_form is None:
        return nominal, set(hayati) | {i + 1 for i in hayati}
    return in_form, set()


def _nominal_value(nominal: StandardDH, key: str, i: int) -> float:
    """The nominal's ``key`` (theta, d, a, alpha, beta) of row ``i`` (β 0 on a standard row)."""
    values = getattr(nominal, _NOMINAL[key], None)
    return 0.0 if values is None else float(values[i])
