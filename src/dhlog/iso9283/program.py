"""The ISO 9283 test program (clause 6): the test cube in the robot's workspace, the five test
poses P1–P5 on its diagonal plane, the test paths in that plane, and the cycle program that visits
them — commanded poses in the robot's base frame and the joint targets that reach them on the
nominal model."""

from __future__ import annotations

from dataclasses import dataclass, field

from dhlog.geometry._checks import FloatArray

#: The standard's number of cycles for pose characteristics (clause 7) and for paths (clause 8).
POSE_CYCLES = 30
PATH_CYCLES = 10


@dataclass(frozen=True)
class TestCube:
    """The test cube (clause 6.2): ``centre`` (3,) and ``size`` (edge, m) in the robot's base
    frame, edges parallel to its axes; ``plane``: the diagonal plane the poses lie in (named by
    its corners, e.g. ``C1-C2-C7-C8``); ``corners`` (8, 3) C1 … C8."""

    centre: FloatArray
    size: float
    plane: str
    corners: FloatArray


@dataclass(frozen=True)
class TestPose:
    """A test pose: ``name`` (P1 … P5), the commanded pose ``T`` (4, 4) of the tool point's frame
    in the base frame, and the joint targets ``q`` (n,) that reach it on the nominal model."""

    name: str
    T: FloatArray
    q: FloatArray


@dataclass(frozen=True)
class TestPath:
    """A test path (clause 8): ``name`` (``line``, ``circle_large``, ``circle_small``), its
    commanded points ``points`` (k, 3) in the base frame with the joint targets ``q`` (k, n) that
    reach them, at the commanded path ``speed`` (m/s)."""

    name: str
    points: FloatArray
    q: FloatArray
    speed: float


@dataclass(frozen=True)
class TestProgram:
    """The whole test: the robot's name, its ``cube``, the five ``poses``, the ``paths``, the
    ``cycles`` of the pose test and ``path_cycles`` of the path test, the ``dwell`` (s) at each
    pose, and the tool point (3,) in the last frame the poses are commanded for."""

    robot: str
    cube: TestCube
    poses: list[TestPose]
    paths: list[TestPath]
    tool_point: FloatArray
    cycles: int = POSE_CYCLES
    path_cycles: int = PATH_CYCLES
    dwell: float = 2.0
    #: what the planner wants the user to know (a cube made smaller by the limits, …)
    notes: list[str] = field(default_factory=list)
