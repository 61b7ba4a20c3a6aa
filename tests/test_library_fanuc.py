"""The FANUC entries against their vendor descriptions, each xacro expanded to
``tests/data/vendor/<name>.urdf``: FANUC's ROS 2 description (FANUC-CORPORATION/fanuc_description
at 250d3fa) for the LR Mate 200iD and the R-2000iC/165F, base_link → ``fanuc_flange``;
ROS-Industrial's support packages (ros-industrial/fanuc at 8fee5e3) for the M-10iA and M-20iA,
base_link → ``tool0``. The library's FK to DH frame 6 is that transform at 200 random joint
vectors within the limits, position to 1e-9 m and rotation-matrix elements to 1e-9. The
descriptions' lengths are whole millimetres and the flange's rotation is xacro's exact π, π/2:
the two compositions differ by float64 rounding only (about 1e-15 m on a 3 m arm), so 1e-9 m
fails on any slipped digit of the table yet passes on rounding. The library's limits are the
description's in degrees to 0.01°. tests/data/fanuc_r2000ic_165f.toml is another source's
R-2000iC/165F (its own frames); the library's follows the vendor description.
"""

from __future__ import annotations

import numpy as np
import pytest

from dhlog.model.robots import load_robot
from vendor_urdf import chain_joints, load_vendor_urdf, worst_fk_difference

FANUC = [
    ("lrmate200id", "fanuc_flange"),
    ("m10ia", "tool0"),
    ("m20ia", "tool0"),
    ("r2000ic165f", "fanuc_flange"),
]


@pytest.mark.parametrize(("name", "flange"), FANUC, ids=[f[0] for f in FANUC])
def test_a_fanuc_entry_is_its_vendor_descriptions_arm_base_link_to_flange(
    name: str, flange: str
) -> None:
    robot = load_robot(name)
    urdf = load_vendor_urdf(name)
    assert f"base_link to {flange}; tests/test_library_fanuc.py" in robot.checked
    joints = chain_joints(urdf, "base_link", flange)
    assert robot.joint_names == tuple(j.name for j in joints)
    vendor_limits = np.array([[j.limit.lower, j.limit.upper] for j in joints])
    assert np.abs(np.degrees(robot.limits - vendor_limits)).max() <= 0.005
    position, rotation = worst_fk_difference(robot, urdf, base="base_link", tip=flange)
    assert position < 1e-9  # m
    assert rotation < 1e-9
    # at the zero pose the upper arm stands and the forearm points along x (its axes J4, J6 point
    # back, d4 and d6 < 0): the flange at (a1 − d4 − d6, 0, d1 + a2 + a3), z along x, x up
    urdf.update_cfg(dict.fromkeys(robot.joint_names, 0.0))
    T = urdf.get_transform(frame_to=flange, frame_from="base_link")
    t = robot.table
    stood = [t.a[0] - t.d_offset[3] - t.d_offset[5], 0, t.d_offset[0] + t.a[1] + t.a[2]]
    np.testing.assert_allclose(T[:3, 3], stood, atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-12)
