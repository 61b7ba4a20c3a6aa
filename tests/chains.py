"""Seeded random DH chains for round-trip tests: canonical ones (following every DESIGN.md
convention, so the extracted table must equal them) and arbitrary ones (checked through FK)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dhlog.geometry.lines import Line, Plane
from dhlog.identify.run import Identification
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_point, joint_axes
from dhlog.simulator.session import Session

PI = np.pi


@dataclass
class Chain:
    table: StandardDH
    T_base: np.ndarray
    tool: np.ndarray
    q_ref: np.ndarray
    kinds: list[str]

    def session(self, rng: np.random.Generator) -> tuple[list[Line], np.ndarray]:
        """Axes at the reference pose, each through a random point of itself (prismatic: anywhere
        on a parallel line), and the target point."""
        points, dirs = joint_axes(self.table, self.q_ref, T_base=self.T_base)
        axes = []
        for p, d, t in zip(points, dirs, self.table.joint_types, strict=True):
            shift = rng.uniform(-1, 1) * d
            if t is JointType.PRISMATIC:
                shift = shift + rng.normal(scale=0.3, size=3)
            axes.append(Line(p + shift, d))
        return axes, fk_point(self.table, self.q_ref, self.tool, T_base=self.T_base)

    def base_plane(self, rng: np.random.Generator) -> Plane:
        z1 = self.T_base[:3, 2]
        tilt = rng.normal(size=3) * 0.3
        return Plane(self.T_base[:3, 3], z1 + tilt - (tilt @ z1) * z1)

    def random_q(self, rng: np.random.Generator, m: int) -> np.ndarray:
        rev = self.table.revolute
        return rev * rng.uniform(-PI, PI, (m, self.table.n)) + (1 - rev) * rng.uniform(
            -0.3, 0.3, (m, self.table.n)
        )


def random_pose(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = q, rng.uniform(-2, 2, 3)
    return T


def _angle_away(rng: np.random.Generator) -> float:
    """An angle in (0, π) at least 0.2 rad from 0 and π."""
    return float(rng.uniform(0.2, PI - 0.2))


def canonical_chain(rng: np.random.Generator) -> Chain:
    """A chain whose table follows every convention of DESIGN.md (and the prismatic rule)."""
    n = int(rng.integers(2, 8))
    types = [JointType.REVOLUTE]
    for _ in range(1, n):
        prismatic = types[-1] is JointType.REVOLUTE and rng.random() < 0.3
        types.append(JointType.PRISMATIC if prismatic else JointType.REVOLUTE)
    q_ref = np.array(
        [rng.uniform(-PI, PI) if t is JointType.REVOLUTE else rng.uniform(-0.2, 0.2) for t in types]
    )
    theta, d, a, alpha = (np.zeros(n) for _ in range(4))
    kinds = []
    for i in range(n):
        theta[i] = 0.0 if i == 0 else rng.uniform(-PI, PI)
        if types[i] is JointType.PRISMATIC and i < n - 1:
            s = rng.uniform(0.3, 1.0) * rng.choice([-1, 1])
            theta[i] = float(np.arcsin(s)) if rng.random() < 0.5 else float(PI - np.arcsin(s))
        if i == n - 1:
            a[i] = rng.uniform(0.02, 0.3)
            if types[i] is JointType.PRISMATIC:
                theta[i] = float(rng.choice([0.0, PI]))
                d[i] = -q_ref[i]
            continue
        prismatic_pair = JointType.PRISMATIC in (types[i], types[i + 1])
        kind = (
            "intersecting"
            if prismatic_pair
            else str(rng.choice(["intersecting", "skew", "parallel", "antiparallel"]))
        )
        kinds.append(kind)
        if kind == "intersecting":
            alpha[i], d[i] = _angle_away(rng), rng.uniform(-0.5, 0.5)
        elif kind == "skew":
            a[i], d[i] = rng.uniform(0.02, 0.5), rng.uniform(-0.5, 0.5)
            alpha[i] = _angle_away(rng) * rng.choice([-1, 1])
        else:
            a[i], alpha[i] = rng.uniform(0.02, 0.5), 0.0 if kind == "parallel" else PI
    tool = np.array([0.0, 0.0, rng.uniform(-0.2, 0.2)])
    return Chain(StandardDH(types, theta, d, a, alpha), random_pose(rng), tool, q_ref, kinds)


def arbitrary_chain(rng: np.random.Generator) -> Chain:
    """A chain with any parameters: signs, prismatic joints anywhere (also first and
    consecutive), exactly parallel and intersecting pairs mixed with skew ones."""
    n = int(rng.integers(1, 8))
    types = [JointType.PRISMATIC if rng.random() < 0.3 else JointType.REVOLUTE for _ in range(n)]
    theta = rng.uniform(-PI, PI, n)
    d = rng.uniform(-0.5, 0.5, n)
    a = rng.uniform(-0.5, 0.5, n)
    alpha = _angle_away(rng) * rng.choice([-1, 1], n)
    kinds = []
    for i in range(n):
        kind = str(rng.choice(["parallel", "antiparallel", "intersecting", "skew"]))
        kinds.append(kind)
        if kind == "parallel":
            alpha[i] = 0.0
        elif kind == "antiparallel":
            alpha[i] = PI
        elif kind == "intersecting":
            a[i] = 0.0
    q_ref = np.where(
        [t is JointType.REVOLUTE for t in types], rng.uniform(-PI, PI, n), rng.uniform(-0.2, 0.2, n)
    )
    tool = rng.uniform(-0.2, 0.2, 3)
    tool[:2] += np.sign(tool[:2]) * 0.02  # keep the target off the last axis
    return Chain(StandardDH(types, theta, d, a, alpha), random_pose(rng), tool, q_ref, kinds)


def fk_error(result: Identification, session: Session, Q: np.ndarray) -> np.ndarray:
    """3-D distance (m) between the result's FK and the simulator's truth at joint vectors
    ``Q`` (m, n): the FK round trip every accuracy test judges by."""
    ex = result.extraction
    assert ex is not None
    got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
    want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
    return np.asarray(np.linalg.norm(got - want, axis=1))
