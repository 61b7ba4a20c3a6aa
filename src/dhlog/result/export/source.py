"""A result (or DH) JSON read for an export: checked field by field first
(:func:`dhlog.result.check.load_result`), its DH model, and the table the URDF forms take (the
Hayati-Mirmirani form where the result has it: the well-conditioned form). An encoder scale has
no place in any of them and is refused."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from dhlog.io.dhfile import DHFileError, DHModel, parse_dh
from dhlog.io.safetext import printable
from dhlog.model.dh import HayatiDH, StandardDH
from dhlog.result.check import load_result


def _table_of(data: dict[str, Any], source: str) -> tuple[StandardDH, DHModel]:
    """The result's table (the Hayati form where it has one) and the DH model."""
    model = parse_dh(data, source)
    rows = data.get("standard_dh", [])
    if any(abs(float(r.get("encoder_scale", 1.0)) - 1.0) > 0 for r in rows):
        raise DHFileError(
            source,
            "the result has fitted encoder scales, which a URDF cannot hold; export a result "
            "made without --fit-encoder-scales.",
        )
    hayati = (data.get("hayati_dh") or {}).get("rows")
    if not hayati:
        return model.table, model
    try:
        table = HayatiDH(
            [r["type"] for r in hayati],
            [float(r["theta_offset"]) for r in hayati],
            [float(r.get("d_offset", 0.0)) for r in hayati],
            [float(r["a"]) for r in hayati],
            [float(r["alpha"]) for r in hayati],
            [float(r.get("beta", 0.0)) for r in hayati],
            [r["form"] == "hayati" for r in hayati],
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise DHFileError(source, f"malformed hayati_dh ({exc}).") from None
    return table, model


def load_table(result_path: str | Path) -> tuple[dict[str, Any], StandardDH, DHModel]:
    """The result (or DH) JSON, its well-conditioned table and its DH model; the file's size,
    nesting and every field used checked first (:func:`dhlog.result.check.load_result`)."""
    data = load_result(result_path)
    table, model = _table_of(data, printable(str(result_path)))
    return data, table, model
