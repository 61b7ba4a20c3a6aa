"""``dhlog.model.ik``: the damped least-squares inverse kinematics of a DH chain."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dhlog.model import ik
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot


def test_the_rotation_vector_agrees_with_scipy_up_to_a_half_turn() -> None:
    R = Rotation.random(500, random_state=0)
    assert np.max(np.abs(ik.rotation_vector(R.as_matrix()) - R.as_rotvec())) < 1e-12
    near = Rotation.from_rotvec([[np.pi - 1e-9, 0, 0], [0, 0, 1e-14], [0, np.pi, 0], [0, 0, 0]])
    got = ik.rotation_vector(near.as_matrix())
    assert np.allclose(np.linalg.norm(got, axis=1), [np.pi - 1e-9, 1e-14, np.pi, 0], atol=1e-12)


@pytest.mark.parametrize("name", ["kr5", "ur5", "puma560", "stanford"])
def test_the_tool_jacobian_is_the_derivative_of_the_tool_pose(name: str) -> None:
    """Central differences (step 1e-6: truncation ~1e-12, rounding ~1e-10) of the tool point
    and of the rotation vector agree with the analytic Jacobian (a prismatic joint included)."""
    robot = load_robot(name)
    q = np.random.default_rng(1).uniform(robot.limits[:, 0], robot.limits[:, 1]) * 0.5
    J = ik.tool_jacobian(robot.table, q, robot.tool_point, T_base=robot.T_base)
    T0 = ik.tool_poses(robot.table, q, robot.tool_point, T_base=robot.T_base)
    h = 1e-6
    for j in range(robot.n):
        d = np.zeros(robot.n)
        d[j] = h
        Tp = ik.tool_poses(robot.table, q + d, robot.tool_point, T_base=robot.T_base)
        Tm = ik.tool_poses(robot.table, q - d, robot.tool_point, T_base=robot.T_base)
        v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        w = (
            ik.rotation_vector(Tp[:3, :3] @ T0[:3, :3].T)
            - ik.rotation_vector(Tm[:3, :3] @ T0[:3, :3].T)
        ) / (2 * h)
        assert np.allclose(J[:3, j], v, atol=1e-8) and np.allclose(J[3:, j], w, atol=1e-8), j


@pytest.mark.parametrize("name", ["kr5", "ur5", "puma560"])
def test_random_poses_are_solved_to_the_tolerance(name: str) -> None:
    """Poses of 200 random joint vectors, solved from starts 0.2 rad off: the solver's joints put
    the tool frame back on each pose (FK written out here) to 1e-11 m and rad, within the
    limits; near-singular rows (condition above 1e4) are left out of the count."""
    robot = load_robot(name)
    rng = np.random.default_rng(2)
    Q = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (200, robot.n)) * 0.8
    frames = fk_frames(robot.table, Q, T_base=robot.T_base)[:, -1]
    goal = frames.copy()
    goal[:, :3, 3] = frames[:, :3, :3] @ robot.tool_point + frames[:, :3, 3]
    kappa = ik.condition(robot.table, Q, robot.tool_point, T_base=robot.T_base)
    sol = ik.solve(
        robot.table,
        goal,
        Q + rng.normal(0, 0.2, Q.shape),
        robot.tool_point,
        T_base=robot.T_base,
        limits=robot.limits,
    )
    fine = kappa < 1e4
    assert fine.sum() > 150 and np.mean(sol.converged[fine]) > 0.95
    got = fk_frames(robot.table, sol.q, T_base=robot.T_base)[:, -1]
    p = got[:, :3, :3] @ robot.tool_point + got[:, :3, 3]
    ok = sol.converged
    assert np.max(np.abs(p[ok] - goal[ok, :3, 3])) < 1e-11
    rot = ik.rotation_vector(np.einsum("mij,mkj->mik", got[ok, :3, :3], goal[ok, :3, :3]))
    assert np.max(np.abs(rot)) < 1e-11
    assert np.all((sol.q >= robot.limits[:, 0]) & (sol.q <= robot.limits[:, 1]))


def test_an_unreachable_pose_is_not_converged() -> None:
    robot = load_robot("kr5")
    goal = np.eye(4)
    goal[:3, 3] = [5.0, 0.0, 0.0]  # beyond the reach
    sol = ik.solve(robot.table, goal[None], np.zeros((1, 6)), robot.tool_point, T_base=robot.T_base)
    assert not sol.converged[0] and sol.position_error[0] > 3.0
