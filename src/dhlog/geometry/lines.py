"""Oriented lines and planes in Plücker form, and the line-geometry constructions of seed 000.

A line is a point ``c`` and a unit direction ``e``; its Plücker coordinates are ``(e, k)`` with the
moment ``k = c × e`` (seed 000, Eq. 1). Two lines are compared with the dual-number line dot
product (Eq. 3) and classified with tolerances in physical units: an angle in radians and a
distance in metres.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import DegenerateGeometryError
from dhlog.geometry._checks import FloatArray, check_unit_direction, check_vector3, cross3

#: Default tolerance below which two directions count as parallel (rad).
ANGLE_TOL = 1e-3
#: Default tolerance below which two lines count as meeting (m).
DISTANCE_TOL = 1e-4


@dataclass(frozen=True, eq=False)
class Line:
    """An oriented line through ``point`` along the unit vector ``direction`` (frame given by use).

    Both are float64 arrays of shape (3,); the direction is normalised on construction.
    """

    point: FloatArray
    direction: FloatArray

    def __init__(self, point: ArrayLike, direction: ArrayLike) -> None:
        object.__setattr__(self, "point", check_vector3("Line point", point))
        object.__setattr__(self, "direction", check_unit_direction("Line direction", direction))

    @classmethod
    def from_plucker(cls, direction: ArrayLike, moment: ArrayLike) -> Line:
        """The line with Plücker coordinates ``(e, k)`` (seed 000, Eq. 1); ``e`` may be scaled."""
        e = check_unit_direction("Plücker direction", direction)
        scale = float(np.linalg.norm(np.asarray(direction, dtype=np.float64)))
        k = check_vector3("Plücker moment", moment) / scale
        return cls(cross3(e, k), e)

    @property
    def moment(self) -> FloatArray:
        """Moment vector ``k = c × e`` (seed 000, Eq. 1), shape (3,)."""
        return cross3(self.point, self.direction)

    @property
    def plucker(self) -> FloatArray:
        """Plücker coordinates ``s = [e; k]`` (seed 000, Eq. 1), shape (6,)."""
        return np.concatenate([self.direction, self.moment])

    def project(self, point: ArrayLike) -> FloatArray:
        """The foot of the perpendicular from ``point`` onto the line, shape (3,)."""
        p = np.asarray(point, dtype=np.float64)
        return self.point + ((p - self.point) @ self.direction) * self.direction

    def distance_to(self, point: ArrayLike) -> float:
        """Distance (m) from ``point`` to the line."""
        p = np.asarray(point, dtype=np.float64)
        return float(np.linalg.norm(cross3(p - self.point, self.direction)))

    def reversed(self) -> Line:
        """The same line with the opposite orientation."""
        return Line(self.point, -self.direction)

    def transformed(self, T_b_a: ArrayLike) -> Line:
        """This line (given in frame a) expressed in frame b, for the 4x4 transform ``T_b_a``."""
        T = np.asarray(T_b_a, dtype=np.float64)
        return Line(T[:3, :3] @ self.point + T[:3, 3], T[:3, :3] @ self.direction)


@dataclass(frozen=True, eq=False)
class Plane:
    """A plane through ``point`` with unit ``normal``: ``normal · x = normal · point``."""

    point: FloatArray
    normal: FloatArray

    def __init__(self, point: ArrayLike, normal: ArrayLike) -> None:
        object.__setattr__(self, "point", check_vector3("Plane point", point))
        object.__setattr__(self, "normal", check_unit_direction("Plane normal", normal))

    @property
    def offset(self) -> float:
        """``d`` of the plane equation ``n · x + d = 0`` (seed 002, Eq. 5)."""
        return -float(self.normal @ self.point)

    def signed_distance(self, points: ArrayLike) -> FloatArray:
        """Signed distance (m) of each point from the plane, along the normal; shape (m,)."""
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        return np.asarray((p - self.point) @ self.normal, dtype=np.float64)


class DualNumber(NamedTuple):
    """A dual number ``real + ε dual`` with ``ε² = 0``."""

    real: float
    dual: float


def line_dot(line1: Line, line2: Line) -> DualNumber:
    """Line dot product ``ŝ1·ŝ2 = e1·e2 + ε(e1·k2 + k1·e2) = cos β − ε d sin β`` (seed 000, Eq. 3).

    ``β`` is the angle between the lines and ``d`` the signed distance along their common normal.
    """
    e1, k1 = line1.direction, line1.moment
    e2, k2 = line2.direction, line2.moment
    return DualNumber(float(e1 @ e2), float(e1 @ k2 + k1 @ e2))


class RelationKind(enum.StrEnum):
    """How two oriented lines lie relative to each other."""

    COLLINEAR = "collinear"
    PARALLEL = "parallel"
    ANTIPARALLEL = "antiparallel"
    INTERSECTING = "intersecting"
    SKEW = "skew"

    @property
    def is_parallel(self) -> bool:
        """True for collinear, parallel and anti-parallel lines."""
        return self in (RelationKind.COLLINEAR, RelationKind.PARALLEL, RelationKind.ANTIPARALLEL)


class LineRelation(NamedTuple):
    """The relation of two lines: kind, angle ``β`` in [0, π] (rad), distance (m).

    The distance is along the common normal, or between the lines when they are parallel.
    """

    kind: RelationKind
    angle: float
    distance: float


def classify_lines(
    line1: Line,
    line2: Line,
    *,
    angle_tol: float = ANGLE_TOL,
    distance_tol: float = DISTANCE_TOL,
) -> LineRelation:
    """Classify two lines from their dual dot product (seed 000, Eq. 3).

    ``angle_tol`` (rad) decides when the directions are parallel or anti-parallel; ``distance_tol``
    (m) decides when the lines meet. The distance of non-parallel lines is the dual part divided by
    ``sin β``; of parallel lines, the distance between them.
    """
    dot = line_dot(line1, line2)
    sin_beta = float(np.linalg.norm(cross3(line1.direction, line2.direction)))
    beta = float(np.arctan2(sin_beta, dot.real))
    if beta < angle_tol or np.pi - beta < angle_tol:
        distance = line1.distance_to(line2.point)
        if distance < distance_tol:
            kind = RelationKind.COLLINEAR
        elif dot.real > 0.0:
            kind = RelationKind.PARALLEL
        else:
            kind = RelationKind.ANTIPARALLEL
        return LineRelation(kind, beta, distance)
    distance = abs(dot.dual) / sin_beta
    kind = RelationKind.INTERSECTING if distance < distance_tol else RelationKind.SKEW
    return LineRelation(kind, beta, distance)


def intersection_point(line1: Line, line2: Line) -> FloatArray:
    """Intersection of two meeting lines, shape (3,).

    ``p = (k1 × k2) / (e2 · k1)`` (seed 000, Eq. 4). When the plane of the two lines passes through
    (or near) the origin, the moments are taken about ``o_G = e1 × e2`` instead and the result is
    shifted back (Eq. 5–10). Eq. 8 is applied as ``k_G = (c − o_G) × e = k − o_G × e``; the seed
    prints the sign of the second term as ``+``, which does not move the moments to frame G.
    For lines that do not quite meet the result is not on either line;
    use :func:`common_normal_feet` there.
    """
    e1, e2 = line1.direction, line2.direction
    n = cross3(e1, e2)
    n2 = float(n @ n)
    if n2 < 1e-24:
        raise DegenerateGeometryError(
            "The two lines are parallel, so they have no single intersection point."
        )
    k1, k2 = line1.moment, line2.moment
    if abs(e2 @ k1) >= 0.5 * n2:
        return np.asarray(cross3(k1, k2) / (e2 @ k1), dtype=np.float64)
    o_g = n  # Eq. 5
    k1_g = k1 - cross3(o_g, e1)  # Eq. 8: (c - o_G) x e
    k2_g = k2 - cross3(o_g, e2)
    p_g = cross3(k1_g, k2_g) / (e2 @ k1_g)  # Eq. 9
    return np.asarray(o_g + p_g, dtype=np.float64)  # Eq. 10


def common_normal_feet(line1: Line, line2: Line) -> tuple[FloatArray, FloatArray]:
    """Feet ``p1`` on line 1 and ``p2`` on line 2 of the common normal of non-parallel lines.

    Seed 000, Eq. 14–15, with ``n = e1 × e2`` and ``β`` the angle between the lines:
    ``p1 = [(k2·n − cos β k1·n) / sin² β] e1 + e1 × k1`` (and symmetrically ``p2``). The seed
    prints ``sin β`` in the denominator with a unit ``n``; with ``n = e1 × e2`` unnormalised the
    factor is ``sin² β``.
    """
    e1, e2 = line1.direction, line2.direction
    k1, k2 = line1.moment, line2.moment
    n = cross3(e1, e2)
    sin2 = float(n @ n)
    if sin2 < 1e-24:
        raise DegenerateGeometryError(
            "The two lines are parallel, so their common normal is not unique."
        )
    cos_beta = float(e1 @ e2)
    p1 = ((k2 @ n - cos_beta * (k1 @ n)) / sin2) * e1 + cross3(e1, k1)
    p2 = ((-(k1 @ n) + cos_beta * (k2 @ n)) / sin2) * e2 + cross3(e2, k2)
    return np.asarray(p1, dtype=np.float64), np.asarray(p2, dtype=np.float64)


def parallel_common_normal(line1: Line, line2: Line, through: ArrayLike) -> tuple[Line, FloatArray]:
    """The common normal of two parallel lines through the point ``through`` on line 1.

    Returns the normal as a line from ``through`` towards line 2 and its foot on line 2.
    Seed 000, Eq. 11–13: ``e1' = c12 × e1``, ``e1'' = e1 × e1' / |e1||e1'|``,
    ``s1'' = [e1''; c1 × e1'']``,
    then the foot from Eq. 4.
    """
    c1 = check_vector3("through", through)
    e1 = line1.direction
    c12 = line2.point - c1
    e1p = cross3(c12, e1)  # Eq. 11
    norm = float(np.linalg.norm(e1p))
    if norm < 1e-15:
        raise DegenerateGeometryError(
            "The two lines are collinear, so their common normal is undefined."
        )
    e1pp = cross3(e1, e1p) / norm  # Eq. 12
    normal = Line(c1, e1pp)  # Eq. 13
    foot = line2.point + ((c1 - line2.point) @ line2.direction) * line2.direction
    return normal, np.asarray(foot, dtype=np.float64)


def intersect_line_plane(line: Line, plane: Plane, *, angle_tol: float = ANGLE_TOL) -> FloatArray:
    """Point where ``line`` meets ``plane``: ``p = (n × k − d e) / (n · e)`` (seed 002, Eq. 7).

    ``n``, ``d`` are the plane's normal and offset (Eq. 5–6), ``e``, ``k`` the line's Plücker
    coordinates. Raises :class:`DegenerateGeometryError` when the line is within ``angle_tol`` (rad)
    of being parallel to the plane.
    """
    n, e, k = plane.normal, line.direction, line.moment
    n_dot_e = float(n @ e)
    if abs(n_dot_e) < np.sin(angle_tol):
        raise DegenerateGeometryError(
            "The joint axis is parallel to the base plane, so it has no intersection with it; "
            "probe the plane the robot is mounted on."
        )
    return np.asarray((cross3(n, k) - plane.offset * e) / n_dot_e, dtype=np.float64)
