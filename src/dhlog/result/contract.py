"""The pieces of the result contract (``dhlog.result/1``) shared by results and truth files."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.identify.read.extract import PairRelation
from dhlog.model.dh import StandardDH, standard_to_modified

RESULT_FORMAT = "dhlog.result/1"


def _num(value: float) -> float | None:
    return None if not math.isfinite(value) else float(value)


def dh_documents(
    table: StandardDH, q: FloatArray, std: FloatArray | None = None, rows: int | None = None
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The ``standard_dh`` and ``modified_dh`` arrays of ``table`` at the reference pose ``q``
    (the first ``rows`` rows), with ``std`` (4n: θ, d, a, α per row) as the ±1σ."""
    n = table.n if rows is None else rows
    theta, d = table.theta(q), table.d(q)
    modified, _ = standard_to_modified(table)
    std_all = np.full(4 * table.n, float("nan")) if std is None else std
    standard = [
        {
            "type": table.joint_types[i].value,
            "theta": float(theta[i]),
            "d": float(d[i]),
            "a": float(table.a[i]),
            "alpha": float(table.alpha[i]),
            "theta_offset": float(table.theta_offset[i]),
            "d_offset": float(table.d_offset[i]),
            "std": dict(
                zip(
                    ("theta", "d", "a", "alpha"),
                    (_num(v) for v in std_all[4 * i : 4 * i + 4]),
                    strict=True,
                )
            ),
        }
        for i in range(n)
    ]
    mod = [
        {
            "alpha": float(modified.alpha[i]),
            "a": float(modified.a[i]),
            "theta": float(modified.theta(q)[i]),
            "d": float(modified.d(q)[i]),
        }
        for i in range(n)
    ]
    return standard, mod


def relation_documents(relations: Sequence[PairRelation]) -> list[dict[str, Any]]:
    """The ``relations`` array: kind, angle (rad) and distance (m) of each consecutive pair."""
    return [
        {
            "joints": list(r.joints),
            "kind": r.relation.kind.value,
            "angle": r.relation.angle,
            "distance": r.relation.distance,
        }
        for r in relations
    ]
