"""Line geometry (seed 000, Sec. 2; seed 002, Eq. 7) against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from dhlog.errors import DegenerateGeometryError, DhlogError
from dhlog.geometry.lines import (
    Line,
    Plane,
    RelationKind,
    classify_lines,
    common_normal_feet,
    intersect_line_plane,
    intersection_point,
    line_dot,
    parallel_common_normal,
)

X, Y, Z = np.eye(3)


def test_plucker_coordinates() -> None:
    line = Line([1.0, 2.0, 3.0], [0.0, 0.0, 2.0])  # direction is normalised
    np.testing.assert_allclose(line.direction, Z)
    np.testing.assert_allclose(line.moment, [2.0, -1.0, 0.0])  # c × e
    back = Line.from_plucker(line.direction * 3.0, line.moment * 3.0)
    np.testing.assert_allclose(back.point, [1.0, 2.0, 0.0])  # foot from the origin


def test_line_dot_is_cos_beta_minus_eps_d_sin_beta() -> None:
    # the x axis and a line along y at height 2: beta = 90 deg, distance 2
    dot = line_dot(Line([0, 0, 0], X), Line([0, 0, 2], Y))
    assert dot.real == pytest.approx(0.0)
    assert dot.dual == pytest.approx(-2.0)
    # at 60 deg and distance 3: dual = -3 sin 60
    e2 = [np.cos(np.pi / 3), np.sin(np.pi / 3), 0.0]
    dot = line_dot(Line([0, 0, 0], X), Line([0, 0, 3], e2))
    assert dot.real == pytest.approx(0.5)
    assert dot.dual == pytest.approx(-3.0 * np.sin(np.pi / 3))


@pytest.mark.parametrize(
    ("line2", "kind", "angle", "distance"),
    [
        (Line([5, 0, 0], X), RelationKind.COLLINEAR, 0.0, 0.0),
        (Line([5, 0, 0], -X), RelationKind.COLLINEAR, np.pi, 0.0),
        (Line([0, 0.3, 0], X), RelationKind.PARALLEL, 0.0, 0.3),
        (Line([0, 0.3, 0.4], -X), RelationKind.ANTIPARALLEL, np.pi, 0.5),
        (Line([2, 0, 0], Y), RelationKind.INTERSECTING, np.pi / 2, 0.0),
        (Line([2, 0, 0.25], Y), RelationKind.SKEW, np.pi / 2, 0.25),
        # just inside / outside the default tolerances (1e-3 rad, 1e-4 m)
        (Line([0, 0, 1], [1, 0.9e-3, 0]), RelationKind.PARALLEL, 0.9e-3, 1.0),
        (Line([0, 0, 1], [1, 1.1e-3, 0]), RelationKind.SKEW, 1.1e-3, 1.0),
        (Line([2, 0, 0.9e-4], Y), RelationKind.INTERSECTING, np.pi / 2, 0.9e-4),
        (Line([2, 0, 1.1e-4], Y), RelationKind.SKEW, np.pi / 2, 1.1e-4),
    ],
)
def test_classify_lines(line2: Line, kind: RelationKind, angle: float, distance: float) -> None:
    relation = classify_lines(Line([0, 0, 0], X), line2)
    assert relation.kind is kind
    assert relation.angle == pytest.approx(angle, abs=1e-6)
    assert relation.distance == pytest.approx(distance, rel=1e-3, abs=1e-12)


def test_tolerances_are_in_physical_units() -> None:
    line1, line2 = Line([0, 0, 0], X), Line([2, 0, 0.01], Y)  # 10 mm apart
    assert classify_lines(line1, line2).kind is RelationKind.SKEW
    assert classify_lines(line1, line2, distance_tol=0.02).kind is RelationKind.INTERSECTING


def test_intersection_point_eq4() -> None:
    p = intersection_point(Line([1, 2, 3], X), Line([1, 2, 3], [0, 1, 1]))
    np.testing.assert_allclose(p, [1, 2, 3])


def test_intersection_point_with_a_line_through_the_origin_eq5_10() -> None:
    # k1 = 0: Eq. 4 alone divides by zero; Eq. 5-10 shift the origin
    p = intersection_point(Line([0, 0, 0], X), Line([2, 5, 0], Y))
    np.testing.assert_allclose(p, [2, 0, 0], atol=1e-12)
    p = intersection_point(Line([0, 0, 0], X), Line([0, 0, 0], [1, 1, 1]))
    np.testing.assert_allclose(p, [0, 0, 0], atol=1e-12)
    with pytest.raises(DegenerateGeometryError):
        intersection_point(Line([0, 0, 0], X), Line([0, 1, 0], X))


def test_skew_common_normal_eq14_15() -> None:
    p1, p2 = common_normal_feet(Line([7, 0, 0], X), Line([3, 4, 2], Y))
    np.testing.assert_allclose(p1, [3, 0, 0], atol=1e-12)
    np.testing.assert_allclose(p2, [3, 0, 2], atol=1e-12)
    # 45 deg apart, offset 1 along z: the feet are (0,0,0) and (0,0,1)
    p1, p2 = common_normal_feet(Line([0, 0, 0], X), Line([1, 1, 1], [1, 1, 0]))
    np.testing.assert_allclose(p1, [0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(p2, [0, 0, 1], atol=1e-12)


def test_parallel_common_normal_eq11_13() -> None:
    normal, foot = parallel_common_normal(Line([0, 0, 0], X), Line([9, 3, 4], X), [5, 0, 0])
    np.testing.assert_allclose(normal.direction, [0, 0.6, 0.8])
    np.testing.assert_allclose(foot, [5, 3, 4])
    with pytest.raises(DegenerateGeometryError, match="collinear"):
        parallel_common_normal(Line([0, 0, 0], X), Line([9, 0, 0], X), [5, 0, 0])


def test_line_plane_intersection_seed002_eq7() -> None:
    plane = Plane([3, 3, 1], Z)  # z = 1
    p = intersect_line_plane(Line([1, 1, 0], [0, 1, 1]), plane)
    np.testing.assert_allclose(p, [1, 2, 1])
    with pytest.raises(DegenerateGeometryError, match="parallel"):
        intersect_line_plane(Line([1, 1, 0], X), plane)


@pytest.mark.parametrize(
    ("point", "direction", "message"),
    [
        ([0, 0, 0], [0, 0, 0], "non-zero direction"),
        ([0, np.nan, 0], [1, 0, 0], "finite"),
        ([0, 0], [1, 0, 0], "3-vector"),
    ],
)
def test_invalid_lines(point: list[float], direction: list[float], message: str) -> None:
    with pytest.raises(DhlogError, match=message):
        Line(point, direction)
