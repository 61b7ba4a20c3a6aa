"""A robot program's targets corrected in order, its configuration kept continuous.

A program is a sequence: the controller reaches each Cartesian target from where the previous
one left the arm. For a pose, the UR controller's inverse kinematics takes the solution nearest
the current joints (URScript's ``movej`` with a pose, ``get_inverse_kin``'s ``qnear``); a
``movel`` moves the tool along the straight line, so the joints follow it continuously. Here
each Cartesian target's nominal joint solution is continued from the previous target's along
the straight line between the two poses (position interpolated, rotation slerped, in steps of
at most :data:`STEP_LENGTH` and :data:`STEP_ANGLE`), each step solved from the last by the
nominal's inverse kinematics (:func:`dhlog.model.ik.solve`); a target with the controller's
configuration given (``qnear``, the CSV's ``j1 … jn``) starts from that instead. The branch
(shoulder, elbow, wrist) therefore stays the previous target's, and neighbouring targets move
the joints a little. The calibrated joints then come from the nominal's solution by Newton's
method on the calibrated model (:func:`dhlog.cell.compensate.compensate`'s solver), which does
not leave the branch (corrections larger than ``MAX_CORRECTION`` are refused).

What cannot stay on the branch is named, the target left out (its row or line in
``problems``): the straight line crosses a singularity (the Jacobian's determinant changes sign
between two steps — the arm would have to change configuration), a step is not reached, the
continued solution leaves the joints' limits, or the calibrated solution is near a singularity
or out of the limits. Joint targets are corrected as :func:`~dhlog.cell.compensate.compensate`
corrects them: they carry their configuration.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel

#: The longest straight-line step (m) and largest rotation step (rad) of the continuation.
STEP_LENGTH = 0.02
STEP_ANGLE = math.radians(5.0)
#: Steps along one segment at most (a 20 m move at 2 cm: beyond any arm).
MAX_STEPS = 1000


@dataclass(frozen=True)
class Target:
    """One target of a program: a joint target ``joints`` (n,; rad or m) or a Cartesian
    ``pose`` (4, 4: the TCP in the nominal's base frame, m) with its ``tcp`` (4, 4: the TCP in
    the last frame) and optionally ``hint`` (n,: the controller's configuration near which the
    pose is solved). ``where``: how a message names it (``line 12``, ``row 3``). ``accepts``:
    for a target that carries its own configuration data (RAPID's confdata), why the nominal's
    joints found for it are not that configuration (None: they are); ``fallback`` then gives
    the start (n,) to solve from instead, from the previous target's joints (or None)."""

    where: str
    joints: FloatArray | None = None
    pose: FloatArray | None = None
    tcp: FloatArray = field(default_factory=lambda: np.eye(4))
    hint: FloatArray | None = None
    accepts: Callable[[FloatArray], str | None] | None = None
    fallback: Callable[[FloatArray | None], FloatArray] | None = None


@dataclass(frozen=True)
class Filtered:
    """The corrected program (m targets, n joints): ``joints`` the corrected joint targets (NaN
    rows where none), ``nominal`` the joints the controller runs for the original targets,
    ``commanded`` the TCP pose to command instead (4, 4 each: the nominal's FK at the corrected
    joints times the TCP), ``error`` the pose error left under the calibrated model (m or rad),
    ``problems`` (index → why, for the targets left out) and ``notes`` (what was assumed)."""

    joints: FloatArray
    nominal: FloatArray
    commanded: FloatArray
    error: FloatArray
    problems: dict[int, str]
    notes: list[str]

    @property
    def largest_step(self) -> float:
        """The largest joint change (rad or m) between neighbouring corrected targets."""
        ok = self.joints[np.isfinite(self.joints[:, 0])]
        if len(ok) < 2:
            return 0.0
        return float(np.max(np.abs(np.diff(ok, axis=0))))


def _flange(nominal: DHModel, q: FloatArray) -> FloatArray:
    """The nominal's last frame (m, 4, 4) at joint vectors ``q`` (m, n)."""
    from dhlog.model.fk import fk_frames

    return np.asarray(fk_frames(nominal.table, q, T_base=nominal.T_base)[:, -1], dtype=np.float64)


def _handedness(nominal: DHModel, q: FloatArray) -> FloatArray:
    """The sign of the nominal's Jacobian determinant at ``q`` (m, n): it changes exactly where
    the arm passes a singularity (shoulder, elbow or wrist); 0 where n ≠ 6."""
    from dhlog.model.ik import tool_jacobian

    if nominal.table.n != 6:
        return np.zeros(len(q))
    J = tool_jacobian(nominal.table, q, np.zeros(3), T_base=nominal.T_base)
    return np.asarray(np.sign(np.linalg.det(J)), dtype=np.float64)


def _segment(start: FloatArray, goal: FloatArray) -> FloatArray:
    """The poses (k, 4, 4) along the straight line from ``start`` to ``goal`` (the last one
    ``goal``), in steps of at most :data:`STEP_LENGTH` and :data:`STEP_ANGLE`."""
    from scipy.spatial.transform import Rotation

    R0 = Rotation.from_matrix(start[:3, :3])
    turn = (R0.inv() * Rotation.from_matrix(goal[:3, :3])).as_rotvec()
    length = float(np.linalg.norm(goal[:3, 3] - start[:3, 3]))
    steps = max(1, math.ceil(max(length / STEP_LENGTH, float(np.linalg.norm(turn)) / STEP_ANGLE)))
    s = np.linspace(0.0, 1.0, min(steps, MAX_STEPS) + 1)[1:]
    T = np.repeat(np.eye(4)[None], len(s), 0)
    T[:, :3, :3] = (R0 * Rotation.from_rotvec(s[:, None] * turn)).as_matrix()
    T[:, :3, 3] = start[:3, 3] + s[:, None] * (goal[:3, 3] - start[:3, 3])
    T[-1] = goal
    return T


def _continued(
    nominal: DHModel, q_start: FloatArray, goal: FloatArray, since: str
) -> tuple[FloatArray | None, str | None]:
    """The nominal's joints at ``goal`` (the last frame, 4, 4) continued from ``q_start`` (n,)
    along the straight line; or None and why (``since``: where the line starts)."""
    from dhlog.model.ik import solve

    q = np.asarray(q_start, dtype=np.float64)
    side = _handedness(nominal, q[None])[0]
    start = _flange(nominal, q[None])[0]
    for T in _segment(start, goal):
        found = solve(nominal.table, T[None], q[None], np.zeros(3), T_base=nominal.T_base)
        if not bool(found.converged[0]):
            mm = float(np.linalg.norm(T[:3, 3] - start[:3, 3])) * 1e3
            return None, (
                f"the nominal does not reach the straight line from {since} to it "
                f"{mm:.0f} mm along (out of reach or at a singularity)"
            )
        q_next = found.q[0]
        now = _handedness(nominal, q_next[None])[0]
        if side and now and now != side:
            mm = float(np.linalg.norm(T[:3, 3] - start[:3, 3])) * 1e3
            return None, (
                f"the straight line from {since} crosses a singularity {mm:.0f} mm along: the "
                "arm would change configuration (shoulder, elbow or wrist) between the two; "
                "add a joint target between them or move the target"
            )
        side = now or side
        q = q_next
    return q, None


def _accepted(
    nominal: DHModel,
    t: Target,
    q: FloatArray,
    previous: tuple[FloatArray, str] | None,
) -> tuple[FloatArray | None, str | None]:
    """``q`` when ``t`` accepts it as its configuration; else the nominal's solution from
    ``t``'s fallback start when that one is accepted; else None and why."""
    from dhlog.model.ik import solve

    assert t.accepts is not None and t.pose is not None
    why = t.accepts(q)
    if why is None:
        return q, None
    if t.fallback is not None:
        start = t.fallback(None if previous is None else previous[0])
        goal = t.pose @ np.linalg.inv(t.tcp)
        found = solve(nominal.table, goal[None], start[None], np.zeros(3), T_base=nominal.T_base)
        if bool(found.converged[0]) and t.accepts(found.q[0]) is None:
            return found.q[0], None
    return None, why


def _outside(q: FloatArray, limits: FloatArray | None) -> str | None:
    """Which joints ``q`` (n,) puts outside ``limits`` (n, 2), as words; None when inside."""
    if limits is None:
        return None
    out = np.flatnonzero((q < limits[:, 0]) | (q > limits[:, 1]))
    return ", ".join(f"joint {j + 1}" for j in out) or None


def filter_targets(
    result: DHModel,
    nominal: DHModel,
    targets: list[Target],
    *,
    limits: FloatArray | None = None,
) -> Filtered:
    """The program ``targets`` corrected in order for ``result`` on a controller running
    ``nominal`` (see the module docstring); ``limits`` (n, 2): the joints' limits."""
    from dhlog.cell.compensate import _checked, _solve, compensate_poses

    m, n = len(targets), nominal.table.n
    q_nom = np.full((m, n), np.nan)
    goal = np.repeat(np.eye(4)[None], m, 0)
    problems: dict[int, str] = {}
    notes: list[str] = []
    previous: tuple[FloatArray, str] | None = None
    for k, t in enumerate(targets):
        if t.joints is not None:
            q = np.asarray(t.joints, dtype=np.float64)
            goal[k] = _flange(nominal, q[None])[0]
        else:
            assert t.pose is not None
            goal[k] = t.pose @ np.linalg.inv(t.tcp)
            if t.hint is not None:
                q_found, why = _continued(nominal, t.hint, goal[k], "the configuration given")
            elif previous is not None:
                q_found, why = _continued(nominal, previous[0], goal[k], previous[1])
            else:
                done, first = compensate_poses(result, nominal, goal[k : k + 1], limits=limits)
                q_found = first[0] if np.isfinite(first[0, 0]) else None
                why = done.problems.get(0)
                if q_found is not None:
                    shown = ", ".join(f"{v:.1f}" for v in np.degrees(q_found))
                    notes.append(
                        f"{t.where}: no joint configuration before it; took the nominal's "
                        f"solution nearest home or a seeded start ({shown}°) — put a joint "
                        "target first to choose the branch"
                    )
            if q_found is not None and t.accepts is not None:
                q_found, why = _accepted(nominal, t, q_found, previous)
            if q_found is None:
                problems[k] = why or "the nominal does not reach it"
                continue
            q = q_found
            out = _outside(q, limits)
            if out is not None:
                problems[k] = (
                    f"on the configuration it is continued on, the nominal reaches it only "
                    f"outside the limits of {out}; another configuration would flip the arm"
                )
                continue
        q_nom[k] = q
        previous = (q, t.where)
    rows = np.flatnonzero(np.isfinite(q_nom[:, 0]))
    joints = np.full((m, n), np.nan)
    error = np.full(m, np.inf)
    if rows.size:
        q_cal, size, solved = _solve(result, True, goal[rows], q_nom[rows], held=result.parked)
        checked = _checked(q_cal, size, solved, q_nom[rows], limits)
        joints[rows], error[rows] = checked.targets, checked.error
        problems.update({int(rows[i]): why for i, why in checked.problems.items()})
        kept = rows[np.isfinite(joints[rows, 0])]
        if kept.size:
            changed = _handedness(nominal, joints[kept]) != _handedness(nominal, q_nom[kept])
            for k in kept[changed].tolist():
                problems[k] = "the correction crosses a singularity (the configuration changes)"
                joints[k] = np.nan
    commanded = np.full((m, 4, 4), np.nan)
    good = np.flatnonzero(np.isfinite(joints[:, 0]))
    if good.size:
        tcp = np.stack([targets[k].tcp for k in good])
        commanded[good] = _flange(nominal, joints[good]) @ tcp
    return Filtered(joints, q_nom, commanded, error, problems, notes)
