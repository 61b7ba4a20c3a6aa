"""The tables a :class:`~dhlog.api.calibration.Calibration` gives as polars frames: its DH
parameters with σ (:func:`parameters_table`, ``Calibration.parameters``) and its held-out
errors (:func:`holdout_table`, ``Calibration.holdout``), read off its result document."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import polars as pl

    from dhlog.io.dhfile import DHModel


class Calibration(Protocol):
    """What the tables read of a :class:`~dhlog.api.calibration.Calibration`."""

    document: dict[str, Any]

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    def identified(self) -> DHModel: ...


def parameters_table(cal: Calibration) -> pl.DataFrame:
    """``Calibration.parameters``: every DH parameter with its σ, one row each (see there)."""

    import polars as pl

    units = cal.document.get("units") or {}
    if units.get("length", "m") != "m" or units.get("angle", "rad") != "rad":
        # a DH file in other units (mm, deg): its values as the model read them, in SI;
        # such a file carries no σ
        t = cal.identified().table
        table = [
            {
                "theta_offset": t.theta_offset[i],
                "d_offset": t.d_offset[i],
                "a": t.a[i],
                "alpha": t.alpha[i],
            }
            for i in range(t.n)
        ]
    else:
        conditioned = cal.document.get("hayati_dh")
        table = (
            conditioned.get("rows", [])
            if isinstance(conditioned, dict)
            else cal.document.get("standard_dh", [])
        )
    rows = []
    names = cal.joint_names
    for i, row in enumerate(table):
        std = row.get("std") or {}
        fixed = set(row.get("fixed") or [])
        form = str(row.get("form", "dh"))
        second = ("beta", "rad") if form == "hayati" else ("d", "m")
        for key, unit in (("theta", "rad"), second, ("a", "m"), ("alpha", "rad")):
            value = row.get(f"{key}_offset", row.get(key))
            sigma = std.get(key)
            rows.append(
                {
                    "joint": i + 1,
                    "name": names[i] if i < len(names) else f"joint_{i + 1}",
                    "form": form,
                    "parameter": key,
                    "value": math.nan if value is None else float(value),
                    "sigma": None if sigma is None or key in fixed else float(sigma),
                    "fixed": key in fixed,
                    "unit": unit,
                }
            )
    schema = {
        "joint": pl.Int64,
        "name": pl.String,
        "form": pl.String,
        "parameter": pl.String,
        "value": pl.Float64,
        "sigma": pl.Float64,
        "fixed": pl.Boolean,
        "unit": pl.String,
    }
    frame = pl.DataFrame(rows, schema=schema, orient="row")
    metres = pl.col("unit") == "m"
    return frame.with_columns(
        value_m=pl.when(metres).then(pl.col("value")),
        value_rad=pl.when(~metres).then(pl.col("value")),
        sigma_m=pl.when(metres).then(pl.col("sigma")),
        sigma_rad=pl.when(~metres).then(pl.col("sigma")),
    )


def holdout_table(cal: Calibration) -> pl.DataFrame:
    """``Calibration.holdout``: the errors at poses not used to fit, one row per check and
    model (see there)."""

    import polars as pl

    rows = []
    for check in (cal.document.get("validation") or {}).get("holdout", []):
        what = (
            f"{check.get('folds')}-fold"
            if check.get("kind") == "cross-validation"
            else Path(str(check.get("path", "log"))).name
        )
        for model in ("nominal", "calibrated"):
            stats = check.get(model)
            if not stats:
                continue
            rows.append(
                {
                    "check": what,
                    "model": model,
                    "n_poses": int(stats["n_poses"]),
                    **{k: float(stats[k]) for k in ("mean", "rms", "p95", "max")},
                }
            )
    schema = {
        "check": pl.String,
        "model": pl.String,
        "n_poses": pl.Int64,
        "mean": pl.Float64,
        "rms": pl.Float64,
        "p95": pl.Float64,
        "max": pl.Float64,
    }
    frame = pl.DataFrame(rows, schema=schema, orient="row")
    return frame.with_columns(pl.col(k).alias(f"{k}_m") for k in ("mean", "rms", "p95", "max"))
