"""Simulated calibration sessions: what a tracker and the robot's encoders would have recorded.

A session moves the robot through piecewise-linear joint trajectories, by protocol:

* ``sweeps``: for each joint, a move that drives several joints at once to that joint's locked
  pose (a transition), a dwell, the sweep (continuous at constant speed, or step-and-measure), a
  dwell.
* ``random-poses``: ``poses`` random still poses within the joint limits (every joint changes
  from one to the next), each held for a dwell; no sweep.
* ``coupled``: each joint swept alone in ``steps`` stops, except joint 2, which only moves
  together with joint 3 (q3 = −q2: the level forearm move), also in ``steps`` stops — the
  industrial session of issue 17, where joints 1 and 3–6 had sweeps and joint 2 never moved
  alone.

Then come the coupled moves asked for (``coupled``: joints moved together, ``q_b = ratio · q_a``,
the ratio held within the limits). ``random-poses`` and ``coupled`` are step-and-measure
protocols: the tracker records only while the robot is still.
The tracker samples the target (FK of the true robot, plus an unmodelled smooth error of the
robot's position if asked, noise, gross outliers and dropouts) at its own rate; the encoders are
sampled at another rate with another clock phase and jitter. Base-plane points are probed first.
Everything is pure numpy; :mod:`dhlog.io.writer` turns a :class:`Session` into an MCAP file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, rotation_about, rotation_from_vector
from dhlog.geometry.lines import Line
from dhlog.identify.extract import extract_dh
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.fk import fk_frames, fk_point, joint_axes
from dhlog.model.robots import Robot
from dhlog.model.terms import Lump, Term, Terms, table_deflection
from dhlog.result.contract import RESULT_FORMAT, dh_documents, relation_documents

START_NS = 1_763_700_000_000_000_000
PROTOCOLS = ("sweeps", "random-poses", "coupled")
#: the ``coupled`` protocol's pair: joint 3 follows joint 2 as q3 = −q2 (the level forearm move)
COUPLED_PAIR = (2, 3, -1.0)
#: the target frame's fixed rotation in the flange frame (rotation vector, rad) of the command
#: line's ``--six-dof``
SIX_DOF_TOOL_ROTATION = (0.3, -0.2, 0.5)
#: smallest change of every joint from one random pose to the next, as a fraction of its range
MIN_POSE_CHANGE = 0.05


@dataclass(frozen=True)
class SimulationConfig:
    """Settings of a simulated session (SI units; noise is σ, or the half-width if uniform)."""

    noise: float = 1e-5
    noise_kind: Literal["gaussian", "uniform"] = "gaussian"
    tracker_rate: float = 100.0
    joint_rate: float = 250.0
    motion: Literal["continuous", "step"] = "continuous"
    sweep: float = math.radians(90.0)
    travel: float = 0.1
    speed: float = 0.5
    linear_speed: float = 0.05
    steps: int = 12
    dwell: float = 0.3
    lock_poses: Literal["home", "random"] = "home"
    #: what the robot does (see the module docstring); ``random-poses`` and ``coupled`` are
    #: step-and-measure whatever ``motion`` says
    protocol: Literal["sweeps", "random-poses", "coupled"] = "sweeps"
    #: random still poses of the ``random-poses`` protocol
    poses: int = 40
    #: the ``random-poses`` protocol's still poses given, in their order (a planned list,
    #: ``simulate --poses CSV``), in place of ``poses`` drawn ones
    pose_list: tuple[tuple[float, ...], ...] = ()
    base_points: int = 12
    outliers: float = 0.0
    outlier_size: float = 3e-3
    dropouts: float = 0.0
    encoders: bool = True
    phase: bool = False
    perturb_length: float = 0.0
    perturb_angle: float = 0.0
    #: σ (m, per coordinate, RMS over the joint limits) of an unmodelled smooth error of the
    #: robot's position (what gravity and gears leave after a geometric model)
    model_error: float = 0.0
    clock_jitter: float = 2e-4
    #: seconds the joint-state clock runs behind the tracker's: the stamps are written that much
    #: early, so a pipeline needs ``clock_offset`` = this value to put them right
    clock_offset: float = 0.0
    skip_joints: tuple[int, ...] = ()
    coupled: tuple[tuple[int, int, float], ...] = ()
    extra_tools: tuple[tuple[float, float, float], ...] = ()
    tool_rotation: tuple[float, float, float] | None = None
    orientation_noise: float = 0.0
    encoder_scales: tuple[float, ...] | None = None
    #: days after START_NS at which the session starts (a series of sessions)
    start_day: float = 0.0
    #: gravity compliance of the truth: (joint, rad per N·m), the torque from the robot's
    #: lumped masses and payload (:func:`truth_terms`)
    compliance: tuple[tuple[int, float], ...] = ()
    #: the payload (kg) at the tool point; None: the robot's
    payload: float | None = None
    #: transmission harmonics of the truth: (joint, a, b), Δq = a sin q + b cos q (rad)
    harmonic: tuple[tuple[int, float, float], ...] = ()
    #: the seed of the random poses alone (None: ``seed``): one plan, other noise
    pose_seed: int | None = None
    #: a laser tracker's noise at the measurement frame's origin, in place of the isotropic
    #: ``noise``: (radial, transverse, transverse per metre of distance) σ, m and m/m (the
    #: ``tracker`` noise model of :mod:`dhlog.model.noise`)
    tracker_model: tuple[float, float, float] | None = None
    seed: int = 0


def config_problems(robot: Robot, cfg: SimulationConfig) -> list[str]:
    """What is wrong with ``cfg`` for ``robot`` (empty when it can be simulated): every rate,
    count, fraction, sweep and travel in its range, joints that exist."""
    out = []
    finite = [
        cfg.noise,
        cfg.tracker_rate,
        cfg.joint_rate,
        cfg.sweep,
        cfg.travel,
        cfg.clock_offset,
        cfg.start_day,
        cfg.model_error,
        cfg.orientation_noise,
        *(v for extra in cfg.extra_tools for v in extra),
    ]
    if not all(math.isfinite(v) for v in finite):
        out.append("every number must be finite")
    checks = [
        (cfg.noise >= 0, f"the noise must be ≥ 0 (got {cfg.noise * 1e3:g} mm)"),
        (
            cfg.tracker_model is None
            or (
                len(cfg.tracker_model) == 3
                and all(math.isfinite(v) and v >= 0 for v in cfg.tracker_model)
                and min(cfg.tracker_model[:2]) > 0
            ),
            "the tracker model needs radial and transverse σ > 0 and a σ per metre ≥ 0",
        ),
        (
            0 < cfg.tracker_rate <= 1e5,
            f"the tracker rate must be in (0, 100 000] Hz (got {cfg.tracker_rate:g})",
        ),
        (
            0 < cfg.joint_rate <= 1e5,
            f"the joint rate must be in (0, 100 000] Hz (got {cfg.joint_rate:g})",
        ),
        (0 <= cfg.outliers < 1, f"the outlier fraction must be in [0, 1) (got {cfg.outliers:g})"),
        (0 <= cfg.dropouts < 1, f"the dropout fraction must be in [0, 1) (got {cfg.dropouts:g})"),
        (cfg.steps >= 2, f"a step sweep needs at least 2 stops (got {cfg.steps})"),
        (cfg.base_points >= 0, f"the base points must be ≥ 0 (got {cfg.base_points})"),
        (cfg.perturb_length >= 0 and cfg.perturb_angle >= 0, "the perturbations must be ≥ 0"),
        (
            abs(cfg.clock_offset) <= 10.0,
            f"the clock offset must be within ±10 s (got {cfg.clock_offset:g} s)",
        ),
        (
            0 <= cfg.start_day <= 36_500,
            f"the start day must be within 0 and 36 500 (got {cfg.start_day:g})",
        ),
    ]
    out += [why for ok, why in checks if not ok]
    out += _protocol_problems(robot, cfg)
    bad = [j for j in cfg.skip_joints if not 1 <= j <= robot.n]
    if bad:
        out.append(f"--skip-joints names joint(s) {bad}; {robot.name} has joints 1-{robot.n}")
    if not 0 < cfg.sweep <= 2 * math.pi:
        out.append(f"the sweep must be in (0, 360]°, not {math.degrees(cfg.sweep):g}°")
    if not 0 < cfg.travel <= 10.0:
        out.append(f"the travel must be in (0, 10 000] mm, not {cfg.travel * 1e3:g} mm")
    return out


def _protocol_problems(robot: Robot, cfg: SimulationConfig) -> list[str]:
    """What is wrong with the protocol, the model error and the targets of ``cfg``."""
    out = []
    checks = [
        (
            0 <= cfg.model_error <= 0.1,
            f"the model error must be in [0, 100] mm (got {cfg.model_error * 1e3:g} mm)",
        ),
        (
            0 <= cfg.orientation_noise <= math.pi / 2,
            f"the orientation noise must be in [0, 90]° "
            f"(got {math.degrees(cfg.orientation_noise):g}°)",
        ),
        (
            cfg.orientation_noise == 0 or cfg.tool_rotation is not None,
            "an orientation noise needs a 6-DoF target (a tool rotation: --six-dof)",
        ),
        (
            all(max(abs(v) for v in extra) <= 10.0 for extra in cfg.extra_tools),
            "the further targets must lie within 10 000 mm of the flange",
        ),
    ]
    out += [why for ok, why in checks if not ok]
    out += _terms_problems(robot, cfg)
    if cfg.protocol not in PROTOCOLS:
        out.append(f"the protocol must be one of {', '.join(PROTOCOLS)}, not '{cfg.protocol}'")
        return out
    bad = sorted({j for a, b, _ in cfg.coupled for j in (a, b) if not 1 <= j <= robot.n})
    if bad:
        out.append(f"the coupled moves name joint(s) {bad}; {robot.name} has joints 1-{robot.n}")
    if cfg.pose_list:
        out += _pose_list_problems(robot, cfg)
    if cfg.protocol == "random-poses" and not cfg.pose_list:
        if not 1 <= cfg.poses <= 100_000:
            out.append(f"the number of poses must be in [1, 100 000] (got {cfg.poses})")
        if cfg.skip_joints:
            out.append("--skip-joints is for sweeps; the random-poses protocol sweeps no joint")
    if cfg.protocol == "coupled":
        types = robot.table.joint_types
        if robot.n < 3:
            out.append(f"the coupled protocol moves joints 2 and 3; {robot.name} has {robot.n}")
        elif not all(types[j - 1] is JointType.REVOLUTE for j in COUPLED_PAIR[:2]):
            out.append(
                f"the coupled protocol moves joints 2 and 3 together (q3 = −q2): both must be "
                f"revolute, and {robot.name}'s are {types[1].value} and {types[2].value}"
            )
    if cfg.protocol != "sweeps" and cfg.dwell * cfg.tracker_rate < 1.0 - 1e-9:
        out.append(
            f"the dwell ({cfg.dwell:g} s) at a tracker rate of {cfg.tracker_rate:g} Hz leaves "
            f"some stops without a sample; raise the tracker rate to ≥ {1.0 / cfg.dwell:g} Hz"
            if cfg.dwell > 0
            else "the dwell must be > 0 for a step-and-measure protocol"
        )
    return out


def _pose_list_problems(robot: Robot, cfg: SimulationConfig) -> list[str]:
    """What is wrong with the given still poses: the protocol, their count, size and limits."""
    if cfg.protocol != "random-poses":
        return ["a list of poses is for the random-poses protocol (static poses)"]
    if len(cfg.pose_list) > 100_000:
        return [f"the list holds {len(cfg.pose_list)} poses; at most 100 000"]
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    for k, pose in enumerate(cfg.pose_list, start=1):
        if len(pose) != robot.n or not all(math.isfinite(v) for v in pose):
            return [f"pose {k} has {len(pose)} values; {robot.name} has {robot.n} joints"]
        q = np.array(pose)
        out = np.flatnonzero((q < lo - 1e-9) | (q > hi + 1e-9))
        if out.size:
            return [
                f"pose {k} leaves the limits of joint {int(out[0]) + 1} ({pose[out[0]]:.6g} not "
                f"in [{lo[out[0]]:.6g}, {hi[out[0]]:.6g}] rad or m)"
            ]
    return []


def _terms_problems(robot: Robot, cfg: SimulationConfig) -> list[str]:
    """What is wrong with the compliance and harmonics of ``cfg``."""
    out = []
    joints = [j for j, _ in cfg.compliance] + [j for j, _, _ in cfg.harmonic]
    values = [c for _, c in cfg.compliance] + [v for _, a, b in cfg.harmonic for v in (a, b)]
    if any(not 1 <= j <= robot.n for j in joints):
        out.append(f"--compliance/--harmonic name joints 1-{robot.n} of {robot.name}")
    if not all(math.isfinite(v) for v in values):
        out.append("--compliance/--harmonic values must be finite")
    if cfg.compliance and robot.masses.size != robot.n - 1:
        out.append(
            f"--compliance needs the robot's lumped masses; {robot.name} has none in the library "
            "(kr5 and kr210 do)"
        )
    if any(not 0 <= c <= 1e-3 for _, c in cfg.compliance):
        out.append("a compliance must be in [0, 1e-3] rad/(N·m)")
    if any(max(abs(a), abs(b)) > 0.01 for _, a, b in cfg.harmonic):
        out.append("a harmonic's amplitudes must be within ±0.01 rad")
    if cfg.payload is not None and not 0 <= cfg.payload <= 10_000:
        out.append(f"the payload must be in [0, 10 000] kg (got {cfg.payload:g})")
    return out


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


def protocol_config(cfg: SimulationConfig) -> SimulationConfig:
    """``cfg`` with what its protocol implies spelled out: step-and-measure for ``random-poses``
    and ``coupled``; for ``coupled`` joint 2 never swept alone and moved together with 3."""
    if cfg.protocol == "random-poses":
        return replace(cfg, motion="step")
    if cfg.protocol == "coupled":
        a, b, _ = COUPLED_PAIR
        pairs = cfg.coupled
        if not any((p, q) == (a, b) for p, q, _ in pairs):
            pairs = (*pairs, COUPLED_PAIR)
        skip = tuple(sorted({*cfg.skip_joints, a}))
        return replace(cfg, motion="step", skip_joints=skip, coupled=pairs)
    return cfg


def swept_joints(robot: Robot, cfg: SimulationConfig) -> list[int]:
    """The joints (1-based) a session of ``cfg`` sweeps alone."""
    if cfg.protocol == "random-poses":
        return []
    skip = protocol_config(cfg).skip_joints
    return [j for j in range(1, robot.n + 1) if j not in skip]


@dataclass
class Session:
    """A simulated session and its ground truth.

    ``point_t_ns``/``point_xyz``: tracker samples (m, 3) in M; ``joint_t_ns``/``joint_q``:
    encoder samples (in chain order, names ``joint_names``); ``base_xyz``: probed base points;
    ``phase``: (t_ns, joint or None) markers; ``table``, ``T_measurement_base``, ``tool_point``,
    ``reference_pose``: the truth, in the result contract's convention.
    """

    robot_name: str
    joint_names: list[str]
    joint_types: tuple[JointType, ...]
    point_t_ns: NDArray[np.int64]
    point_xyz: FloatArray
    joint_t_ns: NDArray[np.int64]
    joint_q: FloatArray
    base_t_ns: NDArray[np.int64]
    base_xyz: FloatArray
    phase: list[tuple[int, int | None]]
    table: StandardDH
    T_measurement_base: FloatArray
    tool_point: FloatArray
    reference_pose: FloatArray
    config: SimulationConfig
    n_outliers: int = 0
    n_dropped: int = 0
    notes: list[str] = field(default_factory=list)
    extra_tool_points: list[FloatArray] = field(default_factory=list)
    extra_point_xyz: list[FloatArray] = field(default_factory=list)
    tool_rotation: FloatArray | None = None
    point_rotation: FloatArray | None = None
    #: each joint's sweep (rad) or travel (m) as simulated (the limits may clip the asked one;
    #: 0 for joints not swept)
    sweeps: FloatArray = field(default_factory=lambda: np.zeros(0))
    #: the unmodelled error added to each target sample (m, 3) in M (zeros when not asked)
    model_error_xyz: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    #: the still poses (k, n) of the ``random-poses`` protocol (none for the others)
    poses: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    #: the truth's compliance and harmonics in ``table``'s frames (None: a geometric robot)
    terms: Terms | None = None


def default_measurement_pose() -> FloatArray:
    """A tracker 2.5 m in front of the robot, turned and slightly tilted (T_measurement_base)."""
    T = np.eye(4)
    T[:3, :3] = rotation_about(np.array([0.0, 0.0, 1.0]), math.radians(155.0)) @ rotation_about(
        np.array([1.0, 0.0, 0.0]), math.radians(1.5)
    )
    T[:3, 3] = [2.1, -1.3, -0.42]
    return T


def _perturbed(table: StandardDH, rng: np.random.Generator, cfg: SimulationConfig) -> StandardDH:
    n = table.n
    return StandardDH(
        table.joint_types,
        table.theta_offset + rng.normal(scale=cfg.perturb_angle, size=n),
        table.d_offset + rng.normal(scale=cfg.perturb_length, size=n),
        table.a + rng.normal(scale=cfg.perturb_length, size=n),
        table.alpha + rng.normal(scale=cfg.perturb_angle, size=n),
    )


def random_poses(robot: Robot, cfg: SimulationConfig, home: FloatArray) -> FloatArray:
    """The ``random-poses`` protocol's still poses (``cfg.poses``, n): drawn uniformly within the
    robot's joint limits from their own generator (the session's other draws stay as they are),
    every joint changing by at least ``MIN_POSE_CHANGE`` of its range from one pose to the next
    (the first from ``home``)."""
    if cfg.pose_list:
        return np.array(cfg.pose_list, dtype=np.float64)
    rng = np.random.default_rng([cfg.seed if cfg.pose_seed is None else cfg.pose_seed, 18])
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    least = MIN_POSE_CHANGE * (hi - lo)
    poses = np.empty((cfg.poses, robot.n))
    previous = home
    for i in range(cfg.poses):
        pose = rng.uniform(lo, hi)
        for _ in range(100):  # a joint too close to its previous value is drawn again
            close = np.abs(pose - previous) < least
            if not np.any(close):
                break
            pose[close] = rng.uniform(lo[close], hi[close])
        poses[i] = previous = pose
    return poses


def coupled_range(
    robot: Robot, home: FloatArray, pair: tuple[int, int, float], extent: float
) -> tuple[float, float]:
    """The range ``(s_start, s_end)`` of a coupled move ``q_a = home_a + s``,
    ``q_b = home_b + ratio · s``: ``extent`` wide about home where the limits of both joints
    allow it, else shifted (and if need be shortened) to fit them, so the ratio always holds."""
    a, b, ratio = pair
    lo, hi = robot.limits[:, 0] - home, robot.limits[:, 1] - home
    s_lo, s_hi = float(lo[a - 1]), float(hi[a - 1])
    if ratio != 0:
        ends = sorted((float(lo[b - 1]) / ratio, float(hi[b - 1]) / ratio))
        s_lo, s_hi = max(s_lo, ends[0]), min(s_hi, ends[1])
    width = max(0.0, min(extent, s_hi - s_lo))
    centre = min(max(0.0, s_lo + width / 2.0), s_hi - width / 2.0)
    return centre - width / 2.0, centre + width / 2.0


def _keyframes(
    robot: Robot,
    home: FloatArray,
    cfg: SimulationConfig,
    rng: np.random.Generator,
    poses: FloatArray,
) -> tuple[list[tuple[float, FloatArray]], list[tuple[float, int | None]], FloatArray]:
    """Piecewise-linear trajectory (time s, q), phase markers (time s, joint or None), and each
    joint's sweep (rad) or travel (m) as the limits let it be (0 for joints not swept). ``cfg``
    with its protocol spelled out (:func:`protocol_config`); ``poses`` (k, n): the random still
    poses, visited first."""
    n = robot.n
    lo, hi = robot.limits[:, 0], robot.limits[:, 1]
    frames: list[tuple[float, FloatArray]] = [(0.0, home.copy())]
    marks: list[tuple[float, int | None]] = [(0.0, None)]
    t, q = 0.0, home.copy()
    sweeps = np.zeros(n)
    revolute = [jt is JointType.REVOLUTE for jt in robot.table.joint_types]

    def go(target: FloatArray, speed_scale: float = 1.0) -> None:
        nonlocal t, q
        step = np.abs(target - q)
        speed = np.where(revolute, cfg.speed, cfg.linear_speed) * speed_scale
        duration = float(np.max(step / speed)) if np.any(step > 0) else 0.0
        t += max(duration, 0.05)
        q = target.copy()
        frames.append((t, q.copy()))

    def hold(seconds: float) -> None:
        nonlocal t
        t += seconds
        frames.append((t, q.copy()))

    for pose in poses:  # point-to-point moves of every joint, at the transitions' speed
        go(pose, 1.5)
        hold(cfg.dwell)
    # joints held at home in the lock poses: the coupled protocol's pair moves only together
    held = [j - 1 for a, b, _ in cfg.coupled for j in (a, b)] if cfg.protocol == "coupled" else []
    for k in range(n):
        if k + 1 in cfg.skip_joints or cfg.protocol == "random-poses":
            continue
        lock = home.copy()
        if cfg.lock_poses == "random":
            span = hi - lo
            lock = np.clip(home + rng.uniform(-0.15, 0.15, n) * span, lo, hi)
            if held:
                lock[held] = home[held]
        half = (cfg.sweep if revolute[k] else cfg.travel) / 2.0
        start = float(np.clip(lock[k] - half, lo[k], hi[k]))
        end = float(np.clip(lock[k] + half, lo[k], hi[k]))
        sweeps[k] = end - start
        target = lock.copy()
        target[k] = start
        go(target, 1.5)  # transition: several joints at once
        hold(cfg.dwell)
        marks.append((t - cfg.dwell * 0.9, k + 1))
        if cfg.motion == "continuous":
            target[k] = end
            go(target)
        else:
            for value in np.linspace(start, end, cfg.steps)[1:]:
                target[k] = value
                go(target)
                hold(cfg.dwell)
        hold(cfg.dwell)
        marks.append((t - cfg.dwell * 0.1, None))
    for a, b, ratio in cfg.coupled:  # coupled moves: q_b follows ratio · q_a (e.g. q3 = −q2)
        extent = cfg.sweep if revolute[a - 1] else cfg.travel
        s_start, s_end = coupled_range(robot, home, (a, b, ratio), extent)

        def coupled_at(s: float, a: int = a, b: int = b, ratio: float = ratio) -> FloatArray:
            pose = home.copy()
            pose[a - 1] += s
            pose[b - 1] += ratio * s
            return pose

        go(coupled_at(s_start), 1.5)
        hold(cfg.dwell)
        if cfg.motion == "continuous":
            go(coupled_at(s_end))
        else:
            for s in np.linspace(s_start, s_end, cfg.steps)[1:-1]:
                go(coupled_at(float(s)))
                hold(cfg.dwell)
            go(coupled_at(s_end))
        hold(cfg.dwell)
    go(home, 1.5)
    if cfg.protocol != "random-poses":  # the random poses end on the last of them
        hold(cfg.dwell)
    return frames, marks, sweeps


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


def _interp(frames: list[tuple[float, FloatArray]], times: FloatArray) -> FloatArray:
    """Joint values at ``times``: each keyframe-to-keyframe move follows the smooth profile
    ``s = 3τ² − 2τ³`` (zero speed at both ends), as a robot's point-to-point motion does."""
    ft = np.array([f[0] for f in frames])
    fq = np.stack([f[1] for f in frames])
    i = np.clip(np.searchsorted(ft, times, side="right") - 1, 0, len(ft) - 2)
    tau = np.clip((times - ft[i]) / (ft[i + 1] - ft[i]), 0.0, 1.0)
    s = tau * tau * (3.0 - 2.0 * tau)
    return np.asarray(fq[i] + (fq[i + 1] - fq[i]) * s[:, None], dtype=np.float64)


def _static(frames: list[tuple[float, FloatArray]], times: FloatArray) -> NDArray[np.bool_]:
    """True where ``times`` fall in a keyframe interval without motion."""
    ft = np.array([f[0] for f in frames])
    fq = np.stack([f[1] for f in frames])
    still = np.all(fq[1:] == fq[:-1], axis=1)
    idx = np.clip(np.searchsorted(ft, times, side="right") - 1, 0, len(still) - 1)
    return np.asarray(still[idx])


def simulate_session(
    robot: Robot,
    cfg: SimulationConfig,
    *,
    T_measurement_robot: FloatArray | None = None,
    tool_point: FloatArray | None = None,
    home: FloatArray | None = None,
) -> Session:
    """Simulate one session of ``robot`` (see the module docstring)."""
    rng = np.random.default_rng(cfg.seed)
    T_mr = default_measurement_pose() if T_measurement_robot is None else T_measurement_robot
    T_mb = T_mr @ robot.T_base
    table = (
        _perturbed(robot.table, rng, cfg)
        if (cfg.perturb_length or cfg.perturb_angle)
        else robot.table
    )
    tool = robot.tool_point if tool_point is None else tool_point
    q_home = (
        np.clip(np.zeros(robot.n), robot.limits[:, 0], robot.limits[:, 1]) if home is None else home
    )
    plan = protocol_config(cfg)
    poses = np.zeros((0, robot.n))
    if cfg.protocol == "random-poses":
        poses = random_poses(robot, cfg, q_home)
    frames, marks, sweeps = _keyframes(robot, q_home, plan, rng, poses)
    duration = frames[-1][0]
    base_time = 2.0 if cfg.base_points else 0.0
    # tracker: its own clock; step-and-measure triggers it only while the robot is still
    t_trk = np.arange(0.0, duration, 1.0 / cfg.tracker_rate) + rng.uniform(
        0, 1.0 / cfg.tracker_rate
    )
    if plan.motion == "step":
        t_trk = t_trk[_static(frames, t_trk)]
    q_trk = _interp(frames, t_trk)
    terms = truth_terms(robot, cfg, T_mr, np.asarray(tool, dtype=np.float64))
    # the joints as they stand: the encoders' values deflected by gravity and the gears
    q_arm = q_trk if terms is None else q_trk + table_deflection(table, terms, q_trk, q_trk)
    xyz = fk_point(table, q_arm, tool, T_base=T_mb)
    error = np.zeros_like(xyz)
    if cfg.model_error > 0:  # the robot's unmodelled error, in M, the same for every target
        error = smooth_model_error(robot, cfg)(q_trk) @ T_mb[:3, :3].T
        xyz = xyz + error
    R_tool = point_rot = None
    if cfg.tool_rotation is not None:  # a 6-DoF target: its frame's orientation is measured too
        from scipy.spatial.transform import Rotation

        R_tool = rotation_from_vector(np.asarray(cfg.tool_rotation, dtype=np.float64))
        point_rot = fk_frames(table, q_arm, T_base=T_mb)[:, -1, :3, :3] @ R_tool
        if cfg.orientation_noise > 0:
            tilt = rng.normal(scale=cfg.orientation_noise, size=(q_trk.shape[0], 3))
            point_rot = Rotation.from_rotvec(tilt).as_matrix() @ point_rot

    def scatter(points: FloatArray) -> FloatArray:
        """``points`` (m, 3) as the tracker measures them."""
        if cfg.tracker_model is not None:
            radial, transverse, per_m = cfg.tracker_model
            distance = np.linalg.norm(points, axis=1, keepdims=True)
            u = points / np.maximum(distance, 1e-9)
            e = rng.normal(size=points.shape) * (transverse + per_m * distance)
            e += u * (np.sum(u * e, axis=1, keepdims=True) * -1.0)  # transverse part only
            radial_e = u * rng.normal(scale=radial, size=(points.shape[0], 1))
            return np.asarray(points + e + radial_e, dtype=np.float64)
        if cfg.noise_kind == "uniform":
            return points + rng.uniform(-cfg.noise, cfg.noise, points.shape)
        return points + rng.normal(scale=cfg.noise, size=points.shape)

    xyz = scatter(xyz)
    n_out = round(cfg.outliers * xyz.shape[0])
    if n_out:
        idx = rng.choice(xyz.shape[0], n_out, replace=False)
        direction = rng.normal(size=(n_out, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        xyz[idx] += direction * rng.uniform(1.0, 3.0, (n_out, 1)) * cfg.outlier_size
    keep = np.ones(xyz.shape[0], dtype=bool)
    if cfg.dropouts:
        n_drop = round(cfg.dropouts * keep.size)
        while np.count_nonzero(~keep) < n_drop:
            start = int(rng.integers(0, keep.size))
            keep[start : start + int(rng.integers(3, 20))] = False
    extra_xyz = []
    for extra in cfg.extra_tools:  # further targets, measured at the same instants
        e = fk_point(table, q_arm, np.asarray(extra, dtype=np.float64), T_base=T_mb) + error
        extra_xyz.append(scatter(e))
    start_ns = START_NS + round(cfg.start_day * 86_400e9)
    t_trk_ns = start_ns + ((t_trk + base_time) * 1e9).astype(np.int64)
    # encoders: another clock phase, rate and jitter
    t_enc = np.arange(0.0, duration, 1.0 / cfg.joint_rate) + rng.uniform(0, 1.0 / cfg.joint_rate)
    t_enc = np.sort(t_enc + rng.uniform(-cfg.clock_jitter, cfg.clock_jitter, t_enc.size))
    q_enc = _interp(frames, np.clip(t_enc, 0.0, duration))
    if cfg.encoder_scales is not None:  # encoders that count a joint's motion times a scale
        q_enc = q_home + (q_enc - q_home) / np.asarray(cfg.encoder_scales, dtype=np.float64)
    # base plane: points of frame 1's xy plane (the mounting plane) around the base origin
    radius = rng.uniform(0.15, 0.45, cfg.base_points)
    angle = rng.uniform(0, 2 * np.pi, cfg.base_points)
    local = np.column_stack(
        [radius * np.cos(angle), radius * np.sin(angle), np.zeros(cfg.base_points)]
    )
    base = scatter(local @ T_mb[:3, :3].T + T_mb[:3, 3])
    base_t = start_ns + (np.linspace(0.1, base_time - 0.2, cfg.base_points) * 1e9).astype(np.int64)
    phase = [(start_ns + int((t + base_time) * 1e9), j) for t, j in marks] if cfg.phase else []
    return Session(
        robot_name=robot.name,
        joint_names=[f"joint_{j + 1}" for j in range(robot.n)],
        joint_types=table.joint_types,
        point_t_ns=t_trk_ns[keep],
        point_xyz=np.asarray(xyz[keep], dtype=np.float64),
        joint_t_ns=start_ns + ((t_enc + base_time - cfg.clock_offset) * 1e9).astype(np.int64)
        if cfg.encoders
        else np.zeros(0, dtype=np.int64),
        joint_q=q_enc if cfg.encoders else np.zeros((0, robot.n)),
        base_t_ns=base_t,
        base_xyz=np.asarray(base, dtype=np.float64),
        phase=phase,
        table=table,
        T_measurement_base=T_mb,
        tool_point=np.asarray(tool, dtype=np.float64),
        reference_pose=np.asarray(q_home, dtype=np.float64),
        config=cfg,
        n_outliers=n_out,
        n_dropped=int(np.count_nonzero(~keep)),
        extra_tool_points=[np.asarray(e, dtype=np.float64) for e in cfg.extra_tools],
        extra_point_xyz=[np.asarray(e[keep], dtype=np.float64) for e in extra_xyz],
        tool_rotation=R_tool,
        point_rotation=None if point_rot is None else np.asarray(point_rot[keep]),
        sweeps=sweeps,
        model_error_xyz=np.asarray(error[keep], dtype=np.float64),
        poses=poses,
        terms=terms,
    )


def truth_document(
    session: Session, *, source_path: str, sha256: str, pipeline: str, version: str
) -> dict[str, object]:
    """The ground truth of ``session`` in the shape of the result contract (``dhlog.result/1``)."""
    table, q = session.table, session.reference_pose
    points, dirs = joint_axes(table, q, T_base=session.T_measurement_base)
    target = fk_point(table, q, session.tool_point, T_base=session.T_measurement_base)
    relations = extract_dh(
        [Line(p, d) for p, d in zip(points, dirs, strict=True)],
        table.joint_types,
        target=target,
        reference_pose=q,
    ).relations
    standard, modified = dh_documents(table, q, np.zeros(4 * table.n))
    cfg = session.config
    plan = protocol_config(cfg)
    return {
        "format": RESULT_FORMAT,
        "dhlog_version": version,
        "source": {"path": source_path, "sha256": sha256, "pipeline": pipeline},
        "units": {"length": "m", "angle": "rad"},
        "reference_pose": q.tolist(),
        "joints": [
            {
                "index": i + 1,
                "name": session.joint_names[i],
                "type": table.joint_types[i].value,
                "axis": {"point": points[i].tolist(), "direction": dirs[i].tolist()},
            }
            for i in range(table.n)
        ],
        "standard_dh": standard,
        "modified_dh": modified,
        "relations": relation_documents(relations),
        "base": {"T_measurement_base": session.T_measurement_base.tolist()},
        "tool": {"point": session.tool_point.tolist()},
        "validation": {"fk_rms": 0.0, "fk_max": 0.0, "n_points": int(session.point_xyz.shape[0])},
        "warnings": [],
        "simulation": {
            "robot": session.robot_name,
            "noise_m": cfg.noise,
            "noise_kind": cfg.noise_kind,
            "tracker_rate_hz": cfg.tracker_rate,
            "joint_rate_hz": cfg.joint_rate,
            "motion": plan.motion,
            "sweep_rad": cfg.sweep,
            "travel_m": cfg.travel,
            "lock_poses": cfg.lock_poses,
            "base_points": cfg.base_points,
            "outliers": session.n_outliers,
            "dropped": session.n_dropped,
            "encoders": cfg.encoders,
            "phase": cfg.phase,
            "seed": cfg.seed,
            "clock_offset_s": cfg.clock_offset,
            "joint_sweeps": [float(v) for v in session.sweeps],
            "perturb_length_m": cfg.perturb_length,
            "perturb_angle_rad": cfg.perturb_angle,
            "protocol": cfg.protocol,
            "poses": int(session.poses.shape[0]),
            "model_error_m": cfg.model_error,
            "steps": cfg.steps if plan.motion == "step" and not session.poses.size else None,
            "coupled": [[a, b, ratio] for a, b, ratio in plan.coupled],
            "tool_rotation_rotvec": None if cfg.tool_rotation is None else list(cfg.tool_rotation),
            "orientation_noise_rad": cfg.orientation_noise,
            "extra_targets_m": [list(extra) for extra in cfg.extra_tools],
            "compliance_rad_per_nm": [[j, c] for j, c in cfg.compliance],
            "payload_kg": cfg.payload,
            "harmonic_rad": [[j, a, b] for j, a, b in cfg.harmonic],
        },
        **({} if session.terms is None else {"nongeometric": session.terms.document()}),
    }
