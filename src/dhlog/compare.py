"""Has the robot changed? Two results compared parameter by parameter and over the joint range.

Each parameter's change is judged by its significance, the difference over the combined σ of
the two sessions (independent measurements: ``√(σ_A² + σ_B²)``); parameters fixed by a
convention in either are not compared. The rows are compared in the form the results show them
(the Hayati–Mirmirani form where both have the same nearly parallel rows, else standard DH).
The forward-kinematics difference is taken in the robot's own base frame (frame 1), so a tracker
placed elsewhere in the second session is no change of the robot.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.dhfile import DHFileError, parse_dh
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.kinematics import fk_point

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
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DHFileError(str(path), f"cannot be read as JSON ({exc}).") from None
    if not isinstance(data, dict) or not isinstance(data.get("standard_dh"), list):
        raise DHFileError(str(path), "is not a dhlog result (no 'standard_dh').")
    return data


def _rows(data: dict[str, Any], hayati: bool) -> list[dict[str, Any]]:
    return list(data["hayati_dh"]["rows"]) if hayati else list(data["standard_dh"])


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
    out: list[Parameter] = []
    for i, row in enumerate(_rows(data, hayati)):
        for key in NAMES:
            if key == "d_offset" and row.get("form") == "hayati":
                key = "beta"
            angular = key in ("theta_offset", "alpha", "beta")
            out.append(
                (f"{key.removesuffix('_offset')}_{i + 1}", float(row[key]), _std(row, key), angular)
            )
    tool = data.get("tool") or {}
    if tool.get("point") is not None:
        for k, axis in enumerate("xyz"):
            sd = (tool.get("std") or [None] * 3)[k]
            out.append((f"tool_{axis}", float(tool["point"][k]), sd, False))
    return out


def compare(
    a_path: str | Path, b_path: str | Path, *, limits: FloatArray | None = None, points: int = 2000
) -> Comparison:
    """Compare two results of the same robot (``limits`` (n, 2): the joint range; default ±π
    and ±0.1 m)."""
    A, B = _load(a_path), _load(b_path)
    if len(A["standard_dh"]) != len(B["standard_dh"]):
        raise DHFileError(
            str(b_path), f"has {len(B['standard_dh'])} joints, {a_path} {len(A['standard_dh'])}."
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
    Q = np.random.default_rng(0).uniform(limits[:, 0], limits[:, 1], (points, n))
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


def read_summary(path: str | Path) -> Any:
    """A batch summary (``summary.csv`` or ``.parquet``) as a polars frame."""
    import polars as pl

    source = str(path)
    try:
        frame = pl.read_parquet(path) if source.endswith(".parquet") else pl.read_csv(path)
    except (OSError, pl.exceptions.PolarsError) as exc:
        raise DHFileError(source, f"cannot be read as a batch summary ({exc}).") from None
    needed = {"log", "session_start", "status"}
    if not needed <= set(frame.columns):
        raise DHFileError(source, "is not a dhlog batch summary (no log, session_start, status).")
    return frame


#: Summary columns that are parameters, by their name's start.
_PARAMETER = ("theta_", "d_", "beta_", "a_", "alpha_", "tool_")


def trends(frame: Any) -> tuple[list[str], list[float], list[Trend]]:
    """Every parameter's trend over the identified sessions of a batch summary, in session
    order: (the logs, their start times in s since the epoch, the trends)."""
    import polars as pl

    rows = frame.filter(pl.col("status").is_in(["ok", "partial"])).sort(
        "session_start", maintain_order=True
    )  # sessions that start together: in the order given
    if rows.height < 2:
        raise DHFileError("summary", "needs two identified sessions or more for a trend.")
    robots = rows.select(["robot", "joints"]).unique()
    if robots.height > 1:
        listed = "; ".join(f"{r} ({j})" for r, j in robots.iter_rows())
        raise DHFileError(
            "summary",
            f"holds sessions of different robots ({listed}); a trend is of one robot — "
            "filter the summary to one.",
        )
    times = [
        datetime.fromisoformat(str(t)).timestamp() if t is not None else float("nan")
        for t in rows["session_start"].to_list()
    ]
    out = []
    for name in rows.columns:
        if not name.startswith(_PARAMETER):
            continue
        values = rows[name].cast(pl.Float64).to_numpy()
        std_col = f"std_{name}"
        sigmas = (
            rows[std_col].cast(pl.Float64).fill_null(float("nan")).to_numpy()
            if std_col in rows.columns
            else np.full(values.size, np.nan)
        )
        if np.all(np.isnan(values)):
            continue
        angular = name.startswith(("theta_", "alpha_", "beta_"))
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
    return [str(v) for v in rows["log"].to_list()], times, out


def write_trend_recording(
    logs: list[str], times: list[float], found: list[Trend], path: str | Path
) -> None:
    """A Rerun recording of every parameter over the sessions (mm and degrees), with ±σ."""
    import rerun as rr
    import rerun.blueprint as rrb

    from dhlog.recording import _recording_file

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
