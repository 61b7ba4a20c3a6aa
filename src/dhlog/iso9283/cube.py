"""The ISO 9283 test program as data (clause 6): the test cube in the robot's workspace
(:class:`TestCube`, :func:`cube_corners`), the five test poses P1–P5 on its diagonal plane
(:class:`TestPose`, :func:`pose_points`), the test paths in that plane (:class:`TestPath`,
:func:`path_points`: a line, a large and a small circle) and the whole program
(:class:`TestProgram`: the poses' cycle order :data:`CYCLE_ORDER`, the cycles of each).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dhlog.errors import UsageError
from dhlog.geometry._checks import FloatArray

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
