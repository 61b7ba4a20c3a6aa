"""Has the robot changed? Two results compared parameter by parameter and over the joint range.

Each parameter's change is judged by its significance, the difference over the combined σ of
the two sessions (independent measurements: ``√(σ_A² + σ_B²)``); parameters fixed by a
convention in either are not compared. The rows are compared in the form the results show them
(the Hayati–Mirmirani form where both have the same nearly parallel rows, else standard DH).
The forward-kinematics difference is taken in the robot's own base frame (frame 1), so a tracker
placed elsewhere in the second session is no change of the robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.io.dhfile import DHFileError, parse_dh
from dhlog.io.safetext import printable
from dhlog.model.fk import fk_point
from dhlog.result.check import MAX_SUMMARY_BYTES, load_result, read_limited
from dhlog.result.fields import MAX_ANGLE_RAD, MAX_LENGTH_M

NAMES = ("theta_offset", "d_offset", "a", "alpha")


@dataclass(frozen=True)
class Change:
    """One parameter's change: name (``a_2``, ``beta_2``, ``tool_x``), A, B, B − A, the
    combined σ (None where either is fixed), and whether it is angular."""

    name: str
    a: float
    b: float
    diff: float
    sigma: float | None
    angular: bool

    @property
    def significance(self) -> float | None:
        """|B − A| over the combined σ."""
        if self.sigma is None or self.sigma <= 0:
            return None
        return abs(self.diff) / self.sigma


@dataclass(frozen=True)
class Comparison:
    """The parameter changes and the FK difference over the joint range (RMS, max, the joint
    vector of the max), in metres."""

    changes: list[Change]
    fk_rms: float
    fk_max: float
    fk_max_at: FloatArray
    samples: int


def _load(path: str | Path) -> dict[str, Any]:
    """A result JSON, its size, nesting and every field used here checked
    (:func:`dhlog.result.check.load_result`)."""
    return load_result(path)


def _rows(data: dict[str, Any], hayati: bool) -> list[dict[str, Any]]:
    return list(data["hayati_dh"]["rows"]) if hayati else list(data["standard_dh"])


def _units(data: dict[str, Any]) -> tuple[float, float]:
    """The result's length and angle scales to metres and radians (a result is in m and rad;
    a DH file may say ``units = {length = "mm", angle = "deg"}``)."""
    units = data.get("units") or {}
    return (1e-3 if units.get("length") == "mm" else 1.0), (
        math.pi / 180 if units.get("angle") == "deg" else 1.0
    )


def _value(row: dict[str, Any], key: str) -> float:
    """A row's parameter, as the DH reader takes it (``theta``/``d`` for the offsets, 0 when
    absent)."""
    if key in row:
        return float(row[key])
    short = key.removesuffix("_offset")
    return float(row.get(short, 0.0)) if short != key else float(row[key])


def _std(row: dict[str, Any], key: str) -> float | None:
    value = (row.get("std") or {}).get(key.removesuffix("_offset"))
    held = key.removesuffix("_offset") in (row.get("fixed") or [])
    return None if value is None or held else float(value)


Parameter = tuple[str, float, float | None, bool]


def parameters(data: dict[str, Any], hayati: bool | None = None) -> list[Parameter]:
    """(name, value, σ or None where held, angular) of every parameter of a result: per row
    θ, d (β in a Hayati–Mirmirani row), a, α, in the form the result shows them (``hayati``:
    the Hayati rows; default: where the result has them), then the tool point."""
    if hayati is None:
        hayati = bool(data.get("hayati_dh"))
    length, angle = _units(data)
    out: list[Parameter] = []
    for i, row in enumerate(_rows(data, hayati)):
        for key in NAMES:
            if key == "d_offset" and hayati and row.get("form") == "hayati":
                key = "beta"
            angular = key in ("theta_offset", "alpha", "beta")
            f = angle if angular else length
            sd = _std(row, key)
            name = f"{key.removesuffix('_offset')}_{i + 1}"
            out.append((name, _value(row, key) * f, None if sd is None else sd * f, angular))
    tool = data.get("tool") or {}
    if tool.get("point") is not None:
        for k, axis in enumerate("xyz"):
            sd = (tool.get("std") or [None] * 3)[k]
            sd = None if sd is None else float(sd) * length
            out.append((f"tool_{axis}", float(tool["point"][k]) * length, sd, False))
    return out


def compare(
    a_path: str | Path, b_path: str | Path, *, limits: FloatArray | None = None, points: int = 2000
) -> Comparison:
    """Compare two results of the same robot (``limits`` (n, 2): the joint range; default ±π
    and ±0.1 m)."""
    A, B = _load(a_path), _load(b_path)
    if len(A["standard_dh"]) != len(B["standard_dh"]):
        raise DHFileError(
            printable(str(b_path)),
            f"has {len(B['standard_dh'])} joints, {printable(str(a_path))} "
            f"{len(A['standard_dh'])}; compare two results of the same robot.",
        )
    forms = [
        [r["form"] for r in d["hayati_dh"]["rows"]] if d.get("hayati_dh") else None for d in (A, B)
    ]
    hayati = forms[0] is not None and forms[0] == forms[1]
    changes = []
    in_b = {p[0]: p for p in parameters(B, hayati)}
    for name, va, sa, angular in parameters(A, hayati):
        if name not in in_b:  # a tool point in one of them only
            continue
        _, vb, sb, _ = in_b[name]
        diff = wrap_angle(vb - va) if angular else vb - va
        sigma = None if sa is None or sb is None else math.hypot(sa, sb)
        changes.append(Change(name, va, vb, diff, sigma, angular))
    ma, mb = parse_dh(A, str(a_path)), parse_dh(B, str(b_path))
    n = ma.table.n
    if limits is None:
        revolute = [t.value == "revolute" for t in ma.table.joint_types]
        limits = np.array([[-math.pi, math.pi] if r else [-0.1, 0.1] for r in revolute])
    limits = np.asarray(limits, dtype=np.float64)
    if limits.shape != (n, 2) or not np.all(np.isfinite(limits)):
        raise DHFileError(
            printable(str(a_path)),
            f"has {n} joints, but the joint range given has {len(limits)}; give the limits of "
            "the same robot (--limits-from).",
        )
    Q = np.random.default_rng(0).uniform(limits[:, 0], limits[:, 1], (points, n))
    with np.errstate(all="ignore"):
        diff = np.linalg.norm(
            fk_point(ma.table, Q, ma.tool_point) - fk_point(mb.table, Q, mb.tool_point), axis=1
        )
    worst = int(np.argmax(diff))
    return Comparison(
        changes, float(np.sqrt(np.mean(diff**2))), float(diff[worst]), Q[worst], points
    )


@dataclass(frozen=True)
class Trend:
    """One parameter over a batch's sessions (in session order): its values and σ, the change
    from the first to the last session with its significance, and the largest step between
    consecutive sessions over their combined σ."""

    name: str
    angular: bool
    values: FloatArray
    sigmas: FloatArray
    change: float
    significance: float | None
    largest_step: float | None


#: The most columns a batch summary may have (100 joints: four parameters and their σ each,
#: the tool's, and a few dozen others).
MAX_SUMMARY_COLUMNS = 1024
#: The columns every summary has, and the columns read as text.
_NEEDED = ("log", "session_start", "status", "robot", "joints")
_TEXT = (*_NEEDED, "reason", "model")
#: Summary columns that are parameters, by their name's start.
_PARAMETER = ("theta_", "d_", "beta_", "a_", "alpha_", "tool_")
_ANGULAR = ("theta_", "alpha_", "beta_")
_SUMMARY_FIX = "repair it, or write the summary again with dhlog batch"


def _summary_fault(source: str, exc: BaseException) -> DHFileError:
    """A reader's error as one line (polars' messages run over several)."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    first = printable(lines[0] if lines else type(exc).__name__)[:200]
    return DHFileError(
        source,
        f"cannot be read as a batch summary ({first}); give the summary.csv or summary.parquet "
        "that dhlog batch wrote.",
    )


def read_summary(path: str | Path) -> Any:
    """A batch summary (``summary.csv`` or ``.parquet``) as a polars frame, checked as untrusted
    input: its size before it is read, at most ``MAX_SUMMARY_COLUMNS`` columns (counted before
    the rows are read), the columns a trend needs present, text columns as text, and every
    parameter and its σ a number in range (a cell that is not names its column and line)."""
    import io

    import polars as pl

    source = printable(str(path))
    raw = read_limited(path, MAX_SUMMARY_BYTES, "batch summary")
    parquet = str(path).endswith(".parquet")
    try:
        if parquet:
            columns = list(pl.read_parquet_schema(io.BytesIO(raw)))
        else:
            columns = pl.read_csv(io.BytesIO(raw), n_rows=0, infer_schema=False).columns
        if len(columns) > MAX_SUMMARY_COLUMNS:
            raise DHFileError(
                source,
                f"has {len(columns)} columns, more than a batch summary has (at most "
                f"{MAX_SUMMARY_COLUMNS}); give the summary that dhlog batch wrote.",
            )
        if parquet:
            frame = pl.read_parquet(io.BytesIO(raw))
        else:  # every cell as text: the columns are typed below, a bad cell named
            frame = pl.read_csv(io.BytesIO(raw), infer_schema=False)
    except (OSError, ValueError, OverflowError, pl.exceptions.PolarsError) as exc:
        raise _summary_fault(source, exc) from None
    except pl.exceptions.PanicException as exc:  # the reader's own fault, on damaged bytes
        raise _summary_fault(source, exc) from None
    missing = [c for c in _NEEDED if c not in frame.columns]
    if missing:
        raise DHFileError(
            source,
            f"is not a dhlog batch summary (no column {', '.join(missing)}); give the "
            "summary.csv or summary.parquet that dhlog batch wrote.",
        )
    typed = []
    for name in frame.columns:
        column = frame[name]
        if name in _TEXT:
            typed.append(_text_column(column, source))
        elif name.startswith(_PARAMETER) or name.removeprefix("std_").startswith(_PARAMETER):
            typed.append(_parameter_column(column, source, parquet))
        elif not parquet:  # other columns: numbers where every cell is one
            try:
                typed.append(column.cast(pl.Float64))
            except pl.exceptions.PolarsError:
                pass
    return frame.with_columns(typed)


def _text_column(column: Any, source: str) -> Any:
    import polars as pl

    try:
        return column.cast(pl.String)
    except pl.exceptions.PolarsError:
        raise DHFileError(
            source,
            f"column {printable(column.name)} holds {column.dtype}, not text; {_SUMMARY_FIX}.",
        ) from None


def _parameter_column(column: Any, source: str, parquet: bool) -> Any:
    """A parameter (or σ) column as float64, NaN where missing; a cell that is no number, or a
    value out of range, names its column and line."""
    import polars as pl

    name = printable(column.name)
    if column.dtype == pl.String:
        values = column.str.strip_chars().cast(pl.Float64, strict=False)
    elif column.dtype == pl.Null or column.dtype.is_numeric():
        values = column.cast(pl.Float64)
    else:
        raise DHFileError(
            source, f"column {name} holds {column.dtype}, not numbers; {_SUMMARY_FIX}."
        )

    def where(index: int) -> str:
        return f"row {index + 1}" if parquet else f"line {index + 2}"

    bad = (values.is_null() & column.is_not_null()).arg_true()
    if bad.len():
        k = int(bad[0])
        cell = printable(str(column[k]))[:40]
        raise DHFileError(
            source, f"column {name}, {where(k)}: '{cell}' is not a number; {_SUMMARY_FIX}."
        )
    array = values.fill_null(float("nan")).to_numpy().astype(np.float64)
    sigma = column.name.startswith("std_")
    angular = column.name.removeprefix("std_").startswith(_ANGULAR)
    bound, unit = (MAX_ANGLE_RAD, "rad") if angular else (MAX_LENGTH_M, "m")
    with np.errstate(invalid="ignore"):
        wrong = np.isinf(array) | (np.abs(array) > bound) | ((array < 0) if sigma else False)
    if np.any(wrong):
        k = int(np.flatnonzero(wrong)[0])
        raise DHFileError(
            source,
            f"column {name}, {where(k)}: {array[k]:.6g} is not a "
            f"{'σ' if sigma else 'value'} within ±{bound:g} {unit}; {_SUMMARY_FIX}.",
        )
    return pl.Series(column.name, array, dtype=pl.Float64)


def trends(frame: Any, source: str = "summary") -> tuple[list[str], list[float], list[Trend]]:
    """Every parameter's trend over the identified sessions of a batch summary
    (:func:`read_summary`), in session order: (the logs, their start times in s since the epoch,
    the trends). ``source`` names the summary in the messages."""
    import polars as pl

    try:
        rows = frame.filter(pl.col("status").is_in(["ok", "partial"])).sort(
            "session_start", maintain_order=True
        )  # sessions that start together: in the order given
        robots = rows.select(["robot", "joints"]).unique(maintain_order=True)
    except pl.exceptions.PolarsError as exc:
        raise _summary_fault(source, exc) from None
    if rows.height < 2:
        raise DHFileError(source, "needs two identified sessions or more for a trend.")
    if robots.height > 1:
        listed = "; ".join(f"{r} ({j})" for r, j in robots.head(4).iter_rows())
        raise DHFileError(
            source,
            f"holds sessions of different robots ({printable(listed)[:300]}); a trend is of one "
            "robot — filter the summary to one.",
        )
    logs = [str(v) for v in rows["log"].to_list()]
    starts = rows["session_start"].to_list()
    times = [_session_time(t, log, source) for t, log in zip(starts, logs, strict=True)]
    present = set(rows.columns)
    out = []
    for name in rows.columns:
        if not name.startswith(_PARAMETER):
            continue
        values = rows[name].cast(pl.Float64).fill_null(float("nan")).to_numpy()
        std_col = f"std_{name}"
        sigmas = (
            rows[std_col].cast(pl.Float64).fill_null(float("nan")).to_numpy()
            if std_col in present
            else np.full(values.size, np.nan)
        )
        if np.all(np.isnan(values)):
            continue
        angular = name.startswith(_ANGULAR)
        with np.errstate(all="ignore"):
            steps = np.diff(values)
            if angular:
                steps = np.array([wrap_angle(s) for s in steps])
            step_sigma = np.hypot(sigmas[1:], sigmas[:-1])
            z = np.abs(steps) / step_sigma
            change = float(steps.sum())  # NaN where a session lacks the parameter
            total_sigma = math.hypot(sigmas[0], sigmas[-1])
        out.append(
            Trend(
                name,
                angular,
                values,
                sigmas,
                change,
                abs(change) / total_sigma if total_sigma > 0 else None,
                float(np.nanmax(z)) if np.any(np.isfinite(z)) else None,
            )
        )
    return logs, times, out


#: Session starts a trend can place: 1970 to 2262 (nanoseconds since the epoch in 64 bits).
_LATEST_S = 9.2e9


def _session_time(value: object, log: str, source: str) -> float:
    """A session's start (ISO 8601 text) in s since the epoch (an identified session has one)."""
    try:
        t = datetime.fromisoformat(str(value)).timestamp() if value is not None else math.nan
    except (ValueError, OverflowError, OSError):
        t = float("nan")
    if not 0.0 <= t < _LATEST_S:  # NaN too
        shown = "empty" if value is None else f"'{printable(str(value))[:40]}'"
        raise DHFileError(
            source,
            f"column session_start of {printable(log)[:80]} is {shown}, not a time from 1970 to "
            f"2262 in ISO 8601 (2026-01-31T08:00:00+00:00); {_SUMMARY_FIX}.",
        )
    return t


def write_trend_recording(
    logs: list[str], times: list[float], found: list[Trend], path: str | Path
) -> None:
    """A Rerun recording of every parameter over the sessions (mm and degrees), with ±σ."""
    import rerun as rr
    import rerun.blueprint as rrb

    from dhlog.present.recording import recording_file as _recording_file

    groups = sorted({t.name.rsplit("_", 1)[0] for t in found})
    blueprint = rrb.Blueprint(
        rrb.Grid(*[rrb.TimeSeriesView(origin=f"trend/{g}", name=g) for g in groups]),
        collapse_panels=True,
    )
    stamps = np.asarray([t * 1e9 for t in times], dtype=np.int64).astype("datetime64[ns]")
    with _recording_file(path, "dhlog trend", blueprint) as rec:
        index = [rr.TimeColumn("session", timestamp=stamps)]
        rec.send_columns("trend/log", indexes=index, columns=rr.TextLog.columns(text=logs))
        for t in found:
            f = 180.0 / math.pi if t.angular else 1e3
            group = t.name.rsplit("_", 1)[0]
            base = f"trend/{group}/{t.name}"
            rec.send_columns(base, indexes=index, columns=rr.Scalars.columns(scalars=t.values * f))
            for sign, label in ((1.0, "plus_sigma"), (-1.0, "minus_sigma")):
                band = (t.values + sign * np.nan_to_num(t.sigmas)) * f
                rec.send_columns(
                    f"{base}/{label}", indexes=index, columns=rr.Scalars.columns(scalars=band)
                )
