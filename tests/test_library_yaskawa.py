"""The Yaskawa (Motoman) entries against Yaskawa's ROS 2 support packages
(Yaskawa-Global/motoman_ros2_support_packages at 34b8847, each xacro expanded to
``tests/data/vendor/<name>.urdf``): the library's FK to DH frame 6 is the description's
``base_link`` → ``tool0`` at 200 random joint vectors within the limits, position to 1e-9 m and
rotation-matrix elements to 1e-9. The descriptions' lengths are whole millimetres and tool0's
rotation is xacro's exact radians(180), radians(−90): the two compositions differ by float64
rounding only (about 1e-15 m), so 1e-9 m fails on any slipped digit of the table yet passes on
rounding. The library's limits are the description's (whole degrees there).
"""

from __future__ import annotations

import numpy as np
import pytest

from dhlog.model.robots import load_robot
from vendor_urdf import chain_joints, load_vendor_urdf, worst_fk_difference

YASKAWA = ["gp7", "gp8", "mh5"]


@pytest.mark.parametrize("name", YASKAWA)
def test_a_yaskawa_entry_is_its_support_packages_arm_base_link_to_tool0(name: str) -> None:
    robot = load_robot(name)
    urdf = load_vendor_urdf(name)
    assert "base_link to tool0; tests/test_library_yaskawa.py" in robot.checked
    joints = chain_joints(urdf, "base_link", "tool0")
    assert robot.joint_names == tuple(j.name for j in joints)
    vendor_limits = np.array([[j.limit.lower, j.limit.upper] for j in joints])
    assert np.abs(np.degrees(robot.limits - vendor_limits)).max() < 1e-9
    position, rotation = worst_fk_difference(robot, urdf, base="base_link", tip="tool0")
    assert position < 1e-9  # m
    assert rotation < 1e-9
    # at the zero pose the lower arm stands and the upper arm points along x (R and T point
    # back, d4 and d6 < 0): tool0 at (a1 − d4 − d6, 0, d1 + a2 + a3), z along x, x up
    urdf.update_cfg(dict.fromkeys(robot.joint_names, 0.0))
    tool0 = urdf.get_transform(frame_to="tool0", frame_from="base_link")
    t = robot.table
    stood = [t.a[0] - t.d_offset[3] - t.d_offset[5], 0, t.d_offset[0] + t.a[1] + t.a[2]]
    np.testing.assert_allclose(tool0[:3, 3], stood, atol=1e-12)
    np.testing.assert_allclose(tool0[:3, :3], [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-12)
