"""Gravity compliance has no term about an axis that stays along gravity at every pose: the first
revolute axis along it, and a later one while every revolute axis before it is along it too (a
SCARA's; a rotary table behind linear stages). Rotations about vertical axes keep a vertical axis
vertical and prismatic joints tilt nothing, so gravity exerts no torque about such an axis and
its compliance column is numerical noise (the real positioner's: tests/test_realdata.py)."""

from __future__ import annotations

import numpy as np

from dhlog.model import terms as ng

UP = np.array([0.0, 0.0, 1.0])
ACROSS = np.array([0.0, 1.0, 0.0])


def _compliant(dirs: list[np.ndarray], revolute: list[bool]) -> list[int]:
    """The joints carrying a compliance term for a chain of ``dirs`` spaced 0.3 m apart along
    x, its target beyond the last axis."""
    points = [np.array([0.3 * i, 0.0, 0.1 * i]) for i in range(len(dirs))]
    target = np.array([0.3 * len(dirs), 0.05, 0.2])
    made = ng.design(("compliance",), points, dirs, target, revolute, -UP)
    return sorted({t.joint for t in made.terms})


def test_a_scara_and_a_rotary_table_have_no_compliance_term() -> None:
    assert _compliant([UP, UP, UP, UP], [True, True, False, True]) == []  # SCARA: R R P R
    assert _compliant([ACROSS, UP, ACROSS, UP], [False, True, False, False]) == []  # stage, table


def test_an_arm_keeps_its_terms_from_the_first_tilting_axis_on() -> None:
    """A six-axis arm (the first axis vertical, the second horizontal): every joint from the
    second on carries compliance, as before; so does a vertical axis after a tilting one."""
    arm = [UP, ACROSS, ACROSS, np.array([1.0, 0.0, 0.0]), ACROSS, UP]
    assert _compliant(arm, [True] * 6) == [1, 2, 3, 4, 5]
    assert _compliant([UP, ACROSS, UP], [True, True, True]) == [1, 2]
