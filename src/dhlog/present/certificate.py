"""The calibration certificate (``dhlog report``): one self-contained HTML page of a result.

:func:`load_sources` reads a result JSON (``<stem>.dh.json``), hashes it, finds and hashes the
log it names and reads ``<stem>.holdout.csv`` beside it; :func:`certificate_html` turns those
into the page: who and what was measured (robot, dates, SHA-256 of the result and of the log),
the tracker and noise model, the held-out error before and after with a histogram beside the
in-sample fit, the DH parameters with ±1σ and measured − nominal (fixed ones marked with their
reason, never shown as measurements), per-joint residuals, the terms beyond the geometry, and
the result's warnings and notes.

Every byte read is untrusted: a missing, mistyped or damaged field is a
:class:`ResultFileError` naming the file and the field; every text from the files is
HTML-escaped. The page has no script and no external resource (inline CSS; plots as inline SVG
drawn by matplotlib, imported only here, with text as paths). Lengths in mm and angles in
degrees, as the console shows them.
"""

from __future__ import annotations

import csv
import hashlib
import html
import io
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from dhlog import __version__
from dhlog.errors import DhlogError, InputError
from dhlog.geometry._checks import roll_pitch_yaw
from dhlog.result.contract import RESULT_FORMAT

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from dhlog.model.dh import StandardDH

#: What to do about a damaged result JSON.
REMEDY = "the file is damaged or not a dhlog result: write it again with dhlog process"
#: What to do about a damaged ``<stem>.holdout.csv``.
CSV_REMEDY = (
    "write it again with dhlog process --holdout (or remove it: the certificate then has no "
    "histogram)"
)
#: A σ beyond these (m, rad) is not a measurement's: the parameter is shown as undetermined
#: (as on the console).
UNDETERMINED_LENGTH = 1.0
UNDETERMINED_ANGLE = math.radians(30.0)
#: Largest result file read (a result of a 6-joint robot is about 50 kB).
MAX_RESULT_BYTES = 64 << 20
#: Colours of the nominal and the calibrated model in every plot.
NOMINAL_COLOUR, CALIBRATED_COLOUR, FIT_COLOUR = "#c8553d", "#2a6f97", "#6c757d"

PARAMETER_SYMBOLS = {"theta": "θ", "d": "d", "beta": "β", "a": "a", "alpha": "α", "scale": "s"}


class ResultFileError(InputError):
    """A result JSON, or a CSV written beside it, cannot be used: ``field`` is the key (or
    column) at fault."""

    def __init__(self, path: str, field: str, problem: str, remedy: str = REMEDY) -> None:
        self.field = field
        super().__init__(f"{path}: {field} {problem}; {remedy}.")


# ---------------------------------------------------------------------------------------------
# reading the result, untrusted


def _kind(value: object) -> str:
    """A JSON value's type as a reader would name it."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, int | float):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


_MISSING = object()


class _Fields:
    """Typed access to an untrusted JSON document: each accessor names the field at fault."""

    def __init__(self, path: str) -> None:
        self.path = path

    def fail(self, field: str, problem: str) -> NoReturn:
        raise ResultFileError(self.path, field, problem)

    def value(self, parent: dict[str, Any], key: str, at: str, *, required: bool) -> Any:
        field = f"{at}.{key}" if at else key
        if key not in parent:
            if required:
                self.fail(field, "is missing")
            return _MISSING
        return parent[key]

    def obj(self, value: Any, field: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            self.fail(field, f"must be an object, not {_kind(value)}")
        return value

    def array(self, value: Any, field: str) -> list[Any]:
        if not isinstance(value, list):
            self.fail(field, f"must be an array, not {_kind(value)}")
        return value

    def number(self, value: Any, field: str, *, minimum: float | None = None) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(field, f"must be a number, not {_kind(value)}")
        try:
            number = float(value)
        except OverflowError:
            self.fail(field, "is out of range")
        if not math.isfinite(number):
            self.fail(field, f"must be a finite number, not {number}")
        if minimum is not None and number < minimum:
            self.fail(field, f"must be at least {minimum:g}, not {number:g}")
        return number

    def number_or_null(
        self, value: Any, field: str, *, minimum: float | None = None
    ) -> float | None:
        return None if value is None else self.number(value, field, minimum=minimum)

    def integer(self, value: Any, field: str, *, minimum: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(field, f"must be a whole number, not {_kind(value)}")
        if minimum is not None and value < minimum:
            self.fail(field, f"must be at least {minimum}, not {value}")
        return value

    def text(self, value: Any, field: str) -> str:
        if not isinstance(value, str):
            self.fail(field, f"must be a string, not {_kind(value)}")
        return value

    def texts(self, value: Any, field: str) -> list[str]:
        return [self.text(v, f"{field}[{k}]") for k, v in enumerate(self.array(value, field))]

    # keyed forms: parent[key] at path ``at`` (optional ones give None when missing or null)

    def get_obj(
        self, parent: dict[str, Any], key: str, at: str = "", *, required: bool = True
    ) -> dict[str, Any] | None:
        v = self.value(parent, key, at, required=required)
        if v is _MISSING or (v is None and not required):
            return None
        return self.obj(v, f"{at}.{key}" if at else key)

    def get_number(
        self,
        parent: dict[str, Any],
        key: str,
        at: str = "",
        *,
        required: bool = True,
        null: bool = False,
        minimum: float | None = None,
    ) -> float | None:
        v = self.value(parent, key, at, required=required)
        if v is _MISSING or (v is None and (null or not required)):
            return None
        return self.number(v, f"{at}.{key}" if at else key, minimum=minimum)

    def get_text(
        self, parent: dict[str, Any], key: str, at: str = "", *, required: bool = True
    ) -> str | None:
        v = self.value(parent, key, at, required=required)
        if v is _MISSING or (v is None and not required):
            return None
        return self.text(v, f"{at}.{key}" if at else key)

    def vector(
        self, value: Any, field: str, size: int, *, null: bool = False
    ) -> list[float | None]:
        items = self.array(value, field)
        if len(items) != size:
            self.fail(field, f"must hold {size} numbers, not {len(items)}")
        if null:
            return [self.number_or_null(v, f"{field}[{k}]") for k, v in enumerate(items)]
        return [self.number(v, f"{field}[{k}]") for k, v in enumerate(items)]


@dataclass(frozen=True)
class Parameter:
    """One shown parameter: ``name`` (``theta``, ``d``, ``beta``, ``a``, ``alpha`` or ``scale``
    for a fitted encoder scale), its value and σ in SI units (σ None where unknown or fixed),
    why it is held when it is (``fixed``), and measured − nominal (SI) when a nominal is given
    and the parameter is measured."""

    name: str
    value: float
    std: float | None
    fixed: str | None
    delta: float | None = None

    @property
    def angular(self) -> bool:
        return self.name in ("theta", "alpha", "beta")


@dataclass(frozen=True)
class ShownRow:
    """A row of the table as the result shows it: ``form`` ``dh`` (θ, d, a, α) or ``hayati``
    (θ, β, a, α: ``Rz(θ) Tx(a) Rx(α) Ry(β)``)."""

    joint: int
    name: str
    type: str
    form: str
    parameters: list[Parameter]


@dataclass(frozen=True)
class Stats:
    """Error statistics of one model at held-out poses (m)."""

    mean: float
    rms: float
    p95: float
    max: float
    n_poses: int


@dataclass(frozen=True)
class Check:
    """One held-out check of ``validation.holdout``, with its per-pose error lengths (m) from
    ``<stem>.holdout.csv`` when that file is beside the result."""

    label: str
    n_poses: int
    nominal: Stats | None
    calibrated: Stats
    notes: list[str]
    nominal_errors: list[float] | None = None
    calibrated_errors: list[float] | None = None


@dataclass(frozen=True)
class JointResidual:
    """A joint's residual summary (m): its own fit (``joints[].fit``) and the FK of the table
    at its samples (``joints[].validation``); ``error`` when it was not identified."""

    joint: int
    name: str
    fit_rms: float | None
    fit_points: int | None
    fk_rms: float | None
    fk_max: float | None
    fk_points: int | None
    error: str | None


@dataclass(frozen=True)
class Triple:
    """A shown 3-vector (tool point, frame 1's origin or rotation) in SI units with its σ
    (None: unknown or fixed) and its fixed coordinates (``x``, ``y``, ``z``) and why."""

    label: str
    values: list[float]
    stds: list[float | None]
    fixed: list[str] = field(default_factory=list)
    reason: str = ""


@dataclass(frozen=True)
class LogCheck:
    """The log the result names: where it was looked for, where it was found (None: not
    found) and its SHA-256 there."""

    name: str
    recorded_sha256: str
    path: Path | None
    sha256: str | None
    searched: tuple[Path, ...]


@dataclass(frozen=True)
class Sources:
    """Everything a certificate is made from, read by :func:`load_sources`: the result document
    (untrusted, checked by :func:`certificate_html`), the result file's own SHA-256 and time,
    the log's check, and the held-out CSV's text (None when it is not beside the result)."""

    result_path: Path
    document: Any
    result_sha256: str
    result_modified: datetime
    log: LogCheck
    holdout_path: Path
    holdout_text: str | None

    @property
    def inputs(self) -> list[Path]:
        """Every file read, so that an output may refuse to replace one."""
        found = [self.result_path]
        if self.log.path is not None:
            found.append(self.log.path)
        if self.holdout_text is not None:
            found.append(self.holdout_path)
        return found


@dataclass(frozen=True)
class Nominal:
    """The nominal table given to ``dhlog report`` (the result JSON does not record it) and the
    name it was given by."""

    name: str
    table: StandardDH


def _stem(path: Path) -> str:
    name = path.name
    for suffix in (".dh.json", ".json"):
        if name.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)]
    return path.stem


def holdout_csv_path(result_path: Path) -> Path:
    """``<stem>.holdout.csv`` beside ``<stem>.dh.json``."""
    return result_path.with_name(f"{_stem(result_path)}.holdout.csv")


def _sha256_of(path: Path) -> str:
    from dhlog.io.writer import sha256_of

    return sha256_of(path)


def load_sources(result_path: Path, *, log: Path | None = None) -> Sources:
    """Read ``result_path`` (JSON, not yet checked), its SHA-256 and modification time; the log
    it names (``source.path``): ``log`` when given, else looked for beside the result and in
    the current folder, hashed where found; and ``<stem>.holdout.csv`` beside it."""
    name = str(result_path)
    try:
        with open(result_path, "rb") as f:
            data = f.read(MAX_RESULT_BYTES + 1)
        modified = datetime.fromtimestamp(result_path.stat().st_mtime, tz=UTC)
    except OSError as exc:
        raise InputError(
            f"{name}: cannot be read ({exc.strerror or exc}); give the <stem>.dh.json that "
            "dhlog process wrote."
        ) from None
    if len(data) > MAX_RESULT_BYTES:
        raise ResultFileError(name, "the file", f"is larger than {MAX_RESULT_BYTES >> 20} MiB")
    try:
        document = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ResultFileError(name, "the file", f"is not UTF-8 text (byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise ResultFileError(
            name, "the file", f"is not valid JSON ({exc.msg} at line {exc.lineno})"
        ) from None
    except ValueError as exc:  # an integer beyond Python's digit limit
        raise ResultFileError(name, "the file", f"is not valid JSON ({exc})") from None
    except RecursionError:
        raise ResultFileError(name, "the file", "nests too deeply to be a result") from None
    source = document.get("source") if isinstance(document, dict) else None
    log_name = source.get("path") if isinstance(source, dict) else None
    recorded = source.get("sha256") if isinstance(source, dict) else None
    log_check = _find_log(
        result_path,
        log_name if isinstance(log_name, str) else "",
        recorded if isinstance(recorded, str) else "",
        log,
    )
    csv_path = holdout_csv_path(result_path)
    holdout_text = None
    if csv_path.is_file():
        try:
            holdout_text = csv_path.read_bytes().decode("utf-8")
        except OSError as exc:
            raise InputError(f"{csv_path}: cannot be read ({exc.strerror or exc}).") from None
        except UnicodeDecodeError as exc:
            raise ResultFileError(
                str(csv_path), "the file", f"is not UTF-8 text (byte {exc.start})", CSV_REMEDY
            ) from None
    return Sources(
        result_path,
        document,
        hashlib.sha256(data).hexdigest(),
        modified,
        log_check,
        csv_path,
        holdout_text,
    )


def _is_log(path: Path) -> bool:
    """A file, or a folder (a rosbag2 bag): never a device, a pipe or a socket."""
    try:
        return path.is_file() or path.is_dir()
    except (OSError, ValueError):
        return False


def _find_log(result_path: Path, name: str, recorded: str, given: Path | None) -> LogCheck:
    """The log: ``given``, else the file ``name`` (its last part only: ``process`` records the
    name alone, and the JSON is untrusted) beside the result or in the current folder."""
    if given is not None:
        if not _is_log(given):
            raise InputError(f"{given}: no such log; give the log the result was computed from.")
        try:
            return LogCheck(name, recorded, given, _sha256_of(given), (given,))
        except OSError as exc:
            raise InputError(f"{given}: cannot be read ({exc.strerror or exc}).") from None
    base = Path(name.replace("\\", "/")).name if "\x00" not in name else ""
    if base in ("", ".", ".."):
        return LogCheck(name, recorded, None, None, ())
    searched = tuple(dict.fromkeys((result_path.parent / base, Path.cwd() / base)))
    for candidate in searched:
        if _is_log(candidate):
            try:
                return LogCheck(name, recorded, candidate, _sha256_of(candidate), searched)
            except OSError:
                continue
    return LogCheck(name, recorded, None, None, searched)


# ---------------------------------------------------------------------------------------------
# the document, checked


@dataclass(frozen=True)
class _Result:
    """What the certificate shows of a result document, every field checked."""

    version: str
    log_name: str
    log_sha256: str
    pipeline: str
    method: str | None
    n_joints: int
    joint_names: list[str]
    joint_types: list[str | None]
    reference_pose: list[float]
    rows: list[ShownRow]
    checks: list[Check]
    fk_rms: float | None
    fk_max: float | None
    fk_points: int
    residuals: list[JointResidual]
    warnings: list[str]
    notes: list[str]
    measurement: list[tuple[str, str]]
    tool: list[Triple]
    nongeometric: dict[str, Any] | None


def _reasons(fixed: list[str], reason: str) -> dict[str, str]:
    """``fixed_reason`` (``"theta: why; d: why"``) split per parameter; a reason in another
    form is every fixed parameter's."""
    parts = re.split(r"(?:^|; )(theta|d|beta|a|alpha|scale): ", reason)
    found: dict[str, str] = {}
    if len(parts) > 1 and not parts[0]:
        for name, why in zip(parts[1::2], parts[2::2], strict=True):
            found[name] = why.strip()
    return {name: found.get(name) or reason or "held by a convention" for name in fixed}


def _rows(f: _Fields, doc: dict[str, Any], names: list[str]) -> list[ShownRow]:
    """The table as shown: ``hayati_dh.rows`` when present, else ``standard_dh``."""
    standard = f.array(f.value(doc, "standard_dh", "", required=True), "standard_dh")
    if len(standard) > len(names):
        f.fail("standard_dh", f"has {len(standard)} rows for {len(names)} joints")
    block = f.get_obj(doc, "hayati_dh", required=False)
    at = "hayati_dh.rows" if block is not None else "standard_dh"
    shown = standard
    if block is not None:
        shown = f.array(f.value(block, "rows", "hayati_dh", required=True), at)
        if len(shown) != len(standard):
            f.fail(at, f"has {len(shown)} rows, standard_dh {len(standard)}")
    out = []
    for i, item in enumerate(shown):
        where = f"{at}[{i}]"
        row = f.obj(item, where)
        plain = f.obj(standard[i], f"standard_dh[{i}]")
        form = "dh"
        if block is not None:
            form = f.get_text(row, "form", where) or "dh"
            if form not in ("dh", "hayati"):
                f.fail(f"{where}.form", f"must be dh or hayati, not {form[:40]!r}")
        kind = f.get_text(row, "type", where, required=False) or "revolute"
        if kind not in ("revolute", "prismatic"):
            f.fail(f"{where}.type", f"must be revolute or prismatic, not {kind[:40]!r}")
        second = "beta" if form == "hayati" else "d"
        keys = ("theta_offset", "beta" if form == "hayati" else "d_offset", "a", "alpha")
        names4 = ("theta", second, "a", "alpha")
        std = f.get_obj(row, "std", where)
        assert std is not None
        fixed_list = []
        if "fixed" in row and row["fixed"] is not None:
            fixed_list = f.texts(row["fixed"], f"{where}.fixed")
            for k, name in enumerate(fixed_list):
                if name not in names4:
                    f.fail(f"{where}.fixed[{k}]", f"names {name[:40]!r}, not one of {names4}")
        reason = f.get_text(row, "fixed_reason", where, required=False) or ""
        held = _reasons(fixed_list, reason)
        params = []
        for key, name in zip(keys, names4, strict=True):
            value = f.get_number(row, key, where)
            assert value is not None
            sd = f.get_number(std, name, f"{where}.std", null=True, minimum=0.0)
            params.append(Parameter(name, value, None if name in held else sd, held.get(name)))
        if "encoder_scale" in plain:
            scale = f.get_number(plain, "encoder_scale", f"standard_dh[{i}]")
            sd = f.get_number(
                plain, "encoder_scale_std", f"standard_dh[{i}]", required=False, minimum=0.0
            )
            assert scale is not None
            params.append(Parameter("scale", scale, sd, None))
        out.append(ShownRow(i + 1, names[i], kind, form, params))
    return out


def _stats(f: _Fields, parent: dict[str, Any], key: str, at: str) -> Stats | None:
    block = f.get_obj(parent, key, at, required=key == "calibrated")
    if block is None:
        return None
    where = f"{at}.{key}"
    values = [f.get_number(block, k, where, minimum=0.0) for k in ("mean", "rms", "p95", "max")]
    n = f.integer(f.value(block, "n_poses", where, required=True), f"{where}.n_poses", minimum=1)
    mean, rms, p95, top = (float(v or 0.0) for v in values)
    return Stats(mean, rms, p95, top, n)


def _calibrated(f: _Fields, entry: dict[str, Any], at: str) -> Stats:
    stats = _stats(f, entry, "calibrated", at)
    assert stats is not None  # required
    return stats


def _checks(f: _Fields, validation: dict[str, Any]) -> list[Check]:
    raw = validation.get("holdout")
    if raw is None:
        return []
    out = []
    for k, item in enumerate(f.array(raw, "validation.holdout")):
        at = f"validation.holdout[{k}]"
        entry = f.obj(item, at)
        kind = f.get_text(entry, "kind", at)
        n = f.integer(f.value(entry, "n_poses", at, required=True), f"{at}.n_poses", minimum=1)
        if kind == "cross-validation":
            folds = f.value(entry, "folds", at, required=False)
            label = "cross-validation"
            if folds is not _MISSING and folds is not None:
                label = f"{f.integer(folds, f'{at}.folds', minimum=2)}-fold cross-validation"
        elif kind == "log":
            path = f.get_text(entry, "path", at, required=False) or "another log"
            label = f"log {Path(path).name}"
            if entry.get("registered") is True:
                label += " (tracker moved: base placed again)"
        else:
            f.fail(f"{at}.kind", f"must be cross-validation or log, not {str(kind)[:40]!r}")
        notes = entry.get("notes")
        out.append(
            Check(
                label,
                n,
                _stats(f, entry, "nominal", at),
                _calibrated(f, entry, at),
                [] if notes is None else f.texts(notes, f"{at}.notes"),
            )
        )
    return out


def _residuals(f: _Fields, joints: list[dict[str, Any]]) -> list[JointResidual]:
    out = []
    for i, j in enumerate(joints):
        at = f"joints[{i}]"
        fit = f.get_obj(j, "fit", at, required=False)
        fit_rms = fit_points = None
        if fit is not None:
            fit_rms = f.get_number(fit, "rms", f"{at}.fit", null=True, minimum=0.0)
            points = f.value(fit, "n_points", f"{at}.fit", required=False)
            if points is not _MISSING and points is not None:
                fit_points = f.integer(points, f"{at}.fit.n_points", minimum=0)
        val = f.get_obj(j, "validation", at, required=False)
        fk_rms = fk_max = fk_points = None
        if val is not None:
            fk_rms = f.get_number(val, "fk_rms", f"{at}.validation", null=True, minimum=0.0)
            fk_max = f.get_number(val, "fk_max", f"{at}.validation", null=True, minimum=0.0)
            points = f.value(val, "n_points", f"{at}.validation", required=False)
            if points is not _MISSING and points is not None:
                fk_points = f.integer(points, f"{at}.validation.n_points", minimum=0)
        error = f.get_text(j, "error", at, required=False)
        name = f.get_text(j, "name", at) or f"joint_{i + 1}"
        out.append(
            JointResidual(i + 1, name, fit_rms, fit_points, fk_rms, fk_max, fk_points, error)
        )
    return out


def _mm(value: float) -> str:
    return f"{value * 1e3:.4f} mm"


def _measurement(f: _Fields, doc: dict[str, Any]) -> list[tuple[str, str]]:
    """The tracker, noise model, clock and fit facts the result records, as (label, text)."""
    lines: list[tuple[str, str]] = []
    noise = f.get_obj(doc, "noise", required=False)
    if noise is not None:
        model = f.get_text(noise, "model", "noise")
        assert model is not None
        if model == "tracker":
            radial = f.get_number(noise, "radial", "noise", required=False, minimum=0.0)
            transverse = f.get_number(noise, "transverse", "noise", required=False, minimum=0.0)
            per_m = f.get_number(noise, "transverse_per_m", "noise", required=False, minimum=0.0)
            parts = ["laser tracker specification"]
            if radial is not None:
                parts.append(f"radial σ {radial * 1e6:.3g} µm")
            if transverse is not None:
                grow = f" + {per_m * 1e6:.3g} µm/m" if per_m is not None else ""
                parts.append(f"transverse σ {transverse * 1e6:.3g} µm{grow}")
            station = noise.get("station")
            if station is not None:
                s = f.vector(station, "noise.station", 3)
                parts.append("station at (" + ", ".join(f"{v or 0.0:.4f}" for v in s) + ") m")
            lines.append(("Noise model", ", ".join(parts)))
        elif model == "per-sample":
            lines.append(
                ("Noise model", "per-sample covariance carried by the log (e.g. the export's U95)")
            )
        elif model == "isotropic":
            sigma = f.get_number(noise, "sigma", "noise", required=False, null=True, minimum=0.0)
            shown = "" if sigma is None else f", σ {_mm(sigma)} per coordinate"
            source = f.get_text(noise, "sigma_source", "noise", required=False)
            lines.append(("Noise model", f"isotropic{shown}" + (f" ({source})" if source else "")))
        else:
            f.fail("noise.model", f"must be isotropic, tracker or per-sample, not {model[:40]!r}")
        err = f.get_number(noise, "model_error_sigma", "noise", required=False, minimum=0.0)
        if err is not None:
            lines.append(
                (
                    "Model-error σ",
                    f"{_mm(err)} per coordinate, estimated and added to every sample's "
                    "declared uncertainty (what the model leaves beyond the tracker)",
                )
            )
        chi2 = f.get_number(noise, "chi2_dof", "noise", required=False, minimum=0.0)
        if chi2 is not None:
            lines.append(("χ²/dof", f"{chi2:.3f}"))
    whole = f.get_obj(doc, "whole_fit", required=False)
    if whole is not None:
        n = f.value(whole, "n_points", "whole_fit", required=False)
        out_ = f.value(whole, "n_outliers", "whole_fit", required=False)
        if n is not _MISSING and n is not None:
            text = f"{f.integer(n, 'whole_fit.n_points', minimum=0)} samples"
            if out_ is not _MISSING and out_ is not None:
                text += (
                    f", {f.integer(out_, 'whole_fit.n_outliers', minimum=0)} held out as outliers"
                )
            lines.append(("Samples fitted", text))
        rot = f.get_number(whole, "sigma_rotation", "whole_fit", required=False, minimum=0.0)
        if rot is not None:
            lines.append(("Orientation σ", f"{math.degrees(rot):.5f}° (6-DoF target)"))
        ident = f.get_obj(whole, "identifiability", "whole_fit", required=False)
        if ident is not None:
            cond = f.get_number(
                ident, "condition_number", "whole_fit.identifiability", required=False, null=True
            )
            if cond is not None:
                lines.append(("Condition number", f"{cond:.4g} (scaled Jacobian of the fit)"))
    timing = f.get_obj(doc, "timing", required=False)
    if timing is not None:
        offset = f.get_number(timing, "clock_offset", "timing")
        sd = f.get_number(timing, "std", "timing", null=True, required=False, minimum=0.0)
        source = f.get_text(timing, "source", "timing", required=False) or "?"
        reason = f.get_text(timing, "reason", "timing", required=False)
        text = f"joint-state stamps {float(offset or 0.0) * 1e3:+.4f} ms"
        if sd is not None:
            text += f" ± {sd * 1e3:.4f} ms"
        text += f" onto the tracker's clock ({source}" + (f": {reason})" if reason else ")")
        lines.append(("Clock offset", text))
    base = f.get_obj(doc, "base", required=False)
    if base is not None:
        origin = f.get_text(base, "frame_1_origin", "base", required=False)
        if origin:
            lines.append(("Frame 1 origin", origin))
    seg = f.get_obj(doc, "segmentation", required=False)
    if seg is not None:
        aside = f.get_obj(seg, "set_aside", "segmentation", required=False)
        if aside:
            counts = [
                f"{str(k)[:40]} {f.integer(v, f'segmentation.set_aside.{str(k)[:40]}', minimum=0)}"
                for k, v in aside.items()
            ]
            lines.append(("Set aside", ", ".join(counts)))
    return lines


def _unknown() -> list[float | None]:
    return [None, None, None]


def _tool(f: _Fields, doc: dict[str, Any], n_rows: int) -> list[Triple]:
    """(label, x y z in SI, σ, fixed coordinates) for the tool point(s) and frame 1 in M."""
    out: list[Triple] = []
    tool = f.get_obj(doc, "tool", required=False)
    if tool is not None and tool.get("point") is not None:
        point = [v or 0.0 for v in f.vector(tool["point"], "tool.point", 3)]
        std = f.vector(tool["std"], "tool.std", 3, null=True) if "std" in tool else _unknown()
        fixed = f.texts(tool["fixed"], "tool.fixed") if tool.get("fixed") is not None else []
        why = f.get_text(tool, "fixed_reason", "tool", required=False) or ""
        out.append(Triple(f"tool point in frame {n_rows + 1} [mm]", point, std, fixed, why))
        extra = tool.get("further_targets")
        for k, item in enumerate([] if extra is None else f.array(extra, "tool.further_targets")):
            at = f"tool.further_targets[{k}]"
            t = f.obj(item, at)
            p = [
                v or 0.0 for v in f.vector(f.value(t, "point", at, required=True), f"{at}.point", 3)
            ]
            sd = f.vector(f.value(t, "std", at, required=True), f"{at}.std", 3, null=True)
            out.append(Triple(f"target {k + 2} in frame {n_rows + 1} [mm]", p, sd))
    base = f.get_obj(doc, "base", required=False)
    if base is not None and base.get("T_measurement_base") is not None:
        rows = f.array(base["T_measurement_base"], "base.T_measurement_base")
        if len(rows) != 4:
            f.fail("base.T_measurement_base", "must be a 4×4 matrix")
        T = [
            [v or 0.0 for v in f.vector(r, f"base.T_measurement_base[{k}]", 4)]
            for k, r in enumerate(rows)
        ]
        base_std = f.get_obj(base, "std", "base", required=False) or {}
        tr = base_std.get("translation")
        rot = base_std.get("rotation")
        t_std = _unknown() if tr is None else f.vector(tr, "base.std.translation", 3, null=True)
        r_std = _unknown() if rot is None else f.vector(rot, "base.std.rotation", 3, null=True)
        out.append(Triple("frame 1 origin in M [mm]", [T[0][3], T[1][3], T[2][3]], t_std))
        rpy = list(roll_pitch_yaw(np.array([r[:3] for r in T[:3]])))
        out.append(Triple("frame 1 rotation in M [°] (roll, pitch, yaw)", rpy, r_std))
    return out


def _nongeometric(f: _Fields, doc: dict[str, Any]) -> dict[str, Any] | None:
    """The ``nongeometric`` block's selection and terms, checked (SI as in the JSON)."""
    block = f.get_obj(doc, "nongeometric", required=False)
    if block is None:
        return None
    at = "nongeometric"
    out: dict[str, Any] = {"mode": None, "chosen": None, "candidates": [], "terms": []}
    sel = f.get_obj(block, "selection", at, required=False)
    if sel is not None:
        out["mode"] = f.get_text(sel, "mode", f"{at}.selection", required=False)
        out["chosen"] = f.get_text(sel, "chosen", f"{at}.selection", required=False)
        cands = sel.get("candidates")
        for k, item in enumerate(
            [] if cands is None else f.array(cands, f"{at}.selection.candidates")
        ):
            w = f"{at}.selection.candidates[{k}]"
            c = f.obj(item, w)
            out["candidates"].append(
                {
                    "model": f.get_text(c, "model", w),
                    "parameters": f.integer(
                        f.value(c, "parameters", w, required=True), f"{w}.parameters", minimum=0
                    ),
                    "bic": f.get_number(c, "bic", w, required=False, null=True),
                    "holdout_rms": f.get_number(
                        c, "holdout_rms", w, required=False, null=True, minimum=0.0
                    ),
                    "range_sd": f.get_number(
                        c, "range_sd", w, required=False, null=True, minimum=0.0
                    ),
                    "chosen": c.get("chosen") is True,
                    "why": f.get_text(c, "why", w, required=False) or "",
                }
            )
    lumps = block.get("lumps")
    lump_names = []
    for k, item in enumerate([] if lumps is None else f.array(lumps, f"{at}.lumps")):
        lump = f.obj(item, f"{at}.lumps[{k}]")
        lump_names.append(f.get_text(lump, "on", f"{at}.lumps[{k}]") or "")
    terms = block.get("terms")
    for k, item in enumerate([] if terms is None else f.array(terms, f"{at}.terms")):
        w = f"{at}.terms[{k}]"
        t = f.obj(item, w)
        lump_at = t.get("lump")
        lump_name = ""
        if lump_at is not None:
            index = f.integer(lump_at, f"{w}.lump", minimum=0)
            if index >= len(lump_names):
                f.fail(f"{w}.lump", f"is {index}; there are {len(lump_names)} lumps")
            lump_name = lump_names[index]
        out["terms"].append(
            {
                "name": f.get_text(t, "name", w),
                "kind": f.get_text(t, "kind", w),
                "joint": f.integer(f.value(t, "joint", w, required=True), f"{w}.joint", minimum=1),
                "lump": lump_name,
                "value": f.get_number(t, "value", w),
                "std": f.get_number(t, "std", w, null=True, minimum=0.0),
                "unit": f.get_text(t, "unit", w),
            }
        )
    deflection = block.get("max_deflection")
    out["max_deflection"] = (
        None
        if deflection is None
        else [
            f.number(v, f"{at}.max_deflection[{k}]")
            for k, v in enumerate(f.array(deflection, f"{at}.max_deflection"))
        ]
    )
    out["max_target_displacement"] = f.get_number(
        block, "max_target_displacement", at, required=False, null=True, minimum=0.0
    )
    return out


def read_result(document: Any, path: str) -> _Result:
    """The result document checked field by field (a :class:`ResultFileError` names the first
    one at fault)."""
    f = _Fields(path)
    doc = f.obj(document, "the document")
    fmt = f.get_text(doc, "format")
    if fmt != RESULT_FORMAT:
        f.fail("format", f"is {str(fmt)[:40]!r}, not {RESULT_FORMAT!r}")
    version = f.get_text(doc, "dhlog_version") or "?"
    source = f.get_obj(doc, "source")
    assert source is not None
    log_name = f.get_text(source, "path", "source") or ""
    sha = f.get_text(source, "sha256", "source") or ""
    if sha and not re.fullmatch(r"[0-9a-f]{64}", sha):
        f.fail("source.sha256", "must be 64 lowercase hexadecimal digits or empty")
    pipeline = f.get_text(source, "pipeline", "source") or ""
    units = f.get_obj(doc, "units")
    assert units is not None
    if units.get("length") != "m" or units.get("angle") != "rad":
        f.fail("units", 'must be {"length": "m", "angle": "rad"} (the result contract)')
    joints = [
        f.obj(j, f"joints[{i}]")
        for i, j in enumerate(f.array(f.value(doc, "joints", "", required=True), "joints"))
    ]
    if not joints:
        f.fail("joints", "is empty")
    names = [f.get_text(j, "name", f"joints[{i}]") or "" for i, j in enumerate(joints)]
    types: list[str | None] = []
    for i, j in enumerate(joints):
        kind = f.get_text(j, "type", f"joints[{i}]", required=False)
        if kind not in (None, "revolute", "prismatic"):
            f.fail(f"joints[{i}].type", f"must be revolute, prismatic or null, not {kind[:40]!r}")
        types.append(kind)
    ref = f.array(f.value(doc, "reference_pose", "", required=True), "reference_pose")
    if len(ref) != len(joints):
        f.fail("reference_pose", f"has {len(ref)} values for {len(joints)} joints")
    reference = [f.number(v, f"reference_pose[{k}]") for k, v in enumerate(ref)]
    rows = _rows(f, doc, names)
    validation = f.get_obj(doc, "validation")
    assert validation is not None
    fk_rms = f.get_number(validation, "fk_rms", "validation", null=True, minimum=0.0)
    fk_max = f.get_number(validation, "fk_max", "validation", null=True, minimum=0.0)
    fk_points = f.integer(
        f.value(validation, "n_points", "validation", required=True),
        "validation.n_points",
        minimum=0,
    )
    warnings = f.texts(f.value(doc, "warnings", "", required=True), "warnings")
    notes_raw = doc.get("notes")
    notes = [] if notes_raw is None else f.texts(notes_raw, "notes")
    method = f.get_text(doc, "method", required=False)
    return _Result(
        version,
        log_name,
        sha,
        pipeline,
        method,
        len(joints),
        names,
        types,
        reference,
        rows,
        _checks(f, validation),
        fk_rms,
        fk_max,
        fk_points,
        _residuals(f, joints),
        warnings,
        notes,
        _measurement(f, doc),
        _tool(f, doc, len(rows)),
        _nongeometric(f, doc),
    )


# ---------------------------------------------------------------------------------------------
# the held-out CSV, untrusted


def read_holdout_csv(text: str, path: str, checks: list[Check]) -> list[Check]:
    """``checks`` with their per-pose errors from ``<stem>.holdout.csv`` (``result.holdout_csv``:
    one row per scored pose, the checks in the JSON's order); a file that does not agree with
    the JSON (another run's) is an error naming it."""
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise ResultFileError(path, "the header", "is missing", CSV_REMEDY)
    header = rows[0]
    unit = None
    for scale, suffix in ((1e-3, "mm"), (1.0, "m")):
        if f"calibrated_error_{suffix}" in header:
            unit = (scale, suffix)
    if unit is None or "check" not in header or "pose" not in header:
        raise ResultFileError(
            path,
            "the header",
            "lacks the columns check, pose and calibrated_error_mm (or _m)",
            CSV_REMEDY,
        )
    scale, suffix = unit
    col = {name: k for k, name in enumerate(header)}
    nominal_col = col.get(f"nominal_error_{suffix}")
    groups: list[tuple[str, list[float | None], list[float]]] = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise ResultFileError(
                path, f"line {line}", f"has {len(row)} cells, the header {len(header)}", CSV_REMEDY
            )
        try:
            pose = int(row[col["pose"]])
        except ValueError:
            raise ResultFileError(
                path, f"line {line}, column pose", "must be a whole number", CSV_REMEDY
            ) from None
        cal = _csv_length(row[col[f"calibrated_error_{suffix}"]], path, line, "calibrated_error")
        if cal is None:
            raise ResultFileError(
                path, f"line {line}, column calibrated_error_{suffix}", "is empty", CSV_REMEDY
            )
        nom = (
            None
            if nominal_col is None
            else _csv_length(row[nominal_col], path, line, "nominal_error")
        )
        name = row[col["check"]]
        if pose == 1 or not groups or groups[-1][0] != name:
            groups.append((name, [], []))
        groups[-1][1].append(None if nom is None else nom * scale)
        groups[-1][2].append(cal * scale)
    if len(groups) != len(checks):
        raise ResultFileError(
            path,
            "the rows",
            f"hold {len(groups)} check(s), the result's validation.holdout {len(checks)}: the "
            "file is from another run",
            CSV_REMEDY,
        )
    out = []
    for k, (check, (_, nominal, calibrated)) in enumerate(zip(checks, groups, strict=True)):
        rms = math.sqrt(sum(v * v for v in calibrated) / len(calibrated))
        if len(calibrated) != check.calibrated.n_poses or not math.isclose(
            rms, check.calibrated.rms, rel_tol=1e-5, abs_tol=1e-12
        ):
            raise ResultFileError(
                path,
                f"check {k + 1}",
                f"has {len(calibrated)} poses of RMS {_mm(rms)}, the result "
                f"{check.calibrated.n_poses} of RMS {_mm(check.calibrated.rms)}: the file is "
                "from another run",
                CSV_REMEDY,
            )
        given = [v for v in nominal if v is not None]
        nominal_errors = given if check.nominal is not None and len(given) == len(nominal) else None
        out.append(
            Check(
                check.label,
                check.n_poses,
                check.nominal,
                check.calibrated,
                check.notes,
                nominal_errors,
                calibrated,
            )
        )
    return out


def _csv_length(cell: str, path: str, line: int, column: str) -> float | None:
    if not cell.strip():
        return None
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise ResultFileError(
            path,
            f"line {line}, column {column}",
            f"must be a length ≥ 0, not {cell[:40]!r}",
            CSV_REMEDY,
        )
    return value


# ---------------------------------------------------------------------------------------------
# measured − nominal


def nominal_deltas(
    rows: list[ShownRow], nominal: StandardDH, reference_pose: Sequence[float]
) -> list[ShownRow]:
    """``rows`` with measured − nominal on every measured parameter (SI, angles wrapped); the
    nominal is put in the rows' form first (its rows of nearly parallel pairs in the
    Hayati–Mirmirani form, as ``dhlog process`` does); rows whose nominal has no such form get
    none."""
    from dhlog.geometry._checks import wrap_angle
    from dhlog.identify.extract import table_in_hayati_form

    hayati = frozenset(r.joint - 1 for r in rows if r.form == "hayati")
    table = nominal
    skip: set[int] = set()
    if hayati:
        try:
            table = table_in_hayati_form(
                nominal, np.asarray(reference_pose, dtype=np.float64), hayati
            )
        except DhlogError:
            table = nominal
            skip = set(hayati) | {i + 1 for i in hayati}
    flags = getattr(table, "hayati", (False,) * table.n)
    beta = getattr(table, "beta", np.zeros(table.n))
    out = []
    for i, row in enumerate(rows):
        if row.type != table.joint_types[i].value or (row.form == "hayati") != bool(flags[i]):
            skip.add(i)
        nom = {
            "theta": float(table.theta_offset[i]),
            "d": float(table.d_offset[i]),
            "beta": float(beta[i]),
            "a": float(table.a[i]),
            "alpha": float(table.alpha[i]),
        }
        params = []
        for p in row.parameters:
            delta = None
            if p.fixed is None and p.name in nom and i not in skip:
                delta = p.value - nom[p.name]
                if p.angular:
                    delta = wrap_angle(delta)
            params.append(Parameter(p.name, p.value, p.std, p.fixed, delta))
        out.append(ShownRow(row.joint, row.name, row.type, row.form, params))
    return out


# ---------------------------------------------------------------------------------------------
# plots (matplotlib, imported here only)


def _figure(width: float, height: float) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    return fig


def _style(ax: Any) -> None:
    ax.spines[["top", "right"]].set_visible(False)
    ax.tick_params(labelsize=8)
    ax.grid(axis="y", color="#e4e7eb", linewidth=0.6)
    ax.set_axisbelow(True)


def _svg(fig: Figure, prefix: str, label: str) -> str:
    """``fig`` as inline SVG: text as paths (no fonts needed), no XML prolog, comments or
    metadata, every id prefixed (several plots share one page), scaled to its container."""
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "path", "svg.hashsalt": "dhlog"}):
        fig.savefig(
            buf,
            format="svg",
            metadata={"Date": None, "Creator": None, "Format": None, "Type": None},
        )
    text = buf.getvalue()
    text = text[text.index("<svg") :]
    text = re.sub(r"<!--.*?-->", "", text, flags=re.DOTALL)
    text = re.sub(r"<metadata>.*?</metadata>", "", text, flags=re.DOTALL)
    text = re.sub(r'\bid="([^"]+)"', rf'id="{prefix}-\1"', text)
    text = re.sub(r"url\(#([^)]+)\)", rf"url(#{prefix}-\1)", text)
    text = re.sub(r'href="#([^"]+)"', rf'href="#{prefix}-\1"', text)
    text = re.sub(
        r'<svg ([^>]*?)width="[^"]*" height="[^"]*"',
        rf'<svg \1class="plot" role="img" aria-label="{_e(label)}"',
        text,
        count=1,
    )
    return re.sub(r"\n\s*", "\n", text).strip()


def histogram_svg(check: Check, in_sample_rms: float | None, prefix: str) -> str | None:
    """Per-pose held-out errors of the nominal and the calibrated model (log-spaced bins), the
    in-sample FK RMS as a dashed line; None without per-pose errors."""
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    if check.calibrated_errors is None:
        return None
    cal = np.asarray(check.calibrated_errors) * 1e3
    nom = None if check.nominal_errors is None else np.asarray(check.nominal_errors) * 1e3
    values = np.concatenate([cal, nom]) if nom is not None else cal
    positive = values[values > 0]
    if positive.size == 0:
        return None
    lo, hi = float(positive.min()) / 1.3, float(positive.max()) * 1.3
    bins = np.geomspace(lo, hi, 36).tolist()
    fig = _figure(10.6, 3.0)
    ax = fig.add_subplot()
    if nom is not None:
        ax.hist(np.maximum(nom, lo), bins, color=NOMINAL_COLOUR, alpha=0.8, label="nominal")
    ax.hist(np.maximum(cal, lo), bins, color=CALIBRATED_COLOUR, alpha=0.85, label="calibrated")
    if in_sample_rms is not None and in_sample_rms * 1e3 > lo:
        ax.axvline(
            in_sample_rms * 1e3,
            color=FIT_COLOUR,
            linestyle="--",
            linewidth=1.2,
            label="in-sample FK RMS",
        )
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("3-D error at a held-out pose [mm]", fontsize=9)
    ax.set_ylabel("poses", fontsize=9)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    _style(ax)
    ax.legend(frameon=False, fontsize=8, loc="upper center", ncols=3)
    ax.set_ylim(top=ax.get_ylim()[1] * 1.25)
    return _svg(fig, prefix, f"histogram of the held-out errors, {check.label}")


def residual_bars_svg(residuals: list[JointResidual], prefix: str) -> str | None:
    """Per joint: its own fit's RMS, and the RMS and max of the table's FK at its samples (µm);
    None when the result has none."""
    series = [
        ("fit RMS", [r.fit_rms for r in residuals], "#8fb8de"),
        ("FK RMS", [r.fk_rms for r in residuals], CALIBRATED_COLOUR),
        ("FK max", [r.fk_max for r in residuals], "#1b3a57"),
    ]
    series = [s for s in series if any(v is not None for v in s[1])]
    if not series:
        return None
    x = np.arange(len(residuals), dtype=np.float64)
    width = 0.8 / len(series)
    fig = _figure(10.6, 2.8)
    ax = fig.add_subplot()
    for k, (label, values, colour) in enumerate(series):
        heights = np.array([np.nan if v is None else v * 1e6 for v in values])
        ax.bar(x + (k - (len(series) - 1) / 2) * width, heights, width, color=colour, label=label)
    ax.set_xticks(x, [str(r.joint) for r in residuals])
    ax.set_xlabel("joint", fontsize=9)
    ax.set_ylabel("residual [µm]", fontsize=9)
    _style(ax)
    ax.legend(frameon=False, fontsize=8, loc="upper center", ncols=len(series))
    ax.set_ylim(top=ax.get_ylim()[1] * 1.2)
    return _svg(fig, prefix, "per-joint residuals")


# ---------------------------------------------------------------------------------------------
# the page


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _places(sigma: float | None, base: int) -> int:
    """Decimals that show ``sigma`` to two significant digits (``base`` to ``base + 3``), as
    the console does."""
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return base
    return max(base, min(base + 3, 1 - math.floor(math.log10(sigma))))


def _fixed(value: float, places: int, *, sign: bool = False) -> str:
    text = f"{value:+.{places}f}" if sign else f"{value:.{places}f}"
    if set(text.lstrip("+-")) <= set("0."):
        text = text.lstrip("+-")
        return f"+{text}" if sign else text
    return text


def _display(p: Parameter) -> tuple[float, str, float]:
    """Display factor, unit and the σ beyond which the parameter is undetermined (display
    units)."""
    if p.name == "scale":
        return 1.0, "", math.inf
    if p.angular:
        return 180.0 / math.pi, "°", math.degrees(UNDETERMINED_ANGLE)
    return 1e3, "mm", UNDETERMINED_LENGTH * 1e3


def _parameter_cell(p: Parameter, joint: int, notes: dict[str, list[str]]) -> str:
    """One parameter: its value, ±1σ (or ``fixed`` with the footnote of its reason, or
    ``undetermined``) and measured − nominal, each on its own line; SI values in ``data-*``."""
    factor, unit, undetermined = _display(p)
    base = 6 if p.name == "scale" else 4
    sd = None if p.std is None else p.std * factor
    places = _places(None if p.fixed else sd, base)
    value = _fixed(p.value * factor, places) + (unit if unit == "°" else "")
    if p.name == "beta":
        value = f"β {value}"
    data = f' data-parameter="{p.name}" data-si="{p.value!r}"'
    lines = [f'<span class="v">{value}</span>']
    if p.fixed is not None:
        held = notes.setdefault(p.fixed, [])
        held.append(f"{PARAMETER_SYMBOLS[p.name]}{joint}")
        mark = list(notes).index(p.fixed) + 1
        data += ' data-fixed="true"'
        lines.append(f'<span class="sd held">fixed <sup>{mark}</sup></span>')
    elif sd is None:
        lines.append('<span class="sd">σ unknown</span>')
    elif sd > undetermined:
        lines.append(f'<span class="sd bad">undetermined ± {sd:.3g}</span>')
    else:
        data += f' data-std="{p.std!r}"'
        lines.append(f'<span class="sd">± {_fixed(sd, places)}</span>')
    if p.delta is not None:
        data += f' data-delta="{p.delta!r}"'
        lines.append(f'<span class="dn">Δ {_fixed(p.delta * factor, places, sign=True)}</span>')
    cls = "p held" if p.fixed is not None else "p"
    return f'<td class="{cls}"{data}>{"".join(lines)}</td>'


def _parameter_table(rows: list[ShownRow], nominal: Nominal | None) -> str:
    """The DH table: one row per joint, each parameter's value with ±1σ and measured − nominal
    under it; the reasons of fixed parameters as footnotes."""
    scales = any(p.name == "scale" for r in rows for p in r.parameters)
    heads = ["θ [°]", "d [mm]", "a [mm]", "α [°]"] + (["encoder scale"] if scales else [])
    out = [
        '<table id="parameters" class="grid params"><thead><tr><th class="c">#</th>'
        "<th>Joint</th><th>Form</th>"
        + "".join(f'<th class="num">{h}</th>' for h in heads)
        + "</tr></thead><tbody>"
    ]
    notes: dict[str, list[str]] = {}
    for row in rows:
        form = "Hayati–Mirmirani" if row.form == "hayati" else "DH"
        cells = [_parameter_cell(p, row.joint, notes) for p in row.parameters]
        if scales and len(cells) == 4:
            cells.append("<td></td>")
        out.append(
            f'<tr data-joint="{row.joint}" data-form="{row.form}"><td class="c">{row.joint}</td>'
            f'<td class="jn">{_e(row.name)}<span class="jt">{_e(row.type)}</span></td>'
            f'<td class="form">{form}</td>{"".join(cells)}</tr>'
        )
    out.append("</tbody></table>")
    legend = "Under each value: ±1σ"
    legend += f", then Δ = measured − nominal ({_e(nominal.name)})." if nominal is not None else "."
    if any(r.form == "hayati" for r in rows):
        legend += " On a Hayati–Mirmirani row, β [°] stands in place of d."
    out.append(f'<p class="caption">{legend}</p>')
    if notes:
        out.append('<ol class="footnotes" id="fixed-reasons">')
        for reason, held in notes.items():
            out.append(f"<li>{', '.join(held)} fixed: {_e(reason)}</li>")
        out.append("</ol>")
    return "\n".join(out)


def _kv(items: list[tuple[str, str]], table_id: str) -> str:
    """A key–value table; values are HTML already escaped by the caller."""
    body = "".join(f"<tr><th>{_e(k)}</th><td>{v}</td></tr>" for k, v in items)
    return f'<table class="kv" id="{table_id}">{body}</table>'


def _stat_cells(s: Stats | None) -> str:
    if s is None:
        return '<td class="num" colspan="5">no nominal given to dhlog process</td>'
    return f'<td class="num">{s.n_poses}</td>' + "".join(
        f'<td class="num" data-si="{v!r}">{v * 1e3:.4f}</td>' for v in (s.mean, s.rms, s.p95, s.max)
    )


def _accuracy(result: _Result) -> str:
    if not result.checks:
        fit = (
            f" The in-sample FK RMS, {result.fk_rms * 1e3:.4f} mm over the fitted samples, says "
            "how well the model fits the session, not how well it predicts the robot."
            if result.fk_rms is not None
            else ""
        )
        return (
            '<div class="alert" id="no-holdout"><strong>No held-out validation.</strong> This '
            "result was not checked at poses left out of the fit, so its accuracy on the robot "
            f"is not shown.{_e(fit)} Run <code>dhlog process LOG --holdout 5</code> (or "
            "<code>--validate OTHER_LOG</code>) and report again.</div>"
        )
    parts = [
        '<table class="grid stats" id="holdout"><thead><tr><th>Check</th><th>Model</th>'
        '<th class="num">Poses</th><th class="num">Mean [mm]</th><th class="num">RMS [mm]</th>'
        '<th class="num">95 % [mm]</th><th class="num">Max [mm]</th></tr></thead><tbody>'
    ]
    for check in result.checks:
        parts.append(
            f'<tr class="nominal"><th rowspan="2">{_e(check.label)}</th><td>nominal</td>'
            f"{_stat_cells(check.nominal)}</tr>"
        )
        parts.append(
            f'<tr class="calibrated"><td>calibrated</td>{_stat_cells(check.calibrated)}</tr>'
        )
    rms = "—" if result.fk_rms is None else f"{result.fk_rms * 1e3:.4f}"
    top = "—" if result.fk_max is None else f"{result.fk_max * 1e3:.4f}"
    parts.append(
        f'<tr class="insample"><th>in-sample fit</th><td>calibrated</td>'
        f'<td class="num">{result.fk_points} samples</td><td class="num">—</td>'
        f'<td class="num">{rms}</td><td class="num">—</td><td class="num">{top}</td></tr>'
    )
    parts.append("</tbody></table>")
    parts.append(
        '<p class="caption">3-D distance [mm] between the measured target and the model\'s '
        "prediction at poses not used to fit it (held out), before (the nominal, its base and "
        "tool placed on the fitted poses) and after calibration; the in-sample row is the FK "
        "residual at the fitted samples. A held-out error far above the in-sample one means the "
        "model fits the session better than it predicts the robot.</p>"
    )
    for k, check in enumerate(result.checks):
        for note in check.notes:
            parts.append(f'<p class="caption">{_e(check.label)}: {_e(note)}</p>')
        svg = histogram_svg(check, result.fk_rms, f"h{k}")
        if svg is None:
            parts.append(
                f'<p class="muted">{_e(check.label)}: no per-pose errors (the '
                "&lt;stem&gt;.holdout.csv that dhlog process writes is not beside the result), "
                "so no histogram.</p>"
            )
        else:
            parts.append(
                f'<figure class="plot">{svg}<figcaption>Held-out error per pose, '
                f"{_e(check.label)}: nominal and calibrated (log scale).</figcaption></figure>"
            )
    return "\n".join(parts)


def _summary(result: _Result) -> str:
    cards = []
    if result.checks:
        c = result.checks[0]
        cards.append(("Held-out RMS, calibrated", f"{c.calibrated.rms * 1e3:.4f} mm", "good"))
        if c.nominal is not None:
            cards.append(("Held-out RMS, nominal", f"{c.nominal.rms * 1e3:.4f} mm", ""))
            if c.calibrated.rms > 0:
                cards.append(
                    ("Improvement", f"{c.nominal.rms / c.calibrated.rms:.1f}× lower", "good")
                )
    else:
        cards.append(("Held-out validation", "none: run --holdout 5", "bad"))
    if result.fk_rms is not None:
        cards.append(("In-sample FK RMS", f"{result.fk_rms * 1e3:.4f} mm", ""))
    cards.append(("Warnings", str(len(result.warnings)), "warn" if result.warnings else "good"))
    return (
        '<div class="cards">'
        + "".join(
            f'<div class="card {cls}"><div class="k">{_e(k)}</div>'
            f'<div class="v">{_e(v)}</div></div>'
            for k, v, cls in cards
        )
        + "</div>"
    )


def _tool_table(tool: list[Triple]) -> str:
    if not tool:
        return ""
    rows = []
    held_by = []
    for triple in tool:
        label, values, stds, fixed = triple.label, triple.values, triple.stds, triple.fixed
        if fixed:
            held_by.append(f"{label.split(' [')[0]} {', '.join(fixed)} fixed: {triple.reason}")
        angular = "rotation" in label
        factor = 180.0 / math.pi if angular else 1e3
        cells = []
        for k, (v, s) in enumerate(zip(values, stds, strict=True)):
            held = "xyz"[k] in fixed
            sd = None if s is None else s * factor
            places = _places(None if held else sd, 4)
            under = "fixed" if held else ("" if sd is None else f"± {_fixed(sd, places)}")
            cells.append(
                f'<td class="num">{_fixed(v * factor, places)}<span class="sd">{under}</span></td>'
            )
        rows.append(f"<tr><th>{_e(label)}</th>{''.join(cells)}</tr>")
    return (
        '<div class="keep"><h3>Tool and base</h3><table class="grid tool" id="tool"><thead>'
        "<tr><th></th>"
        '<th class="num">x</th><th class="num">y</th><th class="num">z</th>'
        "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>"
        "<p class=\"caption\">M: the tracker's measurement frame. The rotation's σ is that of a "
        "small rotation about x, y, z." + "".join(f" {_e(h)}." for h in held_by) + "</p></div>"
    )


def _residual_section(result: _Result) -> str:
    svg = residual_bars_svg(result.residuals, "r")
    failed = [r for r in result.residuals if r.error]
    parts = []
    if svg is None:
        parts.append(
            '<p class="muted" id="no-joint-residuals">The result carries no per-joint residuals: '
            "no joint was swept alone (random static poses or coupled moves), so there are no "
            "per-joint fits; the held-out errors above are the check per pose.</p>"
        )
    else:
        rows = []
        for r in result.residuals:

            def cell(v: float | None) -> str:
                return "—" if v is None else f"{v * 1e3:.4f}"

            rows.append(
                f"<tr><td>{r.joint}</td><td>{_e(r.name)}</td>"
                f'<td class="num">{"—" if r.fit_points is None else r.fit_points}</td>'
                f'<td class="num">{cell(r.fit_rms)}</td><td class="num">{cell(r.fk_rms)}</td>'
                f'<td class="num">{cell(r.fk_max)}</td></tr>'
            )
        parts.append(
            f'<figure class="plot">{svg}<figcaption>Per joint: the RMS of its own circle (or '
            "line) fit, and the RMS and max of the table's FK residual at its samples.</figcaption>"
            "</figure>"
        )
        parts.append(
            '<table class="grid" id="joint-residuals"><thead><tr><th>#</th><th>Joint</th>'
            "<th>Samples</th><th>Fit RMS [mm]</th><th>FK RMS [mm]</th><th>FK max [mm]</th></tr>"
            "</thead><tbody>" + "".join(rows) + "</tbody></table>"
        )
    for r in failed:
        parts.append(
            f'<p class="alert">Joint {r.joint} ({_e(r.name)}) was not identified: {_e(r.error)}</p>'
        )
    return "\n".join(parts)


def _terms_section(block: dict[str, Any] | None) -> str:
    if block is None:
        return (
            '<p class="muted">No search beyond the geometry (dhlog process --model geometric): '
            "the model is the DH table alone.</p>"
        )
    parts = []
    mode, chosen = block["mode"], block["chosen"]
    parts.append(
        f"<p>Model asked: <strong>{_e(mode or '?')}</strong>; chosen: "
        f"<strong>{_e(chosen or '?')}</strong>.</p>"
    )
    if block["candidates"]:
        rows = []
        for c in block["candidates"]:
            held = "—" if c["holdout_rms"] is None else f"{c['holdout_rms'] * 1e3:.4f}"
            rng = "—" if c["range_sd"] is None else f"{c['range_sd'] * 1e3:.4f}"
            bic = "—" if c["bic"] is None else f"{c['bic']:.1f}"
            mark = ' class="chosen"' if c["chosen"] else ""
            rows.append(
                f'<tr{mark}><td>{_e(c["model"])}</td><td class="num">{c["parameters"]}</td>'
                f'<td class="num">{bic}</td><td class="num">{held}</td><td class="num">{rng}</td>'
                f"<td>{'chosen' if c['chosen'] else ''}</td><td>{_e(c['why'])}</td></tr>"
            )
        parts.append(
            '<table class="grid" id="candidates"><thead><tr><th>Model</th><th>Parameters</th>'
            "<th>BIC</th><th>Held-out RMS [mm]</th><th>σ over the ranges [mm]</th><th></th>"
            "<th>Why</th></tr></thead><tbody>" + "".join(rows) + "</tbody></table>"
        )
    if block["terms"]:
        rows = []
        for t in block["terms"]:
            sd = "—" if t["std"] is None else f"{t['std']:.4g}"
            rows.append(
                f"<tr><td>{_e(t['name'])}</td><td>{_e(t['kind'])}</td>"
                f'<td class="num">{t["joint"]}</td><td>{_e(t["lump"])}</td>'
                f'<td class="num" data-si="{t["value"]!r}">{t["value"]:.6g}</td>'
                f'<td class="num">± {sd}</td><td>{_e(t["unit"])}</td></tr>'
            )
        parts.append(
            '<table class="grid" id="terms"><thead><tr><th>Term</th><th>Kind</th><th>Joint</th>'
            "<th>Lump</th><th>Value</th><th>±1σ</th><th>Unit</th></tr></thead><tbody>"
            + "".join(rows)
            + "</tbody></table>"
        )
        if block["max_target_displacement"] is not None:
            parts.append(
                '<p class="caption">The terms move the target by up to '
                f"{block['max_target_displacement'] * 1e3:.4f} mm at the session's poses. Every "
                "FK of this result adds Δq = Σ value · b(q) to the table's joint values.</p>"
            )
    else:
        parts.append(
            '<p class="muted" id="no-terms">No terms beyond the geometry were kept: the '
            "session does not show them above the noise.</p>"
        )
    return "\n".join(parts)


def _list(items: list[str], cls: str, empty: str) -> str:
    if not items:
        return f'<p class="muted">{_e(empty)}</p>'
    return f'<ul class="{cls}">' + "".join(f"<li>{_e(t)}</li>" for t in items) + "</ul>"


def _identification(
    sources: Sources, result: _Result, robot: str | None, nominal: Nominal | None, now: datetime
) -> str:
    log = sources.log
    items: list[tuple[str, str]] = []
    robot_text = (
        _e(robot)
        if robot
        else '<span class="muted">not named (the result JSON does not record it: pass '
        "--robot)</span>"
    )
    items.append(("Robot", robot_text))
    joints = ", ".join(
        f"{_e(n)} ({_e(t or 'not identified')})"
        for n, t in zip(result.joint_names, result.joint_types, strict=True)
    )
    items.append(("Joints", f"{result.n_joints}: {joints}"))
    items.append(
        (
            "Nominal",
            _e(nominal.name)
            if nominal is not None
            else '<span class="muted">not recorded in the result JSON; pass --nominal (the one '
            "given to dhlog process) for measured − nominal</span>",
        )
    )
    items.append(("Result file", f"<code>{_e(sources.result_path.name)}</code>"))
    items.append(
        ("Result SHA-256", f'<code class="hash" id="result-sha256">{sources.result_sha256}</code>')
    )
    stamp = "%Y-%m-%d %H:%M UTC"
    items.append(
        (
            "Result date",
            f"{sources.result_modified.strftime(stamp)} (the file's modification time; the "
            "result JSON records no date)",
        )
    )
    items.append(("Report date", now.strftime(stamp)))
    items.append(
        ("Log", f"<code>{_e(result.log_name or '—')}</code>, pipeline {_e(result.pipeline or '—')}")
    )
    recorded = result.log_sha256 or "—"
    items.append(
        (
            "Log SHA-256, recorded",
            f'<code class="hash" id="log-sha256-recorded">{_e(recorded)}</code> (when the result '
            "was computed)",
        )
    )
    if log.sha256 is None:
        computed = '<span class="warn" id="log-sha256">log not found, hash not computed</span>'
        if log.searched:
            computed += (
                ' <span class="muted">(looked for '
                + ", ".join(f"<code>{_e(p)}</code>" for p in log.searched)
                + ")</span>"
            )
    else:
        same = log.sha256 == result.log_sha256
        verdict = (
            '<span class="good">matches the recorded hash</span>'
            if same
            else '<span class="bad">differs from the recorded hash: not the log this result was '
            "computed from</span>"
        )
        computed = (
            f'<code class="hash" id="log-sha256">{log.sha256}</code> {verdict} '
            f'<span class="muted">({_e(log.path)})</span>'
        )
    items.append(("Log SHA-256, now", computed))
    versions = f"result {_e(result.version)}, report {_e(__version__)}"
    items.append(("dhlog version", versions))
    if result.method:
        items.append(("Method", _e(result.method)))
    return _kv(items, "identification")


CSS = """
:root { --ink: #1d2733; --muted: #5f6b7a; --rule: #d5dbe1; --head: #1f3a5f; --bg: #f6f7f9;
  --good: #1e7a46; --warn: #9a6700; --bad: #b42318; --nom: #c8553d; --cal: #2a6f97; }
* { box-sizing: border-box; }
html { background: #e9ecef; }
body { margin: 0; color: var(--ink); font: 13px/1.45 "Helvetica Neue", Helvetica, Arial,
  "Liberation Sans", "DejaVu Sans", sans-serif; }
.sheet { max-width: 1120px; margin: 24px auto; background: #fff; padding: 36px 48px 28px;
  box-shadow: 0 1px 4px rgba(0,0,0,.12); }
header { display: flex; justify-content: space-between; align-items: flex-end; gap: 24px;
  border-bottom: 3px solid var(--head); padding-bottom: 10px; margin-bottom: 14px; }
h1 { font-size: 24px; margin: 0; color: var(--head); letter-spacing: .01em; }
header .sub { margin: 2px 0 0; color: var(--muted); }
header .robot { text-align: right; font-size: 15px; font-weight: 600; max-width: 45%;
  overflow-wrap: anywhere; }
header .robot small { display: block; font-weight: 400; color: var(--muted); font-size: 12px; }
h2 { font-size: 15px; color: var(--head); margin: 22px 0 8px; padding-bottom: 3px;
  border-bottom: 1px solid var(--rule); break-after: avoid; }
h2 .n { color: var(--muted); font-weight: 400; margin-right: 6px; }
h3 { font-size: 13px; margin: 14px 0 4px; color: var(--head); }
p { margin: 6px 0; }
code { font: 12px/1.3 "DejaVu Sans Mono", "Liberation Mono", Menlo, Consolas, monospace; }
code.hash { word-break: break-all; }
.cards { display: flex; gap: 10px; margin: 10px 0 4px; flex-wrap: wrap; }
.card { flex: 1 1 150px; border: 1px solid var(--rule); border-left: 4px solid var(--rule);
  padding: 6px 10px; background: var(--bg); }
.card .k { font-size: 11px; color: var(--muted); text-transform: uppercase; letter-spacing: .04em; }
.card .v { font-size: 18px; font-weight: 600; font-variant-numeric: tabular-nums; }
.card.good { border-left-color: var(--good); } .card.warn { border-left-color: var(--warn); }
.card.bad { border-left-color: var(--bad); } .card.bad .v { color: var(--bad); }
table { border-collapse: collapse; }
table.kv { width: 100%; }
table.kv th { text-align: left; font-weight: 600; width: 190px; vertical-align: top;
  padding: 3px 12px 3px 0; color: var(--muted); }
table.kv td { padding: 3px 0; overflow-wrap: anywhere; }
table.kv tr + tr > * { border-top: 1px solid #eef0f3; }
table.grid { margin: 6px 0; font-variant-numeric: tabular-nums; width: 100%; }
table.grid th, table.grid td { padding: 4px 10px; border-bottom: 1px solid #e6e9ed;
  text-align: left; vertical-align: top; }
table.grid thead th { border-bottom: 1.5px solid var(--head); font-size: 12px; color: var(--head);
  white-space: nowrap; vertical-align: bottom; }
table.grid .num, table.grid td.p { text-align: right; white-space: nowrap; }
table.grid .c { text-align: center; width: 2em; }
table.stats { width: auto; min-width: 70%; }
table.stats td.num, table.stats th.num { min-width: 6.5em; }
table.params td.p { padding-top: 5px; padding-bottom: 5px; }
td.p span { display: block; }
td.p .v { font-size: 13.5px; }
td.p .sd { font-size: 11.5px; color: var(--muted); }
td.p .dn { font-size: 11.5px; color: var(--nom); }
td.p.held .v { color: var(--muted); }
td.jn { font-weight: 600; overflow-wrap: anywhere; }
.jt { display: block; font-weight: 400; color: var(--muted); font-size: 11px; }
td.form { color: var(--muted); font-size: 12px; width: 9em; white-space: nowrap; }
table.params td.jn { width: 12em; }
.held { font-style: italic; }
sup { font-size: 9px; font-style: normal; }
ol.footnotes { margin: 4px 0 0; padding-left: 22px; color: var(--muted); font-size: 12px; }
tr.insample th, tr.insample td { border-top: 1.5px solid var(--rule); }
tr.calibrated td { font-weight: 600; color: var(--cal); }
tr.nominal td:nth-child(2) { color: var(--nom); } tr.chosen td { font-weight: 600; }
table.tool td .sd { display: block; color: var(--muted); font-size: 11px; }
.caption, figcaption { color: var(--muted); font-size: 12px; }
figure.plot { margin: 10px 0 4px; }
svg.plot { width: 100%; height: auto; display: block; }
.muted { color: var(--muted); } .good { color: var(--good); } .warn { color: var(--warn); }
.bad { color: var(--bad); font-weight: 600; }
.alert { border: 1px solid #f1b8b3; background: #fdf1f0; border-left: 5px solid var(--bad);
  padding: 10px 14px; margin: 8px 0; font-size: 14px; }
ul.warnings li { border-left: 4px solid var(--warn); background: #fff8e6; padding: 6px 10px;
  margin: 6px 0; list-style: none; }
ul.warnings, ul.notes { padding: 0; margin: 6px 0; }
ul.notes li { list-style: none; padding: 3px 0 3px 14px; position: relative; color: #3b4654; }
ul.notes li::before { content: "–"; position: absolute; left: 0; color: var(--muted); }
footer { margin-top: 24px; padding-top: 8px; border-top: 1px solid var(--rule);
  color: var(--muted); font-size: 11px; display: flex; justify-content: space-between; gap: 16px; }
@page { size: A4; margin: 14mm; }
@media print {
  html { background: #fff; } .sheet { box-shadow: none; margin: 0; padding: 0; max-width: none; }
  figure, table, .alert, .cards, tr, .keep { break-inside: avoid; }
  h2, h3 { break-after: avoid; }
  table.grid thead th { white-space: normal; }
}
"""


def certificate_html(
    sources: Sources,
    *,
    robot: str | None = None,
    nominal: Nominal | None = None,
    now: datetime | None = None,
) -> str:
    """The certificate of ``sources`` as one HTML page (no script, no external resource).
    ``robot``: the robot as the certificate names it (the result does not record it);
    ``nominal``: the table given to ``dhlog process``, for measured − nominal. Raises
    :class:`ResultFileError` (or :class:`~dhlog.errors.InputError`) naming the field at fault."""
    name = str(sources.result_path)
    result = read_result(sources.document, name)
    if sources.holdout_text is not None and result.checks:
        checks = read_holdout_csv(sources.holdout_text, str(sources.holdout_path), result.checks)
        result = _replace_checks(result, checks)
    rows = result.rows
    if nominal is not None:
        if nominal.table.n != result.n_joints:
            raise InputError(
                f"{nominal.name}: has {nominal.table.n} joints but {name} has "
                f"{result.n_joints}; give the nominal of this robot (the one given to dhlog "
                "process)."
            )
        rows = nominal_deltas(rows, nominal.table, result.reference_pose)
    now = now or datetime.now(UTC)
    title = robot or result.log_name or sources.result_path.name
    hayati = [r.joint for r in rows if r.form == "hayati"]
    partial = [r for r in result.residuals if r.error]
    intro = (
        "Standard (distal) Denavit–Hartenberg parameters, A = Rz(θ) Tz(d) Tx(a) Rx(α); θ and d "
        "are the offsets at encoder zero. ±1σ from the fit of the whole model to every sample."
    )
    if hayati:
        intro += (
            f" Row(s) {', '.join(map(str, hayati))}: the Hayati–Mirmirani form Rz(θ) Tx(a) Rx(α) "
            "Ry(β), β in place of the ill-conditioned d of a nearly parallel pair (same forward "
            "kinematics; the JSON has both)."
        )
    intro += (
        " Parameters marked fixed are held by a convention, a gauge freedom or a relation the "
        "data cannot reject, or are not determined by the poses: they are not measurements."
    )
    if nominal is None:
        intro += (
            " Measured − nominal is not shown: the result JSON does not record the nominal "
            "(pass --nominal to dhlog report)."
        )
    body = [
        '<main class="sheet">',
        "<header><div><h1>Robot calibration certificate</h1>"
        '<p class="sub">Kinematic (Denavit–Hartenberg) calibration from a laser-tracker log, '
        "identified by dhlog</p></div>"
        f'<div class="robot" id="robot">{_e(title)}<small>{result.n_joints} joints · report '
        f"{now.strftime('%Y-%m-%d')}</small></div></header>",
    ]
    if partial:
        body.append(
            '<div class="alert" id="partial"><strong>Partial result.</strong> Joint(s) '
            + ", ".join(str(r.joint) for r in partial)
            + " could not be identified; see the per-joint section.</div>"
        )
    body += [
        _summary(result),
        '<section id="s-identification"><h2><span class="n">1</span>Identification</h2>',
        _identification(sources, result, robot, nominal, now),
        "</section>",
        '<section id="s-accuracy"><h2><span class="n">2</span>Accuracy at held-out poses</h2>',
        _accuracy(result),
        "</section>",
        '<section id="s-parameters"><h2><span class="n">3</span>DH parameters</h2>',
        f'<p class="caption">{_e(intro)}</p>',
        _parameter_table(rows, nominal)
        if rows
        else '<p class="alert">The result holds no DH parameters.</p>',
        _tool_table(result.tool),
        "</section>",
        '<section id="s-measurement"><h2><span class="n">4</span>Tracker and noise model</h2>',
        _kv([(k, _e(v)) for k, v in result.measurement], "measurement")
        if result.measurement
        else '<p class="muted">The result records no noise model.</p>',
        "</section>",
        '<section id="s-joints"><h2><span class="n">5</span>Per-joint residuals</h2>',
        _residual_section(result),
        "</section>",
        '<section id="s-terms"><h2><span class="n">6</span>Beyond the geometry</h2>',
        _terms_section(result.nongeometric),
        "</section>",
        '<section id="s-warnings"><h2><span class="n">7</span>Warnings and notes</h2>',
        _list(result.warnings, "warnings", "No warnings."),
        _list(result.notes, "notes", "No notes."),
        "</section>",
        f"<footer><span>Written by dhlog {_e(__version__)} (dhlog report) from "
        f"<code>{_e(sources.result_path.name)}</code>. Lengths in mm, angles in degrees, "
        "±1σ.</span><span>SHA-256 "
        f"<code>{sources.result_sha256[:16]}…</code></span></footer>",
        "</main>",
    ]
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f'<meta name="generator" content="dhlog {_e(__version__)}">\n'
        f"<title>Calibration certificate — {_e(title)}</title>\n"
        f"<style>{CSS}</style>\n</head>\n<body>\n" + "\n".join(body) + "\n</body>\n</html>\n"
    )


def _replace_checks(result: _Result, checks: list[Check]) -> _Result:
    return replace(result, checks=checks)
