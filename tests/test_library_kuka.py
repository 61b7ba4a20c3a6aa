"""The library's KUKA arms against KUKA's ROS 2 descriptions and ROS-Industrial's
(tests/data/vendor/, each with its repository and commit): the entry's FK to its last DH frame is
the description's base link → flange link as yourdfpy composes it, at 200 random joint vectors
within the limits, after one constant rotation where the flange link is turned against DH frame
n (a KR's tool0 has z out of the flange, DH frame 6 along joint 6's positive motion, into it:
tool0 is frame 6 turned π about y). The descriptions write their angles to 16 digits, so the two
compositions agree to double rounding (~1e-15 m); 1e-9 m is far above that and far below any
dimension's change (tests/test_library_franka.py shows 1 µm failing it)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot
from vendor_limits import assert_limits_are_the_descriptions
from vendor_urdf import load_vendor_urdf, worst_fk_difference

TOOL0_IN_FRAME_6 = np.diag([-1.0, 1.0, -1.0])  # a KR's tool0: DH frame 6 turned π about y
TURNED_ABOUT_X = np.diag([1.0, -1.0, -1.0, 1.0])  # a KR's DH frame 0: base_link turned π about x
KR_JOINTS = tuple(f"joint_{k}" for k in range(1, 7))  # kuka_drivers' names
LBR_JOINTS = tuple(f"lbr_A{k}" for k in range(1, 8))  # lbr_fri_ros2_stack's names

#: library entry: (fixture, base link, flange link, the flange link in DH frame n, DH frame 0)
CHECKS = {
    "kr6r900sixx": ("kr6r900sixx", "base_link", "tool0", TOOL0_IN_FRAME_6, TURNED_ABOUT_X),
    "kr210r2700": ("kr210r2700", "base_link", "tool0", TOOL0_IN_FRAME_6, TURNED_ABOUT_X),
    "iiwa7": ("iiwa7", "lbr_link_0", "lbr_link_ee", np.eye(3), np.eye(4)),
    "iiwa14": ("iiwa14", "lbr_link_0", "lbr_link_ee", np.eye(3), np.eye(4)),
}


@pytest.mark.parametrize("name", sorted(CHECKS))
def test_a_kuka_entry_is_the_descriptions_base_to_flange(name: str) -> None:
    robot = load_robot(name)
    fixture, base, tip, R_tip, T_base = CHECKS[name]
    urdf = load_vendor_urdf(fixture)
    assert robot.joint_names == tuple(urdf.actuated_joint_names)  # the chain's, in order
    assert robot.joint_names in (KR_JOINTS, LBR_JOINTS)
    assert_limits_are_the_descriptions(robot, urdf)
    np.testing.assert_allclose(robot.T_base, T_base, atol=1e-15)
    worst_p, worst_r = worst_fk_difference(robot, urdf, base=base, tip=tip, flange_rotation=R_tip)
    assert worst_p < 1e-9  # m
    assert worst_r < 1e-9


def test_the_kr6_is_also_kuka_experimentals_with_its_joint_names() -> None:
    """ROS-Industrial's kuka_experimental describes the same KR 6 R900 sixx (its joints named
    joint_a1 … joint_a6, as its ROS 1 RSI driver does): the same FK to 1e-9 m. At the zero pose
    the arm is stretched forward: tool0 at 25 + 455 + 420 + 80 mm ahead, 400 + 35 mm up, z
    forward."""
    robot = load_robot("kr6r900sixx")
    urdf = load_vendor_urdf("kr6r900sixx_kuka_experimental")
    names = tuple(f"joint_a{k}" for k in range(1, 7))
    assert tuple(urdf.actuated_joint_names) == names
    renamed = dataclasses.replace(robot, joint_names=names)
    assert_limits_are_the_descriptions(renamed, urdf)
    worst_p, worst_r = worst_fk_difference(
        renamed, urdf, base="base_link", tip="tool0", flange_rotation=TOOL0_IN_FRAME_6
    )
    assert worst_p < 1e-9 and worst_r < 1e-9
    zero = fk_frames(robot.table, np.zeros(6), T_base=robot.T_base)[-1]
    np.testing.assert_allclose(zero[:3, 3], [0.980, 0.0, 0.435], atol=1e-12)
    np.testing.assert_allclose(zero[:3, :3] @ TOOL0_IN_FRAME_6 @ [0, 0, 1], [1, 0, 0], atol=1e-12)
