"""The ISO 9283 test program (clause 6): the test cube in the robot's workspace, the five test
poses P1–P5 on its diagonal plane, the test paths in that plane, and the cycle program that visits
them — commanded poses in the robot's base frame and the joint targets that reach them on the
nominal model."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dhlog.errors import InputError, UsageError
from dhlog.geometry._checks import FloatArray
from dhlog.model import ik
from dhlog.model.fk import fk_point
from dhlog.model.robots import Robot

#: A pose cycle's order (clause 7.2.1): P1 → P5 → P4 → P3 → P2.
CYCLE_ORDER = ("P1", "P5", "P4", "P3", "P2")

#: The standard's number of cycles for pose characteristics (clause 7) and for paths (clause 8).
POSE_CYCLES = 30
PATH_CYCLES = 10


@dataclass(frozen=True)
class TestCube:
    """The test cube (clause 6.2): ``centre`` (3,) and ``size`` (edge, m) in the robot's base
    frame, edges parallel to its axes; ``plane``: the diagonal plane the poses lie in (named by
    its corners, e.g. ``C1-C2-C7-C8``); ``corners`` (8, 3) C1 … C8."""

    __test__ = False  # a pytest that imports it does not collect it

    centre: FloatArray
    size: float
    plane: str
    corners: FloatArray


@dataclass(frozen=True)
class TestPose:
    """A test pose: ``name`` (P1 … P5), the commanded pose ``T`` (4, 4) of the tool point's frame
    in the base frame, and the joint targets ``q`` (n,) that reach it on the nominal model."""

    __test__ = False  # a pytest that imports it does not collect it

    name: str
    T: FloatArray
    q: FloatArray


@dataclass(frozen=True)
class TestPath:
    """A test path (clause 8): ``name`` (``line``, ``circle_large``, ``circle_small``), its
    commanded points ``points`` (k, 3) in the base frame with the joint targets ``q`` (k, n) that
    reach them, at the commanded path ``speed`` (m/s)."""

    __test__ = False  # a pytest that imports it does not collect it

    name: str
    points: FloatArray
    q: FloatArray
    speed: float


@dataclass(frozen=True)
class TestProgram:
    """The whole test: the robot's name, its ``cube``, the five ``poses``, the ``paths``, the
    ``cycles`` of the pose test and ``path_cycles`` of the path test, the ``dwell`` (s) at each
    pose, and the tool point (3,) in the last frame the poses are commanded for."""

    __test__ = False  # a pytest that imports it does not collect it

    robot: str
    cube: TestCube
    poses: list[TestPose]
    paths: list[TestPath]
    tool_point: FloatArray
    cycles: int = POSE_CYCLES
    path_cycles: int = PATH_CYCLES
    dwell: float = 2.0
    #: what the planner wants the user to know (a cube made smaller by the limits, …)
    notes: list[str] = field(default_factory=list)


class TestProgramError(UsageError):
    """No test cube fits the robot's workspace as asked (a cube size or centre out of reach, a
    robot that cannot hold the tool's orientation): the robot or cube given cannot be used for
    the test; the message names what is unreachable."""

    __test__ = False  # not a pytest class


#: The corners C1 … C8 of the cube (clause 6.2, Figure 2) as signs of (x, y, z) from its centre
#: in the base frame: C1 … C4 the bottom face (z −) counter-clockwise seen from above from the
#: corner at the lowest x and y, C5 … C8 the top face, C(i+4) above C(i). Each of the four
#: measuring planes the standard names (clause 6.3) holds a bottom edge and the opposite top edge.
CORNER_SIGNS = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ],
    dtype=np.float64,
)
#: The measuring planes (clause 6.3): corners a, b, c, d with diagonals a–c and b–d through the
#: centre; P2, P3, P4, P5 lie near a, b, c, d.
PLANES = {
    "C1-C2-C7-C8": (0, 1, 6, 7),
    "C2-C3-C8-C5": (1, 2, 7, 4),
    "C3-C4-C5-C6": (2, 3, 4, 5),
    "C4-C1-C6-C7": (3, 0, 5, 6),
}
#: P2 … P5 lie on the plane's diagonals at this fraction of the diagonal's length from their
#: corners (clause 6.3: (10 ± 2) %).
CORNER_FRACTION = 0.10
#: The large circle's diameter over the cube's edge, and the small one's over the large one's
#: (clause 8.2: 80 % of the edge; 10 % of the large circle), both centred at P1.
LARGE_CIRCLE = 0.80
SMALL_CIRCLE = 0.10
#: Commanded points of the line (P2 → P4) and of each circle (the first point repeated last).
LINE_POINTS = 101
CIRCLE_POINTS = 121
#: The default commanded path speed (m/s): the standard tests at 100 %, 50 % and 10 % of the
#: rated speed, which dhlog does not know; 0.25 m/s is a common moderate speed.
PATH_SPEED = 0.25
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


@dataclass(frozen=True)
class CommandedProgram:
    """The cycle program as :func:`program_csv` writes it and :func:`read_program` reads it, one
    row per commanded target: ``cycle`` (m,), ``step`` (m,: within its cycle, from 1), ``kind``
    (``pose`` or ``path``), ``name`` (P1 … P5, ``line``, ``circle_large``, ``circle_small``),
    ``index`` (m,: the point's number along its path, 0 for a pose), the joint targets ``q``
    (m, n; rad or m) and the commanded tool point ``xyz`` (m, 3; m, base frame)."""

    cycle: np.ndarray
    step: np.ndarray
    kind: list[str]
    name: list[str]
    index: np.ndarray
    q: FloatArray
    xyz: FloatArray


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
            max_iterations=150 if far else 30,
            damping=1e-3 if far else 1e-8,
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


def cube_corners(centre: FloatArray, size: float) -> FloatArray:
    """The corners C1 … C8 (8, 3) of the cube (see :data:`CORNER_SIGNS`)."""
    return np.asarray(np.asarray(centre, dtype=np.float64) + CORNER_SIGNS * size / 2)


def pose_points(cube: TestCube) -> FloatArray:
    """P1 … P5 (5, 3): P1 the cube's centre, P2 … P5 on the measuring plane's diagonals at
    :data:`CORNER_FRACTION` of the diagonal's length from the corners a, b, c, d of the plane."""
    a, b, c, d = PLANES[cube.plane]
    C = cube.corners
    near = [C[i] + CORNER_FRACTION * (C[j] - C[i]) for i, j in ((a, c), (b, d), (c, a), (d, b))]
    return np.array([cube.centre, *near])


def path_points(cube: TestCube) -> dict[str, FloatArray]:
    """The commanded points of the test paths in the measuring plane: ``line`` P2 → P4 (the
    diagonal through P1, 80 % of its length), ``circle_large`` and ``circle_small`` centred at
    P1, starting on the plane's edge direction (a → b) and turning towards its other axis."""
    P = pose_points(cube)
    a, b, _, d = PLANES[cube.plane]
    C = cube.corners
    u = (C[b] - C[a]) / np.linalg.norm(C[b] - C[a])
    w = C[d] - C[a]
    w = w / np.linalg.norm(w)  # the plane's other axis (a → d is perpendicular to a → b)
    t = np.linspace(0.0, 1.0, LINE_POINTS)[:, None]
    phi = np.linspace(0.0, 2 * np.pi, CIRCLE_POINTS)[:, None]
    ring = np.cos(phi) * u + np.sin(phi) * w
    ring[-1] = ring[0]
    large = LARGE_CIRCLE * cube.size / 2
    return {
        "line": P[1] + t * (P[3] - P[1]),
        "circle_large": P[0] + large * ring,
        "circle_small": P[0] + SMALL_CIRCLE * large * ring,
    }


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


def test_program(
    robot: Robot,
    *,
    cube_size: float | None = None,
    cube_centre: FloatArray | None = None,
    plane: str = "C1-C2-C7-C8",
    cycles: int = POSE_CYCLES,
    path_cycles: int = PATH_CYCLES,
    dwell: float = 2.0,
    speed: float | None = None,
    tool_point: FloatArray | None = None,
) -> TestProgram:
    """The ISO 9283 test program of ``robot`` on its nominal model (SI units; see
    docs/iso9283.md, "The test program"): the largest cube (edges along the base's axes) whose
    corners and test paths the tool point reaches with the tool in one of :data:`ORIENTATIONS`,
    within the joint limits, with the Jacobian's condition number below
    :data:`MAX_CONDITION`; or the cube of ``cube_size`` (m) and/or ``cube_centre`` (3,; m, base
    frame) given, checked. The poses P1 … P5 on ``plane``, the line and the two circles in it,
    each with its joint targets. One :class:`TestProgramError` naming what is not reached when
    no cube fits; :class:`~dhlog.errors.UsageError` for an argument out of range."""
    if plane not in PLANES:
        raise UsageError(f"plane '{plane}': choose one of {', '.join(PLANES)} (clause 6.3).")
    for what, value in (("cycles", cycles), ("path cycles", path_cycles)):
        if int(value) != value or value < 1:
            raise UsageError(f"{what} must be a whole number ≥ 1, not {value}.")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise UsageError(f"dwell must be ≥ 0 s, not {dwell}.")
    speed = PATH_SPEED if speed is None else float(speed)
    if not (math.isfinite(speed) and speed > 0):
        raise UsageError(f"speed must be > 0 m/s, not {speed}.")
    if cube_size is not None and not (math.isfinite(cube_size) and cube_size > 0):
        raise UsageError(f"cube size must be > 0 m, not {cube_size}.")
    centre = None
    if cube_centre is not None:
        centre = np.asarray(cube_centre, dtype=np.float64).reshape(-1)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise UsageError("cube centre: give three finite coordinates (x, y, z).")
    best: tuple[TestCube, list[TestPose], list[TestPath], list[str]] | None = None
    first_error: TestProgramError | None = None
    for pointing in ORIENTATIONS:
        setup = _setup(robot, tool_point, pointing)
        try:
            found = _plan(setup, cube_size, centre, plane, speed)
        except TestProgramError as exc:
            first_error = first_error or exc
            continue
        if best is None or found[0].size > best[0].size:
            best = found
        if cube_size is not None or centre is not None:
            break  # the cube given: the first orientation that reaches it
    if best is None:
        assert first_error is not None
        raise first_error
    cube, poses, paths, notes = best
    return TestProgram(
        robot=robot.name,
        cube=cube,
        poses=poses,
        paths=paths,
        tool_point=_setup_tool(robot, tool_point),
        cycles=int(cycles),
        path_cycles=int(path_cycles),
        dwell=float(dwell),
        notes=notes,
    )


test_program.__test__ = False  # type: ignore[attr-defined]  # not a pytest test


def _setup_tool(robot: Robot, tool_point: FloatArray | None) -> FloatArray:
    return robot.tool_point if tool_point is None else np.asarray(tool_point, dtype=np.float64)


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


def program_rows(program: TestProgram) -> CommandedProgram:
    """The cycle program, one row per commanded target: ``cycles`` pose cycles (P1 → P5 → P4 →
    P3 → P2 each, :data:`CYCLE_ORDER`), then ``path_cycles`` path cycles (the line, the large
    circle, the small circle each, every commanded point in turn)."""
    cycle: list[int] = []
    step: list[int] = []
    kind: list[str] = []
    name: list[str] = []
    index: list[int] = []
    q: list[FloatArray] = []
    xyz: list[FloatArray] = []
    names = [pose.name for pose in program.poses]
    ordered = (
        [program.poses[names.index(n)] for n in CYCLE_ORDER]
        if sorted(names) == sorted(CYCLE_ORDER)
        else program.poses
    )
    for c in range(1, program.cycles + 1):
        for s, pose in enumerate(ordered, start=1):
            cycle.append(c)
            step.append(s)
            kind.append("pose")
            name.append(pose.name)
            index.append(0)
            q.append(pose.q[None])
            xyz.append(pose.T[None, :3, 3])
    for c in range(1, program.path_cycles + 1):
        s = 0
        for path in program.paths:
            k = len(path.points)
            cycle += [c] * k
            step += list(range(s + 1, s + k + 1))
            s += k
            kind += ["path"] * k
            name += [path.name] * k
            index += list(range(k))
            q.append(path.q)
            xyz.append(path.points)
    return CommandedProgram(
        np.array(cycle),
        np.array(step),
        kind,
        name,
        np.array(index),
        np.vstack(q),
        np.vstack(xyz),
    )


#: The largest program CSV :func:`read_program` reads (a 30-cycle program is about 0.6 MB).
MAX_PROGRAM_BYTES = 64 * 2**20
#: The columns before and after the joints in :func:`program_csv`.
HEAD = ("cycle", "step", "kind", "name", "index")
TAIL = ("x", "y", "z")
NAMES = ("P1", "P2", "P3", "P4", "P5", "line", "circle_large", "circle_small")


def program_csv(program: TestProgram) -> str:
    """The cycle program as CSV (docs/iso9283.md, "The test program"): a header row, then one
    row per commanded target (:func:`program_rows`): ``cycle, step, kind, name, index``, the
    joint targets ``j1 … jn`` (rad or m) and the commanded tool point ``x, y, z`` (m, base
    frame). Numbers are written to round-trip exactly."""
    rows = program_rows(program)
    n = rows.q.shape[1]
    lines = [",".join([*HEAD, *(f"j{j + 1}" for j in range(n)), *TAIL])]
    for k in range(len(rows.kind)):
        values = [*rows.q[k], *rows.xyz[k]]
        lines.append(
            ",".join(
                [
                    str(rows.cycle[k]),
                    str(rows.step[k]),
                    rows.kind[k],
                    rows.name[k],
                    str(rows.index[k]),
                    *(repr(float(v)) for v in values),
                ]
            )
        )
    return "\n".join(lines) + "\n"


def read_program(path: str | Path, n: int) -> CommandedProgram:
    """A cycle program as :func:`program_csv` writes it, for a robot of ``n`` joints (untrusted:
    every row and field is checked; one-line errors name the file, line and field)."""
    from dhlog.io.textfile import decode_utf8, read_capped

    name = str(path)

    def fail(problem: str) -> InputError:
        return InputError(f"{name}: {problem}")

    hint = "give the test program `dhlog plan ROBOT --iso9283 -o CSV` wrote."
    data = read_capped(path, MAX_PROGRAM_BYTES, fail, what="test program CSV", hint=hint)
    text = decode_utf8(data, fail, what="test program CSV")
    expected = [*HEAD, *(f"j{j + 1}" for j in range(n)), *TAIL]
    lines = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError(f"{name}: is empty; give the test program `dhlog plan --iso9283` wrote.")
    number, header = lines[0]
    cells = [c.strip() for c in header.split(",")]
    if cells != expected:
        raise InputError(
            f"{name}, line {number}: the header is not {','.join(expected)} (a test program "
            f"for {n} joints); give the program `dhlog plan ROBOT --iso9283` wrote for this robot."
        )
    ints: list[list[int]] = []
    words: list[tuple[str, str]] = []
    values: list[list[float]] = []
    for number, line in lines[1:]:
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != len(expected):
            raise InputError(
                f"{name}, line {number}: has {len(cells)} fields, the header {len(expected)}; "
                "give one commanded target per row."
            )
        row_ints = []
        for field_name, cell in zip(("cycle", "step"), cells[:2], strict=True):
            if not cell.isdigit() or int(cell) < 1:
                raise InputError(
                    f"{name}, line {number}: {field_name} '{cell[:20]}' is not a whole number ≥ 1."
                )
            row_ints.append(int(cell))
        kind, target = cells[2], cells[3]
        if kind not in ("pose", "path"):
            raise InputError(f"{name}, line {number}: kind '{kind[:20]}' is not pose or path.")
        poses = NAMES[:5] if kind == "pose" else NAMES[5:]
        if target not in poses:
            raise InputError(
                f"{name}, line {number}: name '{target[:20]}' is not one of {', '.join(poses)} "
                f"(kind {kind})."
            )
        if not cells[4].isdigit():
            raise InputError(
                f"{name}, line {number}: index '{cells[4][:20]}' is not a whole number ≥ 0."
            )
        row_ints.append(int(cells[4]))
        numbers = []
        for field_name, cell in zip(expected[5:], cells[5:], strict=True):
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v) or abs(v) > 1e3:
                raise InputError(
                    f"{name}, line {number}: {field_name} '{cell[:20]}' is not a finite number "
                    "(rad or m, within 1000)."
                )
            numbers.append(v)
        ints.append(row_ints)
        words.append((kind, target))
        values.append(numbers)
    if not values:
        raise InputError(f"{name}: holds no commanded target after its header.")
    whole = np.array(ints, dtype=np.int64)
    V = np.array(values)
    return CommandedProgram(
        whole[:, 0],
        whole[:, 1],
        [w[0] for w in words],
        [w[1] for w in words],
        whole[:, 2],
        V[:, :n],
        V[:, n:],
    )
