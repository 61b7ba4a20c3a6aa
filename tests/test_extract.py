"""DH extraction round trips: FK of the extracted table against FK of the original."""

from __future__ import annotations

import numpy as np
import pytest

from dhlog.errors import DegenerateGeometryError, DhlogError
from dhlog.geometry.lines import Line, Plane, RelationKind
from dhlog.identify.read.extract import extract_dh, place_prismatic_axis
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_point, joint_axes
from dhlog.model.robots import load_robot, robot_names

from chains import Chain, arbitrary_chain, canonical_chain

EXACT = 1e-9  # m and rad: exact data, so only floating-point round-off remains


def wrapped(x: np.ndarray) -> np.ndarray:
    return np.abs(np.arctan2(np.sin(x), np.cos(x)))


def assert_same_kinematics(chain: Chain, ex, rng: np.random.Generator) -> None:  # type: ignore[no-untyped-def]
    Q = chain.random_q(rng, 10)
    want = fk_point(chain.table, Q, chain.tool, T_base=chain.T_base)
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    assert np.abs(want - got).max() < EXACT
    p0, d0 = joint_axes(chain.table, Q, T_base=chain.T_base)
    p1, d1 = joint_axes(ex.standard, Q, T_base=ex.T_measurement_base)
    assert np.abs(d0 - d1).max() < EXACT  # orientation included
    revolute = chain.table.revolute.astype(bool)
    offset = np.cross(p1 - p0, d0)[:, revolute]
    assert np.abs(offset).max(initial=0.0) < EXACT  # revolute axes are the same lines


def assert_same_table(got: StandardDH, want: StandardDH) -> None:
    assert got.joint_types == want.joint_types
    np.testing.assert_allclose(got.a, want.a, atol=EXACT)
    np.testing.assert_allclose(got.d_offset, want.d_offset, atol=EXACT)
    assert wrapped(got.alpha - want.alpha).max() < EXACT
    assert wrapped(got.theta_offset - want.theta_offset).max() < EXACT


@pytest.mark.parametrize("name", robot_names())
@pytest.mark.parametrize("with_plane", [False, True])
def test_library_robots_round_trip(name: str, with_plane: bool) -> None:
    rng = np.random.default_rng(abs(hash((name, with_plane))) % 2**32)
    robot = load_robot(name)
    for _ in range(5):
        T_base = robot.T_base.copy()
        chain = Chain(
            robot.table,
            T_base,
            robot.tool_point,
            rng.uniform(robot.limits[:, 0], robot.limits[:, 1]),
            [],
        )
        axes, target = chain.session(rng)
        plane = chain.base_plane(rng) if with_plane else None
        ex = extract_dh(
            axes,
            robot.table.joint_types,
            target=target,
            reference_pose=chain.q_ref,
            base_plane=plane,
        )
        assert_same_kinematics(chain, ex, rng)
        # with the original as nominal every ambiguous branch matches it: the same table
        ex_nom = extract_dh(
            axes,
            robot.table.joint_types,
            target=target,
            reference_pose=chain.q_ref,
            base_plane=plane,
            nominal=robot.table,
        )
        assert_same_kinematics(chain, ex_nom, rng)
        assert_same_table(ex_nom.standard, robot.table)
        np.testing.assert_allclose(ex_nom.tool_point, robot.tool_point, atol=EXACT)
        if with_plane:
            np.testing.assert_allclose(ex_nom.T_measurement_base, T_base, atol=EXACT)


def test_kr5_follows_conventions_except_the_tool_end() -> None:
    """KR5 (seed 002 Table 2) follows the DESIGN.md rules on rows 1-5: extracted without a
    nominal (base plane through the spec's frame-1 origin), those rows equal the specification."""
    robot = load_robot("kr5")
    rng = np.random.default_rng(5)
    chain = Chain(robot.table, np.eye(4), robot.tool_point, np.zeros(6), [])
    axes, target = chain.session(rng)
    plane = Plane([0.0, 0.0, 0.0], [0.05, 0.1, 1.0])  # tilted, through the base origin
    ex = extract_dh(axes, ["R"] * 6, target=target, reference_pose=np.zeros(6), base_plane=plane)
    t, spec = ex.standard, robot.table
    np.testing.assert_allclose(t.a[:5], spec.a[:5], atol=EXACT)
    np.testing.assert_allclose(t.d_offset[:5], spec.d_offset[:5], atol=EXACT)
    np.testing.assert_allclose(t.alpha[:5], spec.alpha[:5], atol=EXACT)
    np.testing.assert_allclose(t.theta_offset[:5], 0.0, atol=EXACT)
    kinds = [r.relation.kind for r in ex.relations]
    assert kinds == [
        RelationKind.SKEW,
        RelationKind.PARALLEL,
        RelationKind.SKEW,
        RelationKind.INTERSECTING,
        RelationKind.INTERSECTING,
    ]
    # the last frame: z7 parallel to z6 through the target, so the tool point lies on z7
    np.testing.assert_allclose(ex.tool_point[:2], 0.0, atol=EXACT)
    assert t.a[5] == pytest.approx(np.hypot(*robot.tool_point[:2]), abs=EXACT)


@pytest.mark.parametrize("seed", range(4))
def test_canonical_random_chains_are_recovered_exactly(seed: int) -> None:
    """≥ 200 chains mixing intersecting, parallel, anti-parallel, skew and prismatic pairs under a
    random measurement-frame pose: the table, base and tool equal the original."""
    rng = np.random.default_rng(1000 + seed)
    seen: set[str] = set()
    for _ in range(60):
        chain = canonical_chain(rng)
        seen.update(chain.kinds)
        seen.update(t.value for t in chain.table.joint_types)
        axes, target = chain.session(rng)
        ex = extract_dh(
            axes,
            chain.table.joint_types,
            target=target,
            reference_pose=chain.q_ref,
            base_plane=chain.base_plane(rng),
        )
        assert_same_kinematics(chain, ex, rng)
        assert_same_table(ex.standard, chain.table)
        np.testing.assert_allclose(ex.T_measurement_base, chain.T_base, atol=EXACT)
        np.testing.assert_allclose(ex.tool_point, chain.tool, atol=EXACT)
    assert seen >= {"intersecting", "skew", "parallel", "antiparallel", "prismatic"}


@pytest.mark.parametrize("seed", range(4))
def test_arbitrary_random_chains_round_trip_through_fk(seed: int) -> None:
    """Any chain (negative a, prismatic first or consecutive, …): FK of the extracted table
    reproduces FK of the original, with and without base plane, and with the original as
    nominal; for revolute chains the nominal branch reproduces the table itself."""
    rng = np.random.default_rng(2000 + seed)
    for _ in range(60):
        chain = arbitrary_chain(rng)
        axes, target = chain.session(rng)
        for plane in (None, chain.base_plane(rng)):
            ex = extract_dh(
                axes,
                chain.table.joint_types,
                target=target,
                reference_pose=chain.q_ref,
                base_plane=plane,
            )
            assert_same_kinematics(chain, ex, rng)
        ex = extract_dh(
            axes,
            chain.table.joint_types,
            target=target,
            reference_pose=chain.q_ref,
            nominal=chain.table,
        )
        assert_same_kinematics(chain, ex, rng)
        # Prismatic axes are placed from the nominal a, d of the row before them; where that
        # row's frame has no physical anchor (parallel runs without base plane) the later rows
        # may take other (FK-equivalent) values, so the table check is for revolute chains.
        if all(t is JointType.REVOLUTE for t in chain.table.joint_types):
            assert_same_table(ex.standard, chain.table)


def test_modified_table_of_the_extraction_gives_the_same_fk() -> None:
    robot = load_robot("puma560")
    rng = np.random.default_rng(3)
    chain = Chain(robot.table, np.eye(4), robot.tool_point, np.zeros(6), [])
    axes, target = chain.session(rng)
    ex = extract_dh(axes, ["R"] * 6, target=target, reference_pose=np.zeros(6))
    Q = chain.random_q(rng, 10)
    want = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    got = fk_point(
        ex.modified, Q, ex.tool_point, T_base=ex.T_measurement_base, T_tool=ex.T_modified_tool
    )
    np.testing.assert_allclose(got, want, atol=EXACT)


def test_prismatic_axis_is_placed_to_meet_both_neighbours() -> None:
    prev = Line([0, 0, 0], [1, 0, 0])
    nxt = Line([0, 2, 5], [0, 0, 1])
    placed = place_prismatic_axis(np.array([0.0, 1.0, 0.0]), [prev, nxt])
    # hand-computed: in the x-z plane prev is z = 0 and nxt is x = 0, so the axis is the y axis
    np.testing.assert_allclose(placed.project([0, 0, 0]), [0, 0, 0], atol=EXACT)
    assert nxt.distance_to([0, 2, 0]) < EXACT and placed.distance_to([0, 2, 0]) < EXACT
    # a last prismatic axis parallel to the previous one coincides with it
    same = place_prismatic_axis(np.array([1.0, 0.0, 0.0]), [prev, np.array([3.0, 1.0, 1.0])])
    assert same.distance_to([0, 0, 0]) < EXACT


def test_axis_parallel_to_base_plane_is_an_error() -> None:
    axes = [Line([0, 0, 0], [1, 0, 0]), Line([0, 0, 1], [0, 1, 0])]
    plane = Plane([0, 0, 0], [0, 0, 1])
    with pytest.raises(DegenerateGeometryError, match="parallel to the base plane"):
        extract_dh(axes, ["R", "R"], target=[1, 1, 1], reference_pose=[0, 0], base_plane=plane)


def test_mismatched_inputs_are_errors() -> None:
    axes = [Line([0, 0, 0], [0, 0, 1])]
    with pytest.raises(DhlogError, match="reference_pose"):
        extract_dh(axes, ["R"], target=[1, 0, 0], reference_pose=[0, 0])
    with pytest.raises(DhlogError, match="axes"):
        extract_dh(axes, ["R", "R"], target=[1, 0, 0], reference_pose=[0, 0])
    nominal = StandardDH([JointType.PRISMATIC], [0], [0], [0], [0])
    with pytest.raises(DhlogError, match="nominal"):
        extract_dh(axes, ["R"], target=[1, 0, 0], reference_pose=[0], nominal=nominal)
