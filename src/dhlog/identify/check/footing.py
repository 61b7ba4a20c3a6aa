"""Another session's log scored on one footing for every model (``--validate LOG``).

A held-out log may have been measured after the tracker moved (the base no longer where the
calibration put it) or after the probe was re-mounted (the target elsewhere on the flange). What
such a log needs is a property of the log, not of the model scored: so it is decided **once per
log**, and then the nominal and the calibrated model get exactly the same freedom, placed on the
same poses, and are scored at the same poses.

**The decision** (:func:`decide`). The log's poses are split: every third pose (the placing
poses) and the others (the scored poses). Each freedom — none, the tool (its point; with the
measured orientation also its frame), the base (``T_measurement_base``), both — is placed on the
placing poses and judged by the error it leaves at the scored poses (with the orientation: the
position error and the orientation error times :data:`LEVER`). The freedom taken is the smallest
(fewest numbers; a base before a tool of as many) whose error is within :data:`MOVED_RATIO` of the
best: a freedom is taken only when it lowers the error at poses it was not placed on by more than
that factor, i.e. by far more than the model's noise. The decision is made with the calibrated
model: whether the tracker moved or the probe was re-mounted is a fact of the session, and the
calibrated model is the sharpest instrument to see it with (a millimetre's shift stands out of a
0.05 mm error, not of the nominal's 1 mm); being taken once, it is the same for both models
whatever they would each have preferred, so two results scored on one log are comparable.

**What the log determines** (:func:`poses_of`, :class:`Shape`). The measured orientation
(6-DoF probe, where the calibration also measured it, so both models have a tool frame) places the
base from a line or a single point: everything is scored in 3-D. Without it, points spread over a
plane or a volume place the base; points on one line do not fix the base's rotation about the
line and cannot tell a re-mounted probe from a moved tracker — only the base is ever re-placed
there, and the errors across the line are scored (the component along it is left out: the
placement's translation takes its mean, and along a path it is where a clock shows; ISO 9283
measures a path's accuracy across it). Fewer than :data:`MIN_POSES` poses, or position-only
points all within :data:`~dhlog.identify.fit.placement.POINT_SPREAD` of one point, cannot be
scored (:class:`NotScoredError`).

**How a freedom is placed**: by the one placement routine every caller shares
(:func:`~dhlog.identify.fit.placement.place_on`: closed-form starts from the positions and the
measured orientations, robust least squares; the tool point only along the directions the
flange's orientation varies in). **Not scored**: when every freedom tried leaves the calibrated
model beyond :data:`FAR_RATIO` times the calibration's own error and :data:`FAR_FLOOR` at the
poses it was not placed on, no footing was found (another robot, unit or target) and the log is
not scored (:class:`NotScoredError` with ``unplaced``), never given a figure.

**Before.** The nominal comes to the log already placed: its base and tool point (and tool
frame) registered on the calibration session's samples (:func:`nominal_on_session`), the
session the calibrated model was fitted on. Neither model is ever placed on the poses it is scored
at.

Pure numpy/scipy.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray, nearest_rotation
from dhlog.identify.check.holdout import MIN_POSES, ErrorStats, Holdout
from dhlog.identify.fit.leaveout import pose_groups, pose_means
from dhlog.identify.fit.placement import (
    LEVER,
    Stand,
    Standing,
    angles,
    conditioning,
    place_on,
    tool_directions,
)
from dhlog.identify.fit.register import register_nominal
from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames, fk_point

#: A freedom is taken when it lowers the error at the poses it was not placed on by more than
#: this factor over the smaller freedoms (the tracker moved, the probe was re-mounted).
MOVED_RATIO = 2.0
#: A log is not scored when every footing tried leaves the calibrated model's error at the
#: poses it was not placed on beyond this many times the calibration's own error (its held-out
#: or in-sample FK RMS) …
FAR_RATIO = 20.0
#: … and beyond this (m): no footing was found (another robot's log, a wrong unit, poses the
#: placement cannot use), and a figure would say nothing of the calibration.
FAR_FLOOR = 1e-3
#: At most this many poses enter each placement of the decision (evenly strided).
DECISION_POSES = 3000


@dataclass(frozen=True)
class LogHoldout(Holdout):
    """A held-out log's check: beyond :class:`~dhlog.identify.check.holdout.Holdout`'s, whether the
    tool was placed again (``tool_replaced``: the probe was re-mounted) and which components of
    the errors are scored (``components``: ``"3-D"`` or ``"across the line"``), the offset (s)
    its joint states were scored at, added to their stamps as the log has them, the pipeline's
    ``clock_offset`` included, where its clock was checked or moved (``clock_offset``; None: a
    static-pose log in time, scored at its stops, or a clock not checked) and the samples
    taken while the joints moved that a static-pose log's scoring left out
    (``moving_left_out``), the tracker's gross outliers left out (``outliers_left_out``) and
    the drift its joint states' stamps were mapped by (``clock_drift``, s a second; the offset
    then holds at ``drift_reference_ns``) and the step of their clock mid-session taken out
    (``clock_step``, s added to the stamps from the one logged at ``clock_step_at_ns`` on)."""

    tool_replaced: bool = False
    components: str = "3-D"
    clock_offset: float | None = None
    moving_left_out: int = 0
    outliers_left_out: int = 0
    clock_drift: float | None = None
    drift_reference_ns: int = 0
    clock_step: float | None = None
    clock_step_at_ns: int = 0

    def document(self) -> dict[str, object]:
        doc = super().document()
        doc["tool_replaced"] = self.tool_replaced
        doc["components"] = self.components
        if self.clock_offset is not None:
            doc["clock_offset"] = self.clock_offset
        if self.moving_left_out:
            doc["moving_left_out"] = self.moving_left_out
        if self.outliers_left_out:
            doc["outliers_left_out"] = self.outliers_left_out
        if self.clock_drift is not None:
            doc["clock_drift"] = self.clock_drift
            doc["drift_reference_ns"] = self.drift_reference_ns
        if self.clock_step is not None:
            doc["clock_step"] = self.clock_step
            doc["clock_step_at_ns"] = self.clock_step_at_ns
        return doc


class NotScoredError(InputError):
    """A held-out log that cannot be scored (too few poses, one point without orientation, no
    footing found). ``unplaced``: the log could not be placed (one point without orientation,
    every footing far off): the calibration's validation is then missing, which the result
    says is implausible."""

    def __init__(self, message: str, *, unplaced: bool = False) -> None:
        super().__init__(message)
        self.unplaced = unplaced


@dataclass(frozen=True)
class Unscored:
    """A held-out log given but not scored: its ``path``, the ``reason`` (a sentence) and
    whether it could not be placed (``unplaced``: one point without orientation, no footing
    found), which makes the result implausible: its validation is missing."""

    path: str
    reason: str
    unplaced: bool = False

    def document(self) -> dict[str, object]:
        return {
            "path": self.path,
            "scored": False,
            "unplaced": self.unplaced,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class Placed(Standing):
    """A model as it stands in a log's frame M: the table and where it stands (``stand``:
    ``T_measurement_base`` as ``T``, the target in the last frame ``tool``, m, and the target
    frame's orientation there ``R_tool``, None when unknown; read through)."""

    table: StandardDH
    stand: Stand


@dataclass(frozen=True)
class Shape:
    """What a log's poses determine: ``kind`` ``"spread"`` (a plane or a volume), ``"line"``
    (``direction``: the line's unit vector), ``"point"``; ``oriented``: the measured orientation
    is used; ``spread``: the RMS spread (m) along the poses' three principal directions."""

    kind: str
    oriented: bool
    spread: FloatArray
    direction: FloatArray | None = None

    @property
    def across(self) -> bool:
        """Only the errors across the line are scored."""
        return self.kind == "line" and not self.oriented

    def scored(self, vectors: FloatArray) -> FloatArray:
        """The error vectors (k, 3) as scored: across the line where only that is."""
        if not self.across:
            return vectors
        u = self.direction
        assert u is not None
        return np.asarray(vectors - np.outer(vectors @ u, u), dtype=np.float64)


@dataclass(frozen=True)
class Poses:
    """A log's poses: each pose's mean joint values for each model (``Q`` for the calibrated,
    ``Qn`` for the nominal), its mean measured position ``P`` (k, 3) and orientation ``R``
    (k, 3, 3; None without)."""

    Q: FloatArray
    Qn: FloatArray
    P: FloatArray
    R: FloatArray | None


@dataclass(frozen=True)
class Footing:
    """The decision for one log: re-place the ``base`` and/or the ``tool`` on the poses
    ``placing`` (a mask over the poses) and score the others; the held-out errors (m) of the
    calibrated model for each freedom tried (``errors``: name → error), and the log's
    ``shape``."""

    base: bool
    tool: bool
    placing: NDArray[np.bool_]
    errors: dict[str, float]
    shape: Shape

    @property
    def placed(self) -> bool:
        return self.base or self.tool


def poses_of(
    groups: NDArray[np.int64],
    Q: FloatArray,
    Qn: FloatArray,
    P: FloatArray,
    R: FloatArray | None,
) -> Poses:
    """Each pose's mean joint values, position and (chordal mean) orientation."""

    def mean(values: FloatArray) -> FloatArray:
        return pose_means(groups, values)[1]

    rotations = None
    if R is not None:
        U, _, Vt = np.linalg.svd(mean(R))
        D = np.ones((U.shape[0], 3))
        D[:, 2] = np.sign(np.linalg.det(U @ Vt))
        rotations = np.einsum("kij,kj,kjl->kil", U, D, Vt)
    return Poses(mean(Q), mean(Qn), mean(P), rotations)


def shape_of(P: FloatArray, oriented: bool) -> Shape:
    """What the pose positions ``P`` (k, 3) determine (:class:`Shape`, through
    :func:`~dhlog.identify.fit.placement.conditioning`)."""
    c = conditioning(P)
    return Shape(c.kind, oriented, c.spread, c.direction)


_angles = angles


@dataclass(frozen=True)
class _Flange:
    """The last frame of a table at some joint values, in the table's frame 1."""

    R: FloatArray  # (k, 3, 3)
    p: FloatArray  # (k, 3)

    @classmethod
    def of(cls, table: StandardDH, Q: FloatArray) -> _Flange:
        frames = fk_frames(table, Q)[:, -1]
        return cls(frames[:, :3, :3], frames[:, :3, 3])

    def take(self, mask: NDArray[np.bool_] | NDArray[np.intp]) -> _Flange:
        return _Flange(self.R[mask], self.p[mask])


def _predict(
    model: Placed, flange: _Flange, oriented: bool
) -> tuple[FloatArray, FloatArray | None]:
    """The target's position (k, 3) and, ``oriented``, its frame (k, 3, 3) in M."""
    R0, c0 = model.T[:3, :3], model.T[:3, 3]
    local = np.einsum("kij,j->ki", flange.R, model.tool) + flange.p
    pos = local @ R0.T + c0
    if not oriented or model.R_tool is None:
        return np.asarray(pos, dtype=np.float64), None
    frame = np.einsum("ij,kjl,lm->kim", R0, flange.R, model.R_tool)
    return np.asarray(pos, dtype=np.float64), np.asarray(frame, dtype=np.float64)


def place(
    model: Placed,
    flange: _Flange,
    P: FloatArray,
    R: FloatArray | None,
    *,
    base: bool,
    tool: bool,
) -> Placed:
    """``model`` with its base and/or tool (point; frame too when ``R`` is given and the model
    has one) placed on the poses (``flange`` of its table, measured positions ``P`` (k, 3) and
    orientations ``R``) by the one placement routine
    (:func:`~dhlog.identify.fit.placement.place_on`: closed-form starts from the positions and
    the orientations, robust least squares; what the poses do not determine stays as it
    was)."""
    if not (base or tool):
        return model
    oriented = R is not None and model.R_tool is not None
    got = place_on(
        flange.R,
        flange.p,
        P,
        R if oriented else None,
        stand=model.stand,
        base=base,
        point=tool,
        frame=tool and oriented,
    )
    R_tool = got.R_tool if oriented else model.R_tool
    return replace(model, stand=Stand(got.T, got.tool, R_tool))


def _error(
    model: Placed, flange: _Flange, P: FloatArray, R: FloatArray | None, shape: Shape
) -> float:
    """RMS over the poses of the scored position error and, oriented, :data:`LEVER` × the
    orientation error."""
    pos, frame = _predict(model, flange, shape.oriented)
    e2 = np.sum(shape.scored(P - pos) ** 2, axis=1)
    if frame is not None and R is not None:
        e2 = e2 + (LEVER * _angles(np.einsum("kji,kjl->kil", R, frame))) ** 2
    return float(np.sqrt(np.mean(e2)))


def decide(calibrated: Placed, poses: Poses, shape: Shape) -> Footing:
    """The footing of a log (see the module docstring), decided with the calibrated model."""
    k = poses.P.shape[0]
    placing = np.zeros(k, dtype=bool)
    placing[::3] = True
    R = poses.R if shape.oriented else None
    flange = _Flange.of(calibrated.table, poses.Q)
    on = np.flatnonzero(placing)
    off = np.flatnonzero(~placing)
    on = on[:: max(1, on.size // DECISION_POSES)]
    off = off[:: max(1, off.size // DECISION_POSES)]
    Ron = None if R is None else R[on]
    Roff = None if R is None else R[off]
    tool_allowed = shape.kind == "spread" or shape.oriented
    tool_n = 6 if shape.oriented else 3
    tried = [("none", False, False, 0), ("base", True, False, 6)]
    if tool_allowed:
        tried += [("tool", False, True, tool_n), ("base and tool", True, True, 6 + tool_n)]
    errors: dict[str, float] = {}
    for name, base, tool, _ in tried:
        moved = place(calibrated, flange.take(on), poses.P[on], Ron, base=base, tool=tool)
        errors[name] = _error(moved, flange.take(off), poses.P[off], Roff, shape)
    best = min(errors.values())
    order = sorted(tried, key=lambda c: (c[3], c[2]))  # fewest numbers; a base before a tool
    chosen = next(c for c in order if errors[c[0]] <= MOVED_RATIO * best)
    return Footing(chosen[1], chosen[2], placing, errors, shape)


def nominal_on_session(
    table: StandardDH,
    Q: FloatArray,
    P: FloatArray,
    R: FloatArray | None,
    *,
    tool_point: FloatArray,
    T_base: FloatArray,
) -> Placed:
    """The nominal placed on the calibration session's samples (``Q`` its joint values, ``P``
    the primary target's positions, ``R`` its measured orientations or None): base and tool
    point by :func:`~dhlog.identify.fit.register.register_nominal`, the tool frame (with ``R``) as
    the chordal mean of the measured frames carried into the last frame."""
    reg = register_nominal(table, Q, P, tool_point=tool_point, T_base=T_base)
    R_tool = None
    if R is not None:
        flange = fk_frames(table, Q)[:, -1, :3, :3]
        inl = reg.inliers
        R_last = np.einsum("ij,kjl->kil", reg.T_measurement_base[:3, :3], flange[inl])
        R_tool = nearest_rotation(np.einsum("kji,kjl->il", R_last, R[inl]))
    return Placed(table, Stand(reg.T_measurement_base, reg.tool_point, R_tool))


@dataclass(frozen=True)
class LogSamples:
    """A held-out log's samples of its primary target: encoder values ``Q`` (m, n), measured
    positions ``P`` (m, 3) and orientations ``rotations`` (m, 3, 3; None: none, or a 3-DoF
    target), and each model's joint values at ``Q`` where they are not ``Q`` (fitted encoder
    scales, terms beyond the geometry): ``table_values`` the calibrated model's,
    ``nominal_values`` the nominal's (m, n; None: ``Q``)."""

    Q: FloatArray
    P: FloatArray
    rotations: FloatArray | None = None
    table_values: FloatArray | None = None
    nominal_values: FloatArray | None = None


def score_poses(
    calibrated: Placed,
    samples: LogSamples,
    *,
    path: str,
    nominal: Placed | None = None,
    own_error: float | None = None,
) -> LogHoldout:
    """The calibrated model and the nominal (both as they stand in the calibration session's
    frame: the nominal placed there by :func:`nominal_on_session`) at the poses of another
    session (its ``samples``, the log at ``path``), on one footing (see the module docstring).
    ``own_error`` (m): the calibration's own error (its held-out or in-sample FK RMS), against
    which a footing is judged found (:data:`FAR_RATIO`, :data:`FAR_FLOOR`). Raises
    :class:`NotScoredError` when the log cannot be scored."""
    Q, P, rotations = samples.Q, samples.P, samples.rotations
    table_values, nominal_values = samples.table_values, samples.nominal_values
    groups = pose_groups(Q)
    Qc = Q if table_values is None else table_values
    Qn = Q if nominal_values is None else nominal_values
    oriented = (
        rotations is not None
        and calibrated.R_tool is not None
        and (nominal is None or nominal.R_tool is not None)
    )
    poses = poses_of(groups, Qc, Qn, P, rotations if oriented else None)
    k = poses.P.shape[0]
    if k < MIN_POSES:
        raise NotScoredError(
            f"{path}: has {k} distinct pose(s) with encoder values; a held-out check needs at "
            f"least {MIN_POSES}."
        )
    shape = shape_of(poses.P, oriented)
    if shape.kind == "point" and not oriented:
        raise NotScoredError(
            f"{path}: its {k} poses put the target within {shape.spread[0] * 1e3:.3f} mm of one "
            "point and it carries no orientation: no base can be placed on them; measure poses "
            "that spread, or with a 6-DoF probe.",
            unplaced=True,
        )
    footing = decide(calibrated, poses, shape)
    unfound = _unfound(footing, own_error, path)
    if unfound is not None:
        raise NotScoredError(unfound, unplaced=True)
    scored = ~footing.placing if footing.placed else np.ones(k, dtype=bool)
    R = poses.R if oriented else None

    _, pose_of = np.unique(groups, return_inverse=True)  # each sample's pose, 0 … k−1
    rows = scored[pose_of]

    def scored_vectors(model: Placed, Qp: FloatArray, Qs: FloatArray) -> tuple[Placed, FloatArray]:
        """``model`` placed with the footing's freedom (poses' joint values ``Qp``) and its
        error vectors at the scored poses (samples' joint values ``Qs``)."""
        flange = _Flange.of(model.table, Qp[footing.placing])
        Rp = None if R is None else R[footing.placing]
        moved = place(
            model, flange, poses.P[footing.placing], Rp, base=footing.base, tool=footing.tool
        )
        pred = fk_point(model.table, Qs[rows], moved.tool, T_base=moved.T)
        return moved, shape.scored(pose_means(pose_of[rows], P[rows] - pred)[1])

    cal_moved, cal = scored_vectors(calibrated, poses.Q, Qc)
    nom = None
    if nominal is not None:
        _, nom = scored_vectors(nominal, poses.Qn, Qn)
    fixed = tool_directions(_Flange.of(calibrated.table, poses.Q).R).shape[1] == 3
    notes = _notes(footing, calibrated, cal_moved, k, nominal is not None, fixed)
    return LogHoldout(
        kind="log",
        nominal=None if nom is None else ErrorStats.of(np.linalg.norm(nom, axis=1)),
        calibrated=ErrorStats.of(np.linalg.norm(cal, axis=1)),
        positions=poses.P[scored],
        nominal_vectors=nom,
        calibrated_vectors=cal,
        path=path,
        registered=footing.base,
        n_registration_poses=int(np.count_nonzero(footing.placing)) if footing.placed else 0,
        notes=tuple(notes),
        T_measurement_base=cal_moved.T if footing.base else None,
        tool_replaced=footing.tool,
        components="across the line" if shape.across else "3-D",
    )


def _unfound(footing: Footing, own_error: float | None, path: str) -> str | None:
    """Why no footing of the log was found (every freedom tried leaves the calibrated model's
    error beyond :data:`FAR_RATIO` × ``own_error`` and :data:`FAR_FLOOR`), None when one was."""
    best_name = min(footing.errors, key=lambda name: footing.errors[name])
    best = footing.errors[best_name]
    limit = max(FAR_FLOOR, FAR_RATIO * (own_error or 0.0))
    if best <= limit:
        return None
    own = "" if own_error is None else f" (the calibration's own error is {own_error * 1e3:.4f} mm)"
    tried = ", ".join(f"{name} {v * 1e3:.1f} mm" for name, v in footing.errors.items())
    return (
        f"{path}: no footing places the calibrated model on its poses: every freedom tried "
        f"leaves an error far beyond {limit * 1e3:.3g} mm at the poses it was not placed on "
        f"({tried}){own}; it is not the same robot, unit or target as the calibration, or "
        "its poses cannot place it — check the log's robot, joints and units"
    ) + "."


def _notes(
    footing: Footing,
    before: Placed,
    after: Placed,
    k: int,
    with_nominal: bool,
    point_fixed: bool = True,
) -> list[str]:
    """What the log determines, what was placed on how many poses, and what "before" is
    (``point_fixed``: the poses determine the tool point in every direction)."""
    shape, e = footing.shape, footing.errors
    notes = []
    if shape.kind == "line":
        what = (
            f"the poses lie on one line ({shape.spread[1] * 1e3:.3f} mm across it, "
            f"{shape.spread[0] * 1e3:.1f} mm along it, RMS)"
        )
        if shape.oriented:
            notes.append(f"{what}: the measured orientation places the base; scored in 3-D.")
        else:
            notes.append(
                f"{what} and the log has no orientation: the errors across the line are "
                "scored, the component along it left out (a placement's translation takes its "
                "mean, and along a path it is where a clock shows; ISO 9283 measures path "
                "accuracy across the path); such poses cannot tell a re-mounted probe from a "
                "moved tracker, so only the base is ever placed again."
            )
    elif shape.kind == "point":
        notes.append(
            f"the poses lie within {shape.spread[0] * 1e3:.3f} mm of one point: the measured "
            "orientation places the base."
        )
    tried = ", ".join(f"{name} {v * 1e3:.4f} mm" for name, v in e.items())
    n_on = int(np.count_nonzero(footing.placing))
    if not footing.placed:
        what = f"nothing was placed again: both models scored as they stand at all {k} poses"
    else:
        parts = []
        if footing.base:
            parts.append("the base (the tracker moved)")
        if footing.tool:
            shift = np.linalg.norm(after.tool - before.tool) * 1e3
            moved = f"its point moved {shift:.3f} mm"
            if not point_fixed:
                moved = (
                    "its point not determined by these poses, at one orientation of the "
                    "flange: the base's translation takes it up"
                )
            turn = ""
            if after.R_tool is not None and before.R_tool is not None:
                angle = _angles((before.R_tool.T @ after.R_tool)[None])[0]
                turn = f", its frame turned {np.degrees(angle):.2f}°"
            parts.append(f"the tool (the probe was re-mounted: {moved}{turn} on the flange)")
        what = (
            f"{' and '.join(parts)} placed again on {n_on} poses (every third), for both "
            f"models alike; the other {k - n_on} scored"
        )
    notes.append(
        f"{what}. Decided once for this log with the calibrated model (its error at poses a "
        f"placement was not made on, for each freedom: {tried}; a freedom is taken when it "
        f"lowers that error more than {MOVED_RATIO:g}×)."
    )
    if footing.placed:
        other = "tool" if footing.base and not footing.tool else "base"
        if other in e and e[other] <= MOVED_RATIO * min(e.values()):
            notes.append(
                f"placing the {other} instead explains these poses as well "
                f"({e[other] * 1e3:.4f} mm): this log cannot tell a moved tracker from a "
                "re-mounted probe; both models had the same freedom either way."
            )
    if with_nominal:
        frame = " and tool frame" if shape.oriented else ""
        notes.append(
            f"before: the nominal with its base, tool point{frame} placed on the calibration "
            "session's samples (the session the calibrated model was fitted on, never this "
            "log's scored poses), then given the same freedom here as the calibrated model."
        )
    return notes
