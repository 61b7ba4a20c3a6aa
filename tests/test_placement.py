"""The one placement routine (``identify.fit.placement.place_on``) against a known placement:
a KR5's flange frames at poses along a line and a planar curve at one orientation, and at
random poses, measured in a frame turned 125° (a tracker re-stationed to the robot's other
side) and 0.6 m away, the probe's point 1 mm and its frame 1.6° off the start's. Exact data, so
whatever the poses determine comes back to 1e-9; what they do not determine stays at the start.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dhlog.geometry._checks import rotation_about, rotation_from_vector
from dhlog.identify.fit.placement import (
    Stand,
    closed_form_placements,
    conditioning,
    place_on,
    tool_directions,
)
from dhlog.model.fk import fk_frames
from dhlog.model.ik import solve, tool_poses
from dhlog.model.robots import load_robot

ROBOT = load_robot("kr5")
CENTRE = np.array([0.1, -0.3, 0.4, 0.2, 0.5, 0.3])
TRUE_T = np.eye(4)
TRUE_T[:3, :3] = rotation_about(np.array([0.0, 0.0, 1.0]), math.radians(125.0))
TRUE_T[:3, 3] = [0.42, -0.38, 0.22]
TRUE_TOOL = ROBOT.tool_point + np.array([0.6e-3, 0.5e-3, 0.55e-3])
TRUE_R_TOOL = rotation_from_vector(np.array([0.3, -0.2, 0.5]))
START_R_TOOL = TRUE_R_TOOL @ rotation_from_vector(math.radians(1.6) * np.array([0.0, 0.6, 0.8]))


def flanges(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """The flange frames (k, 3, 3), (k, 3) at 60 poses: a 400 mm line or planar curve at one
    orientation (inverse kinematics), or random poses."""
    if kind == "random":
        q = np.random.default_rng(1).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (60, 6))
    else:
        start = tool_poses(ROBOT.table, CENTRE, ROBOT.tool_point)
        s = np.linspace(-0.2, 0.2, 60)
        goal = np.repeat(start[None], 60, axis=0)
        u = np.array([0.6, 0.64, 0.48])
        goal[:, :3, 3] += np.outer(s, u)
        if kind == "curve":
            goal[:, :3, 3] += np.outer(0.1 * np.sin(2 * np.pi * s / 0.4), np.cross(u, [0, 0, 1]))
        q = solve(ROBOT.table, goal, np.repeat(CENTRE[None], 60, axis=0), ROBOT.tool_point).q
    F = fk_frames(ROBOT.table, q)[:, -1]
    return F[:, :3, :3], F[:, :3, 3]


def measured(F: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    P = (np.einsum("kij,j->ki", F, TRUE_TOOL) + f) @ TRUE_T[:3, :3].T + TRUE_T[:3, 3]
    R = np.einsum("ij,kjl,lm->kim", TRUE_T[:3, :3], F, TRUE_R_TOOL)
    return P, R


@pytest.mark.parametrize("kind", ["line", "curve", "random"])
def test_a_restationed_tracker_and_remounted_probe_are_placed(kind: str) -> None:
    """From the old placement (identity, the old tool), with the orientation: every pose put
    back to 1e-9 m, the base found however far it turned; the tool point moved only where the
    orientation varies (random poses: to the truth)."""
    F, f = flanges(kind)
    P, R = measured(F, f)
    start = Stand(tool=ROBOT.tool_point, R_tool=START_R_TOOL)
    got = place_on(F, f, P, R, stand=start, base=True, point=True, frame=True)
    assert got.rms < 1e-9 and got.inliers.all()
    assert got.R_tool is not None
    frames = np.einsum("ij,kjl,lm->kim", np.asarray(got.T[:3, :3]), F, got.R_tool)
    assert np.max(np.abs(frames - R)) < 1e-8
    if kind == "random":
        assert np.allclose(got.T, TRUE_T, atol=1e-8) and np.allclose(got.tool, TRUE_TOOL, atol=1e-8)
    else:  # at one orientation the point is a translation of the base: held at the start's
        assert tool_directions(F).shape[1] == 0
        assert np.allclose(got.tool, ROBOT.tool_point, atol=1e-12)


def test_a_planar_curve_fixes_the_rotation_without_orientation() -> None:
    """Positions alone on a planar curve fix the base's rotation (Kabsch), turned 125° away."""
    F, f = flanges("curve")
    P, _ = measured(F, f)
    assert conditioning(P).kind == "spread"
    got = place_on(F, f, P, stand=Stand(tool=TRUE_TOOL))
    assert got.rms < 1e-9 and np.allclose(got.T[:3, :3], TRUE_T[:3, :3], atol=1e-7)


def test_a_line_without_orientation_keeps_the_turn_about_it_at_the_start() -> None:
    """Positions alone on a line fix the base but for a turn about the line: every pose is
    put back, and the turn about the line stays the start's (here the true one)."""
    F, f = flanges("line")
    P, _ = measured(F, f)
    shape = conditioning(P)
    assert shape.kind == "line" and shape.direction is not None
    start = TRUE_T.copy()
    start[:3, 3] += [0.3, 0.2, -0.1]  # the start's position off, its rotation right
    got = place_on(F, f, P, stand=Stand(start, TRUE_TOOL))
    assert got.rms < 1e-9
    assert np.allclose(got.T[:3, :3], TRUE_T[:3, :3], atol=1e-6)


def test_the_closed_form_places_every_model_of_a_batch_at_once() -> None:
    """``closed_form_placements`` (the closed form of every start, and the joint-permutation
    check's): at the 60 random poses, the KR5 with its joint columns in the true order and
    with joints 2 and 3, 4 and 6 swapped, placed at once from Kabsch at a zero tool point. The
    true order comes back to 1e-9 in the permutation check's 10 rounds (exact data; each round
    carries the tool point towards the answer by a constant factor: 6e-8 m after 5 rounds,
    1e-13 m after 10); every model of the batch is what it gives placed
    alone, to rounding (1e-12); a swapped order misses the points by centimetres. At one
    orientation (the line) the flange's orientation determines no direction of the tool point:
    it stays at its start, the base's translation takes it up."""
    q = np.random.default_rng(1).uniform(ROBOT.limits[:, 0], ROBOT.limits[:, 1], (60, 6))
    P, _ = measured(*flanges("random"))
    orders = [[0, 1, 2, 3, 4, 5], [0, 2, 1, 3, 4, 5], [0, 1, 2, 5, 4, 3]]
    frames = np.stack([fk_frames(ROBOT.table, q[:, o])[:, -1] for o in orders])
    F, f = frames[..., :3, :3], frames[..., :3, 3]
    R, c, t = closed_form_placements(F, f, P, np.zeros((3, 3)), rounds=10)
    np.testing.assert_allclose(R[0], TRUE_T[:3, :3], atol=1e-9)
    np.testing.assert_allclose(c[0], TRUE_T[:3, 3], atol=1e-9)
    np.testing.assert_allclose(t[0], TRUE_TOOL, atol=1e-9)
    for b in range(3):
        alone = closed_form_placements(F[b : b + 1], f[b : b + 1], P, np.zeros((1, 3)), rounds=10)
        for got, one in zip((R, c, t), alone, strict=True):
            np.testing.assert_allclose(got[b], one[0], rtol=0, atol=1e-12)
    miss = np.einsum("bkij,bj->bki", F, t) + f
    miss = np.einsum("bij,bkj->bki", R, miss) + c[:, None] - P
    rms = np.sqrt(np.mean(np.sum(miss**2, axis=2), axis=1))
    assert rms[0] < 1e-9 and np.all(rms[1:] > 0.01), rms
    F1, f1 = flanges("line")
    P1, _ = measured(F1, f1)
    start = np.array([[0.01, 0.02, 0.03]])
    *_, t1 = closed_form_placements(F1[None], f1[None], P1, start, rounds=5)
    np.testing.assert_array_equal(t1, start)
