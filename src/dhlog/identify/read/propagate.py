"""From the fitted whole model to the DH model: its covariance, and what is held by convention.

The DH table, base and tool are read off the fitted axes and target by the line geometry of
seed 000 (``extract_dh``). Its Jacobian with respect to the fit's parameters (and the base
plane's) is taken by central differences — cheap, since no sample is involved — and carries the
fit's covariance to every DH parameter. A parameter on which no fitted quantity has any effect is
held by a convention or a gauge choice of the extraction: it is reported as fixed, with the reason,
never as a measurement.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.geometry.fitting import PlaneFit
from dhlog.geometry.lines import Line, Plane
from dhlog.identify.fit.axismodel import AxisModel
from dhlog.identify.fit.whole import WholeFit
from dhlog.identify.read.extract import Extraction, hayati_table
from dhlog.identify.read.hayati import hayati_parameters, row_reference
from dhlog.model.dh import HayatiDH, JointType, StandardDH

#: A DH parameter whose derivatives with respect to every fitted quantity stay below this is
#: held by a convention (its numerical derivative is then ~1e-9 at most).
FIXED_BELOW = 1e-6

Extractor = Callable[[list[Line], FloatArray, Plane | None], Extraction]


def rotvec(R: FloatArray) -> FloatArray:
    """Rotation vector (axis × angle) of the rotation matrix ``R``."""
    angle = math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0)))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if angle < 1e-12:
        return 0.5 * w
    return angle / (2.0 * math.sin(angle)) * w


def state_names(n: int) -> list[str]:
    """Names of the entries of :func:`state_vector` (4n + 9)."""
    names = []
    for i in range(n):
        names += [f"theta_offset_{i + 1}", f"d_{i + 1}", f"a_{i + 1}", f"alpha_{i + 1}"]
    names += ["tool_x", "tool_y", "tool_z", "base_x", "base_y", "base_z"]
    names += ["base_rx", "base_ry", "base_rz"]
    return names


def state_vector(ex: Extraction, R0: FloatArray | None = None) -> FloatArray:
    """The DH model as one vector: per row ``θ_offset, d_offset, a, α`` (4n), the tool point (3),
    the translation of ``T_measurement_base`` (3) and its rotation relative to ``R0`` as a
    rotation vector (3)."""
    table = ex.standard
    R0 = ex.T_measurement_base[:3, :3] if R0 is None else R0
    return np.concatenate(
        [
            np.column_stack([table.theta_offset, table.d_offset, table.a, table.alpha]).ravel(),
            ex.tool_point,
            ex.T_measurement_base[:3, 3],
            rotvec(R0.T @ ex.T_measurement_base[:3, :3]),
        ]
    )


def angle_mask(n: int) -> FloatArray:
    """True for the angular entries of :func:`state_vector` whose differences must be wrapped."""
    mask = np.zeros(4 * n + 9, dtype=bool)
    mask[: 4 * n] = np.tile([True, False, False, True], n)
    return mask


def state_difference(a: FloatArray, b: FloatArray, n: int) -> FloatArray:
    """``a − b`` of two :func:`state_vector` of an n-joint model, angles wrapped to (−π, π]."""
    diff = np.asarray(a - b, dtype=np.float64)
    mask = angle_mask(n)
    diff[mask] = [wrap_angle(d) for d in diff[mask]]
    return diff


def hayati_vector(
    ex: Extraction, pairs: list[tuple[int, int]], nominal: StandardDH | None = None
) -> FloatArray:
    """θ, a, α, β of the Hayati–Mirmirani rows of ``pairs`` (1-based joints) in ``ex``, on the
    ``nominal``'s branch where one is given."""
    out = []
    for i, k in pairs:
        reference = row_reference(nominal, i - 1, ex.reference_pose)
        h = hayati_parameters(ex.frames[i - 1], ex.axes[k - 1], (i, k), reference)
        out += [h.theta, h.a, h.alpha, h.beta]
    return np.asarray(out, dtype=np.float64)


def mixed_vector(
    ex: Extraction, rows: frozenset[int], nominal: StandardDH | None = None
) -> FloatArray:
    """The extraction with ``rows`` in the Hayati–Mirmirani form (:func:`hayati_table`) as one
    vector: per row ``θ_offset``, ``d_offset`` or (Hayati rows) ``β``, ``a``, ``α`` (4n)."""
    t = hayati_table(ex, rows, nominal)
    second = np.where(t.hayati, t.beta, t.d_offset) if isinstance(t, HayatiDH) else t.d_offset
    return np.column_stack([t.theta_offset, second, t.a, t.alpha]).ravel()


def mixed_angles(n: int, rows: frozenset[int]) -> NDArray[np.bool_]:
    """True for the angular entries of :func:`mixed_vector` (θ, α, and β of Hayati rows)."""
    mask = np.tile([True, False, False, True], n)
    for i in rows:
        mask[4 * i + 1] = True
    return mask


@dataclass(frozen=True, eq=False)
class Propagation:
    """Covariance of :func:`state_vector` and of the Hayati rows, and the fixed entries."""

    covariance: FloatArray
    fixed: np.ndarray
    hayati_covariance: FloatArray
    extra_tool_points: FloatArray
    extra_tool_covariance: FloatArray
    tool_orientation: FloatArray | None = None
    tool_orientation_std: FloatArray | None = None
    mixed_covariance: FloatArray | None = None
    mixed_fixed: NDArray[np.bool_] | None = None
    #: entries of the state (and of the Hayati table) that move along directions the samples
    #: do not determine: held at the start (the nominal), fixed
    undetermined: NDArray[np.bool_] | None = None
    mixed_undetermined: NDArray[np.bool_] | None = None


#: A parameter whose change along the undetermined directions exceeds this fraction of its
#: change along the determined ones (both per unit step of the scaled parameters) is not
#: determined by the samples.
UNDETERMINED_SHARE = 1e-3


def undetermined_rows(J: FloatArray, fit: WholeFit) -> NDArray[np.bool_]:
    """Per row of ``J`` (outputs × the fit's parameters): whether the output moves along a
    direction the samples do not determine (``fit.determined.null``)."""
    d = fit.determined
    if d is None or d.null.shape[1] == 0:
        return np.zeros(J.shape[0], dtype=bool)
    on_null = np.linalg.norm(J @ (d.null / d.scale[:, None]), axis=1)
    on_kept = np.linalg.norm(J @ (d.basis / d.scale[:, None]), axis=1)
    return np.asarray(on_null > UNDETERMINED_SHARE * np.maximum(on_kept, 1e-300), dtype=bool)


def propagate(
    fit: WholeFit,
    base: PlaneFit | None,
    extract: Extractor,
    center: Extraction,
    hayati_pairs: list[tuple[int, int]],
    rows: frozenset[int] = frozenset(),
    nominal_rows: StandardDH | None = None,
    nominal: StandardDH | None = None,
) -> Propagation:
    """First-order covariance of the DH model extracted from ``fit`` (and the base plane); with
    ``rows``, also of the table with those rows in the Hayati–Mirmirani form
    (:func:`mixed_vector`, on the branch of ``nominal_rows``); the Hayati rows of
    ``hayati_pairs`` on the ``nominal``'s branch."""
    model: AxisModel = fit.model
    layout, bases = fit.layout, fit.bases
    n = model.n
    R0 = center.T_measurement_base[:3, :3]
    plane = None if base is None else base.plane
    n_fit = layout.size
    n_in = n_fit + (3 if base is not None else 0)
    cov_in = np.zeros((n_in, n_in))
    cov_in[:n_fit, :n_fit] = fit.covariance
    if base is not None:
        cov_in[n_fit:, n_fit:] = base.covariance

    def evaluate(delta: FloatArray, plane_delta: FloatArray) -> FloatArray:
        moved = model.moved(delta, layout, bases) if np.any(delta) else model
        pl = plane
        if pl is not None and base is not None and np.any(plane_delta):
            u, v = base.basis
            normal = pl.normal + plane_delta[0] * u + plane_delta[1] * v
            pl = Plane(pl.point + plane_delta[2] * pl.normal, normal)
        ex = extract(list(moved.axes), moved.target, pl)
        parts = [state_vector(ex, R0)]
        if hayati_pairs:
            parts.append(hayati_vector(ex, hayati_pairs, nominal))
        if rows:
            parts.append(mixed_vector(ex, rows, nominal_rows))
        if len(moved.extra_targets):  # further targets in the last frame (tool points)
            T = np.linalg.inv(ex.frames[-1])
            parts.append((moved.extra_targets @ T[:3, :3].T + T[:3, 3]).ravel())
        if moved.tool_rotation is not None:  # the target frame in the last frame, vs the centre
            R_tool = ex.frames[-1][:3, :3].T @ moved.tool_rotation
            parts.append(rotvec(R_center.T @ R_tool) if R_center is not None else np.zeros(3))
        return np.concatenate(parts)

    R_center: FloatArray | None = None
    if model.tool_rotation is not None:
        R_center = center.frames[-1][:3, :3].T @ model.tool_rotation

    zero_fit, zero_plane = np.zeros(n_fit), np.zeros(3)
    h = 1e-7
    n_extra = 3 * len(model.extra_targets) + (3 if model.tool_rotation is not None else 0)
    n_mixed = 4 * n if rows else 0
    size = 4 * n + 9 + 4 * len(hayati_pairs) + n_mixed + n_extra
    wrap = np.concatenate(
        [
            angle_mask(n),
            np.tile([True, False, True, True], len(hayati_pairs)),
            mixed_angles(n, rows) if rows else np.zeros(0, dtype=bool),
            np.zeros(n_extra, dtype=bool),
        ]
    )
    J = np.zeros((size, n_in))
    for col in range(n_in):
        outs: list[FloatArray | None] = []
        for sign in (1.0, -1.0):
            d_fit, d_plane = zero_fit.copy(), zero_plane.copy()
            if col < n_fit:
                d_fit[col] = sign * h
            else:
                d_plane[col - n_fit] = sign * h
            try:
                outs.append(evaluate(d_fit, d_plane))
            except DhlogError:
                outs.append(None)
        plus, minus = outs
        if plus is None or minus is None:
            continue
        diff = plus - minus
        diff[wrap] = [wrap_angle(d) for d in diff[wrap]]
        J[:, col] = diff / (2 * h)
    cov = J @ cov_in @ J.T
    n_state = 4 * n + 9
    fixed = np.max(np.abs(J[:n_state]), axis=1) < FIXED_BELOW
    loose = undetermined_rows(J[:, :n_fit], fit)
    undetermined = loose[:n_state] & ~fixed
    fixed |= undetermined
    # nor is anything measured to 0.1 nm or 0.1 nrad: such a σ is a convention's rounding
    fixed |= np.sqrt(np.clip(np.diag(cov)[:n_state], 0.0, None)) < 1e-10
    for i, kind in fit.constrained.items():  # held by the constraint: α (and a, collinear)
        fixed[4 * i + 3] = True
        if kind == "collinear":
            fixed[4 * i + 2] = True
    affected = set(rows) | {i + 1 for i in rows}
    for k in fit.held:  # not determined within the physical bound (identify.hold)
        if k // 4 not in affected:  # the standard row is the shown one
            fixed[k] = True
    cov_state = cov[:n_state, :n_state].copy()
    cov_state[fixed, :] = 0.0
    cov_state[:, fixed] = 0.0
    n_h = n_state + 4 * len(hayati_pairs)
    n_m = n_h + n_mixed
    n_e = n_m + 3 * len(model.extra_targets)
    mixed_cov = mixed_fixed = mixed_undetermined = None
    if rows:
        mixed_fixed = np.max(np.abs(J[n_h:n_m]), axis=1) < FIXED_BELOW
        mixed_undetermined = loose[n_h:n_m] & ~mixed_fixed
        mixed_fixed |= mixed_undetermined
        mixed_fixed |= np.sqrt(np.clip(np.diag(cov)[n_h:n_m], 0.0, None)) < 1e-10
        for i in range(n):  # rows the Hayati form leaves as they were: as the standard table
            if i not in affected:
                mixed_fixed[4 * i : 4 * i + 4] = fixed[4 * i : 4 * i + 4]
        for k in fit.held:
            mixed_fixed[k] = True
        mixed_cov = cov[n_h:n_m, n_h:n_m].copy()
        mixed_cov[mixed_fixed, :] = 0.0
        mixed_cov[:, mixed_fixed] = 0.0
    extra_points = evaluate(zero_fit, zero_plane)[n_m:n_e].reshape(-1, 3)
    rot_std = None
    if R_center is not None:
        rot_std = np.sqrt(np.clip(np.diag(cov[n_e:, n_e:]), 0.0, None))
    return Propagation(
        covariance=np.asarray(cov_state, dtype=np.float64),
        fixed=fixed,
        hayati_covariance=np.asarray(cov[n_state:n_h, n_state:n_h], dtype=np.float64),
        extra_tool_points=np.asarray(extra_points, dtype=np.float64),
        extra_tool_covariance=np.asarray(cov[n_m:n_e, n_m:n_e], dtype=np.float64),
        tool_orientation=R_center,
        tool_orientation_std=rot_std,
        mixed_covariance=mixed_cov,
        mixed_fixed=mixed_fixed,
        undetermined=undetermined,
        mixed_undetermined=mixed_undetermined,
    )


#: The reason given for a parameter the samples do not determine.
NOT_DETERMINED = "not determined by these poses"


def fixed_reasons(
    ex: Extraction,
    fixed: np.ndarray,
    *,
    base_plane: bool,
    nominal: bool,
    constrained: dict[int, str] | None = None,
    undetermined: NDArray[np.bool_] | None = None,
    unseen: dict[int, str] | None = None,
) -> dict[int, str]:
    """Why each fixed entry of :func:`state_vector` is held (index → one sentence);
    ``constrained`` maps the 0-based first joint of a pair held parallel / collinear;
    ``undetermined`` marks the entries the samples do not determine; ``unseen`` those they
    determine only beyond a physical bound (:mod:`dhlog.identify.model.hold`), with the reason."""
    held = constrained or {}
    n = ex.standard.n
    types = ex.standard.joint_types
    kinds = {r.joints[0]: r.relation.kind for r in ex.relations}
    out: dict[int, str] = {}
    for idx in (int(k) for k in np.flatnonzero(fixed)):
        if unseen is not None and idx in unseen:
            out[idx] = unseen[idx]
            continue
        if undetermined is not None and undetermined[idx]:
            out[idx] = NOT_DETERMINED + (" (held at the nominal)" if nominal else "")
            continue
        if idx >= 4 * n:
            out[idx] = (
                "the target defines the last frame (z_{n+1} ∥ z_n through the target)"
                if not nominal
                else "held by the nominal's last row"
            )
            continue
        row, p = divmod(idx, 4)
        name = ("θ", "d", "a", "α")[p]
        kind = kinds.get(row + 1)
        if row in held and (p == 3 or (p == 2 and held[row] == "collinear")) and row < n - 1:
            why = (
                f"axes {row + 1} and {row + 2} are {held[row]} within the noise (the data "
                f"cannot reject it), so {name} is held by that relation"
            )
        elif row == 0 and p == 0:
            why = (
                "x₁ follows the nominal θ₁ offset"
                if nominal
                else "x₁ is chosen so that θ₁ = 0 at encoder zero"
            )
        elif row == 0 and p == 1 and not base_plane:
            why = (
                "frame 1's origin: foot of the common normal to axis 2 — no base points in the log"
            )
        elif row == n - 1:
            why = (
                "last row from the nominal (frame n+1 = frame n · nominal A_n)"
                if nominal
                else "last frame convention: z_{n+1} ∥ z_n through the target"
            )
        elif JointType.PRISMATIC in types[row : row + 2] and p in (1, 2):
            why = "placement of a prismatic axis (only its direction is physical)"
        elif kind is not None and kind.value == "collinear":
            why = f"axes {row + 1} and {row + 2} are collinear: {name} by convention"
        elif kind is not None and kind.is_parallel and p == 1:
            why = (
                f"axes {row + 1} and {row + 2} are parallel: d by convention "
                "(common normal through the previous origin)"
            )
        elif JointType.PRISMATIC in types[max(row - 1, 0) : row + 2]:
            why = "placement of a prismatic axis (only its direction is physical)"
        else:
            why = f"{name} held by a convention of the extraction"
        out[idx] = why
    return out
