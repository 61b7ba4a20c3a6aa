"""A library entry's joint limits against its vendor description's (yourdfpy's joints)."""

from __future__ import annotations

import math

import numpy as np
import yourdfpy  # type: ignore[import-untyped]

from dhlog.model.robots import Robot

#: the library writes limits in degrees rounded inwards at 1e-6°: 1.7e-8 rad, and no more
DEGREE_ROUNDING = math.radians(1e-6) * 1.01


def assert_limits_are_the_descriptions(robot: Robot, urdf: yourdfpy.URDF) -> None:
    """Each joint's library limits are the description's, to the rounding of writing them in
    degrees, and never beyond them; a ``continuous`` joint (no limit in the description) is one
    turn either way in the library."""
    for name, (lo, hi) in zip(robot.joint_names, robot.limits, strict=True):
        joint = urdf.joint_map[name]
        if joint.type == "continuous":
            assert (lo, hi) == (-2 * math.pi, 2 * math.pi), name
            continue
        vlo, vhi = joint.limit.lower, joint.limit.upper
        assert vlo - 1e-12 <= lo <= vlo + DEGREE_ROUNDING, (name, lo, vlo)
        assert vhi - DEGREE_ROUNDING <= hi <= vhi + 1e-12, (name, hi, vhi)
    assert np.all(robot.limits[:, 0] < robot.limits[:, 1])
