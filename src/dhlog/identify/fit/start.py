"""Where the whole-model fit starts for joints never moved alone (no sweep to fit an axis to).

* :func:`start_from_nominal`: the nominal's axes laid onto the axes the sweeps found (at least
  two, fixing a rotation: :func:`align_lines`), or — when fewer joints were swept alone, as with
  random static poses — the nominal registered onto the points
  (:func:`dhlog.identify.fit.register.register_nominal`).
* :func:`start_from_neighbours` (no nominal): a revolute joint moved only together with an
  identified parallel neighbour as ``q_k − ref_k = −(q_j − ref_j)`` (the level forearm move).
  ``Rot_j(Δ) Rot_k(−Δ)`` is then the translation ``(R(Δ) − I)(c_k − c_j)``: the target runs on a
  circle of radius |c_k − c_j| about an axis parallel to both, whose centre gives
  ``c_j = c_k − (p₀ − centre)`` (p₀ the target at Δ = 0).

Either gives a :class:`Start`: every joint's axis at the reference pose, the types, the target
and, for the joints started, where their start came from. The whole-model fit decides whether
the samples determine them. Both are pure numpy/scipy on arrays (``Q`` (m, n) encoder values,
``P`` (m, 3) the primary target's points); :func:`start_unswept` picks one for a run's joints and
measurement table, after checking that every joint to start moved at all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import GeometryError, Note
from dhlog.geometry._checks import FloatArray, nearest_rotation, rotation_about
from dhlog.geometry.lines import Line
from dhlog.identify.fit.register import Registration, register_nominal
from dhlog.identify.joints.sweeps import JointReport, samples_with_encoders, target_labels
from dhlog.identify.segment.segment import Segmentation
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.screws import chain_motion

#: A joint whose encoder values span less than this (rad or m) never moved in the log.
NEVER_MOVED = 1e-3
#: A coupled move's joint values follow q_k − ref_k = −(q_j − ref_j) within this fraction.
COUPLED_RATIO_TOL = 0.05
#: ... and its circle's axis is within this (rad) of the known neighbour's: the pair parallel.
COUPLED_PARALLEL_TOL = math.radians(5.0)


@dataclass(frozen=True)
class Known:
    """What the sweeps found of one joint (0-based ``index``): its type and axis at the
    reference pose (None when it was not identified)."""

    index: int
    type: JointType | None
    axis: Line | None


@dataclass(frozen=True)
class Start:
    """A start of the whole model: ``axes`` and ``types`` of every joint, the ``target`` at the
    reference pose, for each joint started (0-based) where its start came from, and the
    registration when the nominal was placed on the points."""

    axes: tuple[Line, ...]
    types: tuple[JointType, ...]
    target: FloatArray
    sources: dict[int, str]
    registration: Registration | None = None


def start_unswept(
    joints: Sequence[JointReport],
    seg: Segmentation,
    ref: FloatArray,
    nominal: DHModel | None,
    parked: Sequence[int] = (),
) -> tuple[Start | None, tuple[Note, ...]]:
    """The start of the ``joints`` the sweeps did not identify, from every sample with encoder
    values: the nominal's (:func:`start_from_nominal`) or, without one, a coupled move's
    (:func:`start_from_neighbours`). None when one of them never moved, the nominal cannot be
    placed on the points (both said in a warning: ``never-moved``, ``nominal-placement``), or a
    joint has no start. ``parked``
    (0-based; with a nominal): joints that never moved and are held at the nominal's start."""
    rows, Qs, Ps = samples_with_encoders(seg)
    Q, P = Qs[:], Ps[:]  # the start reads every sample at once (a session of still poses)
    held = set(parked)  # said by their own line (held at the nominal, or: give --nominal)
    if rows.size == 0:
        return None, ()
    still = _never_moved_warning([j for j in joints if j.index - 1 not in held], Q)
    if still:
        return None, still
    which = target_labels(seg, rows)
    primary = slice(None) if which is None else which == 0
    known = [Known(j.index - 1, j.type, j.axis if j.ok else None) for j in joints]
    if nominal is None:
        return start_from_neighbours(known, Q[primary], P[primary], ref), ()
    try:
        placed = start_from_nominal(
            known,
            Q[primary],
            P[primary],
            ref,
            nominal.table,
            T_base=nominal.T_base,
            tool_point=nominal.tool_point,
        )
    except GeometryError as exc:
        said = f"the nominal could not be placed on the points: {exc}"
        return None, (Note.warning(said, "nominal-placement"),)
    return placed, ()


def _never_moved_warning(joints: Sequence[JointReport], Q: FloatArray) -> tuple[Note, ...]:
    """A warning (``never-moved``) naming the joints not identified whose encoder never
    moved; empty when there is none."""
    still = never_moved(Q, [j.index - 1 for j in joints if not j.ok])
    if not still:
        return ()
    by_index = {j.index - 1: j.name for j in joints}
    names = ", ".join(f"joint {k + 1} ({by_index[k]})" for k in still)
    said = (
        f"{names}: never moved in this log (its encoder values span less than "
        f"{NEVER_MOVED:g}): nothing in the samples measures it."
    )
    return (Note.warning(said, "never-moved"),)


def never_moved(Q: FloatArray, joints: Sequence[int]) -> list[int]:
    """Of ``joints`` (0-based), those whose encoder values span less than :data:`NEVER_MOVED`."""
    return [k for k in joints if Q.shape[0] == 0 or float(np.ptp(Q[:, k])) < NEVER_MOVED]


def _target_at(
    axes: Sequence[Line],
    types: tuple[JointType, ...],
    Q: FloatArray,
    P: FloatArray,
    ref: FloatArray,
) -> FloatArray:
    """The target at the reference pose from the sample nearest it, moved back through ``axes``."""
    nearest = int(np.argmin(np.sum((Q - ref) ** 2, axis=1)))
    M = chain_motion(list(axes), types, Q[nearest], ref)
    return np.asarray(np.linalg.solve(M, np.r_[P[nearest], 1.0])[:3], dtype=np.float64)


def start_from_nominal(
    known: Sequence[Known],
    Q: FloatArray,
    P: FloatArray,
    ref: FloatArray,
    table: StandardDH,
    *,
    T_base: FloatArray,
    tool_point: FloatArray,
) -> Start:
    """The nominal ``table`` (its ``T_base`` and ``tool_point`` only start a registration) as the
    start of every joint ``known`` does not give an axis for (see the module docstring). Raises
    :class:`~dhlog.errors.DegenerateGeometryError` when neither the swept axes nor the points
    place it."""
    from dhlog.model.fk import fk_point, joint_axes

    types = tuple(table.joint_types)
    found = [k for k in known if k.axis is not None]
    missing = {k.index for k in known if k.axis is None}
    points, dirs = joint_axes(table, ref, T_base=T_base)
    T = (
        align_lines(
            [(points[k.index], dirs[k.index]) for k in found],
            [(k.axis.point, k.axis.direction) for k in found if k.axis is not None],
        )
        if len(found) >= 2
        else None
    )
    if T is not None:
        axes = tuple(
            k.axis
            if k.axis is not None
            else Line(T[:3, :3] @ points[k.index] + T[:3, 3], T[:3, :3] @ dirs[k.index])
            for k in known
        )
        target = _target_at(axes, types, Q, P, ref)
        return Start(axes, types, target, dict.fromkeys(missing, "nominal"))
    reg = register_nominal(table, Q, P, tool_point=tool_point, T_base=T_base)
    points, dirs = joint_axes(table, ref, T_base=reg.T_measurement_base)
    axes = tuple(
        k.axis if k.axis is not None else Line(points[k.index], dirs[k.index]) for k in known
    )
    target = fk_point(table, ref, reg.tool_point, T_base=reg.T_measurement_base)
    return Start(axes, types, target, dict.fromkeys(missing, "nominal"), reg)


def start_from_neighbours(
    known: Sequence[Known], Q: FloatArray, P: FloatArray, ref: FloatArray
) -> Start | None:
    """Without a nominal: every joint ``known`` has no axis for started from its coupled move
    with a parallel neighbour (module docstring); None when one of them has none (no such
    move, the joints before the pair not at the reference pose, a circle that cannot be fitted
    or whose axis is not parallel to the neighbour's)."""
    from dhlog.geometry.circles import fit_circle_encoder

    axes: list[Line | None] = [k.axis for k in known]
    types: list[JointType | None] = [k.type for k in known]
    sources: dict[int, str] = {}
    for k in known:
        if k.axis is not None:
            continue
        jj = k.index
        moving, kk = coupled_samples(Q, ref, jj, known)
        if kk is None:
            return None
        k_axis = known[kk].axis
        assert k_axis is not None
        upstream = slice(0, min(jj, kk))
        if np.any(np.abs(Q[moving][:, upstream] - ref[upstream]) > NEVER_MOVED):
            return None
        try:
            circle = fit_circle_encoder(P[moving], Q[moving, jj], what=f"joint {jj + 1}")
        except GeometryError:
            return None
        w = circle.axis.direction
        if math.acos(min(1.0, abs(float(w @ k_axis.direction)))) > COUPLED_PARALLEL_TOL:
            return None
        c = circle.center
        turns = [rotation_about(w, float(a)) for a in ref[jj] - Q[moving, jj]]
        p0 = np.mean([R @ (p - c) + c for R, p in zip(turns, P[moving], strict=True)], axis=0)
        offset = p0 - c
        offset -= (offset @ w) * w
        axes[jj] = Line(k_axis.point - offset, w)
        types[jj] = JointType.REVOLUTE
        sources[jj] = f"coupled with joint {kk + 1}"
    if any(a is None for a in axes) or any(t is None for t in types):
        return None
    full_axes = tuple(a for a in axes if a is not None)
    full_types = tuple(t for t in types if t is not None)
    return Start(full_axes, full_types, _target_at(full_axes, full_types, Q, P, ref), sources)


def coupled_samples(
    Q: FloatArray, ref: FloatArray, jj: int, known: Sequence[Known]
) -> tuple[NDArray[np.bool_], int | None]:
    """The samples of joint ``jj``'s (0-based) coupled move with an identified revolute
    neighbour ``kk`` (``q_k − ref_k = −(q_j − ref_j)`` within :data:`COUPLED_RATIO_TOL`, every
    other joint locked), and ``kk``; the neighbour with the most such samples (at least 5), or
    None."""
    dq = Q[:, jj] - ref[jj]
    best: tuple[NDArray[np.bool_], int | None] = (np.zeros(Q.shape[0], dtype=bool), None)
    for kk in (jj - 1, jj + 1):
        if not 0 <= kk < len(known):
            continue
        k = known[kk]
        if k.axis is None or k.type is not JointType.REVOLUTE:
            continue
        dk = Q[:, kk] - ref[kk]
        pair = (np.abs(dq) > NEVER_MOVED) & (
            np.abs(dk + dq) <= COUPLED_RATIO_TOL * np.abs(dq) + 1e-4
        )
        if np.count_nonzero(pair) < 5:
            continue
        rest = np.ones(Q.shape[1], dtype=bool)
        rest[[jj, kk]] = False
        lock = np.median(Q[pair][:, rest], axis=0)
        pair &= np.all(np.abs(Q[:, rest] - lock) <= NEVER_MOVED, axis=1)
        if int(np.count_nonzero(pair)) >= max(5, int(np.count_nonzero(best[0])) + 1):
            best = (pair, kk)
    return best


def align_lines(
    nominal: list[tuple[FloatArray, FloatArray]], measured: list[tuple[FloatArray, FloatArray]]
) -> FloatArray | None:
    """The rigid transform (4×4) that best carries the nominal lines onto the measured ones:
    the rotation from the directions (Kabsch), the translation putting each nominal point on
    its measured line (least squares). None when the directions do not fix the rotation."""
    A = np.array([d for _, d in nominal])
    B = np.array([d for _, d in measured])
    S = np.linalg.svd(B.T @ A, compute_uv=False)
    if S[1] < 1e-3 * S[0]:
        return None
    R = nearest_rotation(B.T @ A)
    rows, rhs = [], []
    for (p, _), (c, e) in zip(nominal, measured, strict=True):
        perp = np.eye(3) - np.outer(e, e)
        rows.append(perp)
        rhs.append(perp @ (c - R @ p))
    t, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T
