"""Compensation for controllers that keep their nominal model (``dhlog compensate``).

A controller that cannot load new kinematic parameters runs joint targets through its nominal
model. To bring the calibrated robot to the pose the controller intended, each target ``q`` is
replaced by the ``q'`` at which the calibrated model (its table and, when the result carries them,
its terms beyond the geometry) puts the last frame where the nominal model puts it at ``q``:

    T_cal(q') = T_nom(q)        (position and orientation of the last frame, in the base frame)

solved by Newton's method from ``q`` with a central-difference Jacobian of the whole calibrated
map (the terms included), to 1e-12 m and rad. Both poses are in each model's own base frame:
the result's frame 1 follows the nominal's conventions (``dhlog process --nominal``), so the two
are the robot's base frame. Fewer than six joints: the least-squares ``q'`` (its residual said).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dhlog.dhfile import DHModel
from dhlog.geometry._checks import FloatArray
from dhlog.kinematics import fk_frames

#: Newton iterations at most, and the pose error (m, rad) at which a target has converged.
MAX_ITERATIONS = 30
CONVERGED = 1e-12
#: A target whose Jacobian's condition number exceeds this is too near a singularity.
SINGULAR = 1e8
#: Central-difference step (rad or m).
STEP = 1e-6
#: A correction larger than this (rad, or m for a prismatic joint) is the amplification of a
#: near-singular pose, not a calibration: the target is left out with the size said.
MAX_CORRECTION = 0.05


@dataclass(frozen=True)
class Compensation:
    """Corrected joint targets (m, n; NaN rows where none), the remaining pose error per target
    (m, rad; the larger of position and orientation), and one line per target not corrected
    (``problems``: row index → why)."""

    targets: FloatArray
    error: FloatArray
    problems: dict[int, str]


def _pose(model: DHModel, q: FloatArray, calibrated: bool) -> FloatArray:
    """The last frame (m, 4, 4) in the model's base frame at joint vectors ``q`` (m, n)."""
    values = model.joint_values(q) if calibrated else q
    base = model.T_base if not calibrated else None
    return np.asarray(fk_frames(model.table, values, T_base=base)[:, -1], dtype=np.float64)


def _error(T: FloatArray, goal: FloatArray) -> FloatArray:
    """Per target the 6-vector (position difference, small rotation) from ``goal`` to ``T``."""
    dp = T[:, :3, 3] - goal[:, :3, 3]
    E = np.einsum("mij,mkj->mik", T[:, :3, :3], goal[:, :3, :3])  # R_T R_goalᵀ
    dr = np.stack([E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0], E[:, 1, 0] - E[:, 0, 1]], 1)
    return np.asarray(np.concatenate([dp, dr / 2.0], axis=1), dtype=np.float64)


def compensate(
    result: DHModel,
    nominal: DHModel,
    Q: FloatArray,
    *,
    limits: FloatArray | None = None,
) -> Compensation:
    """The corrected targets of ``Q`` (m, n) for ``result`` on a controller running
    ``nominal`` (see the module docstring); ``limits`` (n, 2): the joints' limits, when known."""
    Q = np.asarray(Q, dtype=np.float64)
    m, n = Q.shape
    goal = _pose(nominal, Q, calibrated=False)
    q = Q.copy()
    active = np.ones(m, dtype=bool)
    problems: dict[int, str] = {}
    err = _error(_pose(result, q, calibrated=True), goal)
    for _ in range(MAX_ITERATIONS):
        size = np.max(np.abs(err), axis=1)
        active &= size > CONVERGED
        if not np.any(active):
            break
        rows = np.flatnonzero(active)
        J = np.empty((rows.size, 6, n))
        for j in range(n):
            step = np.zeros(n)
            step[j] = STEP
            plus = _error(_pose(result, q[rows] + step, calibrated=True), goal[rows])
            minus = _error(_pose(result, q[rows] - step, calibrated=True), goal[rows])
            J[:, :, j] = (plus - minus) / (2 * STEP)
        for k, row in enumerate(rows):
            s = np.linalg.svd(J[k], compute_uv=False)
            if s[-1] <= s[0] / SINGULAR:
                problems[int(row)] = (
                    f"too near a singularity (Jacobian condition {s[0] / max(s[-1], 1e-300):.3g})"
                )
                active[row] = False
                continue
            delta, *_ = np.linalg.lstsq(J[k], -err[row], rcond=None)
            # backtracking: a full Newton step near a singularity can overshoot
            before = float(np.sum(err[row] ** 2))
            for _ in range(40):
                trial = q[row] + delta
                e = _error(_pose(result, trial[None], calibrated=True), goal[row : row + 1])[0]
                if float(np.sum(e**2)) < before or np.max(np.abs(delta)) < CONVERGED:
                    break
                delta = delta / 2.0
            q[row] = trial
            err[row] = e
            if np.max(np.abs(delta)) < CONVERGED:  # least squares (fewer than six joints)
                active[row] = False
    size = np.max(np.abs(err), axis=1)
    exact = n >= 6  # fewer joints reach the pose only in the least-squares sense
    for bad in np.flatnonzero((active | exact) & (size > 1e-9)).tolist():
        if bad not in problems:
            problems[bad] = (
                f"did not converge (pose error {size[bad]:.3g} m or rad): too near a singularity"
            )
    change = np.max(np.abs(q - Q), axis=1)
    for big in np.flatnonzero(change > MAX_CORRECTION).tolist():
        if big not in problems:
            problems[big] = (
                f"too near a singularity: the correction would be {change[big]:.3g} rad or m"
            )
    if limits is not None:
        lo, hi = limits[:, 0], limits[:, 1]
        for k in range(m):
            if k in problems:
                continue
            out = np.flatnonzero((q[k] < lo) | (q[k] > hi))
            if out.size:
                names = ", ".join(f"joint {j + 1}" for j in out)
                problems[k] = f"the corrected target leaves the limits of {names}"
    targets = q.copy()
    for k in problems:
        targets[k] = np.nan
    return Compensation(targets, size, problems)


def read_targets(path: str | Path, n: int) -> tuple[list[str] | None, FloatArray]:
    """Joint targets from a CSV (``,`` or ``;``): one row per target, ``n`` numbers each, an
    optional header row of names. One-line errors name the file and line."""
    from dhlog.errors import InputError

    name = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot be read ({exc}); give a CSV of joint targets.") from None
    header: list[str] | None = None
    rows: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in line.replace(";", ",").split(",")]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if header is None and not rows:
                header = cells
                continue
            raise InputError(
                f"{name}, line {number}: '{line.strip()[:60]}' is not {n} numbers; give one "
                "target per row, one value per joint."
            ) from None
        if len(values) != n or not all(np.isfinite(values)):
            raise InputError(
                f"{name}, line {number}: has {len(values)} values; the result has {n} joints "
                "(finite numbers, one per joint)."
            )
        rows.append(values)
    if header is not None and len(header) != n:
        raise InputError(f"{name}: its header names {len(header)} columns; the result has {n}.")
    if not rows:
        raise InputError(f"{name}: holds no target; give one row of {n} joint values per target.")
    return header, np.array(rows)


def targets_csv(header: list[str] | None, Q: FloatArray, problems: dict[int, str]) -> str:
    """The corrected targets as CSV: the input's row number, then one column per joint (the
    input's header, else ``q1 … qn``); targets not corrected are left out."""
    n = Q.shape[1]
    names = header or [f"q{j + 1}" for j in range(n)]
    lines = [",".join(["row", *names])]
    for k, q in enumerate(Q):
        if k in problems:
            continue
        lines.append(",".join([str(k + 1), *(f"{v:.15g}" for v in q)]))
    return "\n".join(lines) + "\n"
