"""The settings of a simulated session (:class:`SimulationConfig`) and what is wrong with them
for a robot (:func:`config_problems`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from dhlog.model.dh import JointType
from dhlog.model.robots import Robot

PROTOCOLS = ("sweeps", "random-poses", "coupled", "iso9283", "line", "curve")
#: the protocols of still poses (step-and-measure, no sweep): random ones and the paths
STILL_PROTOCOLS = ("random-poses", "line", "curve")
#: the path protocols (:mod:`dhlog.simulator.paths`): still poses along a line or a planar
#: curve, the target's orientation held
PATH_PROTOCOLS = ("line", "curve")
#: the ``coupled`` protocol's pair: joint 3 follows joint 2 as q3 = −q2 (the level forearm move)
COUPLED_PAIR = (2, 3, -1.0)
#: the target frame's fixed rotation in the flange frame (rotation vector, rad) of the command
#: line's ``--six-dof``
SIX_DOF_TOOL_ROTATION = (0.3, -0.2, 0.5)
#: the span (rad or m) a parked joint wanders over from random pose to random pose (a servo
#: holding position; a real dual-arm torso spans 0.27 mrad)
PARK_WANDER = 2e-4


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
    protocol: Literal["sweeps", "random-poses", "coupled", "iso9283", "line", "curve"] = "sweeps"
    #: random still poses of the ``random-poses`` protocol (the path protocols: poses along
    #: the path)
    poses: int = 40
    #: the ``line`` protocol's length, the ``curve``'s extent along its direction (m)
    path_length: float = 0.4
    #: the tracker re-stationed since the calibration (:data:`dhlog.simulator.paths.RESTATION`)
    restation: bool = False
    #: the probe re-mounted since the calibration: its point moved and (6-DoF) its frame
    #: turned on the flange (:data:`dhlog.simulator.paths.REMOUNT_SHIFT`, ``REMOUNT_TURN``)
    remount: bool = False
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
    #: the joint-state clock's drift (ppm × 1e-6): its stamps run this much fast a second from
    #: the session's start (two computers without a common time); dhlog's ``timing.clock_drift``
    #: (what is added to the stamps a second, the pipeline's sign) reads −clock_drift / (1 +
    #: clock_drift). Sweeps and still poses only (not the camera's, nor the iso9283 protocol)
    clock_drift: float = 0.0
    #: seconds the joint-state clock is set on at ``clock_step_at`` (a share of the motion) —
    #: a time daemon stepping it mid-session; negative: set back, the stamps after it before
    #: the last ones. dhlog's ``timing.clock_step`` reads −clock_step. Sweeps and still poses
    #: only, as the drift
    clock_step: float = 0.0
    clock_step_at: float = 0.5
    skip_joints: tuple[int, ...] = ()
    #: joints parked all session (a torso, a rail, an external axis that stays where it is):
    #: (joint, value in rad or m); never swept, the same in every random pose but for a servo's
    #: wander within ±``PARK_WANDER``/2 from pose to pose
    parked: tuple[tuple[int, float], ...] = ()
    #: the span (rad or m) a parked joint wanders over from random pose to random pose
    park_wander: float = PARK_WANDER
    coupled: tuple[tuple[int, int, float], ...] = ()
    extra_tools: tuple[tuple[float, float, float], ...] = ()
    tool_rotation: tuple[float, float, float] | None = None
    orientation_noise: float = 0.0
    encoder_scales: tuple[float, ...] | None = None
    #: days after START_NS at which the session starts (a series of sessions)
    start_day: float = 0.0
    #: gravity compliance of the truth: (joint, rad per N·m), the torque from the robot's
    #: lumped masses and payload (:func:`dhlog.simulator.robot.truth_terms`)
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
    #: the instrument: a laser ``tracker`` (the default), or a ``camera`` and a ChArUco board
    #: (a vision log: :mod:`dhlog.simulator.camera`, every protocol)
    instrument: Literal["tracker", "camera"] = "tracker"
    #: the camera's set-up: fixed in the cell, the board on the flange (``eye-to-hand``), or
    #: on the flange, the board fixed (``eye-in-hand``)
    camera_setup: Literal["eye-to-hand", "eye-in-hand"] = "eye-to-hand"
    #: the images as written: ``jpeg`` or ``png`` (CompressedImage) or ``raw`` (Image, mono8)
    image_format: Literal["jpeg", "png", "raw"] = "jpeg"
    #: the ``iso9283`` protocol (:mod:`dhlog.simulator.iso9283`): cycles of the pose test
    #: (P1 → P5 → P4 → P3 → P2 each) and of the path test, and the dwell at each pose (s)
    iso_cycles: int = 30
    iso_path_cycles: int = 10
    iso_dwell: float = 2.0
    #: σ per coordinate (m) of the attained position's scatter from visit to visit, and σ per
    #: axis (rad) of the attained orientation's
    repeatability: float = 20e-6
    orientation_repeatability: float = 2e-5
    #: the slow (thermal) motion of the position (m: the barycentre of a cycle's attained
    #: positions moves this much from the first cycle to the last), an exponential warm-up of
    #: time constant ``drift_time`` (s; 0: a third of the pose test) along a fixed direction
    drift: float = 50e-6
    drift_time: float = 0.0
    #: the overshoot (m) of each arrival, along the approach: a damped oscillation
    #: e^(−ζωt) sin(ωt) scaled to this peak, ω = 2π ``overshoot_frequency`` (Hz),
    #: ζ = ``overshoot_damping``
    overshoot: float = 100e-6
    overshoot_frequency: float = 5.0
    overshoot_damping: float = 0.2
    #: the paths: a systematic smooth deviation normal to the commanded path of this peak (m),
    #: and a random offset per path cycle of σ ``path_repeatability`` per coordinate (m)
    path_error: float = 200e-6
    path_repeatability: float = 20e-6
    #: the joint states as the robot's ROS 2 driver publishes them: the library robot's joint
    #: names (``library/*.toml``'s ``joint_names``) in alphabetical order, as ros2_control's
    #: joint_state_broadcaster lists a Universal Robots arm's (``elbow_joint`` first)
    driver_joints: bool = False
    seed: int = 0


#: the camera's frame rate of the moving protocols, Hz
FRAME_RATE = 10.0


@dataclass(frozen=True)
class CameraOptions:
    """The cameras a vision log (``instrument="camera"``) is simulated with: the preset's name
    (:data:`dhlog.simulator.camera.presets.PRESETS`; ``dhlog simulate --camera``), the moving
    protocols' frame rate (Hz), the number of fixed cameras, and each frame's exposure (s; 0:
    no motion blur). Checked by :func:`dhlog.simulator.camera.session.vision_problems`."""

    preset: str = "default"
    frame_rate: float = FRAME_RATE
    cameras: int = 1
    exposure: float = 0.0


def config_problems(robot: Robot, cfg: SimulationConfig) -> list[str]:
    """What is wrong with ``cfg`` for ``robot`` (empty when it can be simulated): every rate,
    count, fraction, sweep and travel in its range, joints that exist."""
    out = []
    if cfg.driver_joints and len(robot.joint_names) != robot.n:
        out.append(
            f"--driver-joints: {robot.name} has no driver's joint names (the library entry's "
            "joint_names; dhlog robots lists the robots that have them)"
        )
    finite = [
        cfg.noise,
        cfg.tracker_rate,
        cfg.joint_rate,
        cfg.sweep,
        cfg.travel,
        cfg.clock_offset,
        cfg.clock_drift,
        cfg.clock_step,
        cfg.clock_step_at,
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
            abs(cfg.clock_drift) <= 1e-2,
            f"the clock drift must be within ±10 000 ppm (got {cfg.clock_drift * 1e6:g} ppm)",
        ),
        (
            abs(cfg.clock_step) <= 10.0,
            f"the clock step must be within ±10 s (got {cfg.clock_step:g} s)",
        ),
        (
            0 < cfg.clock_step_at < 1,
            f"the clock step's place must be in (0, 1) of the motion (got {cfg.clock_step_at:g})",
        ),
        (
            0 <= cfg.start_day <= 36_500,
            f"the start day must be within 0 and 36 500 (got {cfg.start_day:g})",
        ),
    ]
    out += [why for ok, why in checks if not ok]
    out += _protocol_problems(robot, cfg)
    out += _camera_problems(cfg)
    bad = [j for j in cfg.skip_joints if not 1 <= j <= robot.n]
    if bad:
        out.append(f"--skip-joints names joint(s) {bad}; {robot.name} has joints 1-{robot.n}")
    for j, value in cfg.parked:
        if not 1 <= j <= robot.n:
            out.append(f"--park-joints names joint {j}; {robot.name} has joints 1-{robot.n}")
        elif not robot.limits[j - 1, 0] <= value <= robot.limits[j - 1, 1]:
            lo, hi = robot.limits[j - 1]
            out.append(
                f"--park-joints parks joint {j} at {value:g}, outside its limits "
                f"[{lo:g}, {hi:g}] (rad or m)"
            )
    if not 0 <= cfg.park_wander <= 1e-3:
        out.append(f"the parked joints' wander must be in [0, 1e-3] (got {cfg.park_wander:g})")
    if len({j for j, _ in cfg.parked}) >= robot.n:
        out.append("--park-joints parks every joint: nothing would move")
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
    if cfg.protocol == "iso9283":
        out += _iso9283_problems(cfg)
    if cfg.protocol not in PROTOCOLS:
        out.append(f"the protocol must be one of {', '.join(PROTOCOLS)}, not '{cfg.protocol}'")
        return out
    bad = sorted({j for a, b, _ in cfg.coupled for j in (a, b) if not 1 <= j <= robot.n})
    if bad:
        out.append(f"the coupled moves name joint(s) {bad}; {robot.name} has joints 1-{robot.n}")
    if cfg.pose_list:
        out += _pose_list_problems(robot, cfg)
    if cfg.protocol in PATH_PROTOCOLS:
        if not 3 <= cfg.poses <= 100_000:
            out.append(f"a path's poses must be in [3, 100 000] (got {cfg.poses})")
        if not 1e-3 <= cfg.path_length <= 5.0 or not math.isfinite(cfg.path_length):
            out.append(
                f"the path length must be in [1, 5000] mm (got {cfg.path_length * 1e3:g} mm)"
            )
        if cfg.skip_joints or cfg.coupled:
            out.append("--skip-joints is for sweeps; a path protocol sweeps no joint")
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


def _iso9283_problems(cfg: SimulationConfig) -> list[str]:
    """What is wrong with the settings of the ``iso9283`` protocol."""
    numbers = [
        cfg.iso_dwell,
        cfg.repeatability,
        cfg.orientation_repeatability,
        cfg.drift,
        cfg.drift_time,
        cfg.overshoot,
        cfg.overshoot_frequency,
        cfg.overshoot_damping,
        cfg.path_error,
        cfg.path_repeatability,
    ]
    if not all(math.isfinite(v) for v in numbers):
        return ["every setting of the iso9283 protocol must be finite"]
    checks = [
        (
            1 <= cfg.iso_cycles <= 1000,
            f"the ISO 9283 pose cycles must be in [1, 1000] (got {cfg.iso_cycles})",
        ),
        (
            0 <= cfg.iso_path_cycles <= 1000,
            f"the ISO 9283 path cycles must be in [0, 1000] (got {cfg.iso_path_cycles})",
        ),
        (
            0.1 <= cfg.iso_dwell <= 60,
            f"the dwell at each ISO 9283 pose must be in [0.1, 60] s (got {cfg.iso_dwell:g} s)",
        ),
        (
            cfg.tracker_rate >= 100,
            f"the iso9283 protocol needs a tracker rate ≥ 100 Hz for the arrivals' "
            f"stabilisation (got {cfg.tracker_rate:g} Hz)",
        ),
        (
            all(0 <= v <= 0.01 for v in (cfg.repeatability, cfg.drift, cfg.overshoot))
            and 0 <= cfg.path_error <= 0.01
            and 0 <= cfg.path_repeatability <= 0.01,
            "the repeatability, drift, overshoot and path errors must be in [0, 10] mm",
        ),
        (
            0 <= cfg.orientation_repeatability <= 0.01,
            "the orientation repeatability must be in [0, 0.01] rad",
        ),
        (cfg.drift_time >= 0, f"the drift time must be ≥ 0 s (got {cfg.drift_time:g} s)"),
        (
            0.1 <= cfg.overshoot_frequency <= 1000,
            f"the overshoot frequency must be in [0.1, 1000] Hz "
            f"(got {cfg.overshoot_frequency:g} Hz)",
        ),
        (
            0 < cfg.overshoot_damping < 1,
            f"the overshoot damping ratio must be in (0, 1) (got {cfg.overshoot_damping:g})",
        ),
    ]
    out = [why for ok, why in checks if not ok]
    unsupported = [
        (bool(cfg.compliance or cfg.harmonic), "--compliance/--harmonic"),
        (bool(cfg.extra_tools), "--extra-targets"),
        (bool(cfg.pose_list), "--poses CSV"),
        (bool(cfg.skip_joints or cfg.coupled), "--skip-joints"),
        (cfg.instrument != "tracker", "--instrument camera"),
        (cfg.restation or cfg.remount, "--restation/--remount"),
        (cfg.clock_drift != 0.0, "--clock-drift-ppm"),
        (cfg.clock_step != 0.0, "--clock-step-ms"),
    ]
    out += [
        f"{what} is not simulated with the iso9283 protocol (it runs the ISO 9283 test program)"
        for bad, what in unsupported
        if bad
    ]
    return out


def _camera_problems(cfg: SimulationConfig) -> list[str]:
    """What is wrong with a vision log's settings (none for a tracker's): the set-up, the
    image format, and what the camera's simulation does not do yet."""
    if cfg.instrument == "tracker":
        return []
    if cfg.instrument != "camera":
        return [f"the instrument must be tracker or camera, not '{cfg.instrument}'"]
    out = []
    if cfg.camera_setup not in ("eye-to-hand", "eye-in-hand"):
        out.append(
            f"the camera set-up must be eye-to-hand or eye-in-hand, not '{cfg.camera_setup}'"
        )
    if cfg.image_format not in ("jpeg", "png", "raw"):
        out.append(f"the image format must be jpeg, png or raw, not '{cfg.image_format}'")
    if cfg.pose_list:
        out.append(
            "a camera's still poses are drawn where the board is seen: give --poses N, "
            "not a list of poses"
        )
    elif cfg.protocol == "random-poses" and not 1 <= cfg.poses <= 10_000:
        out.append(f"a vision log's poses must be in [1, 10 000] (got {cfg.poses})")
    unsupported = [
        (cfg.model_error > 0, "--model-error-mm"),
        (bool(cfg.compliance or cfg.harmonic), "--compliance/--harmonic"),
        (bool(cfg.extra_tools) or cfg.tool_rotation is not None, "further or 6-DoF targets"),
        (not cfg.encoders, "--no-encoders"),
        (cfg.protocol in PATH_PROTOCOLS, "a path protocol"),
        (cfg.restation or cfg.remount, "--restation/--remount"),
        (cfg.clock_drift != 0.0, "--clock-drift-ppm"),
        (cfg.clock_step != 0.0, "--clock-step-ms"),
    ]
    out += [
        f"{what} is for tracker logs; a camera is simulated without it"
        for bad, what in unsupported
        if bad
    ]
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
