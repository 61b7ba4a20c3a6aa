"""The ISO 9283 acceptance report from tracker logs: the visits of :mod:`dhlog.iso9283.cycles`
registered into the robot's base frame and turned into the characteristics of clause 7 per pose
(AP, RP, vAP, stabilisation time and overshoot), between P2 and P4 (AD, RD) and over time (drift).

**The base frame.** With a calibration result, its ``T_measurement_base`` (the tracker where it
stood for the calibration) carries the attained positions into the base frame; otherwise the
nominal is registered on the attained barycentres (a rigid best fit of its forward kinematics at
the commanded joints, :func:`dhlog.identify.fit.register.register_nominal`, the nominal's tool
point kept): the fit absorbs the part of the error a rigid motion explains, so AP is lower than
against the controller's own base frame — the report says so. Without a model the positions
stay in the measurement frame: repeatability, stabilisation and drift of the barycentre need no
model; accuracy is not computed.

**Before / after.** Before: the attained positions against the nominal's forward kinematics of
the commanded joints (the pose the controller, running the nominal, intended). After (with a
result): what ``dhlog compensate``'s corrected commands would attain, to first order — each
attained position minus (the calibrated model's prediction at the commanded joints − the
nominal's), against the same commanded positions; i.e. the error left is the attained position
minus the calibrated prediction. Computed, not measured: the report says so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.errors import DhlogError, InputError, Iso9283Error
from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel
from dhlog.io.pipeline import Pipeline
from dhlog.iso9283.cycles import (
    ARRIVAL_RATE,
    ENCODER_MATCH,
    SAME_DIRECTION,
    DwellSettings,
    PathPass,
    Segmented,
    Visit,
    segment_log,
)
from dhlog.iso9283.stops import NOT_DETERMINED
from dhlog.model.fk import fk_point

#: Stabilisation and overshoot are judged on the tracker's positions averaged over this period
#: (s) where it samples faster: the 100 Hz the standard asks for, so a faster tracker's noise
#: does not leave the band more often (a 1 kHz log read 60 ms long without it).
STABILISATION_PERIOD = 0.01
#: The pair of poses for distance accuracy and repeatability (clause 7.3).
DISTANCE_POSES = ("P2", "P4")
#: The commanded points left out at a path's start and end, tried in turn, when a pass does
#: not cross their normal planes (a robot stopping short of the end).
PATH_TRIMS = ((0, 0), (0, 1), (1, 0), (1, 1), (0, 2), (2, 0), (2, 2), (3, 3))
#: The pose drift is measured at (clause 7.6: P1).
DRIFT_POSE = "P1"


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


# ---------------------------------------------------------------- the formulas, as run uses them


def _accuracy(attained: FloatArray, commanded: FloatArray) -> Accuracy:
    """Clause 7.2.1 (:func:`dhlog.iso9283.formulas.pose_accuracy`)."""
    from dhlog.iso9283.formulas import pose_accuracy

    got = pose_accuracy(attained, commanded)
    d = np.asarray(got.AP_xyz, dtype=np.float64)
    sigma = None
    n = attained.shape[0]
    if n >= 2:  # σ(x̄_c) = S_c / √n; AP's along d/AP (all of it where AP is 0)
        var = np.var(attained, axis=0, ddof=1) / n
        u = d / got.AP_P if got.AP_P > 0 else np.full(3, 1 / math.sqrt(3))
        sigma = float(math.sqrt(float(np.sum(u**2 * var))))
    return Accuracy(float(got.AP_P), d, sigma)


def _repeatability(attained: FloatArray) -> tuple[float, float, float]:
    """Clause 7.2.2 (:func:`dhlog.iso9283.formulas.pose_repeatability`): RP_l, l̄, S_l."""
    from dhlog.iso9283.formulas import pose_repeatability

    got = pose_repeatability(attained)
    return float(got.RP_l), float(got.l_mean), float(got.S_l)


def _orientation_repeatability(attained: FloatArray, rotations: Sequence[FloatArray]) -> FloatArray:
    """Clause 7.2.2's RP_a, RP_b, RP_c (±3 S about the frame's x, y, z)."""
    from dhlog.iso9283.formulas import pose_repeatability

    got = pose_repeatability(attained, np.asarray(rotations))
    assert got.RP_abc is not None
    return np.asarray(got.RP_abc, dtype=np.float64)


def _stabilisation(visit: Visit) -> tuple[float, float] | None:
    """Clauses 7.4, 7.5 of one arrival (:func:`dhlog.iso9283.formulas.stabilisation`) in the
    visit's band around its attained position, on the positions averaged over
    ``STABILISATION_PERIOD`` where the tracker samples faster. The controller's attained-pose
    signal is not in
    the log: the encoders' stop stands in for it (:func:`dhlog.iso9283.cycles._encoders_stop`),
    without encoders the first sample within the band. None when the arrival's samples do not
    begin outside the band or never settle."""
    from dhlog.iso9283.formulas import stabilisation

    t, xyz = _binned(visit.arrival_t, visit.arrival_xyz, STABILISATION_PERIOD)
    d = np.linalg.norm(xyz - visit.position, axis=1)
    inside = np.flatnonzero(d <= visit.band)
    if inside.size == 0 or inside[0] == 0:
        return None
    try:
        got = stabilisation(
            t,
            xyz,
            visit.position,
            float(t[inside[0]]) if visit.arrival is None else visit.arrival,
            band=visit.band,
        )
    except DhlogError:
        return None
    return float(got.time), float(got.overshoot)


def _binned(t: FloatArray, xyz: FloatArray, period: float) -> tuple[FloatArray, FloatArray]:
    """Samples faster than ``period`` (s) averaged over consecutive bins of ``period``: each
    bin's mean time and position (slower samples as they are)."""
    steps = np.diff(t)
    if steps.size == 0 or float(np.median(steps)) >= 0.75 * period:
        return t, xyz
    bins = np.floor((t - t[0]) / period).astype(np.int64)
    edges = np.flatnonzero(np.diff(bins)) + 1
    counts = np.diff(np.r_[0, edges, t.size])
    mean_t = np.add.reduceat(t, np.r_[0, edges]) / counts
    mean_xyz = np.add.reduceat(xyz, np.r_[0, edges], axis=0) / counts[:, None]
    return mean_t, mean_xyz


# ---------------------------------------------------------------- the run


def _base_positions(
    seg: Segmented,
    nominal: DHModel | None,
    calibrated: DHModel | None,
    notes: list[str],
) -> tuple[FloatArray | None, str, str]:
    """The transform from the measurement frame into the nominal's base frame (None: the
    report stays in the measurement frame), its frame's name and how it was found."""
    if calibrated is not None:
        T_mb = calibrated.T_base
        base = nominal.T_base if nominal is not None else np.eye(4)
        _tracker_moved(seg, calibrated, notes)
        return (
            base @ np.linalg.inv(T_mb),
            "base",
            f"the result's T_measurement_base ({calibrated.source}): the tracker where it stood "
            "for the calibration",
        )
    if nominal is None:
        return None, "measurement", "none: no model given (positions in the tracker's frame)"
    if seg.pose_q is None:
        notes.append(
            "no commanded joints: the nominal cannot be registered; positions stay in the "
            "tracker's frame and accuracy is not computed."
        )
        return None, "measurement", "none: no commanded joints to register the nominal on"
    from dhlog.identify.fit.register import register_nominal

    named = [(k, seg.of_pose(n)) for k, n in enumerate(seg.poses) if seg.of_pose(n)]
    if len(named) < 3:
        notes.append(
            f"{len(named)} pose(s) visited: the nominal needs three to be registered on; "
            "accuracy is not computed (give --result)."
        )
        return None, "measurement", "none: fewer than three poses to register the nominal on"
    Q = np.array([seg.pose_q[k] for k, _ in named])
    P = np.array([np.mean([v.position for v in vs], axis=0) for _, vs in named])
    try:
        reg = register_nominal(nominal.table, Q, P, tool_point=nominal.tool_point, fit_tool=False)
    except (DhlogError, np.linalg.LinAlgError) as exc:  # a degenerate set of poses
        notes.append(f"the nominal could not be registered on the poses ({exc}).")
        return None, "measurement", "none: the registration failed"
    if reg.rms > FAR_RMS:
        raise Iso9283Error(
            "the base frame",
            f"the nominal {nominal.source}, placed as well as it can be on the {len(named)} poses' "
            f"attained barycentres, misses them by {reg.rms * 1e3:.1f} mm RMS — no robot's "
            f"nominal is that far off",
            "check that --nominal is this robot's, that the log's lengths are in the pipeline's "
            "unit and that the commanded joints are in radians",
        )
    notes.append(
        "the base frame is the nominal registered on the attained barycentres (a rigid best fit): "
        "it absorbs the error a rigid motion explains, so AP is lower than against the "
        "controller's base; give --result for the calibration's placement."
    )
    return (
        nominal.T_base @ np.linalg.inv(reg.T_measurement_base),
        "base",
        f"the nominal registered on the {len(named)} poses' attained barycentres (rigid best "
        f"fit, RMS {reg.rms * 1e3:.3f} mm)",
    )


#: A model that misses the poses by more than this RMS (m) after its best rigid placement is not
#: this robot's (or the log's units or the commanded joints' are not what they are read as): a
#: real robot's nominal is off by millimetres at most.
FAR_RMS = 0.01

#: A tracker moved since the calibration: the calibrated model, placed by the result, misses the
#: test's barycentres by more than this RMS (m) ...
MOVED_RMS = 1e-4
#: ... and a rigid re-placement of the model on them removes this much of it (RMS ratio): a
#: model error is not rigid; a tracker moved (or knocked) is.
MOVED_RATIO = 3.0


def _tracker_moved(seg: Segmented, calibrated: DHModel, notes: list[str]) -> None:
    """Say so where the result's placement of the tracker does not hold for this test: the
    calibrated model at the commanded joints misses the attained barycentres by more than
    :data:`MOVED_RMS`, and a rigid re-placement of the same model removes most of it
    (:data:`MOVED_RATIO`): the tracker stood elsewhere than for the calibration, and AP before
    and after (both in the result's base frame) carry that move."""
    if seg.pose_q is None:
        return
    named = [(k, seg.of_pose(n)) for k, n in enumerate(seg.poses) if seg.of_pose(n)]
    if len(named) < 3:
        return
    from dhlog.identify.fit.register import register_nominal

    Q = calibrated.joint_values(np.array([seg.pose_q[k] for k, _ in named]))
    P = np.array([np.mean([v.position for v in vs], axis=0) for _, vs in named])
    predicted = fk_point(calibrated.table, Q, calibrated.tool_point, T_base=calibrated.T_base)
    placed = float(np.sqrt(np.mean(np.sum((P - predicted) ** 2, axis=1))))
    if placed <= MOVED_RMS:
        return
    try:
        reg = register_nominal(
            calibrated.table, Q, P, tool_point=calibrated.tool_point, fit_tool=False
        )
    except (DhlogError, np.linalg.LinAlgError):  # a degenerate set of poses: nothing to say
        return
    if reg.rms > FAR_RMS:
        raise Iso9283Error(
            "the base frame",
            f"the calibration {calibrated.source}, placed as well as it can be on the "
            f"{len(named)} poses' barycentres, misses them by {reg.rms * 1e3:.1f} mm RMS",
            "check that --result is this robot's calibration and the log's lengths are in the "
            "pipeline's unit",
        )
    if placed > MOVED_RATIO * reg.rms:
        notes.append(
            f"the tracker has likely moved since the calibration: the calibrated model, placed "
            f"by {calibrated.source}'s T_measurement_base, misses the {len(named)} poses' "
            f"barycentres by {placed * 1e3:.3f} mm RMS, and a rigid re-placement of it by "
            f"{reg.rms * 1e3:.3f} mm; AP before and after carry the move. Measure the test "
            "with the tracker where it stood for the calibration, or run without --result "
            "(the nominal registered on the poses)."
        )


def _moved(T: FloatArray | None, p: FloatArray) -> FloatArray:
    return p if T is None else np.asarray(p @ T[:3, :3].T + T[:3, 3], dtype=np.float64)


def iso9283_report(
    segmented: Sequence[Segmented],
    *,
    nominal: DHModel | None = None,
    calibrated: DHModel | None = None,
) -> Iso9283Report:
    """The report from one or more logs' visits (see the module docstring). ``nominal``: the
    model the controller runs (its FK of the commanded joints is the commanded position);
    ``calibrated``: dhlog's result (placement and the after column)."""
    if not segmented:
        raise Iso9283Error("dhlog iso9283", "no log given", "give the test's log(s)")
    seg0 = segmented[0]
    notes = [n for s in segmented for n in s.notes]
    if len(segmented) > 1:  # the logs' visits in one list, each pose's cycles numbered on
        visits: list[Visit] = []
        passes: list[PathPass] = []
        counts: dict[str, int] = {}
        for s in segmented:
            renamed = _names_as_in(seg0, s, notes)
            for v in s.visits:
                v = replace(v, pose=renamed.get(v.pose, ""))
                c = v.cycle
                if v.pose:
                    c = counts.get(v.pose, 0) + 1
                    counts[v.pose] = c
                visits.append(replace(v, cycle=c))
            for pp in s.passes:
                c = counts.get("path " + pp.path, 0) + 1
                counts["path " + pp.path] = c
                passes.append(replace(pp, cycle=c))
        seg = Segmented(
            ", ".join(s.path for s in segmented),
            visits,
            seg0.poses,
            seg0.pose_q,
            seg0.commanded_from,
            min(s.rate_hz for s in segmented),
            all(s.orientation for s in segmented),
            [],
            passes,
            seg0.paths,
            seg0.stops,
        )
    else:
        seg = seg0
    T, frame, registration = _base_positions(seg, nominal, calibrated, notes)
    n_q = None if seg.pose_q is None else seg.pose_q.shape[1]
    if nominal is not None and n_q is not None and n_q != nominal.table.n:
        raise Iso9283Error(
            "--nominal",
            f"{nominal.source} has {nominal.table.n} joints but the commanded targets have {n_q}",
            "give the robot's own model",
        )
    accuracy = T is not None and nominal is not None and seg.pose_q is not None

    def commanded_at(k: int) -> FloatArray:
        assert nominal is not None and seg.pose_q is not None
        q = seg.pose_q[k]
        return np.asarray(fk_point(nominal.table, q, nominal.tool_point, T_base=nominal.T_base))

    def correction_at(k: int) -> FloatArray:
        """The calibrated prediction − the nominal's at pose k's commanded joints (base)."""
        assert calibrated is not None and nominal is not None and seg.pose_q is not None
        q = seg.pose_q[k]
        pred_m = fk_point(
            calibrated.table,
            calibrated.joint_values(q),
            calibrated.tool_point,
            T_base=calibrated.T_base,
        )
        assert T is not None
        return _moved(T, pred_m) - commanded_at(k)

    stabilising = seg.stops is None and seg.rate_hz >= 0.99 * ARRIVAL_RATE  # 100 Hz or so
    if not stabilising and seg.stops is None:
        notes.append(
            f"the tracker samples at {seg.rate_hz:.0f} Hz: stabilisation time and overshoot need "
            f"{ARRIVAL_RATE:.0f} Hz or more and are not computed."
        )
    poses: list[PoseReport] = []
    for k, name in enumerate(seg.poses):
        vs = seg.of_pose(name)
        if not vs:
            notes.append(f"{name} was never reached (no visit matched its commanded target).")
            continue
        X = _moved(T, np.array([v.position for v in vs]))
        before = after = None
        commanded = None
        if accuracy:
            commanded = commanded_at(k)
            before = _accuracy(X, commanded)
            if calibrated is not None:
                after = _accuracy(X - correction_at(k), commanded)
        RP = l_mean = S_l = None
        if len(vs) >= 2:
            RP, l_mean, S_l = _repeatability(X)
        abc = None
        if seg.orientation and len(vs) >= 2:
            Rs = [v.rotation for v in vs if v.rotation is not None]
            if len(Rs) >= 2:
                if T is None and not any("about the tracker's axes" in n for n in notes):
                    notes.append(
                        "RP_a, RP_b, RP_c are about the tracker's axes (no model places the "
                        "base frame)."
                    )
                R_frame = np.eye(3) if T is None else T[:3, :3]
                abc = _orientation_repeatability(X[: len(Rs)], [R_frame @ R for R in Rs])
        stab = [s for s in (_stabilisation(v) for v in vs) if s is not None] if stabilising else []
        times = [s[0] for s in stab]
        overs = [s[1] for s in stab]
        vap, ndir = _multi_directional(vs, X)
        poses.append(
            PoseReport(
                name,
                len(vs),
                X.mean(axis=0),
                commanded,
                before,
                after,
                RP,
                l_mean,
                S_l,
                abc,
                float(np.mean(times)) if times else None,
                float(np.max(times)) if times else None,
                float(np.mean(overs)) if overs else None,
                float(np.max(overs)) if overs else None,
                sum(1 for v in vs if not v.settled),
                vap,
                ndir,
                X,
            )
        )
        if len(vs) < 2:
            notes.append(
                f"{name}: {len(vs)} cycle: RP needs 2 cycles or more (the standard: 30); not "
                "computed."
            )
    poses.sort(key=lambda p: _name_order(p.name))  # reported P1 … P5, whatever the cycle order
    cycles = max((p.visits for p in poses), default=0)
    if 0 < cycles < 30:
        notes.append(
            f"{cycles} cycle(s) per pose: the standard asks 30; the figures are from these."
        )
    missing = [n for n in ("P1", "P2", "P3", "P4", "P5") if n not in seg.poses]
    if missing:  # (a pose of the program never reached is named above)
        notes.append(
            f"{len(seg.poses)} test pose(s) in the log: the standard has five (P1–P5); "
            f"{', '.join(missing)} not in this log."
        )
    if not any(p.directions > 1 for p in poses):
        notes.append(
            "vAP (multi-directional accuracy variation): not in this log (every pose is "
            "approached from one direction)."
        )
    paths = [] if seg.stops is not None else _paths(seg, T, nominal, calibrated, notes)
    distance = _distance(
        seg,
        T,
        commanded_at if accuracy else None,
        correction_at if accuracy and calibrated is not None else None,
        notes,
    )
    drift = _drift(seg, T, commanded_at if accuracy else None, notes)
    after_basis = None
    if calibrated is not None and accuracy:
        after_basis = (
            "computed: each attained position minus (the calibrated model's prediction at the "
            "commanded joints − the nominal's), i.e. what dhlog compensate's corrected commands "
            "would attain to first order; not measured"
        )
    return Iso9283Report(
        [s.path for s in segmented],
        frame,
        registration,
        seg.commanded_from,
        after_basis,
        seg.rate_hz,
        len(seg.visits),
        cycles,
        poses,
        distance,
        drift,
        seg.orientation,
        notes,
        paths,
        seg.stops,
        [] if seg.stops is None else list(NOT_DETERMINED),
    )


def _name_order(name: str) -> tuple[int, str]:
    """P1 … P5 by number, other names after them as they come."""
    digits = name[1:]
    return (int(digits), "") if name[:1] == "P" and digits.isdigit() else (10**6, name)


def _names_as_in(first: Segmented, other: Segmented, notes: list[str]) -> dict[str, str]:
    """The names ``other``'s poses have in ``first`` (by their commanded joints, within
    ``SAME_TARGET``; by name where either has none); a pose of ``other`` not in ``first`` is
    left out, said."""
    if other is first or first.pose_q is None or other.pose_q is None:
        return {n: n for n in other.poses if n in first.poses}
    out = {}
    for name, q in zip(other.poses, other.pose_q, strict=True):
        hit = [
            n
            for n, fq in zip(first.poses, first.pose_q, strict=True)
            if fq.shape == q.shape and float(np.max(np.abs(fq - q))) <= ENCODER_MATCH
        ]
        if hit:
            out[name] = hit[0]
        else:
            notes.append(
                f"{other.path}: its pose {name} is none of {first.path}'s: its visits are left "
                "out (the logs of one test command the same poses)."
            )
    return out


def tracker_sigma(visits: Sequence[Visit]) -> float | None:
    """The tracker's σ per coordinate (m) from the settled dwells' scatter (each visit's 3-D RMS
    about its mean, pooled; isotropic noise assumed); None without settled visits."""
    scatter = [v.scatter for v in visits if v.settled and v.n_settled > 1]
    return math.sqrt(float(np.mean(np.square(scatter))) / 3.0) if scatter else None


def noise_rt(sigma: float, cycles: int, points: int, draws: int = 200) -> float:
    """The path repeatability RT (clause 8.2: max over points of l̄ + 3 S_l) that isotropic
    tracker noise of σ per coordinate alone gives when each of ``points`` crossings is one
    sample in ``cycles`` passes: its two components in each normal plane, ``draws`` seeded
    draws averaged. What RT reads above the robot's own repeatability comes to about this, added
    in quadrature to first order."""
    rng = np.random.default_rng(0)
    d = rng.normal(0.0, sigma, (draws, cycles, points, 2))
    d -= d.mean(axis=1, keepdims=True)
    lengths = np.linalg.norm(d, axis=3)
    rt = lengths.mean(axis=1) + 3.0 * lengths.std(axis=1, ddof=1)
    return float(np.mean(rt.max(axis=1)))


def _paths(
    seg: Segmented,
    T: FloatArray | None,
    nominal: DHModel | None,
    calibrated: DHModel | None,
    notes: list[str],
) -> list[PathReport]:
    """Clause 8.2 for each of the program's paths (:func:`dhlog.iso9283.formulas.path_accuracy`
    on the passes in the base frame, the commanded points the nominal's FK of the path's joint
    targets); after: the crossings' barycentres less the part in each normal plane of the
    calibrated model's correction at the commanded point (what compensated commands would move
    the crossing by, to first order)."""
    from dhlog.iso9283.formulas import path_accuracy

    if not seg.paths:
        notes.append(
            "paths (AT, RT): the commanded paths come from the test program: give --commanded "
            "with the program dhlog plan --iso9283 wrote; not computed."
        )
        return []
    out = []
    for name, q in seg.paths:
        passes = [p for p in seg.passes if p.path == name]
        if not passes:
            continue  # named by the segmentation
        if len(passes) < 2:
            notes.append(f"path {name}: 1 pass: AT and RT need 2 or more; not computed.")
            continue
        if T is None or nominal is None:
            notes.append(
                f"path {name}: AT and RT need the base frame (--nominal, or --result); not "
                "computed."
            )
            continue
        commanded = np.asarray(
            fk_point(nominal.table, q, nominal.tool_point, T_base=nominal.T_base)
        )
        attained = [_moved(T, p.xyz) for p in passes]
        got = None
        first = 0
        problem = ""
        for a, b in PATH_TRIMS:  # the ends a pass may stop short of (the robot stops there)
            try:
                got = path_accuracy(attained, commanded[a : len(q) - b])
            except DhlogError as exc:
                problem = problem or str(exc)
                continue
            if a or b:
                notes.append(
                    f"path {name}: the first {a} and last {b} commanded point(s) are not crossed "
                    "by every pass (the robot stops at the path's ends, short of their normal "
                    "planes): left out of AT and RT."
                )
            commanded, q, first = commanded[a : len(q) - b], q[a : len(q) - b], a
            break
        if got is None:
            notes.append(f"path {name}: {problem}")
            continue
        after = None
        if calibrated is not None:
            predicted = _moved(
                T,
                np.asarray(
                    fk_point(
                        calibrated.table,
                        calibrated.joint_values(q),
                        calibrated.tool_point,
                        T_base=calibrated.T_base,
                    )
                ),
            )
            # the compensated commands move the path by −(predicted − commanded): its crossing
            # of each normal plane moves by that correction's part in the plane
            tangent = np.gradient(commanded, axis=0, edge_order=2)
            tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
            correction = predicted - commanded
            correction -= np.sum(correction * tangent, axis=1, keepdims=True) * tangent
            left = got.barycentres - correction - commanded
            after = float(np.max(np.linalg.norm(left, axis=1)))
        sigma = tracker_sigma(seg.visits)
        floor = None if sigma is None else noise_rt(sigma, int(got.cycles), len(q))
        if sigma is not None and floor is not None and floor > 0.25 * float(got.RT_P):
            notes.append(
                f"path {name}: the tracker's noise ({sigma * 1e6:.1f} µm per coordinate, from "
                f"the dwells) alone gives RT {floor * 1e3:.3f} mm, "
                f"{100 * floor / float(got.RT_P):.0f} % of the {float(got.RT_P) * 1e3:.3f} mm "
                "measured (each crossing is one sample): the robot's own RT is about "
                f"{math.sqrt(max(float(got.RT_P) ** 2 - floor**2, 0.0)) * 1e3:.3f} mm "
                "(√(RT² − noise's²))."
            )
        out.append(
            PathReport(
                name,
                int(got.cycles),
                len(q),
                first,
                float(got.AT_P),
                after,
                float(got.RT_P),
                int(np.argmax(got.deviation)),
                int(np.argmax(got.repeatability)),
                commanded,
                attained,
                RT_noise=floor,
            )
        )
    return out


def _multi_directional(vs: list[Visit], X: FloatArray) -> tuple[float | None, int]:
    """Clause 7.2.3: the visits grouped by approach direction (within ``SAME_DIRECTION``, two
    visits at least); vAP (:func:`dhlog.iso9283.formulas.multi_directional`) from the groups'
    barycentres (None with one direction), and the number of directions."""
    from dhlog.iso9283.formulas import multi_directional

    groups: list[tuple[FloatArray, list[int]]] = []
    for i, v in enumerate(vs):
        if not np.any(v.direction):
            continue
        for d, members in groups:
            if float(np.dot(d, v.direction)) >= math.cos(SAME_DIRECTION):
                members.append(i)
                break
        else:
            groups.append((v.direction, [i]))
    groups = [g for g in groups if len(g[1]) >= 2]
    if len(groups) < 2:
        return None, len(groups)
    bary = np.array([X[m].mean(axis=0) for _, m in groups])
    return float(multi_directional(bary).vAP_P), len(groups)


def _distance(
    seg: Segmented,
    T: FloatArray | None,
    commanded_at: Any,
    correction_at: Any,
    notes: list[str],
) -> DistanceReport | None:
    """Clause 7.3 between P2 and P4 (:func:`dhlog.iso9283.formulas.distance_accuracy` with a
    model): D_j = |P4_j − P2_j| per cycle, AD = D̄ − D_c, RD = 3 S_D."""
    from dhlog.iso9283.formulas import distance_accuracy

    a, b = DISTANCE_POSES
    if a not in seg.poses or b not in seg.poses:
        notes.append(f"AD/RD: {a} or {b} not in this log; not computed.")
        return None
    pa = {v.cycle: v.position for v in seg.of_pose(a)}
    pb = {v.cycle: v.position for v in seg.of_pose(b)}
    both = sorted(set(pa) & set(pb))
    if not both:
        notes.append(f"AD/RD: no cycle visits both {a} and {b}; not computed.")
        return None
    Xa = _moved(T, np.array([pa[c] for c in both]))
    Xb = _moved(T, np.array([pb[c] for c in both]))
    D = np.linalg.norm(Xb - Xa, axis=1)
    ka, kb = seg.poses.index(a), seg.poses.index(b)
    Dc = AD = AD_after = None
    RD = float(3.0 * D.std(ddof=1)) if D.size >= 2 else None
    if commanded_at is not None:
        ca, cb = commanded_at(ka), commanded_at(kb)
        Dc = float(np.linalg.norm(cb - ca))
        AD = float(D.mean() - Dc)
        if D.size >= 2:
            got = distance_accuracy(Xa, Xb, ca, cb)
            AD, RD = float(got.AD_P), float(got.RD)
        if correction_at is not None:
            Da = np.linalg.norm((Xb - correction_at(kb)) - (Xa - correction_at(ka)), axis=1)
            AD_after = float(Da.mean() - Dc)
    if RD is None:
        notes.append(f"RD: {D.size} cycle with both {a} and {b}: needs 2 or more; not computed.")
    return DistanceReport((a, b), int(D.size), float(D.mean()), Dc, AD, AD_after, RD)


#: A test shorter than this (h) between its first and last P1 cycles is not a drift test.
DRIFT_HOURS = 0.5


def _drift(
    seg: Segmented, T: FloatArray | None, commanded_at: Any, notes: list[str]
) -> DriftReport | None:
    """Clause 7.6 at P1 between the first and the last ``min(10, n // 2)`` cycles
    (:func:`dhlog.iso9283.formulas.drift` with a model; without one, dRP and the shift)."""
    from dhlog.iso9283.formulas import drift

    vs = seg.of_pose(DRIFT_POSE)
    if len(vs) < 4:
        notes.append(
            f"drift: {len(vs)} visit(s) to {DRIFT_POSE}: needs 4 or more (two groups of two); "
            "not computed."
        )
        return None
    g = min(10, len(vs) // 2)
    X = _moved(T, np.array([v.position for v in vs]))
    t_h = np.array([(v.t_start_ns - vs[0].t_start_ns) * 1e-9 / 3600.0 for v in vs])
    first, last = X[:g], X[-g:]
    hours = float(t_h[-g:].mean() - t_h[:g].mean())
    dAP = None
    dRP = abs(_repeatability(first)[0] - _repeatability(last)[0])
    if commanded_at is not None:
        got = drift([first, last], commanded_at(seg.poses.index(DRIFT_POSE)))
        dAP, dRP = float(got.dAP), float(got.dRP)
    shift = float(np.linalg.norm(last.mean(axis=0) - first.mean(axis=0)))
    rate = 0.0
    if np.ptp(t_h) > 0:
        slope = np.polyfit(t_h, X, 1)[0]
        rate = float(np.linalg.norm(slope))
    if hours < DRIFT_HOURS:
        notes.append(
            f"drift: the first and last cycles at {DRIFT_POSE} are {hours * 60:.1f} min apart: "
            "clause 7.6's drift test runs over hours (from a cold start); these figures are the "
            "change over this test only (rate_per_hour: a line through these minutes, not shown)."
        )
    return DriftReport(DRIFT_POSE, g, hours, dAP, dRP, shift, rate)


# ---------------------------------------------------------------- logs in, the document out

#: The report file's format name.
FORMAT = "dhlog.iso9283/1"


def run_logs(
    logs: Sequence[str | Path],
    *,
    pipeline: Pipeline | None = None,
    nominal: DHModel | None = None,
    calibrated: DHModel | None = None,
    commanded_csv: str | Path | None = None,
    settings: DwellSettings | None = None,
    stops: bool | None = None,
    further_tools: Sequence[FloatArray] = (),
) -> Iso9283Report:
    """``dhlog iso9283``: read each log, find its visits and path passes, and report.
    ``commanded_csv``: the test program ``dhlog plan --iso9283`` wrote
    (:func:`dhlog.iso9283.program.read_program`); ``stops``: the logs are static measurements,
    one per stop (None: detected; :mod:`dhlog.iso9283.stops`). Several targets: the primary
    one's report, each further target's in ``further``; ``further_tools``: the result's tool
    points of targets 2, 3, … (its ``tool.further_targets``), which give their AP and AD
    (with ``calibrated``)."""
    from dhlog.io.reader import read_log
    from dhlog.iso9283.program import read_program
    from dhlog.iso9283.stops import synthetic_timing, target_count

    segmented = []
    further: list[list[Segmented]] = []
    program = None
    named = calibrated if calibrated is not None else nominal  # the joints matched by its names
    said: list[str] = []
    if (
        nominal is not None
        and calibrated is not None
        and not np.any(nominal.tool_point)
        and np.any(calibrated.tool_point)
    ):
        # a nominal without a tool (a DH file to the flange) scored against the target would
        # measure the tool's length, not the robot's accuracy: the result's tool, as --validate
        # gives the nominal
        nominal = replace(nominal, tool_point=np.asarray(calibrated.tool_point, np.float64))
        said.append(
            "AP before: the nominal gives no tool point, so it carries the result's "
            f"({_mm(calibrated.tool_point)} mm on the flange), as --validate does; the before "
            "and after differ only by the robot's geometry."
        )
    for log in logs:
        data = read_log(
            log,
            pipeline,
            joint_names=None if named is None else named.joint_names,
            joint_source="model" if named is None else named.source,
        )
        if commanded_csv is not None and program is None:
            n = nominal.table.n if nominal is not None else len(data.joint_names)
            if n == 0:
                raise InputError(
                    f"{log}: no joint names to read {commanded_csv} with; give --nominal."
                )
            program = read_program(commanded_csv, n)
            if nominal is not None:
                _program_is_the_nominals(program, nominal, commanded_csv)
        kw: dict[str, Any] = dict(
            settings=settings,
            program=program,
            program_source=f"the test program {commanded_csv}",
            stops=stops,
        )
        segmented.append(segment_log(data, **kw))
        for k in range(1, target_count(data.points)):
            if len(further) < k:
                further.append([])
            further[k - 1].append(segment_log(data, **kw, target=k))
    if program is not None:
        names = {n for n, k in zip(program.name, program.kind, strict=True) if k == "pose"}
        matched = {v.pose for seg in segmented for v in seg.visits} & names
        if not matched:
            raise Iso9283Error(
                "the test program",
                f"no visit in the log matches a pose of {commanded_csv}",
                "check that the program is the one the robot ran (its joints in radians, this "
                "robot's)",
            )
    if len(further) >= 2:  # three reflectors or more: the tool's orientation from them
        from dhlog.iso9283.reflectors import with_reflector_frames

        segmented = [
            with_reflector_frames(seg, [further[0][i], further[1][i]], seg.notes)
            for i, seg in enumerate(segmented)
        ]
    synthetic = all(synthetic_timing(log) for log in logs)
    report = _timed(iso9283_report(segmented, nominal=nominal, calibrated=calibrated), synthetic)
    if said:
        report = replace(report, notes=[*said, *report.notes])
    if not further:
        return report
    from dhlog.iso9283.stops import further_note

    others = []
    placed = 0
    for k, segs in enumerate(further, start=2):
        nominal_k = calibrated_k = None
        if nominal is not None and calibrated is not None and k - 2 < len(further_tools):
            tool = np.asarray(further_tools[k - 2], dtype=np.float64)
            nominal_k = replace(nominal, tool_point=tool)
            calibrated_k = replace(calibrated, tool_point=tool)
            placed += 1
        got = iso9283_report(segs, nominal=nominal_k, calibrated=calibrated_k)
        others.append(replace(_timed(got, synthetic), target=k))
    note = further_note(1 + len(others), placed)
    return replace(report, further=others, notes=[*report.notes, note])


def _mm(point: FloatArray) -> str:
    return ", ".join(f"{1e3 * v:.3f}" for v in np.asarray(point, dtype=np.float64))


def _timed(report: Iso9283Report, synthetic: bool) -> Iso9283Report:
    """Stops whose stamps are not times (``dhlog import``'s one stop every 2 s,
    :func:`dhlog.iso9283.stops.synthetic_timing`): the drift's hours and rate not known (NaN:
    null in the JSON), said in a note."""
    if report.stops is None or report.drift is None or not synthetic:
        return report
    notes = [n for n in report.notes if not n.startswith("drift: the first and last cycles")]
    notes.append(
        "drift: the stops are in the export's row order, taken as time order; their stamps are "
        "dhlog import's (one stop every 2 s), so the time between the first and last cycles is "
        "not known (hours and rate_per_hour null): dAP and dRP are the change over the test."
    )
    drift = replace(report.drift, hours=math.nan, rate=math.nan)
    return replace(report, drift=drift, notes=notes)


def _program_is_the_nominals(program: Any, nominal: DHModel, source: str | Path) -> None:
    """The program's tool points (``x, y, z``) are the nominal's forward kinematics of its
    joint targets, for some tool point (the one it was planned with, found by least squares: a
    DH file's nominal may carry none): a program of another robot, or with its joints in
    degrees, is one clear error."""
    from dhlog.model.fk import fk_frames

    if not len(program.q):
        return
    last = fk_frames(nominal.table, program.q, T_base=nominal.T_base)[:, -1]
    A = last[:, :3, :3].reshape(-1, 3)
    b = (program.xyz - last[:, :3, 3]).reshape(-1)
    tool = np.linalg.lstsq(A, b, rcond=None)[0]
    fk = np.einsum("kij,j->ki", last[:, :3, :3], tool) + last[:, :3, 3]
    worst = float(np.max(np.linalg.norm(fk - program.xyz, axis=1)))
    if worst > PROGRAM_TOLERANCE:
        raise Iso9283Error(
            "the test program",
            f"{source}'s tool points are not the nominal {nominal.source}'s forward kinematics of "
            f"its joint targets (up to {worst * 1e3:.1f} mm apart)",
            "give the program dhlog plan --iso9283 wrote for this robot's nominal (joints in "
            "radians), or the nominal it was planned with",
        )


#: How far (m) a program's tool point may lie from the nominal's FK of its joints (rounding).
PROGRAM_TOLERANCE = 1e-6


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
