"""A calibration as a Python object: :class:`Calibration`, what :func:`dhlog.process` returns and
:func:`dhlog.load` reads back — the tables with σ and covariance, base and tool, the terms beyond
the geometry, the held-out statistics, and the operations of the commands (``fk``, ``export``,
``compensate``, ``save``, ``log_to_rerun``)."""

from __future__ import annotations

import json
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from dhlog.api.models import _dh_model, _library_limits
from dhlog.api.outputs import _refuse_existing, _write_text, output_names, write_run
from dhlog.errors import UsageError
from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import ModifiedDH, StandardDH, standard_to_modified
from dhlog.model.fk import fk_frames, fk_point

if TYPE_CHECKING:
    import polars as pl
    import rerun as rr

    from dhlog.cell.compensate import Compensation
    from dhlog.identify.run import Identification
    from dhlog.io.dhfile import DHModel
    from dhlog.model.robots import Robot
    from dhlog.model.terms import Terms

#: The formats :meth:`Calibration.export` writes (``dhlog export --format``).
ExportFormat = Literal["urdf", "ur", "rtb", "dh-csv", "dh-json", "tf"]
EXPORT_FORMATS: tuple[str, ...] = ("urdf", "ur", "rtb", "dh-csv", "dh-json", "tf")


@dataclass(eq=False)
class Calibration:
    """An identified robot model: what ``dhlog process`` writes as ``<stem>.dh.json``, as an
    object.

    Made by :func:`dhlog.process` (a run: everything the run found, and the outputs of the command
    — CSV tables, the recording — can be written from it) or :func:`dhlog.load` (a result JSON or
    a DH file read back: the model, σ, covariance and held-out statistics the file holds).

    Units are SI throughout: metres and radians. Positions are in the measurement frame M (the
    tracker's or camera's), as the result contract defines them (``FK = T_measurement_base · A_1 ⋯
    A_n · tool``).
    """

    #: the result document (the ``dhlog.result/1`` JSON contract; for a DH file, what it holds)
    document: dict[str, Any]
    #: the model as forward kinematics reads it (None: a run that identified no joint — its
    #: warnings say why; the model's properties then raise a UsageError naming the joints)
    model: DHModel | None
    #: the nominal the run followed, a :class:`~dhlog.DHModel` (``dhlog.process(nominal=…)``,
    #: ``dhlog.load(nominal=…)``; None when none was given — a result file does not carry it):
    #: what :meth:`changes` subtracts and :meth:`compensate` takes as the controller's model
    nominal: DHModel | None = None
    #: where it came from: the log processed, or the file loaded
    source: str = ""
    #: the nominal's joint limits (n, 2; rad or m) when it is a library robot
    limits: FloatArray | None = None
    _result: Identification | None = field(default=None, repr=False, init=False)
    #: what the run was asked that adds outputs: a held-out check, terms beyond the geometry
    _asked: tuple[bool, bool] = field(default=(False, False), repr=False, init=False)
    #: the run's other inputs (held-out logs): never an output
    _inputs: tuple[str, ...] = field(default=(), repr=False, init=False)

    @property
    def run(self) -> Identification | None:
        """The run's one record (a :class:`dhlog.identify.run.Identification`: everything the run
        found, frozen) that this calibration's document, model, console report and recording
        are all made from; None for a calibration loaded from a file."""
        return self._result

    # ------------------------------------------------------------------ the model

    def identified(self) -> DHModel:
        """The model; a run that identified no joint raises a :class:`~dhlog.UsageError` naming
        the joints and why (the run's warnings)."""
        if self.model is None:
            failed = [
                f"joint {j.get('index')} ({j.get('error')})"
                for j in self.document.get("joints", [])
                if "error" in j
            ]
            raise UsageError(
                f"{Path(self.source).name}: no joint was identified, so there is no model: "
                + "; ".join(failed or self.warnings or ["see the warnings"])
            )
        return self.model

    @property
    def table(self) -> StandardDH:
        """The standard DH table (offsets at encoder zero)."""
        return self.identified().table

    @property
    def modified(self) -> ModifiedDH:
        """The same model as a modified (Craig) DH table; its base transform is
        ``T_base @ standard_to_modified(table)[1]`` (the result's ``modified_dh`` rows)."""
        return standard_to_modified(self.identified().table)[0]

    @property
    def n(self) -> int:
        """The number of joints."""
        return self.identified().table.n

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints' names, as the log (or file) names them."""
        return self.identified().joint_names

    @property
    def T_base(self) -> FloatArray:
        """DH frame 1 (the base) in the measurement frame M, a 4×4 transform."""
        return self.identified().T_base

    @property
    def tool_point(self) -> FloatArray:
        """The target (tool point) in the last DH frame, m (3,)."""
        return self.identified().tool_point

    @property
    def terms(self) -> Terms | None:
        """The terms beyond the geometry (gravity compliance, transmission harmonics) the run
        chose, in the table's frames; None for a geometric model."""
        return self.identified().terms

    @property
    def complete(self) -> bool:
        """True when every joint was identified (a partial result keeps what was)."""
        return not any("error" in j for j in self.document.get("joints", []))

    @property
    def plausible(self) -> bool:
        """False when dhlog judges this calibration implausible (``dhlog process`` exits 4 on
        it): :attr:`implausible` says why. True for a DH file and a result written before
        results were judged."""
        return not self.implausible

    @property
    def implausible(self) -> tuple[str, ...]:
        """Why dhlog judges this calibration implausible, one sentence each naming the evidence
        and the fix (lengths all k times the nominal's, an FK check far above the noise and the
        nominal's own miss, a board of another size …); empty when plausible."""
        from dhlog.result.check import implausible_reasons

        return tuple(implausible_reasons(self.document))

    @property
    def warnings(self) -> list[str]:
        """What may need the user's action (the console's warnings)."""
        return [str(w) for w in self.document.get("warnings", [])]

    @property
    def notes(self) -> list[str]:
        """What a reader should know but need not act on."""
        return [str(w) for w in self.document.get("notes", [])]

    @property
    def version(self) -> str | None:
        """The dhlog version that made the result (None: a DH file)."""
        found = self.document.get("dhlog_version")
        return None if found is None else str(found)

    # ------------------------------------------------------------------ σ and covariance

    @property
    def parameters(self) -> pl.DataFrame:
        """Every DH parameter with its σ, one row each, in the well-conditioned form the result
        shows (as ``<stem>.dh.csv``): ``joint`` (1 …), ``name``, ``form`` (``dh``; ``hayati``
        where a nearly parallel pair makes ``d`` ill-conditioned: ``beta``, a rotation about y,
        in its place), ``parameter`` (theta, d or beta, a, alpha; theta and d are the offsets at
        encoder zero), ``value``, ``sigma`` (null where fixed), ``fixed`` (a convention or gauge
        the data cannot determine, never a measurement), ``unit`` (m or rad) — and the same
        value and σ with the unit in the column's name: ``value_m``, ``value_rad``,
        ``sigma_m``, ``sigma_rad`` (the column of the other unit null)."""
        from dhlog.api.tables import parameters_table

        return parameters_table(self)

    def changes(self) -> pl.DataFrame:
        """Measured − nominal: each parameter's change from :attr:`nominal` with its σ and
        whether it is fixed, one row per parameter as :attr:`parameters` has them — ``joint``,
        ``name``, ``form``, ``parameter``, ``unit``, ``change_m`` / ``change_rad`` (the change
        in its unit's column, the other null; angles wrapped to ±π; null where the nominal has
        no such parameter, as β), ``sigma_m`` / ``sigma_rad`` (null where fixed), ``fixed``.
        The console's "Measured − nominal" table to the digits it shows. A calibration without
        a nominal raises a :class:`~dhlog.UsageError`."""
        from dhlog.api.changes import changes_table

        return changes_table(self.parameters, self.nominal, self.document, self._result)

    @property
    def covariance(self) -> FloatArray | None:
        """The covariance of the fitted parameters (SI units), ordered as
        :attr:`covariance_names`; None when the result holds none."""
        block = self.document.get("covariance")
        if not isinstance(block, dict) or block.get("matrix") is None:
            return None
        return np.asarray(block["matrix"], dtype=np.float64)

    @property
    def covariance_names(self) -> list[str]:
        """The names of :attr:`covariance`'s rows (``d_1``, ``theta_offset_2``, …, ``tool_x``,
        ``base_rz``)."""
        block = self.document.get("covariance")
        return [str(p) for p in block.get("parameters", [])] if isinstance(block, dict) else []

    # ------------------------------------------------------------------ held out

    @property
    def holdout(self) -> pl.DataFrame:
        """The errors at poses not used to fit (``holdout=K``, ``validate=[…]``), one row per
        check and model: ``check`` (``5-fold`` or the held-out log's name), ``model`` (nominal,
        calibrated), ``n_poses``, ``mean``, ``rms``, ``p95``, ``max`` (m) — the same also with
        the unit in the name: ``mean_m``, ``rms_m``, ``p95_m``, ``max_m``. Empty when the run
        made no held-out check."""
        from dhlog.api.tables import holdout_table

        return holdout_table(self)

    @property
    def fk_rms(self) -> float | None:
        """The in-sample check: RMS (m) of every sample's distance from the model's forward
        kinematics (None: not in the result)."""
        found = (self.document.get("validation") or {}).get("fk_rms")
        return None if found is None else float(found)

    # ------------------------------------------------------------------ operations

    def fk(self, q: ArrayLike) -> FloatArray:
        """The target's position in M (…, 3) at encoder values ``q`` (…, n; rad or m), the terms
        beyond the geometry applied (the joints deflected first, as the model was fitted)."""
        values = self.table.check_q(q)
        return fk_point(
            self.table, self.identified().joint_values(values), self.tool_point, T_base=self.T_base
        )

    def fk_frames(self, q: ArrayLike) -> FloatArray:
        """DH frames 1 … n+1 in M (…, n+1, 4, 4) at encoder values ``q``, terms applied."""
        values = self.table.check_q(q)
        return fk_frames(self.table, self.identified().joint_values(values), T_base=self.T_base)

    def export(
        self,
        format: ExportFormat = "urdf",
        path: str | Path | None = None,
        *,
        limits_from: str | None = None,
        template: str | Path | None = None,
        zero_offsets: Literal["origins", "calibration"] = "origins",
        xacro_args: Mapping[str, str] | None = None,
        keep_xacro: bool | None = None,
        overwrite: bool = False,
    ) -> str:
        """The model in a form a robot stack loads (``dhlog export``): ``urdf``, ``ur`` (the UR
        description's calibration YAML), ``rtb`` (a roboticstoolbox ``DHRobot`` in Python),
        ``dh-csv`` / ``dh-json`` (both DH tables), ``tf`` (a ROS 2 launch file: the tracker's
        frame and the target in the robot's frames, or a camera calibration's hand-eye poses).
        Returns the text; with ``path``, also writes it atomically (``overwrite``: replace an
        existing file). ``limits_from``: a library robot or DH file whose name, joint names and
        limits the URDF gets (default: the nominal, when it is a library robot); ``template``: a
        URDF or xacro description whose joints get the calibrated origins (``xacro_args``: the
        xacro's arguments; ``keep_xacro``: write a xacro, not the expanded URDF — default when
        ``path`` ends in ``.xacro``); ``zero_offsets``: ``calibration`` puts the offsets in each
        joint's ``<calibration rising>`` instead of the origins."""
        from dhlog.io.dhfile import robot_or_dh_file
        from dhlog.result import export as exports
        from dhlog.result.export.expand import template_inputs

        if format not in EXPORT_FORMATS:
            raise UsageError(
                f"export: format must be one of {', '.join(EXPORT_FORMATS)}, not {format!r}."
            )
        if zero_offsets not in ("origins", "calibration") or (
            zero_offsets == "calibration" and (template is not None or format != "urdf")
        ):
            raise UsageError(
                "export: zero_offsets must be 'origins' or 'calibration' (calibration: a URDF "
                "without a template)."
            )
        if template is not None and format not in ("urdf", "tf"):
            raise UsageError("export: a template is for the urdf and tf formats.")
        target = None if path is None else Path(path)
        as_xacro = (
            keep_xacro
            if keep_xacro is not None
            else bool(path and Path(path).name.endswith(".xacro"))
        )
        read = template_inputs(template, xacro_args, xacro_out=as_xacro and format == "urdf")
        if target is not None:
            _refuse_existing(target, overwrite, self.source, template, limits_from, *read)
        with self._as_file() as result:
            robot = robot_or_dh_file(limits_from) if limits_from else self._library_robot()
            names = () if robot is None else robot.joint_names
            if format == "urdf" and template is not None:
                text = (
                    exports.xacro_from_template(
                        result, template, args=xacro_args, joint_names=names
                    )
                    if as_xacro
                    else exports.urdf_from_template(
                        result, template, joint_names=names, xacro_args=xacro_args
                    )
                )
            elif format == "urdf":
                limits = robot.limits if robot is not None else self.limits
                text = exports.urdf_document(
                    result, limits=limits, zero_offsets=zero_offsets, robot=robot
                )
            elif format == "ur":
                flange = None if self.nominal is None else self.nominal.table
                text = exports.ur_calibration(result, flange)[0]
            elif format == "rtb":
                text = exports.rtb_document(result)
            elif format == "tf":
                text = exports.tf_document(
                    result, template=template, joint_names=names, xacro_args=xacro_args
                )
            else:
                text = exports.dh_table_document(result, format)
        if target is not None:
            _write_text(target, text)
        return text

    def _library_robot(self) -> Robot | None:
        """The nominal as a library robot (its name, joint names and limits), when it is one."""
        from dhlog.model.robots import UnknownRobotError, load_robot

        if self.nominal is None or Path(self.nominal.source).exists():
            return None
        try:
            return load_robot(self.nominal.source)
        except UnknownRobotError:
            return None

    def compensate(
        self,
        targets: ArrayLike,
        *,
        nominal: str | Path | DHModel | Robot | Calibration | None = None,
        limits: ArrayLike | None = None,
    ) -> Compensation:
        """The joint targets to command a controller running the ``nominal`` model so that the
        robot, as calibrated, reaches where the nominal meant ``targets`` (m, n; rad or m) to go
        (``dhlog compensate --joints``). ``nominal``: the controller's model (default: the run's
        nominal); ``limits`` (n, 2): the joints' limits (default: the library robot's).

        Returns a :class:`~dhlog.Compensation`: ``targets`` (m, n; NaN rows where none),
        ``error`` (the pose error left per target, m or rad) and ``problems`` (row → why)."""
        from dhlog.cell.compensate import compensate

        controller, bounds = self._controller(nominal, limits, "compensate")
        Q = np.asarray(targets, dtype=np.float64)
        if Q.ndim == 1:
            Q = Q[None]
        if Q.ndim != 2 or Q.shape[1] != self.n:
            raise UsageError(
                f"compensate: targets must be (m, {self.n}) joint vectors, not shape {Q.shape}."
            )
        if not np.all(np.isfinite(Q)):
            raise UsageError("compensate: targets must be finite numbers.")
        return _warned_rows(compensate(self.identified(), controller, Q, limits=bounds))

    def compensate_poses(
        self,
        poses: ArrayLike,
        *,
        configuration: ArrayLike | None = None,
        nominal: str | Path | DHModel | Robot | Calibration | None = None,
        limits: ArrayLike | None = None,
    ) -> Compensation:
        """Cartesian targets (m, 4, 4: the last frame in the nominal's base frame, m) to the
        joint targets that make the calibrated robot reach them (``dhlog compensate --poses``);
        ``configuration`` (m, n): the controller's joint configuration per target (default: the
        nearest solution from home or seeded starts). ``nominal`` and ``limits`` as in
        :meth:`compensate`."""
        from dhlog.cell.compensate import compensate_poses

        controller, bounds = self._controller(nominal, limits, "compensate_poses")
        T = np.asarray(poses, dtype=np.float64)
        if T.ndim == 2:
            T = T[None]
        if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.all(np.isfinite(T)):
            raise UsageError(
                f"compensate_poses: poses must be finite (m, 4, 4) transforms, not shape {T.shape}."
            )
        config = None
        if configuration is not None:
            config = np.asarray(configuration, dtype=np.float64)
            if config.shape != (len(T), self.n) or not np.all(np.isfinite(config)):
                raise UsageError(
                    f"compensate_poses: configuration must be finite ({len(T)}, {self.n}) joint "
                    f"vectors, one per pose, not shape {config.shape}."
                )
        done = compensate_poses(
            self.identified(), controller, T, configuration=config, limits=bounds
        )[0]
        return _warned_rows(done)

    def _controller(
        self,
        nominal: str | Path | DHModel | Robot | Calibration | None,
        limits: ArrayLike | None,
        what: str,
    ) -> tuple[DHModel, FloatArray | None]:
        """The controller's model and the joints' limits for a compensation."""
        controller = self.nominal if nominal is None else _dh_model(nominal)
        if controller is None:
            raise UsageError(
                f"{what}: this calibration names no nominal; pass nominal= (a library robot "
                "name, a DH file or dhlog.robot(...)) — the model the controller runs."
            )
        if controller.table.n != self.n:
            raise UsageError(
                f"{what}: the nominal {controller.source} has {controller.table.n} joints but "
                f"the calibration has {self.n}; give the nominal of this robot."
            )
        if limits is not None:
            return controller, np.asarray(limits, dtype=np.float64)
        return controller, self.limits if nominal is None else _library_limits(nominal)

    def save(
        self,
        path: str | Path,
        *,
        units: Literal["mm", "m"] = "mm",
        recording: bool = False,
        with_log: bool = False,
        overwrite: bool = False,
    ) -> list[Path]:
        """Write the result JSON to ``path`` (``<stem>.dh.json``) atomically, and — for a run —
        what ``dhlog process`` writes beside it: ``<stem>.dh.csv`` (in ``units``: mm or m),
        the held-out poses' and the terms' CSV when the run has them, and the Rerun recording
        ``<stem>.rrd`` (``recording``; ``with_log``: the log's own channels in it). All move
        into place together; an existing file is an error unless ``overwrite``. Returns the
        paths written."""
        target = Path(path)
        if units not in ("mm", "m"):
            raise UsageError(f"save: units must be 'mm' or 'm', not {units!r}.")
        if self._result is None:
            if recording:
                raise UsageError(
                    "save: a loaded calibration has no run to record; log_to_rerun() draws its "
                    "model."
                )
            if target.suffix != ".json":
                raise UsageError(f"save: {target} must be a .json path (the result is JSON).")
            _refuse_existing(target, overwrite, self.source)
            _write_text(target, json.dumps(self.document, indent=2) + "\n")
            return [target]
        outputs = self.output_paths(target, recording=recording)
        for p in outputs:
            _refuse_existing(p, overwrite, self.source, *self._inputs)
        target.parent.mkdir(parents=True, exist_ok=True)
        write_run(self, outputs, units, with_log=with_log)
        return outputs

    def output_paths(self, path: str | Path, *, recording: bool = False) -> list[Path]:
        """The files :meth:`save` writes for ``path`` (``<stem>.dh.json``): the JSON, then the
        CSV table (a run's), the recording (``recording``), the held-out poses' and the terms'
        CSV as the run has them — the order ``dhlog process`` writes them in."""
        if self._result is None:
            return [Path(path)]
        return output_names(path, recording=recording, heldout=self._asked[0], terms=self._asked[1])

    def log_to_rerun(
        self,
        path: str | Path | None = None,
        *,
        recording: rr.RecordingStream | None = None,
        with_log: bool = False,
        overwrite: bool = False,
    ) -> rr.RecordingStream | None:
        """The Rerun recording: for a run, what ``dhlog process`` records (the raw points, the
        fitted circles and axes, the DH frames, the residuals, the held-out errors, a camera's
        images); for a loaded calibration, its model with each joint swept in turn (``dhlog
        show``). With ``path``, written to that ``.rrd`` file atomically; otherwise logged into
        ``recording`` (default: a new stream, returned — in a notebook, call its
        ``notebook_show()``); an existing file is kept unless ``overwrite``."""
        import rerun as rr

        from dhlog.present.recording.writers import (
            log_process_recording,
            log_robot_recording,
            process_recording_blueprint,
            robot_blueprint,
            write_process_recording,
            write_robot_recording,
        )

        result = self._result
        if path is not None:
            if recording is not None:
                raise UsageError("log_to_rerun: give a path or a recording, not both.")
            _refuse_existing(Path(path), overwrite, self.source, *self._inputs)
            if result is not None:
                write_process_recording(result, path, with_log=with_log)
            else:
                write_robot_recording(
                    self.table,
                    path,
                    T_base=self.T_base,
                    limits=self.limits,
                    title=Path(self.source).name,
                )
            return None
        rec = recording if recording is not None else rr.RecordingStream("dhlog")
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        if result is not None:
            rec.send_blueprint(process_recording_blueprint(result))
            log_process_recording(rec, result, with_log=with_log)
        else:
            rec.send_blueprint(robot_blueprint())
            log_robot_recording(
                rec, self.table, T_base=self.T_base, limits=self.limits, title=self.source
            )
        return rec

    # ------------------------------------------------------------------ shown

    def report(self, units: Literal["mm", "m"] = "mm", width: int = 80) -> str:
        """The console report of ``dhlog process`` as text (a run), or the DH table with σ (a
        loaded calibration)."""
        from io import StringIO

        from rich.console import Console

        console = Console(
            file=StringIO(),
            width=width,
            color_system=None,
            force_terminal=False,
            force_jupyter=False,  # in a notebook too: the text, not an HTML display
        )
        if self._result is not None:
            from dhlog.present.console import print_result

            print_result(console, self._result, units=units)
        else:
            console.print(self.parameters)
        text = console.file.getvalue()  # type: ignore[attr-defined]
        return str(text)

    def __repr__(self) -> str:
        held = self.holdout.filter(model="calibrated")
        shown = (
            f", held-out RMS {held['rms'][0] * 1e3:.4f} mm ({held['check'][0]})"
            if held.height
            else ""
        )
        rms = f", FK RMS {self.fk_rms * 1e3:.4f} mm" if self.fk_rms is not None else ""
        state = "" if self.complete else ", partial"
        n = len(self.document.get("joints", []))
        return f"<Calibration of {Path(self.source).name}: {n} joints{rms}{shown}{state}>"

    @contextmanager
    def _as_file(self) -> Iterator[str]:
        """The result as a file the exporters read: the file loaded, or the run's document
        written to a temporary file."""
        if self._result is None and self.source and Path(self.source).is_file():
            yield self.source
            return
        with tempfile.TemporaryDirectory(prefix="dhlog-") as folder:
            stem = Path(self.source).name.removesuffix(".mcap").removesuffix(".db3") or "result"
            written = Path(folder) / f"{stem}.dh.json"
            written.write_text(json.dumps(self.document))
            yield str(written)


__all__ = ["EXPORT_FORMATS", "Calibration", "ExportFormat", "UsageError"]


def _warned_rows(done: Compensation) -> Compensation:
    """``done``, each target it did not correct given as a :class:`~dhlog.DhlogWarning`
    (``warnings.warn`` and the ``dhlog`` logger; the command line names them itself)."""
    from dhlog.errors import give_warning

    for row, why in sorted(done.problems.items()):
        give_warning(f"target {row + 1} not corrected: {why}", stacklevel=3)
    return done
