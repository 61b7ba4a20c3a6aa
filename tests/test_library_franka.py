"""The library's Franka arms against Franka's own descriptions (tests/data/vendor/, each with its
repository and commit): the entry's FK to its last DH frame is the description's ``<arm>_link0``
→ ``<arm>_link8`` (the flange) as yourdfpy composes it, at 200 random joint vectors within the
limits. Both are double-precision compositions of the same exact numbers (Franka writes π/2 to
16 digits), so they agree to rounding, ~1e-15 m: 1e-9 m is far above that and far below any
dimension's change (a 1 µm change in d7 fails it, as the last test shows)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dhlog.model.dh import StandardDH
from dhlog.model.fk import fk_frames
from dhlog.model.robots import load_robot
from vendor_limits import assert_limits_are_the_descriptions
from vendor_urdf import load_vendor_urdf, worst_fk_difference

ARMS = {"panda": "panda", "fr3": "fr3"}  # library entry: its arm_id (fixture, link prefix)


@pytest.mark.parametrize("name", sorted(ARMS))
def test_a_franka_entry_is_the_descriptions_link0_to_link8(name: str) -> None:
    robot = load_robot(name)
    arm = ARMS[name]
    urdf = load_vendor_urdf(arm)
    assert robot.joint_names == tuple(urdf.actuated_joint_names)  # the chain's, in order
    assert robot.joint_names == tuple(f"{arm}_joint{k}" for k in range(1, 8))
    assert_limits_are_the_descriptions(robot, urdf)
    assert np.array_equal(robot.T_base, np.eye(4))  # DH frame 0 is <arm>_link0
    worst_p, worst_r = worst_fk_difference(robot, urdf, base=f"{arm}_link0", tip=f"{arm}_link8")
    assert worst_p < 1e-9  # m
    assert worst_r < 1e-9
    # at the zero pose, Franka's stretched arm: the flange over the base, 0.088 m forward and
    # 0.333 + 0.316 + 0.384 − 0.107 m up, facing down
    zero = fk_frames(robot.table, np.zeros(7), T_base=robot.T_base)[-1]
    np.testing.assert_allclose(zero[:3, 3], [0.088, 0.0, 0.926], atol=1e-12)
    np.testing.assert_allclose(zero[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)


def test_a_micrometre_off_the_description_is_seen() -> None:
    """The check can fail: the FR3 with its flange 1 µm further out is 1 µm off the description."""
    robot = load_robot("fr3")
    t = robot.table
    d = np.r_[t.d_offset[:-1], t.d_offset[-1] + 1e-6]
    off = dataclasses.replace(
        robot, table=StandardDH(t.joint_types, t.theta_offset, d, t.a, t.alpha)
    )
    worst_p, _ = worst_fk_difference(
        off, load_vendor_urdf("fr3"), base="fr3_link0", tip="fr3_link8", samples=10
    )
    assert 1e-6 / np.sqrt(3) <= worst_p <= 1e-6 + 1e-12  # the largest coordinate of 1 µm
