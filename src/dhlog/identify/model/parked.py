"""Joints parked in the session (a torso, a rail, a turntable or an external axis that stayed
where it was): held at the nominal while every other joint is identified.

A joint whose encoder values span less than :data:`PARKED_SPAN` (rad or m) over every sample
with encoder values did not move in the session. Its axis cannot be measured from it: an arc of
1 mrad at 1 m is 1 mm long, and with a tracker's 10 µm noise its direction would be known to
about σ / arc ≈ 10 mrad — nothing a calibration can use — and a prismatic travel of 1 mm gives
its direction to the same 10 mrad. Nor does the rest of the chain tell where it is: the parked
joint's row merges with its neighbours (or, for the first joint, with the base; for the last,
with the tool), so the session determines only their product.

So the parked joint is held: its axis is placed by the nominal (the nominal's axis, carried
onto the fitted axes nearest it by the rigid motion that best lays the nominal's on them:
:func:`~dhlog.identify.fit.start.align_lines`), the whole-model fit leaves it there
(:attr:`~dhlog.identify.fit.axismodel.AxisModel.held_axes`: its Jacobian columns are zero) while
still applying its small motion at the encoder values (through the nominal's axis rather than the
true one, which errs by the span times the axis's misplacement: at most 1 mrad × (1 mm + 1 m ×
1 mrad) = 2 µm for a nominal 1 mm and 1 mrad off), and its row is marked fixed with
:data:`PARKED_REASON` (no σ). The base and the neighbouring rows absorb what the held row does
not say. The reference pose takes the parked joint's median value, so the table reproduces the
fit exactly at the parked value wherever the axis is placed.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line
from dhlog.identify.fit.start import align_lines
from dhlog.identify.segment.persample import SampleArray, blocks
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import JointType

#: A joint whose encoder values span less than this (rad for a revolute joint, m for a prismatic
#: one) over the session did not move: held at the nominal (see the module docstring).
PARKED_SPAN = 1e-3
#: The ``fixed_reason`` of a parked joint's row.
PARKED_REASON = "joint parked in the session: held at the nominal"


def encoder_spans(Q: SampleArray) -> FloatArray:
    """Each joint's span (max − min, rad or m) of the encoder values ``Q`` (m, n), read a
    block at a time (zeros when there are no samples)."""
    m, n = Q.shape[0], Q.shape[1]
    lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
    for sl in blocks(m):
        q = Q[sl]
        lo, hi = np.minimum(lo, q.min(axis=0)), np.maximum(hi, q.max(axis=0))
    return np.asarray(hi - lo if m else np.zeros(n), dtype=np.float64)


def parked_joints(spans: FloatArray) -> list[int]:
    """The joints (0-based) whose encoder ``spans`` (:func:`encoder_spans`) are less than
    :data:`PARKED_SPAN`."""
    return [k for k in range(spans.size) if float(spans[k]) < PARKED_SPAN]


def parked_pose(Q: SampleArray, ref: FloatArray, parked: Sequence[int]) -> FloatArray:
    """``ref`` with each parked joint at its median encoder value (the pose it was parked at),
    the parked joints' columns of ``Q`` alone gathered a block at a time."""
    out = np.array(ref, dtype=np.float64)
    cols = list(parked)
    if not cols or Q.shape[0] == 0:
        return out
    values = np.concatenate([Q[sl][:, cols] for sl in blocks(Q.shape[0])])
    out[cols] = np.median(values, axis=0)
    return out


def span_text(spans: FloatArray, k: int, joint_type: JointType) -> str:
    """The span of joint ``k``'s (0-based) encoder values, in mrad or mm."""
    span = float(spans[k]) * 1e3
    return f"{span:.3g} {'mrad' if joint_type is JointType.REVOLUTE else 'mm'}"


def parked_warning(
    names: Sequence[str], parked: Sequence[int], spans: FloatArray, types: Sequence[JointType]
) -> str:
    """The one warning naming the parked joints of a run with a nominal."""
    which = ", ".join(
        f"joint {k + 1} ({names[k]}, its encoder spans {span_text(spans, k, types[k])})"
        for k in parked
    )
    return (
        f"{which}: parked in the session (spans under {PARKED_SPAN * 1e3:g} mrad or mm); its "
        "row is held at the nominal (fixed, no σ) and the base and neighbouring rows absorb it; "
        "every other joint is identified. Sweep it, or move it between poses, to calibrate it."
    )


def no_nominal_reason(spans: FloatArray, k: int, joint_type: JointType | None) -> str:
    """Why a parked joint (0-based ``k``) is not identified without a nominal (one line, after
    "joint k (name) was not identified: ")."""
    span = float(spans[k]) * 1e3
    unit = {JointType.REVOLUTE: "mrad", JointType.PRISMATIC: "mm", None: "mrad or mm"}
    return (
        f"it was parked in the session (its encoder spans {span:.3g} {unit[joint_type]}), so "
        "nothing measures it and without the robot's nominal it cannot be held — give "
        "--nominal (a library robot or the robot's DH file) to hold it at the nominal and "
        "identify every other joint"
    )


def mark_parked(fixed: dict[int, str], std: FloatArray, parked: Sequence[int]) -> None:
    """Mark each parked joint's row (θ, d, a, α: entries ``4k … 4k+3`` of the state vector)
    fixed with :data:`PARKED_REASON` and its σ NaN, in place."""
    for k in parked:
        for p in range(4):
            fixed[4 * k + p] = PARKED_REASON
            std[4 * k + p] = np.nan


def place_parked(
    axes: Sequence[Line], parked: Sequence[int], nominal: DHModel, ref: FloatArray
) -> tuple[Line, ...]:
    """``axes`` (the fitted model's, at ``ref``) with each parked joint's axis placed where the
    nominal has it relative to the nearest other axes: the nominal's axes at ``ref`` laid onto
    the fitted ones nearest the parked joint (the two either side first, more until their
    directions fix a rotation; :func:`align_lines`). An axis left as it is when no such set
    exists."""
    from dhlog.model.fk import joint_axes

    points, dirs = joint_axes(nominal.table, ref, T_base=nominal.T_base)
    out = list(axes)
    free = [j for j in range(len(axes)) if j not in parked]
    for k in parked:
        order = sorted(free, key=lambda j: (abs(j - k), j < k))
        for count in range(2, len(order) + 1):
            near = order[:count]
            T = align_lines(
                [(points[j], dirs[j]) for j in near],
                [(axes[j].point, axes[j].direction) for j in near],
            )
            if T is not None:
                out[k] = Line(T[:3, :3] @ points[k] + T[:3, 3], T[:3, :3] @ dirs[k])
                break
    return tuple(out)
