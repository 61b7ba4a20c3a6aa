"""The library's Stäubli arms against ROS-Industrial's staubli_experimental descriptions
(tests/data/vendor/, each with its repository and commit): the entry's FK to its last DH frame
is the description's base_link → tool0 as yourdfpy composes it, at 200 random joint vectors
within the limits. The descriptions' angles are exact (radians(90) from xacro), so the two
compositions agree to double rounding (~1e-15 m); 1e-9 m is far above that and far below any
dimension's change (tests/test_library_franka.py shows 1 µm failing it)."""

from __future__ import annotations

import numpy as np
import pytest

from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot
from vendor_limits import assert_limits_are_the_descriptions
from vendor_urdf import load_vendor_urdf, worst_fk_difference

#: library entry: its fixture, and tool0 at the zero pose (the arm upright: joint 1's height +
#: the arm + the forearm + the flange up, the elbow's offset aside)
ARMS = {"tx260": ("tx260", [0.0, 0.02, 1.045]), "tx290": ("tx290", [0.05, 0.05, 1.428])}


@pytest.mark.parametrize("name", sorted(ARMS))
def test_a_staubli_entry_is_the_descriptions_base_link_to_tool0(name: str) -> None:
    robot = load_robot(name)
    fixture, tool0_at_zero = ARMS[name]
    urdf = load_vendor_urdf(fixture)
    assert robot.joint_names == tuple(urdf.actuated_joint_names)  # the chain's, in order
    assert robot.joint_names == tuple(f"joint_{k}" for k in range(1, 7))
    assert_limits_are_the_descriptions(robot, urdf)
    assert np.array_equal(robot.T_base, np.eye(4))  # DH frame 0 is base_link
    worst_p, worst_r = worst_fk_difference(robot, urdf, base="base_link", tip="tool0")
    assert worst_p < 1e-9  # m
    assert worst_r < 1e-9
    zero = fk_frames(robot.table, np.zeros(6), T_base=robot.T_base)[-1]
    np.testing.assert_allclose(zero[:3, 3], tool0_at_zero, atol=1e-12)
