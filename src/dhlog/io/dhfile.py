"""DH files: JSON or TOML with a ``standard_dh`` array; a dhlog result JSON is one too.

Each row has ``type`` (revolute/prismatic, default revolute), ``theta_offset`` (or ``theta``),
``d_offset`` (or ``d``), ``a`` and ``alpha`` in metres and radians, unless the file says
``units = {length = "mm", angle = "deg"}``. Optional: ``base.T_measurement_base`` (4×4),
``tool.point``, ``joints[].name``, ``joints[].limits`` (``[lower, upper]`` in the file's angle
unit, or its length unit for a prismatic joint), and a result's ``nongeometric`` block (its terms
deflect the joint values: :meth:`DHModel.joint_values`).

Every byte is untrusted: the file is read only when it is a regular file of at most
:data:`MAX_BYTES`, as UTF-8; every value is checked for its type (a JSON ``true`` is not a
number) and range (:data:`MAX_LENGTH_M`, :data:`MAX_ANGLE_RAD`), and every failure is one
:class:`DHFileError` naming the file and the field.
"""

from __future__ import annotations

import datetime
import json
import math
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import DhlogError, InputError, ShapeError
from dhlog.geometry._checks import FloatArray
from dhlog.io.textfile import decode_utf8, read_capped
from dhlog.model.dh import JointType, StandardDH
from dhlog.model.robots import Robot, UnknownRobotError, load_robot
from dhlog.model.terms import Terms, from_document, table_deflection

#: The largest DH file read (bytes): a result JSON of a long chain is a few hundred kB.
MAX_BYTES = 10 * 2**20
#: The most joints a DH table may have.
MAX_JOINTS = 64
#: The largest DH length (a, d, the tool point) in metres: no robot reaches further.
MAX_LENGTH_M = 100.0
#: The largest standard-DH ``d`` (m): that of a nearly parallel pair's row is ill-conditioned and
#: its common normal lies far away (0.5 km in a real KR5, 13.5 km in a simulated one: about the
#: offset over the angle between the axes), so only absurd values are refused.
MAX_OFFSET_M = 1e9
#: The largest distance of the robot's base from the measurement frame's origin (m).
MAX_BASE_M = 1000.0
#: The largest DH angle (two turns either way).
MAX_ANGLE_RAD = 4.0 * math.pi
#: How far ``T_measurement_base``'s rotation may be from orthonormal (rounding in the file).
ROTATION_TOLERANCE = 1e-3
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180}


class DHFileError(InputError):
    """A DH file is malformed."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


@dataclass(frozen=True, eq=False)
class DHModel:
    """A robot model as forward kinematics reads it (public as ``dhlog.DHModel``; what
    :attr:`dhlog.Calibration.model` and :attr:`dhlog.Calibration.nominal` are): the standard DH
    ``table`` (offsets at encoder zero), ``T_base`` (DH frame 1 in the measurement frame, 4×4),
    ``tool_point`` (the target in the last DH frame, m), ``joint_names``, ``source`` (the file
    or library robot it came from) and ``terms`` beyond the geometry. SI units."""

    table: StandardDH
    T_base: FloatArray
    tool_point: FloatArray
    joint_names: tuple[str, ...]
    source: str
    #: a result's joint-value terms beyond the geometry (compliance, harmonics) in the table's
    #: frames, from its ``nongeometric`` block (None: a geometric model)
    terms: Terms | None = None
    #: the joint limits (n, 2) in rad or m, where the file gives any (``joints[].limits``; a
    #: joint without them ±π or ±0.1 m); None: the file gives none
    limits: FloatArray | None = None
    #: the joints (0-based) a result held at the nominal because they never moved in its session
    #: (``joints[].parked``): not calibrated, so compensation keeps them where commanded
    parked: tuple[int, ...] = ()

    def joint_values(self, q: ArrayLike) -> FloatArray:
        """The table's joint values at encoder values ``q`` (..., n): ``q`` deflected by the
        terms when the model carries them (gravity compliance, transmission harmonics), so that
        ``fk_point(model.table, model.joint_values(q), …)`` is the model's forward kinematics."""
        values = np.asarray(q, dtype=np.float64)
        if self.terms is None or not self.terms.size:
            return values
        flat = values.reshape(-1, self.table.n)
        deflected = flat + table_deflection(self.table, self.terms, flat, flat)
        return np.asarray(deflected.reshape(values.shape), dtype=np.float64)


def _shown(value: object) -> str:
    """A value as the file spells it, cut short (``true``, ``null``, ``"abc"``, ``[1, 2]``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, int) and abs(value) > 10**30:
        return "an integer of more than 30 digits"
    if isinstance(value, datetime.date | datetime.time):  # a TOML date or time
        return f"the date/time {value.isoformat()}"
    text = json.dumps(value) if isinstance(value, str) else repr(value)
    return text if len(text) <= 40 else text[:37] + "…"


class _Fields:
    """Typed reads of parsed DH data; each failure a :class:`DHFileError` naming the field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, field: str, problem: str) -> DHFileError:
        return DHFileError(self.source, f"{field} {problem}")

    def table(self, data: dict[str, Any], key: str, field: str) -> dict[str, Any]:
        value = data.get(key)
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.error(field, f"is {_shown(value)}; it must be a table (an object).")
        return value

    def text(self, value: object, field: str) -> str:
        if not isinstance(value, str):
            raise self.error(field, f"is {_shown(value)}; it must be a string.")
        if len(value) > 200:
            raise self.error(field, f"is a string of {len(value)} characters (at most 200).")
        return value

    def number(self, value: object, field: str, scale: float, limit: float, unit: str) -> float:
        """``value`` × ``scale``: a finite number (not a boolean) within ±``limit``."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(field, f"is {_shown(value)}, not a number; give a number.")
        try:
            x = float(value) * scale
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            raise self.error(field, f"is {_shown(value)}: not a finite number; give a number.")
        if abs(x) > limit:
            raise self.error(
                field,
                f"is {_shown(value)}, beyond ±{limit:g} {unit} once in SI units; check the value "
                'and the file\'s units (units = {length = "mm", angle = "deg"}).',
            )
        return x

    def unit(self, units: dict[str, Any], key: str, known: dict[str, float], default: str) -> float:
        name = units.get(key, default)
        if not isinstance(name, str) or name not in known:
            raise self.error(f"units.{key}", f"is {_shown(name)}; use one of {', '.join(known)}.")
        return known[name]


def parse_dh(data: dict[str, Any], source: str) -> DHModel:
    """A :class:`DHModel` from parsed JSON/TOML ``data`` (untrusted: every value checked)."""
    f = _Fields(source)
    rows = data.get("standard_dh")
    if not isinstance(rows, list) or not rows:
        raise DHFileError(source, "no 'standard_dh' array; give one row per joint.")
    if len(rows) > MAX_JOINTS:
        raise f.error("standard_dh", f"has {len(rows)} rows; dhlog takes at most {MAX_JOINTS}.")
    units = f.table(data, "units", "units")
    length = f.unit(units, "length", LENGTH_UNITS, "m")
    angle = f.unit(units, "angle", ANGLE_UNITS, "rad")
    joints = data.get("joints") or []
    if not isinstance(joints, list) or not all(isinstance(j, dict) for j in joints):
        raise f.error("joints", "must be an array of objects ({name = …, type = …}).")
    types: list[JointType] = []
    names: list[str] = []
    limits: list[tuple[float, float] | None] = []
    parked: list[int] = []
    theta: list[float] = []
    d: list[float] = []
    a: list[float] = []
    alpha: list[float] = []
    for i, row in enumerate(rows):
        at = f"standard_dh[{i}] (joint {i + 1})"
        if not isinstance(row, dict):
            raise f.error(at, f"is {_shown(row)}; each row must be an object.")
        joint = joints[i] if i < len(joints) else {}
        jt = f.text(row.get("type") or joint.get("type") or "revolute", f"{at}.type")
        try:
            types.append(JointType.parse(jt))
        except ShapeError:
            raise f.error(f"{at}.type", f"is {_shown(jt)}; use revolute or prismatic.") from None
        for key, alias, out, scale, limit, unit in (
            ("theta_offset", "theta", theta, angle, MAX_ANGLE_RAD, "rad"),
            ("d_offset", "d", d, length, MAX_OFFSET_M, "m"),
            ("a", None, a, length, MAX_LENGTH_M, "m"),
            ("alpha", None, alpha, angle, MAX_ANGLE_RAD, "rad"),
        ):
            name = key if key in row or alias is None else alias
            if name not in row:
                if alias is None:
                    raise f.error(at, f"has no '{key}'; give a and alpha in every row.")
                out.append(0.0)
                continue
            out.append(f.number(row[name], f"{at}.{name}", scale, limit, unit))
        names.append(f.text(joint.get("name", f"joint_{i + 1}"), f"joints[{i}].name"))
        limits.append(_limits(f, joint.get("limits"), i, types[-1], angle, length))
        if joint.get("parked"):
            parked.append(i)
    twice = [k for k, name in enumerate(names) if name in names[:k]]
    if twice:
        k = twice[0]
        raise f.error(
            f"joints[{k}].name",
            f"is {_shown(names[k])}, the name of joint {names.index(names[k]) + 1} too; name "
            "each joint once (joint states are matched to the joints by name).",
        )
    table = StandardDH(types, theta, d, a, alpha)
    base = f.table(data, "base", "base").get("T_measurement_base")
    T_base = np.eye(4) if base is None else _transform(f, base, length)
    tool_raw = f.table(data, "tool", "tool").get("point", [0.0, 0.0, 0.0])
    if not isinstance(tool_raw, list) or len(tool_raw) != 3:
        raise f.error("tool.point", f"is {_shown(tool_raw)}; it must be three numbers [x, y, z].")
    tool = np.array(
        [f.number(v, f"tool.point[{k}]", length, MAX_LENGTH_M, "m") for k, v in enumerate(tool_raw)]
    )
    terms = None
    block = data.get("nongeometric")
    if isinstance(block, dict) and block.get("terms"):
        if length != 1.0 or angle != 1.0:
            raise DHFileError(source, "a nongeometric block needs units m and rad.")
        try:
            terms = from_document(block, table.n, source)
        except DhlogError:
            raise
        except (ArithmeticError, LookupError, TypeError, ValueError, AttributeError) as exc:
            raise f.error("nongeometric", f"is malformed ({type(exc).__name__}).") from None
        terms = terms if terms.size else None
    given = None
    if any(lim is not None for lim in limits):
        pairs = zip(types, limits, strict=True)
        given = np.array([_DEFAULT_LIMITS[t] if lim is None else lim for t, lim in pairs])
    return DHModel(table, T_base, tool, tuple(names), source, terms, given, tuple(parked))


#: a joint's limits where a DH file gives none (rad or m)
_DEFAULT_LIMITS = {JointType.REVOLUTE: (-math.pi, math.pi), JointType.PRISMATIC: (-0.1, 0.1)}


def _limits(
    f: _Fields, value: object, i: int, kind: JointType, angle: float, length: float
) -> tuple[float, float] | None:
    """``joints[i].limits``: [lower, upper] in the file's unit (angle, or length if prismatic)."""
    if value is None:
        return None
    field = f"joints[{i}].limits"
    if not isinstance(value, list) or len(value) != 2:
        raise f.error(field, f"is {_shown(value)}; give two numbers [lower, upper].")
    if kind is JointType.REVOLUTE:
        lo, hi = (f.number(v, field, angle, MAX_ANGLE_RAD, "rad") for v in value)
    else:
        lo, hi = (f.number(v, field, length, MAX_LENGTH_M, "m") for v in value)
    if not lo < hi:
        raise f.error(field, f"is {_shown(value)}; the lower limit must be below the upper.")
    return lo, hi


def _transform(f: _Fields, value: object, length: float) -> FloatArray:
    """``base.T_measurement_base``: a 4×4 rigid transform, its translation in the file's unit."""
    field = "base.T_measurement_base"
    if (
        not isinstance(value, list)
        or len(value) != 4
        or not all(isinstance(r, list) and len(r) == 4 for r in value)
    ):
        raise f.error(field, f"is {_shown(value)}; it must be 4 rows of 4 numbers.")
    T = np.eye(4)
    for i, row in enumerate(value):
        for k, v in enumerate(row):
            at = f"{field}[{i}][{k}]"
            if k == 3 and i < 3:
                T[i, k] = f.number(v, at, length, MAX_BASE_M, "m")
            else:  # a rotation entry, or the last row: |x| <= 1, checked below
                T[i, k] = f.number(v, at, 1.0, math.inf, "")
                if abs(T[i, k]) > 1.0 + ROTATION_TOLERANCE:
                    T[i, k] = math.inf
    R = T[:3, :3]
    rigid = bool(np.all(np.isfinite(T))) and np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9)
    if not rigid or float(np.max(np.abs(R.T @ R - np.eye(3)))) > ROTATION_TOLERANCE:
        raise f.error(
            field,
            "is not a rigid transform (its rotation block must be orthonormal and its last row "
            "0 0 0 1); give the measurement-to-base pose.",
        )
    return T


def load_dh(path: str | Path) -> DHModel:
    """Read a DH file (``.json`` or ``.toml``; at most :data:`MAX_BYTES`, UTF-8)."""
    name = str(path)
    kind = "TOML" if name.endswith(".toml") else "JSON"

    def fail(problem: str) -> DHFileError:
        return DHFileError(name, problem)

    data = read_capped(
        path,
        MAX_BYTES,
        fail,
        what="DH file",
        hint="give the DH file or result JSON itself.",
    )
    text = decode_utf8(data, fail, what="DH file")
    try:
        parsed = tomllib.loads(text) if kind == "TOML" else json.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise fail(f"not valid {kind} ({exc}).") from None
    except RecursionError:
        raise fail(f"is nested too deeply to be a DH file; not valid {kind} for dhlog.") from None
    except ValueError:  # an integer beyond Python's digit limit
        raise fail(
            f"holds an integer of more than {sys.get_int_max_str_digits()} digits; not a DH "
            "file: check what the file holds."
        ) from None
    if not isinstance(parsed, dict):
        raise fail("must hold an object with a 'standard_dh' array.")
    try:
        return parse_dh(parsed, name)
    except DhlogError:
        raise
    except (ArithmeticError, LookupError, TypeError, ValueError, AttributeError) as exc:
        raise fail(f"malformed DH data ({type(exc).__name__}: {exc}).") from None
    except RecursionError:
        raise fail("is nested too deeply to be a DH file.") from None


def robot_or_dh_file(spec: str) -> Robot:
    """A library robot by name, or a robot built from a DH file (its ``joints[].limits``, or
    ±π and ±0.1 m)."""
    if Path(spec).suffix in (".json", ".toml") or Path(spec).exists():
        model = load_dh(spec)
        limits = model.limits
        if limits is None:
            limits = np.array([_DEFAULT_LIMITS[t] for t in model.table.joint_types])
        tool = model.tool_point if np.any(model.tool_point) else np.array([0.05, 0.03, 0.08])
        return Robot(
            Path(spec).stem, Path(spec).stem, spec, model.table, model.T_base, tool, limits
        )
    try:
        return load_robot(spec)
    except UnknownRobotError:
        raise


def dh_model_from(spec: str) -> DHModel:
    """A DH model from a DH file or a library robot name."""
    from dhlog.model.robots import load_robot

    if Path(spec).suffix in (".json", ".toml") or Path(spec).exists():
        return load_dh(spec)
    robot = load_robot(spec)
    names = robot.joint_names or tuple(f"joint_{i + 1}" for i in range(robot.n))
    return DHModel(
        robot.table, robot.T_base, robot.tool_point, names, robot.name, limits=robot.limits
    )
