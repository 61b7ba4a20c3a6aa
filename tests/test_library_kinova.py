"""The library's Kinova Gen3 against ros2_kortex's kortex_description (tests/data/vendor/gen3.urdf,
with its repository and commit): the entry's FK to its last DH frame is the description's
base_link → end_effector_link as yourdfpy composes it, after one constant rotation (the
end_effector_link is DH frame 7 turned π about x), at 200 random joint vectors within the limits.

The description writes π/2 as 1.5708 and π as 3.1416 (and leaves CAD residues like 2.7629e-18 in
its rpy): read as it is, its axes are off the right angles by up to 7.3 µrad, which moves the
flange by micrometres. The entry holds the exact angles; the first test compares it with the
description's rpy restored to the multiples of π/2 they round (each within 1e-4 rad of one),
to 1e-9 m as for the other makers (both then compose exact numbers, agreeing to ~1e-15 m); the
second bounds what the description's rounding itself moves the flange by.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import yourdfpy  # type: ignore[import-untyped]

from dhlog.model.robots import load_robot
from vendor_limits import assert_limits_are_the_descriptions
from vendor_urdf import VENDOR, load_vendor_urdf, worst_fk_difference

EE_IN_FRAME_7 = np.diag([1.0, -1.0, -1.0])  # end_effector_link: DH frame 7 turned π about x
RPY = re.compile(r'rpy="([^"]*)"')


def _right_angle(value: str) -> float:
    """A 5-digit multiple of π/2 (1.5708, 3.1416, 2.7629E-18) as the exact one it rounds."""
    x = float(value)
    k = round(x / (math.pi / 2))
    assert abs(x - k * math.pi / 2) < 1e-4, value  # only roundings: no real angle is snapped
    return k * math.pi / 2


def _restored(tmp_path: Path) -> tuple[yourdfpy.URDF, float]:
    """The description with its rpy restored, and the sum of the restorations (rad)."""
    text = (VENDOR / "gen3.urdf").read_text(encoding="utf-8")
    moved = 0.0

    def restore(match: re.Match[str]) -> str:
        nonlocal moved
        values = match.group(1).split()
        exact = [_right_angle(v) for v in values]
        moved += sum(abs(float(v) - e) for v, e in zip(values, exact, strict=True))
        return 'rpy="' + " ".join(repr(e) for e in exact) + '"'

    path = tmp_path / "gen3.urdf"
    path.write_text(RPY.sub(restore, text), encoding="utf-8")
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_collision_scene_graph=False)
    return urdf, moved


def test_the_gen3_is_kortex_descriptions_arm_with_its_right_angles(tmp_path: Path) -> None:
    robot = load_robot("gen3")
    urdf, _ = _restored(tmp_path)
    assert robot.joint_names == tuple(urdf.actuated_joint_names)  # the chain's, in order
    assert robot.joint_names == tuple(f"joint_{k}" for k in range(1, 8))
    assert_limits_are_the_descriptions(robot, urdf)
    np.testing.assert_allclose(robot.T_base, np.diag([1.0, -1.0, -1.0, 1.0]), atol=1e-15)
    worst_p, worst_r = worst_fk_difference(
        robot, urdf, base="base_link", tip="end_effector_link", flange_rotation=EE_IN_FRAME_7
    )
    assert worst_p < 1e-9  # m
    assert worst_r < 1e-9


def test_the_descriptions_own_rounding_moves_the_flange_by_micrometres(tmp_path: Path) -> None:
    """Against the description as written, the entry differs by what the 5-digit angles move:
    more than 1e-9 m (so the restoration above is needed), less than the first-order bound of
    the angles' changes times the arm's length (1.21 m along its links): 8.4 µm at 200 joint
    vectors."""
    robot = load_robot("gen3")
    _, moved = _restored(tmp_path)
    worst_p, worst_r = worst_fk_difference(
        robot,
        load_vendor_urdf("gen3"),
        base="base_link",
        tip="end_effector_link",
        flange_rotation=EE_IN_FRAME_7,
        samples=50,
    )
    length = float(np.abs(robot.table.d_offset).sum())  # its a are all 0
    assert 1e-9 < worst_p < moved * length
    assert 1e-9 < worst_r < moved
