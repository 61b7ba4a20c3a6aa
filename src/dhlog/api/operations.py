"""The commands as functions: :func:`process`, :func:`load`, :func:`robot`, :func:`simulate` and
:func:`plan` — what ``dhlog process``, ``export``/``compensate`` (on a loaded result), ``show``,
``simulate`` and ``plan`` run, with typed arguments in SI units. The command line parses its text
options into these arguments and prints what they return."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from dhlog.api.calibration import Calibration, UsageError
from dhlog.api.models import _dh_model, _library_limits
from dhlog.errors import Note

if TYPE_CHECKING:
    from dhlog.cell.plan import Plan, Tracker
    from dhlog.geometry._checks import FloatArray
    from dhlog.identify.stages import Identification
    from dhlog.io.dhfile import DHModel
    from dhlog.io.pipeline import Pipeline
    from dhlog.iso9283.run import Iso9283Report
    from dhlog.model.robots import Robot

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


def calibration_of(result: Identification, *, limits: FloatArray | None = None) -> Calibration:
    """A run's :class:`Calibration` made from its one record ``result`` (a
    :class:`~dhlog.identify.run.Identification`): the document written from it, the model read
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
