"""The simulated robot as it stands, not as its table says: its table off the nominal, its
compliance and transmission harmonics (:func:`truth_terms`, with the URDF of its masses), and an
unmodelled smooth error of its position (:class:`SmoothError`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.robots import Robot
from dhlog.model.terms import Lump, Term, Terms
from dhlog.simulator.config import SimulationConfig


def perturbed(table: StandardDH, rng: np.random.Generator, cfg: SimulationConfig) -> StandardDH:
    """``table`` off its nominal: normal errors of σ ``cfg.perturb_angle`` on every θ offset and
    α, of σ ``cfg.perturb_length`` on every d offset and a (drawn in that order)."""
    n = table.n
    return StandardDH(
        table.joint_types,
        table.theta_offset + rng.normal(scale=cfg.perturb_angle, size=n),
        table.d_offset + rng.normal(scale=cfg.perturb_length, size=n),
        table.a + rng.normal(scale=cfg.perturb_length, size=n),
        table.alpha + rng.normal(scale=cfg.perturb_angle, size=n),
    )


#: Standard gravity (m/s²).
GRAVITY = 9.80665


def truth_terms(
    robot: Robot, cfg: SimulationConfig, T_mr: FloatArray, tool: FloatArray
) -> Terms | None:
    """The truth's joint-value terms (:mod:`dhlog.model.terms`) in the frames of the robot's
    table, perturbed or not (its lumps sit at frame origins): per compliant joint i,
    ``Δq_i = c_i τ_i`` with the gravity torque of the robot's masses (at the DH frame origins on
    the later axes) and the payload (at the tool point), gravity along the robot's −z; the
    harmonics as given. None without either."""
    if not cfg.compliance and not cfg.harmonic:
        return None
    n = robot.n
    g_m = T_mr[:3, :3] @ np.array([0.0, 0.0, -1.0])
    R_base = T_mr[:3, :3] @ robot.T_base[:3, :3]  # the table's base frame in M
    lumps = [Lump(axis, np.zeros(3)) for axis in range(1, n)] + [Lump(-1, tool.copy())]
    payload = robot.payload if cfg.payload is None else cfg.payload
    mass = [*robot.masses, payload] if cfg.compliance else []
    terms, values = [], []
    for joint, c in cfg.compliance:
        i = joint - 1
        for k, lump in enumerate(lumps):
            if lump.target or lump.axis > i:
                terms.append(Term("compliance", i, k))
                values.append(c * GRAVITY * mass[k])
    for joint, a, b in cfg.harmonic:
        terms += [Term("harmonic_sin", joint - 1), Term("harmonic_cos", joint - 1)]
        values += [a, b]
    return Terms(tuple(terms), tuple(lumps), R_base.T @ g_m, np.array(values))


def masses_urdf(robot: Robot) -> str:
    """A URDF of the library robot's nominal table whose links carry its lumped masses where
    the simulator's truth puts them (the DH frame origins on joints 2 … n's axes): link k
    (after joint k) has its frame on joint k's axis, at the DH frame origin before it, z along
    the axis — what a maker's description with ``<inertial>`` elements gives ``--masses``."""
    from scipy.spatial.transform import Rotation

    n = robot.n
    A = robot.table.link_transforms(np.zeros(n))
    parts = [f'<robot name="{robot.name}">', '  <link name="base"/>']
    for k in range(1, n + 1):
        T = robot.T_base if k == 1 else A[k - 2]
        rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
        mass = float(robot.masses[k - 2]) if k >= 2 and robot.masses.size == n - 1 else 0.0
        inertial = (
            f'<inertial><origin xyz="0 0 0"/><mass value="{mass:g}"/>'
            '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'
            if mass > 0
            else ""
        )
        kind = "prismatic" if robot.table.joint_types[k - 1] is JointType.PRISMATIC else "revolute"
        lo, hi = robot.limits[k - 1]
        parts += [
            f'  <link name="link_{k}">{inertial}</link>',
            f'  <joint name="joint_{k}" type="{kind}">'
            f'<parent link="{"base" if k == 1 else f"link_{k - 1}"}"/><child link="link_{k}"/>'
            f'<origin xyz="{" ".join(f"{v:.12g}" for v in T[:3, 3])}" '
            f'rpy="{" ".join(f"{v:.12g}" for v in rpy)}"/><axis xyz="0 0 1"/>'
            f'<limit lower="{lo:.9g}" upper="{hi:.9g}" effort="1" velocity="1"/></joint>',
        ]
    return "\n".join([*parts, "</robot>", ""])


@dataclass(frozen=True)
class SmoothError:
    """An unmodelled error of the robot's position, a fixed smooth function of the joint vector:
    ``e_c(q) = Σ_k A_ck sin(w_ck · (q / unit) + φ_ck)`` for each coordinate c of the base frame
    (m). ``frequency`` (3, K, n), ``phase`` and ``amplitude`` (3, K); ``unit`` (n,): 1 rad for a
    revolute joint, 0.1 m for a prismatic one."""

    frequency: FloatArray
    phase: FloatArray
    amplitude: FloatArray
    unit: FloatArray

    def __call__(self, q: FloatArray) -> FloatArray:
        """The error (m, 3) at joint vectors ``q`` (m, n), in chunks."""
        q = np.atleast_2d(q) / self.unit
        out = np.empty((q.shape[0], 3))
        for i in range(0, q.shape[0], 20_000):
            arg = np.einsum("mn,ckn->mck", q[i : i + 20_000], self.frequency) + self.phase
            out[i : i + 20_000] = np.einsum("mck,ck->mc", np.sin(arg), self.amplitude)
        return out


def smooth_model_error(
    robot: Robot, cfg: SimulationConfig, *, terms: int = 20, probes: int = 4096
) -> SmoothError:
    """The session's :class:`SmoothError`: ``terms`` sines per coordinate with frequency vectors
    of random direction and magnitude 1–2 per rad, scaled so that the RMS of each coordinate over
    ``probes`` joint vectors drawn uniformly within the limits is ``cfg.model_error``. Drawn from
    its own generator: the session's other draws stay as they are."""
    rng = np.random.default_rng([cfg.seed, 17])
    n = robot.n
    direction = rng.normal(size=(3, terms, n))
    direction /= np.linalg.norm(direction, axis=2, keepdims=True)
    frequency = direction * rng.uniform(1.0, 2.0, (3, terms, 1))
    phase = rng.uniform(0.0, 2 * np.pi, (3, terms))
    revolute = [jt is JointType.REVOLUTE for jt in robot.table.joint_types]
    unit = np.where(revolute, 1.0, 0.1)
    raw = SmoothError(frequency, phase, rng.normal(size=(3, terms)), unit)
    probe = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (probes, n))
    rms = np.sqrt(np.mean(raw(probe) ** 2, axis=0))
    return replace(raw, amplitude=raw.amplitude * (cfg.model_error / rms)[:, None])
