"""ISO 9283 from stops: a tracker's static measurements, one point per stop, as most tracker
software exports a repeatability test (and ``dhlog import`` writes a table without a time
column: one stop per row).

**Stops.** The tracker's samples split into runs at gaps longer than ``DwellSettings.gap``
(0.1 s); each run is one stop and its mean the stop's attained position (a run is one sample for
an export of averaged points). A log is read as stops when no dwell is found and no run lasts
``DwellSettings.min_time`` (0.5 s): the samples are too sparse in time to hold a dwell, so the
log cannot be a time series of the test (detected; said in the report), or when ``--stops``
says so. Visits are told apart by their commanded joints (else the encoders at the stop) as for
dwells (:func:`dhlog.iso9283.cycles.segment_log`): stops whose joint vectors agree within
``SAME_TARGET`` are visits to one pose, their order gives the cycles; every target visited twice
or more is a test pose (more than five: named P1 … Pk as first visited).

**What stops determine.** AP (with the commanded positions: ``--nominal``/``--result``, the
same footing as for dwells), RP, vAP (where a pose's visits come from several directions: the
stop before each visit, 30° apart), AD/RD, drift (where the stops are in time order: the
import's stops are the export's row order, their 2 s spacing is not a time, so the hours
between the drift groups are not known). Not determined by stops: the stabilisation time and
overshoot (clauses 7.4, 7.5: no samples of the arrival) and the path characteristics (clause 8:
no path is measured): marked not determined, no figure printed.

**Several targets** (``dhlog import --targets``, or a pipeline's ``extra_topics``): each
reflector is its own target with its own report (``Iso9283Report.further``), RP, RD and drift per
reflector. AP needs each reflector's commanded position: the nominal's tool point is the
primary target's, so the further targets' AP and AD are not determined (said), unless the
result gives their points (``tool.further_targets``, :func:`further_tool_points`): then the
nominal's and the result's forward kinematics of the commanded joints with that point.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from dhlog.errors import Iso9283Error
from dhlog.geometry._checks import FloatArray

#: With ``--stops`` a run of samples longer than this (s) is refused: a time series, not a stop.
MAX_STOP = 10.0
#: What stops do not determine, one line each (the report's ``not_determined``).
NOT_DETERMINED = (
    "stabilisation time and overshoot (clauses 7.4, 7.5): stops hold no samples of the arrival",
    "path accuracy and repeatability AT, RT (clause 8): no path is measured in stops",
)


def stop_runs(
    name: str, t_s: FloatArray, *, gap: float, min_time: float, explicit: bool
) -> tuple[list[tuple[int, int]], str | None]:
    """The stops of a tracker stream at times ``t_s`` (s): (first, end) sample indices of each
    run between gaps longer than ``gap`` (s), and how the log was found to be stops (None: it
    is not: a run lasts ``min_time`` (s) or more, and ``explicit`` is False). ``explicit``
    (``--stops``): a run longer than ``MAX_STOP`` is refused."""
    breaks = np.flatnonzero(np.diff(t_s) > gap) + 1
    edges = np.r_[0, breaks, t_s.size].astype(np.int64)
    runs = [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]
    longest = max((float(t_s[b - 1] - t_s[a]) for a, b in runs), default=0.0)
    per_stop = t_s.size / max(len(runs), 1)
    shape = (
        f"{t_s.size} sample(s) in {len(runs)} stop(s) ({per_stop:.3g} a stop), more than "
        f"{gap:g} s apart"
    )
    if explicit:
        if longest > MAX_STOP:
            raise Iso9283Error(
                name,
                f"--stops: the tracker stream runs {longest:.0f} s without a gap (a time series, "
                "not one measurement per stop)",
                "leave --stops out: the dwells of a time series are found",
            )
        return runs, f"stops (--stops): {shape}"
    if len(runs) < 2 or longest >= min_time:
        return [], None
    return runs, (
        f"stops (detected: {shape}, none lasting {min_time:g} s — static measurements, no time "
        "series to find dwells in)"
    )


#: A stop this far (m) from the stop before it was moved to from there (a repeat measured in
#: place, nearer, has no approach direction).
STOP_APPROACH = 1e-3


def stop_direction(position: FloatArray, previous: object) -> FloatArray:
    """The approach direction of a stop (unit, (3,)): from the stop before it, where that one
    lies ``STOP_APPROACH`` or more away; zeros otherwise (the first stop, a repeat in place)."""
    if previous is None:
        return np.zeros(3)
    d = position - np.asarray(previous, dtype=np.float64)
    norm = float(np.linalg.norm(d))
    return np.asarray(d / norm if norm >= STOP_APPROACH else np.zeros(3), dtype=np.float64)


def synthetic_timing(log: str | Path) -> bool:
    """Whether the log's stamps are ``dhlog import``'s one stop every 2 s (an export without a
    time column: the order is the export's, the spacing is not a time)."""
    from dhlog.io.choose import import_record

    if Path(log).is_dir():
        return False
    return import_record(log).get("timing", "").startswith("step and measure")


def target_count(points: object) -> int:
    """How many targets a log's point table holds (its ``target`` column: 0, 1, …)."""
    import polars as pl

    assert isinstance(points, pl.DataFrame)
    if "target" not in points.columns or points.height == 0:
        return 1
    return int(points["target"].max()) + 1  # type: ignore[arg-type]


def further_note(count: int, placed: int) -> str:
    """The note of a log with ``count`` targets of which ``placed`` further ones have the
    result's tool point: what is computed for the further ones."""
    head = (
        f"{count} targets: each reflector is its own target (targets 2 … {count} in "
        "further_targets, each its own report)"
    )
    if placed >= count - 1:
        return (
            f"{head}; each further target's AP and AD against the nominal's and the result's "
            "forward kinematics with the result's point of that target (tool.further_targets: "
            "the nominal has none)."
        )
    which = f"targets {placed + 2} … {count}" if placed else "the further targets"
    return (
        f"{head}; AP and AD of {which} are not determined (the nominal's tool point is the "
        "primary target's; a result with tool.further_targets, given with --nominal, gives "
        "theirs); RP, RD and drift are."
    )


def further_tool_points(document: dict[str, object], source: str) -> list[FloatArray]:
    """The further targets' tool points (m, the last frame) of a result document's
    ``tool.further_targets`` (target 2, 3, … in order); each checked (three finite numbers
    within 10 m), a bad one refused naming the field."""
    from dhlog.errors import InputError

    tool = document.get("tool")
    items = tool.get("further_targets") if isinstance(tool, dict) else None
    if items is None:
        return []
    if not isinstance(items, list):
        raise InputError(f"{source}: tool.further_targets must be a list; re-write the result.")
    out = []
    for k, item in enumerate(items):
        point = item.get("point") if isinstance(item, dict) else None
        ok = (
            isinstance(point, list)
            and len(point) == 3
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in point)
        )
        value = np.asarray(point if ok else [np.nan] * 3, dtype=np.float64)
        if not ok or not np.all(np.isfinite(value)) or float(np.max(np.abs(value))) > 10.0:
            raise InputError(
                f"{source}: tool.further_targets[{k}].point must be three finite numbers (m); "
                "re-write the result with dhlog process."
            )
        out.append(value)
    return out
