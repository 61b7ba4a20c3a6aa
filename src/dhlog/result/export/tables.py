"""A result's DH tables as plain files: standard and modified, SI units, with σ where the result
has it (``dhlog export --format dh-csv`` / ``dh-json``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from dhlog.model.dh import standard_to_modified
from dhlog.result.export.source import load_table


def dh_table_document(result_path: str | Path, fmt: str) -> str:
    """The standard and modified DH tables as CSV (``dh-csv``: one row per joint and
    convention) or JSON (``dh-json``), SI units, with σ where the result has it."""
    source = str(result_path)
    data, _, model = load_table(result_path)
    table = model.table
    modified, post = standard_to_modified(table)
    std_rows = data.get("standard_dh", [])
    names = list(model.joint_names)
    out: list[dict[str, Any]] = []
    for i in range(table.n):
        sigma = (std_rows[i].get("std") or {}) if i < len(std_rows) else {}
        common = {"joint": names[i], "type": str(table.joint_types[i])}
        out.append(
            {
                "convention": "standard",
                **common,
                "theta_offset": float(table.theta_offset[i]),
                "d": float(table.d_offset[i]),
                "a": float(table.a[i]),
                "alpha": float(table.alpha[i]),
                **{
                    f"std_{k}": sigma.get(key)
                    for k, key in (
                        ("theta_offset", "theta"),
                        ("d", "d"),
                        ("a", "a"),
                        ("alpha", "alpha"),
                    )
                },
            }
        )
    for i in range(table.n):
        out.append(
            {
                "convention": "modified",
                "joint": names[i],
                "type": str(table.joint_types[i]),
                "alpha_prev": float(modified.alpha[i]),
                "a_prev": float(modified.a[i]),
                "theta_offset": float(modified.theta_offset[i]),
                "d": float(modified.d_offset[i]),
            }
        )
    if fmt == "dh-json":
        doc = {
            "source": Path(source).name,
            "units": {"length": "m", "angle": "rad"},
            "T_base": model.T_base.tolist(),
            "tool_point": model.tool_point.tolist(),
            "standard": [r for r in out if r["convention"] == "standard"],
            "modified": [r for r in out if r["convention"] == "modified"],
            "modified_T_tool_end": post.tolist(),
        }
        return json.dumps(doc, indent=2) + "\n"
    import csv
    import io

    columns = [
        "convention",
        "joint",
        "type",
        "theta_offset",
        "d",
        "a",
        "alpha",
        "alpha_prev",
        "a_prev",
        "std_theta_offset",
        "std_d",
        "std_a",
        "std_alpha",
    ]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, columns, lineterminator="\n")
    writer.writeheader()
    for row in out:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in columns})
    return buf.getvalue()
