"""The whole model's prediction of each sample and its analytic Jacobian (samples along the last
axis, so that every operation is on contiguous rows).

A sample is predicted by the product of exponentials about the model's axes
(:mod:`dhlog.identify.fit.axismodel`). With ``R_<i`` the rotation of joints 1 … i−1 and ``D_i`` the
target relative to axis i's point as it sits at the sample, a tilt ``w`` of axis i moves the
target by ``b × D_i`` and a shift ``w`` by ``b``, where ``b = R_<i (I − R_i) w``
(:func:`predict_columns`); a 6-DoF target's orientation turns by the same ``b``
(:func:`predict_orientation`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.geometry.lines import Line
from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
from dhlog.model.dh import JointType


def rotate(R: FloatArray, X: FloatArray) -> FloatArray:
    """``R X`` for per-sample rotations ``R`` (3, 3, m) and vectors ``X`` (3, m) or blocks
    (3, k, m)."""
    if X.ndim == 2:
        return np.stack([R[a, 0] * X[0] + R[a, 1] * X[1] + R[a, 2] * X[2] for a in range(3)])
    return np.stack(
        [R[a, 0][None] * X[0] + R[a, 1][None] * X[1] + R[a, 2][None] * X[2] for a in range(3)]
    )


Prefix = tuple[
    FloatArray,
    list[FloatArray | None],
    list[FloatArray],
    list[FloatArray | None],
    list[FloatArray | None],
    FloatArray | None,
]


def prefix_motions(model: AxisModel, Q: FloatArray, rates: FloatArray | None = None) -> Prefix:
    """The joint moves ``dq`` (n, m) and the prefix motions ``g_<i`` for i = 1 … n+1:
    rotation rows (3, 3, m) (None for the identity) and translations (3, m), with each revolute
    joint's ``sin δ`` and ``1 − cos δ``; ``rates`` (m, n) the joints' speeds (clock offset); and
    the joint-value terms' functions (k, m) (None without terms). ``dq`` is the scaled encoder
    move plus the terms' deflection, whose functions (gravity torques) are taken at the pose the
    encoders give."""
    dq = (model.moves(Q, rates) * model.scales).T
    if model.terms is None or not model.terms.size:
        return (dq, *_chain(model, dq), None)
    pre_R, pre_t, _, _ = _chain(model, dq)
    m = Q.shape[0]
    points, dirs = [], []
    for i, axis in enumerate(model.axes):
        R0, t0 = pre_R[i], pre_t[i]
        points.append(
            np.broadcast_to(axis.point[:, None], (3, m))
            if R0 is None
            else rotate(R0, _col(axis.point, m)) + t0
        )
        dirs.append(
            np.broadcast_to(axis.direction[:, None], (3, m))
            if R0 is None
            else rotate(R0, _col(axis.direction, m))
        )
    lumps = []
    for lump in model.terms.lumps:
        k = model.n if lump.target else lump.axis
        R0, t0 = pre_R[k], pre_t[k]
        lumps.append(
            np.broadcast_to(lump.point[:, None], (3, m))
            if R0 is None
            else rotate(R0, _col(lump.point, m)) + t0
        )
    B = model.terms.basis(Q, points, dirs, lumps)
    dq = dq + model.terms.deflection(B, model.n)
    return (dq, *_chain(model, dq), B)


def _chain(
    model: AxisModel, dq: FloatArray
) -> tuple[
    list[FloatArray | None], list[FloatArray], list[FloatArray | None], list[FloatArray | None]
]:
    """The prefix motions of the joint moves ``dq`` (n, m) (see :func:`prefix_motions`)."""
    # prefix motions g_<i (rotation rows (3, 3, m) or None for the identity; translation (3, m))
    pre_R: list[FloatArray | None] = [None]
    pre_t: list[FloatArray] = [np.zeros((3, 1))]
    sins: list[FloatArray | None] = []
    coss: list[FloatArray | None] = []
    for i, (axis, jt) in enumerate(zip(model.axes, model.types, strict=True)):
        R0, t0 = pre_R[-1], pre_t[-1]
        if jt is JointType.PRISMATIC:
            step = axis.direction[:, None] * dq[i]
            sins.append(None)
            coss.append(None)
            pre_R.append(R0)
            pre_t.append(t0 + (step if R0 is None else rotate(R0, step)))
            continue
        K = skew(axis.direction)
        K2 = K @ K
        s, c1 = np.sin(dq[i]), 1.0 - np.cos(dq[i])
        sins.append(s)
        coss.append(c1)
        Ri = K[:, :, None] * s + K2[:, :, None] * c1
        Ri[0, 0] += 1.0
        Ri[1, 1] += 1.0
        Ri[2, 2] += 1.0
        ti = -((K @ axis.point)[:, None] * s + (K2 @ axis.point)[:, None] * c1)
        if R0 is None:
            pre_R.append(Ri)
            pre_t.append(t0 + ti)
        else:
            pre_R.append(_compose(R0, Ri))
            pre_t.append(t0 + rotate(R0, ti))
    return pre_R, pre_t, sins, coss


def _carried_inward(model: AxisModel, dq: FloatArray, target: FloatArray) -> FloatArray:
    """The target (3, m) moved by the joints' moves ``dq`` (n, m), the last joint first:
    ``x ← c + R_i (x − c)`` (Rodrigues on the vector: ``r + sin δ K r + (1 − cos δ) K² r``,
    ``K = [ω]×``, each product one matrix product over the samples) or ``x ← x + d_i δ`` — the
    position alone, without the prefix motions' (3, 3, m) rotations the Jacobian needs (equal
    to them to rounding)."""
    x = np.array(target, dtype=np.float64)
    for i in range(model.n - 1, -1, -1):
        axis = model.axes[i]
        if model.types[i] is JointType.PRISMATIC:
            x += axis.direction[:, None] * dq[i]
            continue
        K = skew(axis.direction)
        a = K @ (x - axis.point[:, None])
        b = K @ a
        a *= np.sin(dq[i])
        b *= 1.0 - np.cos(dq[i])
        x += a
        x += b
    return x


def _tilt_move(
    axis: Line, w: FloatArray, s: FloatArray, c1: FloatArray, R0: FloatArray | None
) -> FloatArray:
    """``b = R_<i (I − R_i) w`` (3, m) for a revolute joint turned by δ (``s = sin δ``,
    ``c1 = 1 − cos δ``): ``(I − R_i) w = −(sin δ K w + (1 − cos δ) K² w)``, ``K = [ω]×``."""
    K = skew(axis.direction)
    a = -((K @ w)[:, None] * s + (K @ (K @ w))[:, None] * c1)
    return a if R0 is None else rotate(R0, a)


def predict_orientation(
    model: AxisModel,
    Q: FloatArray,
    layout: ParameterLayout,
    bases: list[tuple[FloatArray, FloatArray]],
    prefix: Prefix | None = None,
    rates: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The target frame's predicted orientation (3, 3, m) and the Jacobian (``layout.size``,
    3, m) of a small rotation of it, in M, with respect to the local parameters: a tilt of a
    revolute axis rotates it by ``b = R_<i (I − R_i) w`` (as in :func:`predict_columns`), a shift
    or a prismatic joint not at all, the target frame's own rotation by ``R_all δ``. ``prefix``:
    the prefix motions at ``Q`` when already computed."""
    assert model.tool_rotation is not None and layout.rotation_at is not None
    m = Q.shape[0]
    _, pre_R, _, sins, coss, B = prefix_motions(model, Q, rates) if prefix is None else prefix
    R_all = pre_R[-1]
    eye = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, m))
    R_tool = np.broadcast_to(model.tool_rotation[:, :, None], (3, 3, m))
    R_pred = np.ascontiguousarray(R_tool if R_all is None else _compose(R_all, R_tool))
    J = np.zeros((layout.size, 3, m))
    moved = model.moves(Q, rates)
    for i, (axis, jt) in enumerate(zip(model.axes, model.types, strict=True)):
        if jt is JointType.PRISMATIC:
            continue
        u, v = bases[i]
        R0 = pre_R[i]
        s, c1 = sins[i], coss[i]
        assert s is not None and c1 is not None
        k = layout.axis_at[i]
        for col, w in enumerate((u, v)):
            J[k + col] = _tilt_move(axis, w, s, c1, R0)
        if layout.scale_at is not None or layout.clock_at is not None or B is not None:
            omega = axis.direction[:, None] if R0 is None else rotate(R0, _col(axis.direction, m))
            if layout.scale_at is not None:
                J[layout.scale_at + i] = omega * moved[:, i]
            if layout.clock_at is not None and rates is not None:
                J[layout.clock_at] -= omega * (model.scales[i] * rates[:, i])
            _term_columns(J, layout, model, B, i, omega)
    _zero_held(J, model, layout)
    r = layout.rotation_at
    J[r : r + 3] = np.moveaxis(eye if R_all is None else R_all, 1, 0)
    return R_pred, J


def _zero_held(J: FloatArray, model: AxisModel, layout: ParameterLayout) -> None:
    """Zero the axis columns of the joints ``model`` holds (a parked joint): the fit leaves
    them where they are (:class:`~dhlog.identify.fit.whole.Determined`: undetermined)."""
    for i in model.held_axes:
        k = layout.axis_at[i]
        J[k : k + (4 if model.types[i] is JointType.REVOLUTE else 2)] = 0.0


def orientation_residual(R_pred: FloatArray, R_meas: FloatArray) -> FloatArray:
    """The small rotation (3, m) from the measured to the predicted orientation, in M:
    ``vee(E − Eᵀ) / 2`` of ``E = R_pred R_measᵀ`` (first order, exact as ``sin`` of the angle)."""
    E = np.einsum("ikm,jkm->ijm", R_pred, R_meas)
    return np.stack([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 2.0


def predict_columns(
    model: AxisModel,
    Q: FloatArray,
    layout: ParameterLayout | None = None,
    bases: list[tuple[FloatArray, FloatArray]] | None = None,
    which: NDArray[np.int64] | None = None,
    prefix: Prefix | None = None,
    rates: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Predicted target positions (3, m) at the joint vectors ``Q`` (m, n) and, with ``layout``,
    the Jacobian (``layout.size``, 3, m) with respect to the local parameters. Samples run along
    the last axis so that every operation is on contiguous rows. ``which`` (m,) names each
    sample's target (0 the primary one, j the j-th of ``extra_targets``; default all 0).

    With ``g_<i = (R_<i, t_<i)`` the motion of joints 1 … i−1 and ``D_i = p − g_<i(c_i)`` the
    target relative to axis i's point as it sits at this sample, a move ``η = (w, v)`` of axis i
    gives ``δp = b × D_i + R_<i (I − R_i) v`` with ``b = R_<i (I − R_i) w`` (joint i's own rotation
    leaves its axis point where it is), so a tilt column is ``b_w × D_i`` and a shift column
    ``b_w`` itself (:func:`_tilt_move`). ``prefix``: the prefix motions at ``Q`` when already
    computed."""
    m = Q.shape[0]
    if which is None or not len(model.extra_targets):
        tgt = np.broadcast_to(model.target[:, None], (3, m))
    else:
        tgt = np.ascontiguousarray(model.targets()[which].T)
    if layout is None and prefix is None and (model.terms is None or not model.terms.size):
        return _carried_inward(model, (model.moves(Q, rates) * model.scales).T, tgt), None
    dq, pre_R, pre_t, sins, coss, B = prefix_motions(model, Q, rates) if prefix is None else prefix
    R_all, t_all = pre_R[-1], pre_t[-1]
    p = (tgt if R_all is None else rotate(R_all, tgt)) + t_all
    p = np.ascontiguousarray(np.broadcast_to(p, (3, m)))
    if layout is None:
        return p, None
    assert bases is not None
    J = np.empty((layout.size, 3, m))
    moved = model.moves(Q, rates)
    clock = layout.clock_at if rates is not None else None
    if layout.clock_at is not None:
        J[layout.clock_at] = 0.0
    if layout.terms_at is not None:  # a term on a joint the loop skips stays zero
        J[layout.terms_at :] = 0.0
    for i, (axis, jt) in enumerate(zip(model.axes, model.types, strict=True)):
        u, v = bases[i]
        R0, t0 = pre_R[i], pre_t[i]
        k = layout.axis_at[i]
        omega = axis.direction[:, None] if R0 is None else rotate(R0, _col(axis.direction, m))
        if jt is JointType.PRISMATIC:
            for col, w in enumerate((u, v)):
                w_world = w[:, None] if R0 is None else rotate(R0, _col(w, m))
                J[k + col] = cross_rows(w_world, omega) * dq[i]
            if layout.scale_at is not None:
                J[layout.scale_at + i] = np.broadcast_to(omega, (3, m)) * moved[:, i]
            if clock is not None:
                assert rates is not None
                J[clock] -= np.broadcast_to(omega, (3, m)) * (model.scales[i] * rates[:, i])
            _term_columns(J, layout, model, B, i, np.broadcast_to(omega, (3, m)))
            continue
        s, c1 = sins[i], coss[i]
        assert s is not None and c1 is not None
        c_world = (axis.point[:, None] if R0 is None else rotate(R0, _col(axis.point, m))) + t0
        D = p - c_world
        for col, w in enumerate((u, v)):
            b = _tilt_move(axis, w, s, c1, R0)
            J[k + col] = cross_rows(b, D)
            J[k + 2 + col] = b
        if layout.scale_at is not None or clock is not None or B is not None:
            turn = cross_rows(np.broadcast_to(omega, (3, m)), D)
            if layout.scale_at is not None:
                J[layout.scale_at + i] = turn * moved[:, i]
            if clock is not None:
                assert rates is not None
                J[clock] -= turn * (model.scales[i] * rates[:, i])
            _term_columns(J, layout, model, B, i, turn)
    _zero_held(J, model, layout)
    t = layout.target_at
    rot = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, m)) if R_all is None else R_all
    J[t : t + 3] = np.moveaxis(rot, 1, 0)
    if layout.rotation_at is not None:  # the target frame's orientation does not move the point
        J[layout.rotation_at : layout.rotation_at + 3] = 0.0
    extra = len(model.extra_targets)
    if extra:  # each sample moves only its own target's columns
        J[t + 3 : t + 3 + 3 * extra] = 0.0
        if which is not None:
            for j in range(1, extra + 1):
                mask = which == j
                J[t + 3 * j : t + 3 * j + 3, :, mask] = J[t : t + 3, :, mask]
            J[t : t + 3, :, which != 0] = 0.0
    return p, J


def _term_columns(
    J: FloatArray,
    layout: ParameterLayout,
    model: AxisModel,
    B: FloatArray | None,
    joint: int,
    per_unit: FloatArray,
) -> None:
    """The columns of the terms on ``joint``: its move per unit angle (``per_unit``, (3, m))
    times each term's function (each term moves one joint: its column is set once)."""
    if B is None or layout.terms_at is None or model.terms is None:
        return
    k0 = layout.terms_at
    for k, t in enumerate(model.terms.terms):
        if t.joint == joint:
            J[k0 + k] = per_unit * B[k]


def skew(k: FloatArray) -> FloatArray:
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def _col(x: FloatArray, m: int) -> FloatArray:
    return np.broadcast_to(x[:, None], (3, m))


def cross_rows(a: FloatArray, b: FloatArray) -> FloatArray:
    """Row-wise ``a × b`` for (3, m) arrays (either may broadcast from (3, 1))."""
    return np.stack(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _compose(A: FloatArray, B: FloatArray) -> FloatArray:
    """Per-sample product ``A B`` of rotation rows (3, 3, m)."""
    return np.stack(
        [
            np.stack([A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c] for c in range(3)])
            for r in range(3)
        ]
    )


def predict(
    model: AxisModel,
    Q: FloatArray,
    layout: ParameterLayout | None = None,
    bases: list[tuple[FloatArray, FloatArray]] | None = None,
    which: NDArray[np.int64] | None = None,
    rates: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray | None]:
    """Predicted target positions (m, 3) at the joint vectors ``Q`` (m, n) and, with ``layout``,
    the Jacobian (m, 3, ``layout.size``) with respect to the local parameters; ``rates`` (m, n)
    the joints' speeds when the model carries a clock offset."""
    p, J = predict_columns(model, Q, layout, bases, which, rates=rates)
    return p.T.copy(), None if J is None else np.transpose(J, (2, 1, 0)).copy()
