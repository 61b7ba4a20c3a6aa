"""The ISO 9283 test program (clause 6) for a robot (:func:`test_program`): the test cube
placed in its workspace (:mod:`dhlog.iso9283.placement`), the five test poses P1–P5 on its
diagonal plane and the test paths in that plane (:mod:`dhlog.iso9283.cube`), and the cycle
program that visits them — commanded poses in the robot's base frame and the joint targets that
reach them on the nominal model. The program as a file (:func:`program_csv`,
:func:`read_program`) is :mod:`dhlog.iso9283.commanded`'s; the names of those modules stay
importable from here."""

from __future__ import annotations

import math

import numpy as np

from dhlog.errors import UsageError
from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.commanded import CommandedProgram as CommandedProgram
from dhlog.iso9283.commanded import program_csv as program_csv
from dhlog.iso9283.commanded import program_rows as program_rows
from dhlog.iso9283.commanded import read_program as read_program
from dhlog.iso9283.cube import CYCLE_ORDER as CYCLE_ORDER
from dhlog.iso9283.cube import PATH_CYCLES, PATH_SPEED, POSE_CYCLES
from dhlog.iso9283.cube import PLANES as PLANES
from dhlog.iso9283.cube import TestCube as TestCube
from dhlog.iso9283.cube import TestPath as TestPath
from dhlog.iso9283.cube import TestPose as TestPose
from dhlog.iso9283.cube import TestProgram as TestProgram
from dhlog.iso9283.cube import TestProgramError as TestProgramError
from dhlog.iso9283.cube import cube_corners as cube_corners
from dhlog.iso9283.cube import path_points as path_points
from dhlog.iso9283.cube import pose_points as pose_points
from dhlog.iso9283.placement import ORIENTATIONS, _plan, _setup
from dhlog.model.robots import Robot


def test_program(
    robot: Robot,
    *,
    cube_size: float | None = None,
    cube_centre: FloatArray | None = None,
    plane: str = "C1-C2-C7-C8",
    cycles: int = POSE_CYCLES,
    path_cycles: int = PATH_CYCLES,
    dwell: float = 2.0,
    speed: float | None = None,
    tool_point: FloatArray | None = None,
) -> TestProgram:
    """The ISO 9283 test program of ``robot`` on its nominal model (SI units; see
    docs/iso9283.md, "The test program"): the largest cube (edges along the base's axes) whose
    corners and test paths the tool point reaches with the tool in one of :data:`ORIENTATIONS`,
    within the joint limits, with the Jacobian's condition number below
    :data:`MAX_CONDITION`; or the cube of ``cube_size`` (m) and/or ``cube_centre`` (3,; m, base
    frame) given, checked. The poses P1 … P5 on ``plane``, the line and the two circles in it,
    each with its joint targets. One :class:`TestProgramError` naming what is not reached when
    no cube fits; :class:`~dhlog.errors.UsageError` for an argument out of range."""
    if plane not in PLANES:
        raise UsageError(f"plane '{plane}': choose one of {', '.join(PLANES)} (clause 6.3).")
    for what, value in (("cycles", cycles), ("path cycles", path_cycles)):
        if int(value) != value or value < 1:
            raise UsageError(f"{what} must be a whole number ≥ 1, not {value}.")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise UsageError(f"dwell must be ≥ 0 s, not {dwell}.")
    speed = PATH_SPEED if speed is None else float(speed)
    if not (math.isfinite(speed) and speed > 0):
        raise UsageError(f"speed must be > 0 m/s, not {speed}.")
    if cube_size is not None and not (math.isfinite(cube_size) and cube_size > 0):
        raise UsageError(f"cube size must be > 0 m, not {cube_size}.")
    centre = None
    if cube_centre is not None:
        centre = np.asarray(cube_centre, dtype=np.float64).reshape(-1)
        if centre.shape != (3,) or not np.all(np.isfinite(centre)):
            raise UsageError("cube centre: give three finite coordinates (x, y, z).")
    best: tuple[TestCube, list[TestPose], list[TestPath], list[str]] | None = None
    first_error: TestProgramError | None = None
    for pointing in ORIENTATIONS:
        setup = _setup(robot, tool_point, pointing)
        try:
            found = _plan(setup, cube_size, centre, plane, speed)
        except TestProgramError as exc:
            first_error = first_error or exc
            continue
        if best is None or found[0].size > best[0].size:
            best = found
        if cube_size is not None or centre is not None:
            break  # the cube given: the first orientation that reaches it
    if best is None:
        assert first_error is not None
        raise first_error
    cube, poses, paths, notes = best
    return TestProgram(
        robot=robot.name,
        cube=cube,
        poses=poses,
        paths=paths,
        tool_point=_setup_tool(robot, tool_point),
        cycles=int(cycles),
        path_cycles=int(path_cycles),
        dwell=float(dwell),
        notes=notes,
    )


test_program.__test__ = False  # type: ignore[attr-defined]  # not a pytest test


def _setup_tool(robot: Robot, tool_point: FloatArray | None) -> FloatArray:
    return robot.tool_point if tool_point is None else np.asarray(tool_point, dtype=np.float64)
