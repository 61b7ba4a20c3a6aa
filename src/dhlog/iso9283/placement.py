"""Where the ISO 9283 test cube goes in a robot's workspace, on the nominal model: the tool held in
one orientation (:data:`ORIENTATIONS`), every corner reached along the straight line from the
cube's centre (:data:`WALK`, each point seeded by the previous) within the joint limits and with
the tool Jacobian's condition below :data:`MAX_CONDITION`; the largest such cube over a grid of
centres in the base's x–z plane (:data:`GRID`, then a finer grid around the best; the edge by
:data:`BISECTIONS` steps of bisection), or with an edge given the best-conditioned centre where
it fits (:func:`_search`, kept per robot for the process). The test poses' and paths' joint
targets are then solved from the reference pose at the centre (:func:`_build`, :func:`_plan`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.cube import (
    CORNER_SIGNS,
    PLANES,
    TestCube,
    TestPath,
    TestPose,
    TestProgramError,
    cube_corners,
    path_points,
    pose_points,
)
from dhlog.model import ik
from dhlog.model.fk import fk_point
from dhlog.model.robots import Robot

#: The orientations the tool frame may keep at every pose and path point, tried in this order
#: (the larger cube wins, the first on a tie): its z axis pointing down (−z of the base) with its
#: x axis along the base's +x, as over a work table. (Pointing forward, +x, was tried too: it
#: gave a smaller cube for the KR5 and the UR5 and a slightly larger one for the PUMA 560, at
#: twice the search's time.)
ORIENTATIONS = {"pointing down": np.diag([1.0, -1.0, -1.0])}


#: Away from singularities: the condition number of the tool Jacobian (its translational rows
#: divided by the robot's reach, so both halves are dimensionless) stays below this everywhere
#: on the cube's diagonals and paths.
MAX_CONDITION = 100.0


#: The walk from P1 to each corner: these fractions of the way, each seeded by the previous.
WALK = (0.2, 0.4, 0.6, 0.8, 1.0)


#: Cube centres tried (a grid in the base's x–z plane, y = 0), then a finer grid around the best.
GRID = 9


#: Bisection steps on the edge at each centre.
BISECTIONS = 7


#: Starting joint vectors for the reference pose at a centre: home and these, seeded.
STARTS = 15


#: The inverse kinematics from afar (a reference pose's seeded starts) and from near (seeded by
#: a solution nearby: a walk's previous step, the reference pose): more steps and a larger first
#: damping from afar.
_FAR = ik.IKSettings(max_iterations=150, damping=1e-3)
_NEAR = ik.IKSettings(max_iterations=30, damping=1e-8)


@dataclass
class _Setup:
    """What every reachability check needs: the robot, the tool point, the orientation, the
    reach (the Jacobian's length scale) and the limits."""

    robot: Robot
    tool: FloatArray
    R: FloatArray
    reach: float
    #: how the tool points (a key of :data:`ORIENTATIONS`), for messages
    pointing: str = "pointing down"

    def goals(self, points: FloatArray) -> FloatArray:
        T = np.zeros((*points.shape[:-1], 4, 4))
        T[..., :3, :3] = self.R
        T[..., :3, 3] = points
        T[..., 3, 3] = 1.0
        return T

    def solve(
        self, points: FloatArray, start: FloatArray, far: bool = False
    ) -> tuple[FloatArray, np.ndarray, FloatArray]:
        """Joint targets (m, n) of tool points (m, 3) from ``start``; reached (converged, within
        the limits, condition below the bound) and the condition numbers (m,)."""
        r = self.robot
        sol = ik.solve(
            r.table,
            self.goals(points),
            start,
            self.tool,
            T_base=r.T_base,
            limits=r.limits,
            length=self.reach,
            settings=_FAR if far else _NEAR,
        )
        kappa = ik.condition(r.table, sol.q, self.tool, T_base=r.T_base, length=self.reach)
        ok = sol.converged & (kappa < MAX_CONDITION)
        return sol.q, ok, kappa

    def track(self, q0: FloatArray, points: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Follow each row's points (m, k, 3) from ``q0`` (m, n), each seeded by the previous:
        the joint targets (m, k, n) and the index of the first point not reached (k: all)."""
        m, k = points.shape[:2]
        Q = np.full((m, k, q0.shape[1]), np.nan)
        first = np.full(m, k)
        q = q0.copy()
        for j in range(k):
            alive = np.flatnonzero(first == k)  # a row stops at its first point not reached
            if not alive.size:
                break
            q[alive], ok, _ = self.solve(points[alive, j], q[alive])
            Q[alive, j] = q[alive]
            first[alive[~ok]] = j
        return Q, first


def _setup(robot: Robot, tool_point: FloatArray | None, pointing: str) -> _Setup:
    tool = robot.tool_point if tool_point is None else np.asarray(tool_point, dtype=np.float64)
    rng = np.random.default_rng(0)
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (2000, robot.n))
    p = fk_point(robot.table, Q, tool, T_base=robot.T_base)
    reach = float(np.max(np.linalg.norm(p, axis=1)))
    return _Setup(robot, tool, ORIENTATIONS[pointing], reach, pointing)


def _mm(p: FloatArray) -> str:
    return "(" + ", ".join(f"{v * 1e3:.1f}" for v in p) + ") mm"


def _reference(setup: _Setup, centres: FloatArray) -> tuple[FloatArray, np.ndarray]:
    """The reference pose at each centre (m, 3): the best-conditioned of the solutions reached
    from home (zero, clipped into the limits) and :data:`STARTS` seeded starts within the
    limits; (m, n) and reached (m,)."""
    r = setup.robot
    m = len(centres)
    rng = np.random.default_rng(0)
    starts = np.vstack(
        [np.clip(np.zeros(r.n), r.limits[:, 0], r.limits[:, 1])[None]]
        + [rng.uniform(r.limits[:, 0], r.limits[:, 1])[None] for _ in range(STARTS)]
    )
    S = starts.shape[0]
    q, ok, kappa = setup.solve(np.repeat(centres, S, 0), np.tile(starts, (m, 1)), far=True)
    kappa = np.where(ok, kappa, np.inf).reshape(m, S)
    best = np.argmin(kappa, axis=1)
    return q.reshape(m, S, r.n)[np.arange(m), best], np.isfinite(kappa[np.arange(m), best])


def _corners_reached(
    setup: _Setup, centres: FloatArray, sizes: FloatArray, q0: FloatArray
) -> tuple[np.ndarray, FloatArray, np.ndarray]:
    """Per cube (m,): every corner reached along the straight line from its centre (the
    :data:`WALK`, which passes P2 … P5 at 0.8), the joint targets (m, 8, len(WALK), n) and the
    first corner not reached (8: none)."""
    m = len(centres)
    corners = centres[:, None, :] + CORNER_SIGNS[None] * sizes[:, None, None] / 2  # (m, 8, 3)
    f = np.array(WALK)[None, None, :, None]
    points = centres[:, None, None, :] + f * (corners - centres[:, None, :])[:, :, None, :]
    Q, first = setup.track(np.repeat(q0, 8, 0), points.reshape(m * 8, len(WALK), 3))
    bad = (first < len(WALK)).reshape(m, 8)
    failing = np.where(bad.any(axis=1), np.argmax(bad, axis=1), 8)
    return np.asarray(~bad.any(axis=1)), Q.reshape(m, 8, len(WALK), q0.shape[1]), failing


def _largest(setup: _Setup, centres: FloatArray, q0: FloatArray, top: FloatArray) -> FloatArray:
    """The largest edge (m,) up to ``top`` at each centre whose corners are all reached
    (bisection; 0 where none is)."""
    lo = np.zeros(len(centres))
    hi = top.copy()
    for _ in range(BISECTIONS):
        mid = (lo + hi) / 2
        ok, _, _ = _corners_reached(setup, centres, mid, q0)
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
    return lo


def _room(setup: _Setup, centres: FloatArray) -> FloatArray:
    """The largest edge the cell allows at each centre: above the base's x–y plane (the floor
    or mounting plane) and in front of the robot (x ≥ 10 % of the reach, clear of its column),
    at most the reach."""
    x_room = 2 * (centres[:, 0] - 0.1 * setup.reach)
    z_room = 2 * centres[:, 2]
    return np.asarray(np.clip(np.minimum(np.minimum(x_room, z_room), setup.reach), 0.0, None))


#: The searches made in this process (a robot's model, tool, orientation and size asked → the
#: cube found): a second program of the same robot (the API, then the command) does not search
#: again.
_SEARCHED: dict[tuple[object, ...], tuple[FloatArray, float, FloatArray]] = {}


def _search(setup: _Setup, size: float | None) -> tuple[FloatArray, float, FloatArray]:
    """The cube (centre, edge) and the reference pose at its centre: the largest whose corners
    are reached, over a grid of centres in the base's x–z plane (y = 0) and a finer one around
    the best; with ``size`` given, the best-conditioned centre where that edge fits."""
    r = setup.robot
    t = r.table
    key = (
        type(t).__name__,
        *(np.asarray(v, dtype=np.float64).tobytes() for v in (t.theta_offset, t.d_offset, t.a)),
        *(np.asarray(v, dtype=np.float64).tobytes() for v in (t.alpha, t.revolute, r.T_base)),
        np.asarray(getattr(t, "beta", ()), dtype=np.float64).tobytes(),
        r.limits.tobytes(),
        setup.tool.tobytes(),
        setup.R.tobytes(),
        size,
    )
    if key not in _SEARCHED:
        if len(_SEARCHED) > 32:
            _SEARCHED.clear()
        _SEARCHED[key] = _searched(setup, size)
    centre, edge, q = _SEARCHED[key]
    return centre.copy(), edge, q.copy()


def _searched(setup: _Setup, size: float | None) -> tuple[FloatArray, float, FloatArray]:
    """:func:`_search` itself."""
    R = setup.reach
    xs = np.linspace(0.15 * R, 0.85 * R, GRID)
    zs = np.linspace(0.05 * R, 0.95 * R, GRID)
    step = np.array([xs[1] - xs[0], zs[1] - zs[0]])
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    centres = np.column_stack([X.ravel(), np.zeros(X.size), Z.ravel()])
    best_c, best_s, best_q = np.zeros(3), 0.0, np.zeros(setup.robot.n)
    for refine in (False, True):
        if refine:
            gx, gz = np.meshgrid(np.linspace(-0.5, 0.5, 5), np.linspace(-0.5, 0.5, 5))
            centres = best_c + np.column_stack(
                [gx.ravel() * step[0], np.zeros(gx.size), gz.ravel() * step[1]]
            )
        if size is not None:  # only where the cell has room for it
            centres = centres[_room(setup, centres) >= size]
            if not len(centres):
                continue
        q0, reached = _reference(setup, centres)
        centres, q0 = centres[reached], q0[reached]
        if not len(centres):
            continue
        top = _room(setup, centres)
        if size is not None:
            ok = top >= size
            fits, _, _ = _corners_reached(setup, centres[ok], np.full(ok.sum(), size), q0[ok])
            if np.any(fits):
                kappa = ik.condition(
                    setup.robot.table,
                    q0[ok][fits],
                    setup.tool,
                    T_base=setup.robot.T_base,
                    length=R,
                )
                k = int(np.argmin(kappa))
                return centres[ok][fits][k], size, q0[ok][fits][k]
            continue
        sizes = _largest(setup, centres, q0, top)
        k = int(np.argmax(sizes))
        if sizes[k] > best_s:
            best_c, best_s, best_q = centres[k], float(sizes[k]), q0[k]
    if size is not None:
        raise TestProgramError(
            f"{setup.robot.name}: no test cube of edge {size * 1e3:.0f} mm fits the workspace "
            f"with the tool {setup.pointing} (every corner reached within the joint limits, "
            f"Jacobian condition below {MAX_CONDITION:g}); give a smaller --cube-size, or leave "
            "it out for the largest that fits."
        )
    if best_s <= 0:
        raise TestProgramError(
            f"{setup.robot.name}: no test cube fits the workspace with the tool {setup.pointing} "
            f"within the joint limits away from singularities (condition below "
            f"{MAX_CONDITION:g}); the ISO 9283 program needs a robot that holds that "
            "orientation over a volume."
        )
    return best_c, best_s, best_q


def _build(
    setup: _Setup,
    cube: TestCube,
    q_ref: FloatArray,
    speed: float,
) -> tuple[list[TestPose], list[TestPath], str | None]:
    """The poses and paths of ``cube`` from the reference pose at its centre, or what is not
    reached (one phrase)."""
    names = [f"C{i + 1}" for i in range(8)]
    q1, ok, _ = setup.solve(cube.centre[None], q_ref[None])
    if not ok[0]:
        return [], [], f"P1 (the cube's centre {_mm(cube.centre)})"
    reached, Q, failing = _corners_reached(setup, cube.centre[None], np.array([cube.size]), q1)
    if not reached[0]:
        c = int(failing[0])
        return [], [], f"corner {names[c]} {_mm(cube.corners[c])}"
    P = pose_points(cube)
    plane = PLANES[cube.plane]
    poses = [TestPose("P1", setup.goals(P[0]), q1[0])]
    for k, corner in enumerate(plane):
        q = Q[0, corner, WALK.index(0.8)]
        poses.append(TestPose(f"P{k + 2}", setup.goals(P[k + 1]), q))
    wanted = path_points(cube)
    k = max(len(points) for points in wanted.values())
    # from P1 out to each path's first point (not commanded), then along the path; a shorter
    # path is padded with its last point
    starts = np.array([points[0] for points in wanted.values()])
    lead = P[0] + np.linspace(0.25, 1.0, 4)[None, :, None] * (starts - P[0])[:, None, :]
    Ql, first = setup.track(np.repeat(q1, len(wanted), 0), lead)
    for (name, points), j in zip(wanted.items(), first, strict=True):
        if j < lead.shape[1]:
            return [], [], f"the {name.replace('_', ' ')}'s first point {_mm(points[0])}"
    padded = np.array([np.vstack([p, np.repeat(p[-1:], k - len(p), 0)]) for p in wanted.values()])
    Qp, first = setup.track(Ql[:, -1], padded)
    paths: list[TestPath] = []
    for row, (name, points) in enumerate(wanted.items()):
        if first[row] < len(points):
            j = int(first[row])
            return [], [], f"the {name.replace('_', ' ')} at point {j} {_mm(points[j])}"
        paths.append(TestPath(name, points, Qp[row, : len(points)], speed))
    return poses, paths, None


def _plan(
    setup: _Setup,
    cube_size: float | None,
    cube_centre: FloatArray | None,
    plane: str,
    speed: float,
) -> tuple[TestCube, list[TestPose], list[TestPath], list[str]]:
    """The cube, poses and paths with the tool held as ``setup`` says, and the notes."""
    robot = setup.robot
    notes = [f"the tool's z axis {setup.pointing} at every pose and path point"]
    where = f"with the tool {setup.pointing} within the joint limits away from singularities"
    if cube_centre is not None:
        centre = cube_centre
        q0, reached = _reference(setup, centre[None])
        if not reached[0]:
            raise TestProgramError(
                f"{robot.name}: the cube's centre {_mm(centre)} is not reached {where}; give "
                "another --cube-centre."
            )
        if cube_size is None:
            size = float(_largest(setup, centre[None], q0, np.array([setup.reach]))[0])
            if size <= 0:
                raise TestProgramError(
                    f"{robot.name}: no cube around {_mm(centre)} has every corner reached "
                    f"{where}; give another --cube-centre."
                )
            notes.append(f"the largest cube around the centre given: edge {size * 1e3:.0f} mm")
        else:
            size = cube_size
        q_ref = q0[0]
    else:
        centre, size, q_ref = _search(setup, cube_size)
        centre = np.round(centre * 1e3) / 1e3  # whole millimetres
    given = cube_size is not None
    if not given:
        size = math.floor(size * 1e3) / 1e3
    last = None
    for _ in range(1 if given else 12):
        cube = TestCube(centre, size, plane, cube_corners(centre, size))
        poses, paths, last = _build(setup, cube, q_ref, speed)
        if last is None or given:
            break
        size = math.floor(size * 0.97 * 1e3) / 1e3  # the paths reach less far than the corners
    if last is not None:
        raise TestProgramError(
            f"{robot.name}: the test cube of edge {size * 1e3:.0f} mm at {_mm(centre)}: {last} "
            f"is not reached {where} (condition below {MAX_CONDITION:g}); give a smaller "
            "--cube-size or another --cube-centre."
        )
    if cube_centre is None:
        notes.append(
            f"the cube's centre: the best of {GRID}×{GRID} centres in the base's x–z plane "
            "(y = 0) and 25 around it"
            + ("" if given else f"; the largest edge found there, {size * 1e3:.0f} mm")
        )
    return cube, poses, paths, notes
