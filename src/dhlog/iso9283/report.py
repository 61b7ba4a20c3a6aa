"""The ISO 9283 acceptance report as data: per pose (:class:`PoseReport`: AP with its σ, RP, vAP,
stabilisation time and overshoot), between P2 and P4 (:class:`DistanceReport`: AD, RD), over
time (:class:`DriftReport`), per path (:class:`PathReport`: AT, RT, the velocity
characteristics) and the whole (:class:`Iso9283Report`); the report document
(:func:`report_document`, format :data:`FORMAT`) and its atomic write (:func:`write_report`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dhlog.geometry._checks import FloatArray


@dataclass(frozen=True)
class Accuracy:
    """Pose accuracy (clause 7.2.1): ``AP`` (m) = |x̄ − x_c| and its components (3,), and
    ``sigma`` (m): AP's standard uncertainty from the barycentre's sampling (the visits'
    scatter over √n; the commanded position and, after, the model taken as exact)."""

    AP: float
    components: FloatArray
    sigma: float | None = None

    def document(self) -> dict[str, Any]:
        x, y, z = (float(v) for v in self.components)
        return {"AP": self.AP, "AP_x": x, "AP_y": y, "AP_z": z, "AP_sigma": self.sigma}


@dataclass(frozen=True)
class PoseReport:
    """One test pose's characteristics (SI: m, rad, s); None where not computed."""

    name: str
    visits: int
    barycentre: FloatArray  # (3,) in the report's frame
    commanded: FloatArray | None  # (3,) the nominal's FK of the commanded joints, base frame
    before: Accuracy | None
    after: Accuracy | None
    RP: float | None
    l_mean: float | None
    S_l: float | None
    RP_abc: FloatArray | None  # (3,) ±3 S_a, S_b, S_c (rad)
    stabilisation_time: float | None  # mean over arrivals (s)
    stabilisation_max: float | None
    overshoot: float | None  # mean over arrivals (m)
    overshoot_max: float | None
    unsettled: int
    vAP: float | None
    directions: int
    #: each visit's attained position (n, 3) in the report's frame, in cycle order
    attained: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        def vec(v: FloatArray | None) -> list[float] | None:
            return None if v is None else [float(x) for x in v]

        return {
            "pose": self.name,
            "visits": self.visits,
            "barycentre": vec(self.barycentre),
            "commanded": vec(self.commanded),
            "before": None if self.before is None else self.before.document(),
            "after": None if self.after is None else self.after.document(),
            "RP": self.RP,
            "l_mean": self.l_mean,
            "S_l": self.S_l,
            "RP_abc": vec(self.RP_abc),
            "stabilisation_time": self.stabilisation_time,
            "stabilisation_time_max": self.stabilisation_max,
            "overshoot": self.overshoot,
            "overshoot_max": self.overshoot_max,
            "unsettled": self.unsettled,
            "vAP": self.vAP,
            "directions": self.directions,
            "attained": None if self.attained is None else [vec(a) for a in self.attained],
        }


@dataclass(frozen=True)
class DistanceReport:
    """Distance accuracy and repeatability between two poses (clause 7.3): ``D_mean`` the mean
    attained distance over ``cycles``, ``D_commanded`` (None without a model), ``AD`` = D̄ − D_c
    (before; ``AD_after`` with a result), ``RD`` = 3 S_D."""

    poses: tuple[str, str]
    cycles: int
    D_mean: float
    D_commanded: float | None
    AD: float | None
    AD_after: float | None
    RD: float | None

    def document(self) -> dict[str, Any]:
        return {
            "poses": list(self.poses),
            "cycles": self.cycles,
            "D_mean": self.D_mean,
            "D_commanded": self.D_commanded,
            "AD": self.AD,
            "AD_after": self.AD_after,
            "RD": self.RD,
        }


@dataclass(frozen=True)
class DriftReport:
    """Drift at ``pose`` (clause 7.6) between the first and the last ``group`` cycles, ``hours``
    apart (their mean times): dAP = |AP_first − AP_last| (None without a model), dRP =
    |RP_first − RP_last|, the barycentre's shift (m) and its rate (m/h, a line fitted to every
    visit's position over time)."""

    pose: str
    group: int
    hours: float
    dAP: float | None
    dRP: float | None
    shift: float
    rate: float

    def document(self) -> dict[str, Any]:
        return {
            "pose": self.pose,
            "group": self.group,
            "hours": self.hours,
            "dAP": self.dAP,
            "dRP": self.dRP,
            "shift": self.shift,
            "rate_per_hour": self.rate,
        }


@dataclass(frozen=True)
class PathReport:
    """Path accuracy and repeatability of one test path (clause 8.2) over ``cycles`` passes at
    ``points`` of its commanded points from index ``first_point`` on (a pass may stop short of
    the ends): ``AT`` (before: against the nominal's FK of the commanded
    joints; ``AT_after`` with a result), ``RT``, and the points where each is largest."""

    path: str
    cycles: int
    points: int
    first_point: int
    AT: float
    AT_after: float | None
    RT: float
    AT_at_point: int
    RT_at_point: int
    #: the commanded points used (m, 3) and each pass's samples (k, 3), in the report's frame
    commanded: FloatArray | None = None
    passes: list[FloatArray] = field(default_factory=list)
    #: the RT the tracker's noise alone gives at these cycles and points (m; None: the noise
    #: unknown): each crossing is one sample, so RT carries it (:func:`noise_rt`)
    RT_noise: float | None = None

    def document(self) -> dict[str, Any]:
        return {
            "path": self.path,
            "cycles": self.cycles,
            "points": self.points,
            "first_point": self.first_point,
            "AT": self.AT,
            "AT_after": self.AT_after,
            "RT": self.RT,
            "AT_at_point": self.AT_at_point,
            "RT_at_point": self.RT_at_point,
            "RT_noise": self.RT_noise,
        }


@dataclass(frozen=True)
class Iso9283Report:
    """The acceptance report: per pose, distance, drift, per path,
    the frame and how it was found, where the commanded targets came from, and ``notes`` (one
    line each: what is missing or assumed)."""

    logs: list[str]
    frame: str
    registration: str
    commanded_from: str
    after_basis: str | None
    rate_hz: float
    visits: int
    cycles: int
    poses: list[PoseReport]
    distance: DistanceReport | None
    drift: DriftReport | None
    orientation: bool
    notes: list[str] = field(default_factory=list)
    paths: list[PathReport] = field(default_factory=list)
    #: None: the visits are dwells of a time series; else how the log was read as stops
    #: (:mod:`dhlog.iso9283.stops`)
    stops: str | None = None
    #: what the log does not determine, one line each (stops: stabilisation, paths)
    not_determined: list[str] = field(default_factory=list)
    #: which target of the log (1: the primary one) and the further targets' own reports
    target: int = 1
    further: list[Iso9283Report] = field(default_factory=list)

    def document(self) -> dict[str, Any]:
        """The ``iso9283`` block (docs/iso9283.md, src/dhlog/schemas/iso9283.schema.json)."""
        extra: dict[str, Any] = {}
        if self.stops is not None or self.further or self.target != 1:
            extra = {
                "measured_as": "dwells" if self.stops is None else "stops",
                "stops": self.stops,
                "not_determined": list(self.not_determined),
                "target": self.target,
            }
        if self.further:
            extra["further_targets"] = [r.document() for r in self.further]
        return {
            **extra,
            "units": {"length": "m", "angle": "rad", "time": "s"},
            "frame": self.frame,
            "registration": self.registration,
            "commanded_from": self.commanded_from,
            "after": self.after_basis,
            "tracker_rate_hz": self.rate_hz,
            "visits": self.visits,
            "cycles": self.cycles,
            "orientation": self.orientation,
            "poses": [p.document() for p in self.poses],
            "distance": None if self.distance is None else self.distance.document(),
            "drift": None if self.drift is None else self.drift.document(),
            "paths": [p.document() for p in self.paths],
            "notes": list(self.notes),
        }


#: The report file's format name.
FORMAT = "dhlog.iso9283/1"


def report_document(report: Iso9283Report, source: dict[str, Any]) -> dict[str, Any]:
    """``<stem>.iso9283.json``: the format, dhlog's version, the sources and the block."""
    from dhlog._version import version

    return {
        "format": FORMAT,
        "dhlog_version": version(),
        "source": source,
        "iso9283": report.document(),
    }


def write_report(document: dict[str, Any], path: str | Path) -> None:
    """The document written atomically as JSON (non-finite numbers as null)."""
    import json

    from dhlog.io.writer import atomic_output

    def clean(v: Any) -> Any:
        if isinstance(v, float):
            return v if math.isfinite(v) else None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, list):
            return [clean(x) for x in v]
        return v

    text = json.dumps(clean(document), indent=2, allow_nan=False) + "\n"
    with atomic_output(path) as f:
        f.write(text.encode("utf-8"))
