"""``dhlog simulate``: a simulated calibration session and its ground truth."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from dhlog.cli.common import (
    EXIT_USAGE,
    check_folder,
    fail,
    plain,
    refuse_existing,
    stderr,
    stdout,
)
from dhlog.cli.options import joint_numbers, parked_joints, triples, tuples
from dhlog.errors import DhlogError


def simulate(
    robot: Annotated[
        str,
        typer.Argument(
            help="A library robot (dhlog robots lists them: kr5, ur5e, panda, …) or a DH file."
        ),
    ],
    output: Annotated[
        Path,
        typer.Option(
            "-o",
            "--output",
            help="The MCAP file to write; the truth goes beside it as <stem>.truth.json.",
        ),
    ],
    encoding: Annotated[
        str, typer.Option(help="ros2 (as rosbag2 writes it), json or protobuf.")
    ] = "ros2",
    noise_mm: Annotated[
        float, typer.Option(help="Tracker noise: σ (gaussian) or half-width (uniform), mm.")
    ] = 0.01,
    noise_kind: Annotated[str, typer.Option(help="gaussian or uniform.")] = "gaussian",
    motion: Annotated[
        str, typer.Option(help="continuous, or step (step-and-measure).")
    ] = "continuous",
    tracker_rate: Annotated[float, typer.Option(help="Tracker samples per second.")] = 100.0,
    joint_rate: Annotated[
        float, typer.Option(help="Joint-state samples per second (own clock).")
    ] = 250.0,
    sweep_deg: Annotated[float, typer.Option(help="Sweep of each revolute joint, degrees.")] = 90.0,
    travel_mm: Annotated[float, typer.Option(help="Travel of each prismatic joint, mm.")] = 100.0,
    steps: Annotated[int, typer.Option(help="Stops per sweep in step mode.")] = 12,
    lock_poses: Annotated[
        str, typer.Option(help="home (all sweeps from one pose) or random.")
    ] = "home",
    protocol: Annotated[
        str,
        typer.Option(
            help="sweeps (each joint alone), random-poses (--poses still poses within the "
            "limits, every joint changing) or coupled (each joint alone in --steps stops, "
            "except joint 2: only with joint 3 as q3 = -q2); these two measure only at stops. "
            "iso9283: the ISO 9283 test program (dhlog plan --iso9283's) run by a robot of known "
            "repeatability, drift, overshoot and path error (--cycles, --repeatability-mm, …), "
            "with the commanded joints on /joint_command and every attained pose in the truth. "
            "line, curve: a task session, --poses still poses along a straight line or a "
            "planar curve (--path-length-mm), the target's orientation held (the nominal's "
            "inverse kinematics, as a controller's): a --validate log."
        ),
    ] = "sweeps",
    path_length_mm: Annotated[
        float,
        typer.Option(help="--protocol line: the line's length; curve: its extent, mm."),
    ] = 400.0,
    restation: Annotated[
        bool,
        typer.Option(
            "--restation",
            help="The tracker re-stationed since the calibration (0.61 m away, turned 125° "
            "about its vertical): another T_measurement_base, for a --validate log.",
        ),
    ] = False,
    leica_export: Annotated[
        bool,
        typer.Option(
            "--leica-export",
            help="Also write <stem>.leica.csv: the still poses as a Leica 6-DoF export (Point "
            "Name, X Y Z [mm], U(95), Q0..Q3 scalar first, j1.. in degrees) for dhlog import "
            "--format leica; with --six-dof and a still-pose protocol.",
        ),
    ] = False,
    remount: Annotated[
        bool,
        typer.Option(
            "--remount",
            help="The probe re-mounted since the calibration: its point moved 0.95 mm on the "
            "flange and, with --six-dof, its frame turned 1.6°.",
        ),
    ] = False,
    cycles: Annotated[
        int, typer.Option(help="--protocol iso9283: cycles of the pose test (P1 P5 P4 P3 P2).")
    ] = 30,
    path_cycles: Annotated[
        int, typer.Option(help="--protocol iso9283: cycles of the path test (each test path).")
    ] = 10,
    repeatability_mm: Annotated[
        float,
        typer.Option(
            help="--protocol iso9283: σ per coordinate of the attained position from visit to "
            "visit, mm."
        ),
    ] = 0.02,
    drift_mm: Annotated[
        float,
        typer.Option(
            help="--protocol iso9283: the drift (a warm-up): the barycentre of a cycle's "
            "positions moves this much from the first cycle to the last, mm."
        ),
    ] = 0.05,
    overshoot_mm: Annotated[
        float,
        typer.Option(
            help="--protocol iso9283: each arrival's overshoot along its approach (a damped "
            "5 Hz oscillation, damping ratio 0.2), mm."
        ),
    ] = 0.1,
    path_error_mm: Annotated[
        float,
        typer.Option(
            help="--protocol iso9283: the peak of the paths' systematic deviation normal to the "
            "command, mm (and a random offset per path cycle of σ 0.02 mm)."
        ),
    ] = 0.2,
    poses: Annotated[
        str,
        typer.Option(
            metavar="N|CSV",
            help="Still poses of --protocol random-poses: how many to draw, or a CSV of joint "
            "vectors to visit in order (one per row, a header row kept; what plan --select "
            "writes), in --angle-unit.",
        ),
    ] = "40",
    angle_unit: Annotated[
        str, typer.Option(metavar="rad|deg", help="The unit of --poses CSV's revolute joints.")
    ] = "rad",
    model_error_mm: Annotated[
        float,
        typer.Option(
            help="σ per coordinate of an unmodelled smooth error of the robot's position "
            "(what gravity and gears leave after a geometric model), mm."
        ),
    ] = 0.0,
    compliance: Annotated[
        str,
        typer.Option(
            metavar="J:C,…",
            help="Gravity compliance of the truth: joint J yields C rad per N·m of the gravity "
            "torque of the robot's lumped masses and payload (kr5, kr210), e.g. '2:2e-8,3:3e-8'.",
        ),
    ] = "",
    payload_kg: Annotated[
        float | None, typer.Option(help="Payload at the tool point for --compliance, kg.")
    ] = None,
    harmonic: Annotated[
        str,
        typer.Option(
            metavar="J:A:B,…",
            help="Transmission error of the truth: Δq_J = A sin q_J + B cos q_J, rad, e.g. "
            "'2:1e-4:5e-5'.",
        ),
    ] = "",
    six_dof: Annotated[
        bool,
        typer.Option(
            "--six-dof",
            help="A 6-DoF target: its frame, turned on the flange, written with its "
            "orientation (PoseStamped / PoseInFrame).",
        ),
    ] = False,
    driver_joints: Annotated[
        bool,
        typer.Option(
            "--driver-joints",
            help="Joint states as the robot's ROS 2 driver publishes them: its joint names "
            "(the UR arms, kr5, panda: dhlog robots), in alphabetical order (a UR arm's "
            "elbow_joint first).",
        ),
    ] = False,
    orientation_noise_deg: Annotated[
        float, typer.Option(help="σ of the 6-DoF target's orientation noise, degrees.")
    ] = 0.0,
    extra_targets: Annotated[
        str,
        typer.Option(
            help="Further targets (SMRs) as 'x,y,z;x,y,z', mm in the flange frame, measured at "
            "the same instants on /tracker/point_2, /tracker/point_3, …"
        ),
    ] = "",
    base_points: Annotated[int, typer.Option(help="Points probed on the mounting plane.")] = 12,
    outliers: Annotated[float, typer.Option(help="Fraction of gross outliers (mm-sized).")] = 0.0,
    dropouts: Annotated[
        float, typer.Option(help="Fraction of tracker samples lost in bursts.")
    ] = 0.0,
    no_encoders: Annotated[
        bool, typer.Option("--no-encoders", help="Write no joint states (phase markers instead).")
    ] = False,
    phase: Annotated[bool, typer.Option("--phase", help="Write phase markers.")] = False,
    point_type: Annotated[
        str, typer.Option(help="ROS 2 target message: point (PointStamped) or pose (PoseStamped).")
    ] = "point",
    perturb_mm: Annotated[
        float, typer.Option(help="σ of length errors of the simulated robot against its table, mm.")
    ] = 0.0,
    perturb_deg: Annotated[
        float, typer.Option(help="σ of angle errors of the simulated robot, degrees.")
    ] = 0.0,
    skip_joints: Annotated[
        str,
        typer.Option(
            help="Joints (1-based, comma-separated) never swept, to make a partial session."
        ),
    ] = "",
    park_joints: Annotated[
        str,
        typer.Option(
            metavar="J[:VALUE],…",
            help="Joints parked all session (a torso, a rail, an external axis): never swept, "
            "the same in every random pose (a servo's 0.2 mrad or mm wander from pose to "
            "pose), at VALUE (rad or m; default 0), e.g. '1' or '1:0.3'.",
        ),
    ] = "",
    clock_offset_ms: Annotated[
        float,
        typer.Option(
            help="Joint-state stamps written this many ms early (the tracker's clock is right): "
            "the clock offset a pipeline would need."
        ),
    ] = 0.0,
    clock_drift_ppm: Annotated[
        float,
        typer.Option(
            help="The joint-state clock runs this many ppm fast against the tracker's from the "
            "session's start (two computers without a common time drift by 10-50)."
        ),
    ] = 0.0,
    clock_step_ms: Annotated[
        float,
        typer.Option(
            help="The joint-state clock is set this many ms on mid-session (a time daemon "
            "stepping it; negative: set back)."
        ),
    ] = 0.0,
    clock_step_at: Annotated[
        float,
        typer.Option(help="Where the clock step falls: a share of the motion, in (0, 1)."),
    ] = 0.5,
    start_day: Annotated[
        float,
        typer.Option(help="Days after 2025-11-21 04:40 UTC the session starts (a series)."),
    ] = 0.0,
    instrument: Annotated[
        str,
        typer.Option(
            metavar="tracker|camera",
            help="tracker (a laser tracker's points), or camera: a vision log, a ChArUco board "
            "rendered through a pinhole camera with lens distortion, blur and noise at each "
            "still pose where it is seen (random-poses) or every 1/--frame-rate s where it is "
            "seen (sweeps, coupled; each sweep limited to the part where it is seen), with "
            "CameraInfo and the joint states; the truth gains the camera's pose, the board's "
            "mount and the intrinsics.",
        ),
    ] = "tracker",
    camera_setup: Annotated[
        str,
        typer.Option(
            metavar="eye-to-hand|eye-in-hand",
            help="--instrument camera: the camera fixed in the cell and the board on the "
            "flange, or the camera on the flange and the board fixed.",
        ),
    ] = "eye-to-hand",
    image_format: Annotated[
        str,
        typer.Option(
            metavar="jpeg|png|raw",
            help="--instrument camera: CompressedImage (JPEG, PNG) on "
            "/camera/image_raw/compressed, or Image (mono8) on /camera/image_raw.",
        ),
    ] = "jpeg",
    camera: Annotated[
        str,
        typer.Option(
            metavar="default|full-hd|small",
            help="--instrument camera: default (1280x800, f 1800 px, a 7x5 ChArUco board of "
            "40 mm squares, 1.5 m away eye-to-hand), full-hd (1920x1080, f 1600 px, a 10x7 "
            "board of 30 mm squares, 0.3 m across, 2 m away) or small (640x400, the default's "
            "view, a board of 60 mm squares).",
        ),
    ] = "default",
    frame_rate: Annotated[
        float,
        typer.Option(help="--instrument camera, sweeps and coupled: frames per second."),
    ] = 10.0,
    exposure_ms: Annotated[
        float,
        typer.Option(
            help="--instrument camera, sweeps and coupled: each frame blurred by the motion "
            "over this exposure about its stamp, ms (0: none)."
        ),
    ] = 0.0,
    cameras: Annotated[
        int,
        typer.Option(
            help="--instrument camera, eye-to-hand: fixed cameras, each placed differently, on "
            "/camera_1/..., /camera_2/..., ... (one: /camera/...)."
        ),
    ] = 1,
    seed: Annotated[int, typer.Option(help="Random seed.")] = 0,
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing outputs.")] = False,
) -> None:
    """Write a simulated calibration session and its ground truth."""
    from dhlog.api.simulation import simulate_config
    from dhlog.io.dhfile import robot_or_dh_file
    from dhlog.simulator.config import (
        PROTOCOLS,
        SIX_DOF_TOOL_ROTATION,
        CameraOptions,
        SimulationConfig,
        config_problems,
    )

    choices = {
        "encoding": (encoding, ("ros2", "json", "protobuf")),
        "noise-kind": (noise_kind, ("gaussian", "uniform")),
        "motion": (motion, ("continuous", "step")),
        "lock-poses": (lock_poses, ("home", "random")),
        "point-type": (point_type, ("point", "pose")),
        "protocol": (protocol, PROTOCOLS),
        "angle-unit": (angle_unit, ("rad", "deg")),
        "instrument": (instrument, ("tracker", "camera")),
        "camera-setup": (camera_setup, ("eye-to-hand", "eye-in-hand")),
        "image-format": (image_format, ("jpeg", "png", "raw")),
    }
    for option, (value, allowed) in choices.items():
        if value not in allowed:
            stderr.print(
                f"error: --{option} must be one of {', '.join(allowed)}, not '{plain(value)}'."
            )
            raise typer.Exit(EXIT_USAGE)
    iso_options = (cycles, path_cycles, repeatability_mm, drift_mm, overshoot_mm, path_error_mm)
    if protocol != "iso9283" and iso_options != (30, 10, 0.02, 0.05, 0.1, 0.2):
        stderr.print(
            "error: --cycles, --path-cycles, --repeatability-mm, --drift-mm, --overshoot-mm and "
            "--path-error-mm are for --protocol iso9283."
        )
        raise typer.Exit(EXIT_USAGE)
    camera_options = (camera, frame_rate, cameras, exposure_ms) != ("default", 10.0, 1, 0.0)
    if instrument != "camera" and camera_options:
        stderr.print(
            "error: --camera, --frame-rate, --exposure-ms and --cameras are for "
            "--instrument camera."
        )
        raise typer.Exit(EXIT_USAGE)
    extra_tools = triples(extra_targets, "--extra-targets")
    compliant = [(int(j), c) for j, c in tuples(compliance, "--compliance", 2)]
    harmonics = [(int(j), a, b) for j, a, b in tuples(harmonic, "--harmonic", 3)]
    truth_path = output.with_name(output.stem + ".truth.json")
    urdf_path = output.with_name(output.stem + ".urdf") if compliant else None
    export_path = output.with_name(output.stem + ".leica.csv") if leica_export else None
    check_folder(output.parent)
    for path in (output, truth_path, *(p for p in (urdf_path, export_path) if p)):
        refuse_existing(path, force)
    pose_file = None if poses.strip().isdigit() else Path(poses)
    if pose_file is not None and pose_file.resolve() in {
        p.resolve() for p in (output, truth_path, *([urdf_path] if urdf_path else []))
    }:
        stderr.print(f"error: --poses {plain(poses)} is an output; name another.")
        raise typer.Exit(EXIT_USAGE)
    try:
        rob = robot_or_dh_file(robot)
        pose_list: tuple[tuple[float, ...], ...] = ()
        if pose_file is not None:
            pose_list = _pose_file(pose_file, rob, angle_unit)
        cfg = SimulationConfig(
            noise=noise_mm * 1e-3,
            noise_kind=noise_kind,  # type: ignore[arg-type]
            tracker_rate=tracker_rate,
            joint_rate=joint_rate,
            motion=motion,  # type: ignore[arg-type]
            sweep=math.radians(sweep_deg),
            travel=travel_mm * 1e-3,
            steps=steps,
            lock_poses=lock_poses,  # type: ignore[arg-type]
            protocol=protocol,  # type: ignore[arg-type]
            poses=len(pose_list) or int(poses),
            pose_list=pose_list,
            path_length=path_length_mm * 1e-3,
            restation=restation,
            remount=remount,
            model_error=model_error_mm * 1e-3,
            tool_rotation=SIX_DOF_TOOL_ROTATION if six_dof else None,
            driver_joints=driver_joints,
            orientation_noise=math.radians(orientation_noise_deg),
            extra_tools=tuple((x * 1e-3, y * 1e-3, z * 1e-3) for x, y, z in extra_tools),
            base_points=base_points,
            outliers=outliers,
            dropouts=dropouts,
            encoders=not no_encoders,
            phase=phase or no_encoders,
            perturb_length=perturb_mm * 1e-3,
            perturb_angle=math.radians(perturb_deg),
            skip_joints=tuple(joint_numbers(skip_joints, "--skip-joints")),
            parked=parked_joints(park_joints),
            clock_offset=clock_offset_ms * 1e-3,
            clock_drift=clock_drift_ppm * 1e-6,
            clock_step=clock_step_ms * 1e-3,
            clock_step_at=clock_step_at,
            start_day=start_day,
            compliance=tuple(compliant),
            payload=payload_kg,
            harmonic=tuple(harmonics),
            instrument=instrument,  # type: ignore[arg-type]
            camera_setup=camera_setup,  # type: ignore[arg-type]
            image_format=image_format,  # type: ignore[arg-type]
            iso_cycles=cycles,
            iso_path_cycles=path_cycles,
            repeatability=repeatability_mm * 1e-3,
            drift=drift_mm * 1e-3,
            overshoot=overshoot_mm * 1e-3,
            path_error=path_error_mm * 1e-3,
            seed=seed,
        )
        problems = config_problems(rob, cfg)
        if problems:
            stderr.print(f"error: {plain(problems[0])}.")
            raise typer.Exit(EXIT_USAGE)
        found = simulate_config(
            rob,
            cfg,
            output,
            encoding=encoding,
            point_type=point_type,
            vision=CameraOptions(camera, frame_rate, cameras, exposure_ms * 1e-3),
            overwrite=True,  # refused above without --force
            leica_export=leica_export,
        )
    except DhlogError as exc:
        fail(exc)
    for note in found.notes:
        stdout.print(f"note: {note}", markup=False)
    for warning in found.warnings:
        stderr.print(f"warning: {plain(warning)}.")
    stdout.print(
        f"wrote {plain(output)} ({found.described}) and {plain(truth_path)}"
        + (
            f"; {plain(found.urdf)} (the nominal robot with its lumped masses, for --masses)"
            if found.urdf
            else ""
        ),
        markup=False,
    )
    if found.export is not None:
        stdout.print(
            f"wrote {plain(found.export)} (a Leica 6-DoF export: dhlog import "
            f"{plain(found.export)} --format leica)",
            markup=False,
        )
    if instrument == "camera":
        return
    if protocol == "iso9283":
        stdout.print(
            "note: the truth's iso9283 block lists every visit and path cycle without the "
            "tracker's noise (docs/iso9283.md, Simulating the test); analyse the log with "
            f"dhlog iso9283 {plain(output)} --nominal {plain(robot)}.",
            markup=False,
        )
    if six_dof:
        stdout.print(
            "note: the target's orientation is in /tracker/point: read it with "
            "orientation = true in the pipeline's [streams.point].",
            markup=False,
        )
    if extra_tools:
        topics = ", ".join(f'"/tracker/point_{k + 2}"' for k in range(len(extra_tools)))
        stdout.print(
            f"note: read the further targets with extra_topics = [{topics}] in the pipeline's "
            "[streams.point].",
            markup=False,
        )


def _pose_file(path: Path, robot: Any, angle_unit: str) -> tuple[tuple[float, ...], ...]:
    """``simulate --poses CSV``: the joint vectors (rad or m) to visit, in the file's order."""
    from dhlog.cell.compensate import read_targets

    _, Q = read_targets(path, robot.n)
    if angle_unit == "deg":
        revolute = np.array([t.value == "revolute" for t in robot.table.joint_types])
        Q = np.where(revolute, np.radians(Q), Q)
    return tuple(tuple(float(v) for v in q) for q in Q)
