"""DH files: JSON or TOML with a ``standard_dh`` array; a dhlog result JSON is one too.

Each row has ``type`` (revolute/prismatic, default revolute), ``theta_offset`` (or ``theta``),
``d_offset`` (or ``d``), ``a`` and ``alpha`` in metres and radians, unless the file says
``units = {length = "mm", angle = "deg"}``. Optional: ``base.T_measurement_base`` (4×4),
``tool.point``, ``joints[].name``, and a result's ``nongeometric`` block (its terms deflect the
joint values: :meth:`DHModel.joint_values`).
"""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.dh import JointType, StandardDH
from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray
from dhlog.nongeometric import Terms, from_document, table_deflection
from dhlog.robots import Robot, UnknownRobotError, load_robot


class DHFileError(InputError):
    """A DH file is malformed."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


@dataclass(frozen=True, eq=False)
class DHModel:
    """A DH table with its optional base transform, tool point and joint names."""

    table: StandardDH
    T_base: FloatArray
    tool_point: FloatArray
    joint_names: tuple[str, ...]
    source: str
    #: a result's joint-value terms beyond the geometry (compliance, harmonics) in the table's
    #: frames, from its ``nongeometric`` block (None: a geometric model)
    terms: Terms | None = None

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


def _scales(data: dict[str, Any]) -> tuple[float, float]:
    units = data.get("units", {})
    length = {"m": 1.0, "mm": 1e-3}.get(str(units.get("length", "m")))
    angle = {"rad": 1.0, "deg": math.pi / 180}.get(str(units.get("angle", "rad")))
    if length is None or angle is None:
        raise ValueError("units must be length m|mm and angle rad|deg")
    return length, angle


def parse_dh(data: dict[str, Any], source: str) -> DHModel:
    """A :class:`DHModel` from parsed JSON/TOML ``data``."""
    rows = data.get("standard_dh")
    if not isinstance(rows, list) or not rows:
        raise DHFileError(source, "no 'standard_dh' array; give one row per joint.")
    try:
        length, angle = _scales(data)
        joints = data.get("joints") or []
        types, theta, d, a, alpha = [], [], [], [], []
        for i, row in enumerate(rows):
            jt = row.get("type") or (joints[i].get("type") if i < len(joints) else None)
            types.append(JointType.parse(str(jt or "revolute")))
            theta.append(float(row.get("theta_offset", row.get("theta", 0.0))) * angle)
            d.append(float(row.get("d_offset", row.get("d", 0.0))) * length)
            a.append(float(row["a"]) * length)
            alpha.append(float(row["alpha"]) * angle)
        table = StandardDH(types, theta, d, a, alpha)
        base = data.get("base", {}).get("T_measurement_base")
        T_base = np.eye(4) if base is None else np.asarray(base, dtype=np.float64)
        T_base[:3, 3] *= length if base is not None else 1.0
        tool = np.asarray(data.get("tool", {}).get("point", [0.0, 0.0, 0.0]), dtype=np.float64)
        tool = tool * length
        names = tuple(
            str(j.get("name", f"joint_{i + 1}")) if i < len(joints) else f"joint_{i + 1}"
            for i, j in enumerate(joints + [{}] * (len(rows) - len(joints)))
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise DHFileError(source, f"malformed DH data ({exc}).") from None
    if T_base.shape != (4, 4) or tool.shape != (3,):
        raise DHFileError(source, "base must be 4x4 and tool.point a 3-vector.")
    terms = None
    block = data.get("nongeometric")
    if isinstance(block, dict) and block.get("terms"):
        if length != 1.0 or angle != 1.0:
            raise DHFileError(source, "a nongeometric block needs units m and rad.")
        terms = from_document(block, table.n, source)
        terms = terms if terms.size else None
    return DHModel(table, T_base, tool, names, source, terms)


def load_dh(path: str | Path) -> DHModel:
    """Read a DH file (``.json`` or ``.toml``)."""
    name = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise DHFileError(name, f"cannot be read ({exc.strerror}).") from None
    try:
        data = tomllib.loads(text) if name.endswith(".toml") else json.loads(text)
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as exc:
        raise DHFileError(
            name, f"not valid {'TOML' if name.endswith('.toml') else 'JSON'} ({exc})."
        ) from None
    if not isinstance(data, dict):
        raise DHFileError(name, "must hold an object with a 'standard_dh' array.")
    return parse_dh(data, name)


def robot_or_dh_file(spec: str) -> Robot:
    """A library robot by name, or a robot built from a DH file (limits ±π, ±0.1 m)."""
    if Path(spec).suffix in (".json", ".toml") or Path(spec).exists():
        model = load_dh(spec)
        limits = np.array(
            [
                [-np.pi, np.pi] if t is JointType.REVOLUTE else [-0.1, 0.1]
                for t in model.table.joint_types
            ]
        )
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
    from dhlog.robots import load_robot

    if Path(spec).suffix in (".json", ".toml") or Path(spec).exists():
        return load_dh(spec)
    robot = load_robot(spec)
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    return DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)
