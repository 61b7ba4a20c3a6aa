"""Simulated sessions as a function (:func:`simulate`, :class:`Simulation`): what ``dhlog
simulate`` runs (:func:`simulate_config` its path), with typed arguments in SI units."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from dhlog.api.calibration import Calibration, UsageError
from dhlog.api.operations import load
from dhlog.api.operations import robot as _robot
from dhlog.errors import DhlogError

if TYPE_CHECKING:
    from dhlog.model.robots import Robot
    from dhlog.simulator.config import CameraOptions, SimulationConfig


@dataclass(frozen=True)
class Simulation:
    """What :func:`simulate` wrote: the ``log`` (MCAP) and its ground ``truth`` (a DH file of the
    simulated robot, with the session's faults), the sample counts, and what to know about them
    (``notes``: e.g. a sweep cut short by the limits; ``warnings``)."""

    log: Path
    truth: Path
    samples: int
    joint_states: int
    urdf: Path | None = None
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: what the log holds, in words (the command's "wrote" line)
    described: str = ""
    #: the session as a Leica 6-DoF export (``leica_export=True``: ``<stem>.leica.csv``)
    export: Path | None = None

    def truth_model(self) -> Calibration:
        """The simulated robot's true model, read back (compare a calibration with it)."""
        return load(self.truth)


def simulate(
    robot: str | Path | Robot = "kr5",
    out: str | Path = "session.mcap",
    *,
    protocol: Literal["sweeps", "random-poses", "coupled", "iso9283", "line", "curve"] = "sweeps",
    noise: float = 1e-5,
    seed: int = 0,
    encoding: Literal["ros2", "json", "protobuf"] = "ros2",
    point_type: Literal["point", "pose"] = "point",
    instrument: Literal["tracker", "camera"] = "tracker",
    camera: str = "default",
    frame_rate: float = 10.0,
    cameras: int = 1,
    exposure: float = 0.0,
    overwrite: bool = False,
    **options: Any,
) -> Simulation:
    """Simulate a calibration session of ``robot`` (a library robot, a DH file or
    :func:`robot`'s result) and write it to ``out`` (MCAP) with its truth beside it
    (``<stem>.truth.json``) — ``dhlog simulate``.

    ``protocol``: each joint swept alone, random still poses, joints moved together, or the
    ISO 9283 test program (``iso9283``: ``iso_cycles``, ``repeatability``, ``drift``,
    ``overshoot``, ``path_error``, … — :mod:`dhlog.simulator.iso9283`);
    ``noise``: the tracker's σ per coordinate (m); ``encoding`` of the messages; ``point_type``
    ``pose`` writes a 6-DoF probe's pose. ``instrument="camera"`` renders a camera's images of a
    ChArUco board instead (``camera``: the preset, ``frame_rate`` Hz, ``cameras``, ``exposure``
    s of motion blur). Further ``options`` are the simulator's settings, SI units: ``poses``,
    ``sweep`` (rad), ``travel`` (m), ``steps``, ``motion`` (continuous, step), ``tracker_rate``,
    ``joint_rate`` (Hz), ``model_error`` (m), ``perturb_length`` (m), ``perturb_angle`` (rad):
    the robot off its nominal, ``clock_offset`` (s), ``outliers``, ``dropouts`` (fractions),
    ``compliance`` ((joint, rad/N·m), …), ``harmonic`` ((joint, a, b), …), ``camera_setup``,
    ``image_format``, … (every field of ``dhlog.simulator.config.SimulationConfig``)."""
    from dhlog.simulator.config import CameraOptions, SimulationConfig

    known = {f.name for f in dataclasses.fields(SimulationConfig)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise UsageError(
            f"simulate: no setting {', '.join(unknown)}; the settings are "
            f"{', '.join(sorted(known))}."
        )
    cfg = SimulationConfig(
        noise=noise, protocol=protocol, seed=seed, instrument=instrument, **options
    )
    rob = robot if not isinstance(robot, (str, Path)) else _robot(robot)
    made = simulate_config(
        rob,
        cfg,
        Path(out),
        encoding=encoding,
        point_type=point_type,
        vision=CameraOptions(camera, frame_rate, cameras, exposure),
        overwrite=overwrite,
    )
    from dhlog.errors import give_warning

    for message in made.warnings:
        give_warning(f"{made.log.name}: {message}", stacklevel=2)
    return made


def simulate_config(
    rob: Robot,
    cfg: SimulationConfig,
    output: Path,
    *,
    encoding: str = "ros2",
    point_type: str = "point",
    vision: CameraOptions | None = None,
    overwrite: bool = False,
    leica_export: bool = False,
) -> Simulation:
    """:func:`simulate` with the simulator's configuration given whole (the command line's
    path). ``vision``: the cameras of an ``instrument="camera"`` session (None: the default
    preset, one camera at the default frame rate, no exposure). ``leica_export``: also the
    session's still poses as a Leica 6-DoF export beside the log (``<stem>.leica.csv``:
    :mod:`dhlog.simulator.exports`)."""
    from dhlog._version import __version__
    from dhlog.io.writer import sha256_of, write_session, write_truth
    from dhlog.simulator.config import CameraOptions, config_problems
    from dhlog.simulator.protocols import swept_joints
    from dhlog.simulator.session import simulate_session
    from dhlog.simulator.truth import truth_document

    if encoding not in ("ros2", "json", "protobuf"):
        raise UsageError(f"simulate: encoding must be ros2, json or protobuf, not {encoding!r}.")
    if point_type not in ("point", "pose"):
        raise UsageError(f"simulate: point_type must be point or pose, not {point_type!r}.")
    truth_path = output.with_name(output.stem + ".truth.json")
    urdf_path = output.with_name(output.stem + ".urdf") if cfg.compliance else None
    export_path = output.with_name(output.stem + ".leica.csv") if leica_export else None
    outputs = [output, truth_path, *([urdf_path] if urdf_path else [])]
    outputs += [export_path] if export_path else []
    from dhlog.io.paths import refuse_inputs_as_outputs

    robot_file = Path(rob.source)
    if robot_file.is_file():  # a DH file: never overwritten by its own session
        refuse_inputs_as_outputs([(robot_file, "robot's DH file")], outputs)
    for path in outputs:
        if path.exists() and not overwrite:
            raise UsageError(f"{path} exists; pass overwrite=True (--force) to replace it.")
    problems = config_problems(rob, cfg)
    if problems:
        raise UsageError(f"{problems[0]}.")
    if cfg.instrument == "camera":
        if encoding != "ros2":
            raise UsageError("simulate: a vision log is written in ros2 encoding only, so far.")
        return _simulate_vision(
            rob, cfg, output, truth_path, vision or CameraOptions(), __version__
        )
    if cfg.protocol == "iso9283":  # the ISO 9283 test program
        from dhlog.simulator.iso9283 import simulate_iso9283

        session = simulate_iso9283(rob, cfg)
    else:
        session = simulate_session(rob, cfg)
    swept = swept_joints(rob, cfg)
    notes = []
    for k, (got, jt) in enumerate(zip(session.sweeps, rob.table.joint_types, strict=True)):
        asked = cfg.sweep if jt.value == "revolute" else cfg.travel
        if k + 1 in swept and got < asked - 1e-9:
            shown = (
                f"sweep {math.degrees(got):.1f}° (asked {math.degrees(asked):g}°)"
                if jt.value == "revolute"
                else f"travel {got * 1e3:.1f} mm (asked {asked * 1e3:g} mm)"
            )
            notes.append(f"joint {k + 1}: {shown}, as its limits allow.")
    from dhlog.simulator.session import as_published

    if export_path is not None:  # before the log: a session no export can hold writes nothing
        from dhlog.simulator.exports import leica_export as export_text

        text = export_text(session)
    written = as_published(session) if cfg.driver_joints else session
    write_session(written, output, encoding, point_type=point_type)  # type: ignore[arg-type]
    if export_path is not None:
        from dhlog.io.writer import atomic_output

        with atomic_output(export_path) as f:
            f.write(text.encode("utf-8"))
    pipeline = (
        "phase_markers"
        if not cfg.encoders
        else {"ros2": "ros2_tracker", "json": "foxglove_json", "protobuf": "foxglove_protobuf"}[
            encoding
        ]
    )
    doc = truth_document(
        session,
        source_path=output.name,
        sha256=sha256_of(output),
        pipeline=pipeline,
        version=__version__,
    )
    write_truth(doc, truth_path)
    if urdf_path is not None:  # the maker's description of the masses, for --masses
        from dhlog.io.writer import atomic_output
        from dhlog.simulator.robot import masses_urdf

        with atomic_output(urdf_path) as f:
            f.write(masses_urdf(rob).encode())
    samples, states = int(session.point_xyz.shape[0]), int(session.joint_t_ns.size)
    return Simulation(
        output,
        truth_path,
        samples,
        states,
        urdf_path,
        notes,
        described=f"{samples} target samples, {states} joint states, "
        + (
            f"{session.command_t_ns.size} commanded joint targets, "
            if cfg.protocol == "iso9283"
            else ""
        )
        + encoding,
        export=export_path,
    )


def _simulate_vision(
    rob: Robot,
    cfg: SimulationConfig,
    output: Path,
    truth_path: Path,
    vision: CameraOptions,
    version: str,
) -> Simulation:
    """``instrument="camera"``: the vision log of the cameras ``vision`` and its truth
    (:mod:`dhlog.simulator.camera`)."""
    from dhlog.io.writer import sha256_of, write_truth
    from dhlog.simulator.camera import (
        simulate_vision,
        vision_problems,
        vision_truth,
        write_vision_log,
    )

    problems = vision_problems(cfg.camera_setup, vision)
    if problems:
        raise UsageError(f"{problems[0]}.")
    session = simulate_vision(
        rob,
        cfg,
        cfg.camera_setup,
        cfg.image_format,
        preset=vision.preset,
        frame_rate=vision.frame_rate,
        cameras=vision.cameras,
        exposure=vision.exposure,
    )
    if not session.frame_t_ns.size:
        raise DhlogError(
            f"{rob.name}: the board is seen in no frame; try another --seed, --camera-setup "
            "or --protocol"
        )
    write_vision_log(session, output, cfg.seed)
    doc = vision_truth(
        session,
        source_path=output.name,
        sha256=sha256_of(output),
        pipeline="none (a vision log)",
        version=version,
    )
    write_truth(doc, truth_path)
    kind = "Image" if cfg.image_format == "raw" else f"CompressedImage ({cfg.image_format})"
    frames = " + ".join(str(view.frame_t_ns.size) for view in session.cameras)
    where = (
        f"{cfg.camera_setup}, {len(session.cameras)} cameras"
        if vision.cameras > 1
        else cfg.camera_setup
    )
    states = int(session.session.joint_t_ns.size)
    return Simulation(
        output,
        truth_path,
        int(session.frame_t_ns.size),
        states,
        None,
        [f"{note}." for note in session.notes],
        list(session.warnings),
        described=f"{frames} {kind} frames of a ChArUco board, {where}, {states} joint states",
    )
