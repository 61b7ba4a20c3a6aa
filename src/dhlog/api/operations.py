"""The commands as functions: :func:`process`, :func:`load`, :func:`robot`, :func:`simulate` and
:func:`plan` — what ``dhlog process``, ``export``/``compensate`` (on a loaded result), ``show``,
``simulate`` and ``plan`` run, with typed arguments in SI units. The command line parses its text
options into these arguments and prints what they return."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from dhlog.api.calibration import Calibration, UsageError, _dh_model, _library_limits
from dhlog.errors import DhlogError, Note

if TYPE_CHECKING:
    from dhlog.cell.plan import Plan, Tracker
    from dhlog.io.dhfile import DHModel
    from dhlog.io.pipeline import Pipeline
    from dhlog.iso9283.run import Iso9283Report
    from dhlog.model.robots import Robot
    from dhlog.simulator.config import SimulationConfig

#: ``process(model=…)``: the terms beyond the geometry to try (auto) or force.
ModelName = Literal["auto", "geometric", "compliance", "harmonic", "full"]


def process(
    log: str | Path,
    *,
    nominal: str | Path | Robot | Calibration | DHModel | None = None,
    pipeline: str | Path | Pipeline | None = None,
    holdout: int = 0,
    validate: Sequence[str | Path] = (),
    model: ModelName = "auto",
    gravity: Sequence[float] | None = None,
    harmonic_joints: Sequence[int] | None = None,
    masses: str | Path | None = None,
    reference_pose: ArrayLike | None = None,
    analytic_only: bool = False,
    fit_encoder_scales: bool = False,
    camera_setup: Literal["eye-to-hand", "eye-in-hand"] | None = None,
    refine_intrinsics: bool = False,
    frames: tuple[int | None, int | None] | None = None,
    jobs: int = 1,
    progress: Callable[[str, float], None] | None = None,
) -> Calibration:
    """Identify the robot's model from a calibration log — ``dhlog process`` without writing
    anything (write with :meth:`Calibration.save`).

    ``log``: an MCAP file or a ROS 2 bag folder (a tracker's or a camera's session).
    ``nominal``: the robot's nominal model (a library robot's name, a DH file, :func:`robot`'s
    result or a calibration): ambiguous choices follow it, and it is the model held-out errors
    and compensation compare with. ``pipeline``: a shipped pipeline's name or a pipeline file
    (default: the shipped one whose topics the log holds). ``holdout`` K ≥ 2: K-fold
    cross-validation, the error at poses not used to fit (:attr:`Calibration.holdout`);
    ``validate``: logs of other poses of the same robot that score the result. ``model``: the
    terms beyond the geometry (``auto`` keeps gravity compliance and transmission harmonics only
    where they lower both the held-out error and the BIC); ``gravity`` (x, y, z in M),
    ``harmonic_joints`` (1-based) and ``masses`` (the robot's URDF) refine it.
    ``reference_pose`` (n,; rad or m): the pose the table's offsets refer to (default: the one
    most sweeps share). ``analytic_only``: the circle fits and line geometry alone.
    ``fit_encoder_scales``: one scale per encoder. A camera's log: ``camera_setup`` (default:
    decided from the data), ``refine_intrinsics``, ``frames`` (first, end) of the image topic,
    ``jobs`` processes decoding images. ``progress(stage, fraction)`` is called as the run goes.

    A partial result (some joints not identified) is returned with what was identified
    (:attr:`Calibration.complete` is False); bad input raises a :class:`~dhlog.DhlogError` whose
    message names the file or field and what to do."""
    from dhlog.identify.model.select import MODELS, ModelRequest
    from dhlog.identify.run import ProcessOptions, process_log

    if model not in MODELS:
        raise UsageError(f"process: model must be one of {', '.join(MODELS)}, not {model!r}.")
    if holdout == 1 or not 0 <= holdout <= 1000:
        raise UsageError(
            f"process: holdout must be 0 (none) or a fold count of 2 to 1000, not {holdout}."
        )
    if camera_setup not in (None, "eye-to-hand", "eye-in-hand"):
        raise UsageError(
            f"process: camera_setup must be 'eye-to-hand' or 'eye-in-hand', not {camera_setup!r}."
        )
    if not 1 <= jobs <= 256:
        raise UsageError(f"process: jobs must be 1 to 256, not {jobs}.")
    g = None
    if gravity is not None:
        values = [float(v) for v in gravity]
        if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
            raise UsageError("process: gravity takes three finite numbers x, y, z, not all zero.")
        g = (values[0], values[1], values[2])
    joints = None
    if harmonic_joints is not None:
        numbers = [int(j) for j in harmonic_joints]
        if not numbers or any(not 1 <= j <= 64 for j in numbers):
            raise UsageError("process: harmonic_joints takes joint numbers (1, 2, …).")
        joints = tuple(sorted({j - 1 for j in numbers}))
    if masses is not None and not Path(masses).is_file():
        raise UsageError(f"process: masses {masses}: no such file; give the robot's URDF.")
    request = ModelRequest(model, g, joints, None if masses is None else str(masses))
    pipe = _pipeline(pipeline)
    nom = None if nominal is None else _dh_model(nominal)
    ref = None
    if reference_pose is not None:
        ref = np.asarray(reference_pose, dtype=np.float64).ravel()
        if not np.all(np.isfinite(ref)) or np.any(np.abs(ref) > 2 * math.pi):
            raise UsageError(
                "process: reference_pose must be finite joint values in rad (m for prismatic "
                "joints), each within ±2π: values beyond look like degrees (np.radians them)."
            )
    result = process_log(
        log,
        ProcessOptions(
            pipeline=pipe,
            nominal=nom,
            reference_pose=ref,
            analytic_only=analytic_only,
            fit_scales=fit_encoder_scales,
            holdout=holdout,
            validate=tuple(validate),
            model=request,
            camera_setup=camera_setup,
            refine_intrinsics=refine_intrinsics,
            jobs=jobs,
            frames=frames,
        ),
        progress=progress,
    )
    found = calibration_of(result, limits=_library_limits(nominal))
    found._asked = (bool(holdout or validate), model != "geometric" and not analytic_only)
    found._inputs = tuple(str(v) for v in validate)
    return _warned(found, run=True)


def _warned(found: Calibration, *, run: bool = False) -> Calibration:
    """``found``, a run's warnings (``run``; a loaded result's were given when it was made)
    given first through :func:`warnings.warn` (a :class:`~dhlog.errors.DhlogWarning` each) and
    the ``dhlog`` logger, and an :class:`~dhlog.errors.ImplausibleWarning` when dhlog judges
    it implausible (the command line prints them its own way, and exits 4)."""
    from dhlog.errors import ImplausibleWarning, give_warning
    from dhlog.io.safetext import printable

    name = printable(Path(found.source).name)
    if run:
        for message in found.warnings:
            give_warning(f"{name}: {printable(message)}", stacklevel=3)
    if not found.plausible:
        give_warning(
            f"{name}: implausible result: " + " ".join(found.implausible),
            ImplausibleWarning,
            stacklevel=3,
        )
    return found


def _pipeline(spec: str | Path | Pipeline | None) -> Pipeline | None:
    """A pipeline given by name, file or as read (the command line reads it first)."""
    from dhlog.io.pipeline import Pipeline, pipeline_from

    if spec is None or isinstance(spec, Pipeline):
        return spec
    return pipeline_from(str(spec))


def calibration_of(result: Any, *, limits: Any = None) -> Calibration:
    """A run's :class:`Calibration` made from its one record ``result`` (a
    :class:`~dhlog.identify.run.ProcessResult`): the document written from it, the model read
    off it (:func:`~dhlog.result.model.model_of`, equal to what the document reads back as)."""
    from dhlog.result.document import result_document
    from dhlog.result.model import model_of

    found = Calibration(
        document=result_document(result),
        model=model_of(result),
        nominal=result.nominal,
        source=str(result.path),
        limits=limits,
    )
    found._result = result
    return found


def with_info(calibration: Calibration, said: str, code: str) -> Calibration:
    """A run's calibration with a note (``said``, its code ``code``) added to its record, the
    document made again from that one record (the console and the JSON read the same notes)."""
    result = calibration.run
    if result is None:
        raise ValueError("with_info: a run's calibration (not a loaded one)")
    found = calibration_of(result.said(Note.info(said, code)), limits=calibration.limits)
    found._asked, found._inputs = calibration._asked, calibration._inputs
    return found


def load(path: str | Path, *, nominal: str | Path | Robot | None = None) -> Calibration:
    """A result (``<stem>.dh.json``) or a DH file (``.json``, ``.toml``; a truth file) read back
    as a :class:`Calibration`. ``nominal``: the model the robot's controller runs (for
    :meth:`Calibration.compensate`; a result file does not carry it)."""
    from dhlog.io.dhfile import load_dh, parse_dh
    from dhlog.io.safetext import printable

    name = str(path)
    if name.endswith(".toml"):
        import tomllib

        model = load_dh(path)  # every byte checked: a bad file is one line naming it
        document: dict[str, Any] = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    else:  # a result (or DH) JSON: size, nesting and every field checked as export reads it
        from dhlog.result.check import load_result

        document = load_result(path)
        model = parse_dh(document, printable(name))
    return _warned(
        Calibration(
            document=document,
            model=model,
            nominal=None if nominal is None else _dh_model(nominal),
            source=name,
            limits=_library_limits(nominal),
        )
    )


def robot(name: str | Path) -> Robot:
    """A robot of the library (``ur5e``, ``ur10e``, ``ur5``, ``kr5``, ``panda``, …; ``dhlog
    robots`` lists them) or one built from a DH file: its standard DH table, base transform, a
    tool point and the joint limits (SI units; a DH file's ``joints[].limits``, or ±π and
    ±0.1 m)."""
    from dhlog.io.dhfile import robot_or_dh_file

    return robot_or_dh_file(str(name))


#: :func:`robot` under another name: simulate's and plan's parameter ``robot`` hides it there
_robot = robot


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
    from dhlog.simulator.config import SimulationConfig

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
        camera=camera,
        frame_rate=frame_rate,
        cameras=cameras,
        exposure=exposure,
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
    camera: str = "default",
    frame_rate: float = 10.0,
    cameras: int = 1,
    exposure: float = 0.0,
    overwrite: bool = False,
    leica_export: bool = False,
) -> Simulation:
    """:func:`simulate` with the simulator's configuration given whole (the command line's
    path). ``leica_export``: also the session's still poses as a Leica 6-DoF export beside the
    log (``<stem>.leica.csv``: :mod:`dhlog.simulator.exports`)."""
    from dhlog._version import __version__
    from dhlog.io.writer import sha256_of, write_session, write_truth
    from dhlog.simulator.config import config_problems
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
            rob, cfg, output, truth_path, camera, frame_rate, cameras, exposure, __version__
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
    preset: str,
    frame_rate: float,
    cameras: int,
    exposure: float,
    version: str,
) -> Simulation:
    """``instrument="camera"``: the vision log and its truth (:mod:`dhlog.simulator.camera`)."""
    from dhlog.io.writer import sha256_of, write_truth
    from dhlog.simulator.camera import (
        simulate_vision,
        vision_problems,
        vision_truth,
        write_vision_log,
    )

    problems = vision_problems(cfg.camera_setup, preset, frame_rate, cameras, exposure)
    if problems:
        raise UsageError(f"{problems[0]}.")
    vision = simulate_vision(
        rob,
        cfg,
        cfg.camera_setup,
        cfg.image_format,
        preset=preset,
        frame_rate=frame_rate,
        cameras=cameras,
        exposure=exposure,
    )
    if not vision.frame_t_ns.size:
        raise DhlogError(
            f"{rob.name}: the board is seen in no frame; try another --seed, --camera-setup "
            "or --protocol"
        )
    write_vision_log(vision, output, cfg.seed)
    doc = vision_truth(
        vision,
        source_path=output.name,
        sha256=sha256_of(output),
        pipeline="none (a vision log)",
        version=version,
    )
    write_truth(doc, truth_path)
    kind = "Image" if cfg.image_format == "raw" else f"CompressedImage ({cfg.image_format})"
    frames = " + ".join(str(view.frame_t_ns.size) for view in vision.cameras)
    where = (
        f"{cfg.camera_setup}, {len(vision.cameras)} cameras" if cameras > 1 else cfg.camera_setup
    )
    states = int(vision.session.joint_t_ns.size)
    return Simulation(
        output,
        truth_path,
        int(vision.frame_t_ns.size),
        states,
        None,
        [f"{note}." for note in vision.notes],
        list(vision.warnings),
        described=f"{frames} {kind} frames of a ChArUco board, {where}, {states} joint states",
    )


def plan(
    robot: str | Path | Robot,
    *,
    protocol: Literal["sweeps", "random-poses", "coupled"] = "random-poses",
    poses: int = 40,
    steps: int = 12,
    sweep: float = math.pi / 2,
    noise: float = 1e-5,
    tracker_rate: float = 100.0,
    six_dof: bool = False,
    seed: int = 0,
    tracker: Tracker | None = None,
) -> Plan:
    """Before the session (``dhlog plan``): the σ of every DH parameter and of the FK over the
    workspace that a protocol will give, and what it cannot determine. SI units: ``sweep`` rad,
    ``noise`` m (the tracker's σ per coordinate). ``tracker``: where the tracker stands, its
    range and noise model (:class:`dhlog.cell.plan.Tracker`; default: anywhere, isotropic).

    Returns a :class:`~dhlog.Plan`: ``rows_std`` (n, 4: θ, d or β, a, α; NaN where fixed),
    ``fk_sd`` (m, at random joint vectors within the limits), ``fixed`` (why), ``samples``."""
    from dhlog.cell.plan import plan_session
    from dhlog.simulator.config import SIX_DOF_TOOL_ROTATION, SimulationConfig, config_problems

    rob = robot if not isinstance(robot, (str, Path)) else _robot(robot)
    cfg = SimulationConfig(
        noise=noise,
        tracker_rate=tracker_rate,
        motion="step",
        sweep=sweep,
        steps=steps,
        protocol=protocol,
        poses=poses,
        tool_rotation=SIX_DOF_TOOL_ROTATION if six_dof else None,
        base_points=12,
        seed=seed,
    )
    problems = config_problems(rob, cfg)
    if problems:
        raise UsageError(f"{problems[0]}.")
    found = plan_session(rob, cfg, tracker)
    if found.out_of_range:
        from dhlog.errors import give_warning

        give_warning(
            f"plan: {found.out_of_range} of the drawn poses put the target beyond the "
            "tracker's range and were left out.",
            stacklevel=2,
        )
    return found


def acceptance_test(
    logs: str | Path | Sequence[str | Path],
    *,
    nominal: str | Path | Robot | Calibration | DHModel | None = None,
    result: str | Path | Calibration | None = None,
    pipeline: str | Path | Pipeline | None = None,
    commanded: str | Path | None = None,
    stops: bool | None = None,
) -> Iso9283Report:
    """The ISO 9283 acceptance test from tracker logs (``dhlog iso9283``): per pose P1–P5 the
    pose accuracy AP and repeatability RP (orientation parts with a 6-DoF target), stabilisation
    time and overshoot, vAP where poses are approached from several directions, distance
    accuracy and repeatability AD/RD, drift, and per test path AT/RT — as ISO 9283:1998 defines
    them (``docs/iso9283.md``).

    ``logs``: the test's log(s), read as one test. ``nominal``: the model the controller runs
    (its FK of the commanded joints is the commanded position; without it, only what needs no
    model: RP, stabilisation, overshoot, drift). ``result``: a calibration of this robot (a
    result file or a :class:`Calibration`): its placement gives the base frame, and each
    accuracy figure is also given as the calibration's compensated commands would attain it.
    ``commanded``: the test program ``dhlog plan --iso9283`` wrote (names the poses, gives the
    paths). ``stops``: the logs are a tracker's static measurements, one point per stop (None:
    detected where the samples are too sparse for a dwell; several targets each get their own
    report in ``.further``). Returns the report; ``.document()`` is the ``iso9283`` JSON
    block."""
    from dhlog.iso9283.run import run_logs

    if result is not None and nominal is None:
        raise UsageError(
            "acceptance_test: result needs nominal (the model the controller runs: the "
            "commanded positions are its forward kinematics)."
        )
    paths = [logs] if isinstance(logs, (str, Path)) else list(logs)
    if not paths:
        raise UsageError("acceptance_test: give at least one log.")
    pipe = _pipeline(pipeline)
    nom = None if nominal is None else _dh_model(nominal)
    from dhlog.iso9283.stops import further_tool_points

    calibrated = None
    further_tools: list[Any] = []
    if result is not None:
        cal = result if isinstance(result, Calibration) else load(result)
        calibrated = cal.identified()
        further_tools = further_tool_points(cal.document, str(cal.source))
    if nom is not None and calibrated is not None and nom.table.n != calibrated.table.n:
        raise UsageError(
            f"acceptance_test: the nominal {nom.source} has {nom.table.n} joints but the result "
            f"{calibrated.source} has {calibrated.table.n}; give the nominal of this robot."
        )
    report = run_logs(
        paths,
        pipeline=pipe,
        nominal=nom,
        calibrated=calibrated,
        commanded_csv=commanded,
        stops=stops,
        further_tools=further_tools,
    )
    from dhlog.errors import give_warning

    for note in report.notes:  # what is missing or was assumed, as the console says it
        give_warning(f"acceptance_test: {note}", stacklevel=2)
    return report
