"""``<stem>.holdout.csv`` read for the certificate, untrusted: :func:`read_holdout_csv` gives
each held-out check its per-pose errors, a file that does not agree with the result JSON (another
run's) a :class:`~dhlog.present.certificate.read.ResultFileError` naming it."""

from __future__ import annotations

import csv
import io
import math

from dhlog.present.certificate.read import ResultFileError
from dhlog.present.certificate.shown import Check, mm

#: What to do about a damaged ``<stem>.holdout.csv``.
CSV_REMEDY = (
    "write it again with dhlog process --holdout (or remove it: the certificate then has no "
    "histogram)"
)


def read_holdout_csv(text: str, path: str, checks: list[Check]) -> list[Check]:
    """``checks`` with their per-pose errors from ``<stem>.holdout.csv`` (``result.holdout_csv``:
    one row per scored pose, the checks in the JSON's order); a file that does not agree with
    the JSON (another run's) is an error naming it."""
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise ResultFileError(path, "the header", "is missing", CSV_REMEDY)
    header = rows[0]
    unit = None
    for scale, suffix in ((1e-3, "mm"), (1.0, "m")):
        if f"calibrated_error_{suffix}" in header:
            unit = (scale, suffix)
    if unit is None or "check" not in header or "pose" not in header:
        raise ResultFileError(
            path,
            "the header",
            "lacks the columns check, pose and calibrated_error_mm (or _m)",
            CSV_REMEDY,
        )
    scale, suffix = unit
    col = {name: k for k, name in enumerate(header)}
    nominal_col = col.get(f"nominal_error_{suffix}")
    groups: list[tuple[str, list[float | None], list[float]]] = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise ResultFileError(
                path, f"line {line}", f"has {len(row)} cells, the header {len(header)}", CSV_REMEDY
            )
        try:
            pose = int(row[col["pose"]])
        except ValueError:
            raise ResultFileError(
                path, f"line {line}, column pose", "must be a whole number", CSV_REMEDY
            ) from None
        cal = _csv_length(row[col[f"calibrated_error_{suffix}"]], path, line, "calibrated_error")
        if cal is None:
            raise ResultFileError(
                path, f"line {line}, column calibrated_error_{suffix}", "is empty", CSV_REMEDY
            )
        nom = (
            None
            if nominal_col is None
            else _csv_length(row[nominal_col], path, line, "nominal_error")
        )
        name = row[col["check"]]
        if pose == 1 or not groups or groups[-1][0] != name:
            groups.append((name, [], []))
        groups[-1][1].append(None if nom is None else nom * scale)
        groups[-1][2].append(cal * scale)
    if len(groups) != len(checks):
        raise ResultFileError(
            path,
            "the rows",
            f"hold {len(groups)} check(s), the result's validation.holdout {len(checks)}: the "
            "file is from another run",
            CSV_REMEDY,
        )
    out = []
    for k, (check, (_, nominal, calibrated)) in enumerate(zip(checks, groups, strict=True)):
        rms = math.sqrt(sum(v * v for v in calibrated) / len(calibrated))
        if len(calibrated) != check.calibrated.n_poses or not math.isclose(
            rms, check.calibrated.rms, rel_tol=1e-5, abs_tol=1e-12
        ):
            raise ResultFileError(
                path,
                f"check {k + 1}",
                f"has {len(calibrated)} poses of RMS {mm(rms)}, the result "
                f"{check.calibrated.n_poses} of RMS {mm(check.calibrated.rms)}: the file is "
                "from another run",
                CSV_REMEDY,
            )
        given = [v for v in nominal if v is not None]
        nominal_errors = given if check.nominal is not None and len(given) == len(nominal) else None
        out.append(
            Check(
                check.label,
                check.n_poses,
                check.nominal,
                check.calibrated,
                check.notes,
                nominal_errors,
                calibrated,
            )
        )
    return out


def _csv_length(cell: str, path: str, line: int, column: str) -> float | None:
    if not cell.strip():
        return None
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise ResultFileError(
            path,
            f"line {line}, column {column}",
            f"must be a length ≥ 0, not {cell[:40]!r}",
            CSV_REMEDY,
        )
    return value
