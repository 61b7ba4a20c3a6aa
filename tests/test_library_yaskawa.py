"""The Yaskawa (Motoman) entries against ROS-Industrial's Motoman support packages
(ros-industrial/motoman at 433be15, each xacro expanded to ``tests/data/vendor/<name>.urdf``): the
library's FK to DH frame 6 is the description's ``base_link`` → flange frame at 200 random joint
vectors within the limits, position to 1e-9 m and rotation-matrix elements to 1e-9 after one
constant rotation of the flange frame. The descriptions' lengths are whole tenths of a millimetre:
the two compositions differ by float64 rounding only (about 1e-15 m), so 1e-9 m fails on any
slipped digit of the table yet passes on rounding.

The flange frames: the GP7's and GP8's ``tool0`` is link_6_t turned by rpy="3.1415926 -1.570796
0", π and −π/2 cut to 8 and 7 digits; frame 6 takes the exact angles, and the constant rotation
is the cut (3.3e-7 rad), so the rotation check holds the rest to 1e-9. The MH5's description ends
at link_t (no tool0 or flange link; its axes those of base_link at the zero pose): frame 6 is at
link_t's origin with z out of the flange, and link_t is frame 6 turned by a fixed permutation.
The library's limits are the description's in degrees to 0.01°.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dhlog.model.robots import load_robot
from vendor_urdf import chain_joints, load_vendor_urdf, worst_fk_difference


def _cut_rpy() -> np.ndarray:
    """tool0 in frame 6: the description's truncated rpy against the exact (π, −π/2, 0)."""
    exact = Rotation.from_euler("xyz", [np.pi, -np.pi / 2, 0]).as_matrix()
    cut = Rotation.from_euler("xyz", [3.1415926, -1.570796, 0]).as_matrix()
    return np.asarray(exact.T @ cut)


LINK_T_IN_FRAME_6 = np.array([[0.0, 0, 1], [0, -1, 0], [1, 0, 0]])  # columns: link_t's x, y, z

YASKAWA = [
    ("gp7", "tool0", _cut_rpy()),
    ("gp8", "tool0", _cut_rpy()),
    ("mh5", "link_t", LINK_T_IN_FRAME_6),
]


@pytest.mark.parametrize(("name", "tip", "turned"), YASKAWA, ids=[y[0] for y in YASKAWA])
def test_a_yaskawa_entry_is_its_support_packages_arm_base_link_to_flange(
    name: str, tip: str, turned: np.ndarray
) -> None:
    robot = load_robot(name)
    urdf = load_vendor_urdf(name)
    assert f"base_link to {tip}; tests/test_library_yaskawa.py" in robot.checked
    joints = chain_joints(urdf, "base_link", tip)
    assert robot.joint_names == tuple(j.name for j in joints)
    vendor_limits = np.array([[j.limit.lower, j.limit.upper] for j in joints])
    assert np.abs(np.degrees(robot.limits - vendor_limits)).max() <= 0.005
    position, rotation = worst_fk_difference(
        robot, urdf, base="base_link", tip=tip, flange_rotation=turned
    )
    assert position < 1e-9  # m
    assert rotation < 1e-9
    # at the zero pose the lower arm stands and the upper arm points along x (R and T point
    # back, d4 and d6 < 0): the flange at (a1 − d4 − d6, 0, d1 + a2 + a3)
    urdf.update_cfg(dict.fromkeys(robot.joint_names, 0.0))
    flange = urdf.get_transform(frame_to=tip, frame_from="base_link")
    t = robot.table
    stood = [t.a[0] - t.d_offset[3] - t.d_offset[5], 0, t.d_offset[0] + t.a[1] + t.a[2]]
    np.testing.assert_allclose(flange[:3, 3], stood, atol=1e-12)
