"""Forward kinematics, the spatial Jacobian and convention conversions (seed 004)."""

from __future__ import annotations

import numpy as np
import pytest

from dhlog.model.dh import (
    ModifiedDH,
    StandardDH,
    modified_dh_transform,
    modified_to_standard,
    standard_dh_transform,
    standard_to_modified,
)
from dhlog.model.fk import fk_frames, fk_point, spatial_jacobian
from dhlog.model.robots import load_robot, robot_names

from chains import arbitrary_chain


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    i, j = {"x": (1, 2), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def trans(axis: str, dist: float) -> np.ndarray:
    T = np.eye(4)
    T["xyz".index(axis), 3] = dist
    return T


def test_link_transforms_are_the_textbook_products() -> None:
    th, d, a, al = 0.3, -0.2, 0.7, 1.1
    want_std = rot("z", th) @ trans("z", d) @ trans("x", a) @ rot("x", al)
    np.testing.assert_allclose(standard_dh_transform(th, d, a, al), want_std, atol=1e-15)
    want_mod = rot("x", al) @ trans("x", a) @ rot("z", th) @ trans("z", d)
    np.testing.assert_allclose(modified_dh_transform(al, a, th, d), want_mod, atol=1e-15)


def test_scara_at_zero_matches_seed_004_figure_2() -> None:
    """Seed 004: the SCARA tool frame at θ = 0 has no rotation and sits at x = 15, z = 13."""
    robot = load_robot("scara")
    T = fk_frames(robot.table, np.zeros(4))[-1]
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(T[:3, 3], [0.15, 0.0, 0.13], atol=1e-15)


def test_kr5_is_seed_002_table_2_specification() -> None:
    t = load_robot("kr5").table
    np.testing.assert_allclose(t.d_offset * 1e3, [400, 0, 0, 620, 0, 0])
    np.testing.assert_allclose(t.a * 1e3, [180, 600, 120, 0, 0, 0])
    np.testing.assert_allclose(np.degrees(t.alpha), [90, 0, 90, 90, 90, 0])


@pytest.mark.parametrize("name", robot_names())
def test_library_robots_load_with_limits(name: str) -> None:
    robot = load_robot(name)
    assert robot.limits.shape == (robot.n, 2)
    assert np.all(robot.limits[:, 0] < robot.limits[:, 1])
    assert robot.tool_point.shape == (3,)


def test_batched_fk_equals_loop() -> None:
    rng = np.random.default_rng(1)
    robot = load_robot("puma560")
    Q = rng.uniform(-1, 1, (5, 6))
    batch = fk_point(robot.table, Q, robot.tool_point)
    single = np.array([fk_point(robot.table, q, robot.tool_point) for q in Q])
    np.testing.assert_allclose(batch, single, atol=1e-15)


@pytest.mark.parametrize("seed", range(3))
def test_standard_modified_conversions_keep_fk(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(20):
        chain = arbitrary_chain(rng)
        Q = chain.random_q(rng, 5)
        want = fk_frames(chain.table, Q, T_base=chain.T_base)[..., -1, :, :]
        modified, T_post = standard_to_modified(chain.table)
        got = fk_frames(modified, Q, T_base=chain.T_base)[..., -1, :, :] @ T_post
        np.testing.assert_allclose(got, want, atol=1e-12)
        T_pre, standard = modified_to_standard(modified)
        again = fk_frames(standard, Q, T_base=chain.T_base @ T_pre)[..., -1, :, :] @ T_post
        np.testing.assert_allclose(again, want, atol=1e-12)


def test_spatial_jacobian_is_the_derivative_of_fk() -> None:
    """Column i equals the twist (ṗ − ω × p, ω) from ∂g/∂q_i · g⁻¹ (seed 004, Eq. 5-6)."""
    rng = np.random.default_rng(4)
    for name in ("stanford", "scara", "ur5"):
        robot = load_robot(name)
        q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1]) * 0.5
        J = spatial_jacobian(robot.table, q, T_base=robot.T_base)
        g = fk_frames(robot.table, q, T_base=robot.T_base)[-1]
        h = 1e-6
        for i in range(robot.n):
            dq = np.zeros(robot.n)
            dq[i] = h
            gp = fk_frames(robot.table, q + dq, T_base=robot.T_base)[-1]
            gm = fk_frames(robot.table, q - dq, T_base=robot.T_base)[-1]
            xi = ((gp - gm) / (2 * h)) @ np.linalg.inv(g)
            w = np.array([xi[2, 1], xi[0, 2], xi[1, 0]])
            np.testing.assert_allclose(J[3:, i], w, atol=1e-8)
            np.testing.assert_allclose(J[:3, i], xi[:3, 3], atol=1e-8)


def test_table_validation() -> None:
    with pytest.raises(ValueError, match="3 finite values"):
        StandardDH(["R", "R", "R"], [0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="'revolute' or 'prismatic'"):
        ModifiedDH(["X"], [0], [0], [0], [0])
    with pytest.raises(ValueError, match="length 2"):
        StandardDH(["R", "P"], [0, 0], [0, 0], [0, 0], [0, 0]).theta([1.0])


@pytest.mark.parametrize("name", robot_names())
def test_chunked_fk_equals_the_frame_by_frame_fk(name: str) -> None:
    """``fk_points_chunked`` (the tool point carried back row by row, in chunks) gives the same
    points as ``fk_point`` (every link frame), across chunk boundaries, to rounding."""
    from dhlog.model.fk import fk_points_chunked

    robot = load_robot(name)
    Q = np.random.default_rng(4).uniform(robot.limits[:, 0], robot.limits[:, 1], (1000, robot.n))
    want = fk_point(robot.table, Q, robot.tool_point, T_base=robot.T_base)
    got = fk_points_chunked(robot.table, Q, robot.tool_point, T_base=robot.T_base, chunk=300)
    assert np.abs(got - want).max() < 1e-12
