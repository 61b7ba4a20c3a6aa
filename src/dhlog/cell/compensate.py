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

from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel
from dhlog.model.fk import fk_frames

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
    from scipy.spatial.transform import Rotation

    E = np.einsum("mij,mkj->mik", T[:, :3, :3], goal[:, :3, :3])  # R_T R_goalᵀ
    # the rotation vector, not the skew part: that vanishes again at a half turn, a false
    # solution inverse kinematics from afar finds
    dr = Rotation.from_matrix(E).as_rotvec()
    return np.asarray(np.concatenate([dp, dr], axis=1), dtype=np.float64)


def _solve(
    model: DHModel,
    calibrated: bool,
    goal: FloatArray,
    start: FloatArray,
    *,
    far: bool = False,
    held: tuple[int, ...] = (),
) -> tuple[FloatArray, FloatArray, dict[int, str]]:
    """The joint vectors (m, n) at which ``model`` puts its last frame at ``goal`` (m, 4, 4),
    by Newton's method with backtracking from ``start`` (m, n); the remaining pose error per row
    (m, rad) and one line per row that is too near a singularity or did not converge. ``far``:
    the start may be far from the solution (inverse kinematics): damped steps (Levenberg) while
    the error is large, and the singularity judged at the solution only. ``held``: joints
    (0-based) kept at their start (a result's parked joints: not calibrated)."""
    m, n = start.shape
    free = [j for j in range(n) if j not in held]
    q = start.copy()
    active = np.ones(m, dtype=bool)
    problems: dict[int, str] = {}
    err = _error(_pose(model, q, calibrated), goal)
    for _ in range(MAX_ITERATIONS * (4 if far else 1)):
        size = np.max(np.abs(err), axis=1)
        active &= size > CONVERGED
        if not np.any(active):
            break
        rows = np.flatnonzero(active)
        J = np.empty((rows.size, 6, len(free)))
        for c, j in enumerate(free):
            step = np.zeros(n)
            step[j] = STEP
            plus = _error(_pose(model, q[rows] + step, calibrated), goal[rows])
            minus = _error(_pose(model, q[rows] - step, calibrated), goal[rows])
            J[:, :, c] = (plus - minus) / (2 * STEP)
        for k, row in enumerate(rows):
            s = np.linalg.svd(J[k], compute_uv=False)
            near = float(np.max(np.abs(err[row]))) < 1e-6
            if s[-1] <= s[0] / SINGULAR and (near or not far):
                problems[int(row)] = (
                    f"too near a singularity (Jacobian condition {s[0] / max(s[-1], 1e-300):.3g})"
                )
                active[row] = False
                continue
            if far and not near:  # Levenberg: a bounded step through near-singular iterates
                damping = 1e-3 * s[0] ** 2
                step_free = np.linalg.solve(
                    J[k].T @ J[k] + damping * np.eye(len(free)), -J[k].T @ err[row]
                )
            else:
                step_free, *_ = np.linalg.lstsq(J[k], -err[row], rcond=None)
            delta = np.zeros(n)
            delta[free] = step_free
            # backtracking: a full Newton step near a singularity can overshoot
            before = float(np.sum(err[row] ** 2))
            for _ in range(40):
                trial = q[row] + delta
                e = _error(_pose(model, trial[None], calibrated), goal[row : row + 1])[0]
                if float(np.sum(e**2)) < before or np.max(np.abs(delta)) < CONVERGED:
                    break
                delta = delta / 2.0
            q[row] = trial
            err[row] = e
            if np.max(np.abs(delta)) < CONVERGED:  # least squares (fewer than six joints)
                active[row] = False
    size = np.max(np.abs(err), axis=1)
    exact = len(free) >= 6  # fewer joints reach the pose only in the least-squares sense
    for bad in np.flatnonzero((active | exact) & (size > 1e-9)).tolist():
        if bad not in problems:
            problems[bad] = (
                f"did not converge (pose error {size[bad]:.3g} m or rad): too near a singularity"
            )
    return q, size, problems


def _checked(
    q: FloatArray,
    size: FloatArray,
    problems: dict[int, str],
    reference: FloatArray,
    limits: FloatArray | None,
) -> Compensation:
    """``q`` with the rows too far from ``reference`` (a near-singular amplification) or out of
    ``limits`` left out (NaN), each with its line."""
    change = np.max(np.abs(q - reference), axis=1)
    for big in np.flatnonzero(change > MAX_CORRECTION).tolist():
        if big not in problems:
            problems[big] = (
                f"too near a singularity: the correction would be {change[big]:.3g} rad or m"
            )
    if limits is not None:
        lo, hi = limits[:, 0], limits[:, 1]
        for k in range(q.shape[0]):
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
    goal = _pose(nominal, Q, calibrated=False)
    q, size, problems = _solve(result, True, goal, Q, held=result.parked)
    return _checked(q, size, problems, Q, limits)


#: Starting joint vectors tried, after the given configuration or home, for a Cartesian target
#: with none given (seeded, uniform within the limits).
IK_STARTS = 24


def compensate_poses(
    result: DHModel,
    nominal: DHModel,
    goal: FloatArray,
    *,
    configuration: FloatArray | None = None,
    limits: FloatArray | None = None,
) -> tuple[Compensation, FloatArray]:
    """Cartesian targets ``goal`` (m, 4, 4: the last frame in the nominal's base frame): the
    joint vectors at which the calibrated robot reaches them, and the nominal's own solution
    (m, n; what the controller would run). The nominal's inverse kinematics starts from
    ``configuration`` (m, n: the controller's joint configuration of each target) when given,
    else from home and :data:`IK_STARTS` seeded vectors within ``limits`` (the solution nearest
    home is not guaranteed: give the configuration to choose the branch); the calibrated one
    starts from the nominal's and is checked as :func:`compensate` checks its corrections."""
    goal = np.asarray(goal, dtype=np.float64)
    m, n = goal.shape[0], nominal.table.n
    if configuration is not None:
        starts = [np.asarray(configuration, dtype=np.float64)]
    else:
        home = np.zeros((m, n))
        if limits is not None:
            home = np.clip(home, limits[:, 0], limits[:, 1])
        starts = [home]
        if limits is not None:
            rng = np.random.default_rng(0)
            starts += [
                np.repeat(rng.uniform(limits[:, 0], limits[:, 1])[None], m, 0)
                for _ in range(IK_STARTS)
            ]
    q_nom = np.full((m, n), np.nan)
    nom_problems: dict[int, str] = {}
    todo = np.arange(m)
    for start in starts:
        q, _, problems = _solve(nominal, False, goal[todo], start[todo], far=True)
        inside = np.ones(todo.size, dtype=bool)
        if limits is not None:
            inside = np.all((q >= limits[:, 0]) & (q <= limits[:, 1]), axis=1)
        for k, row in enumerate(todo.tolist()):
            if k in problems:
                nom_problems[row] = f"the nominal does not reach it: {problems[k]}"
            elif not inside[k]:
                nom_problems[row] = "the nominal reaches it only outside the limits"
            else:
                q_nom[row] = q[k]
                nom_problems.pop(row, None)
        todo = todo[~np.isfinite(q_nom[todo, 0])]
        if not todo.size:
            break
    reached = np.isfinite(q_nom[:, 0])
    q_cal = q_nom.copy()
    size = np.full(m, np.inf)
    problems = dict(nom_problems)
    if np.any(reached):
        rows = np.flatnonzero(reached)
        q, s, solved = _solve(result, True, goal[rows], q_nom[rows], held=result.parked)
        q_cal[rows], size[rows] = q, s
        problems.update({int(rows[k]): why for k, why in solved.items()})
    # rows the nominal does not reach are NaN and already have their line in ``problems``
    done = _checked(np.nan_to_num(q_cal), size, problems, np.nan_to_num(q_nom), limits)
    return done, q_nom


def read_poses(path: str | Path, n: int) -> tuple[FloatArray, FloatArray | None]:
    """Cartesian targets from a CSV (:func:`dhlog.cell.posecsv.read_pose_table`, the
    convention from the header): the poses (m, 4, 4, m) and the configurations (m, n, as
    written) or None."""
    from dhlog.cell.posecsv import read_pose_table

    table = read_pose_table(path, n)
    return table.poses, table.configuration


def read_targets(path: str | Path, n: int) -> tuple[list[str] | None, FloatArray]:
    """Joint targets from a CSV (``,`` or ``;``): one row per target, ``n`` numbers each, an
    optional header row of names; a first column headed ``row`` (what ``plan --select`` and this
    module write) is left out. One-line errors name the file and line."""
    from dhlog.errors import InputError

    name = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{name}: cannot be read ({exc}); give a CSV of joint targets.") from None
    header: list[str] | None = None
    numbered = False
    rows: list[list[float]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in line.replace(";", ",").split(",")]
        if numbered:
            cells = cells[1:]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if header is None and not rows:
                header = cells
                numbered = len(cells) == n + 1 and cells[0].lower() == "row"
                if numbered:
                    header = cells[1:]
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


def targets_csv(
    header: list[str] | None,
    Q: FloatArray,
    problems: dict[int, str],
    units: list[str] | None = None,
) -> str:
    """The corrected targets as CSV: the input's row number, then one column per joint (the
    input's header, else ``q1 … qn``; ``units``: each name's unit appended, ``a1_deg``, unless
    the name already ends with it); targets not corrected are left out."""
    n = Q.shape[1]
    names = list(header or [f"q{j + 1}" for j in range(n)])
    if units is not None:
        names = [
            c if c.lower().endswith(f"_{u}") else f"{c}_{u}"
            for c, u in zip(names, units, strict=True)
        ]
    lines = [",".join(["row", *names])]
    for k, q in enumerate(Q):
        if k in problems:
            continue
        lines.append(",".join([str(k + 1), *(f"{v:.15g}" for v in q)]))
    return "\n".join(lines) + "\n"
