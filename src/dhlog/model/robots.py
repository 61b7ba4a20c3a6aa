"""The robot library: the seed robots and the arms users own as data (``dhlog/library/*.toml``,
one file per maker, its format in that folder's README.md), loadable by name."""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

import numpy as np

from dhlog.errors import DhlogError
from dhlog.geometry._checks import FloatArray
from dhlog.model.dh import JointType, ModifiedDH, StandardDH, modified_to_standard

_LENGTH_SCALE = {"m": 1.0, "mm": 1e-3, "cm": 1e-2}


class UnknownRobotError(DhlogError):
    """A robot name that is not in the library."""

    def __init__(self, name: str, known: list[str]) -> None:
        super().__init__(
            f"Unknown robot '{name}'; the library has {', '.join(known)} "
            "(or give a DH file instead)."
        )


@dataclass(frozen=True, eq=False)
class Robot:
    """A library robot in SI units: its standard DH table, the base transform that places frame 1
    (identity unless the source table is modified DH), a tool point in the last frame and the joint
    limits (n, 2) in rad or m."""

    name: str
    title: str
    source: str
    table: StandardDH
    T_base: FloatArray
    tool_point: FloatArray
    limits: FloatArray
    #: lumped link masses (kg) at the DH frame origins on joints 2 … n's axes (n−1,), and the
    #: payload (kg) at the tool point: the simulator's gravity compliance (empty: none given)
    masses: FloatArray = field(default_factory=lambda: np.zeros(0))
    payload: float = 0.0
    #: the joints as the robot's ROS 2 driver names them (empty: none given)
    joint_names: tuple[str, ...] = ()
    #: the vendor description the entry's FK is tested against, and the test (empty: not checked)
    checked: str = ""
    #: each joint's velocity limit (rad/s or m/s) and effort limit (N·m or N), as the vendor's
    #: description gives them (empty: the library has none)
    velocity_limits: FloatArray = field(default_factory=lambda: np.zeros(0))
    effort_limits: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.table.n


def _robot_from_entry(name: str, entry: dict[str, Any]) -> Robot:
    scale = _LENGTH_SCALE[entry.get("length_unit", "m")]
    types = tuple(JointType.parse(t) for t in entry["type"])
    rad = math.radians
    theta = [rad(v) for v in entry["theta"]]
    alpha = [rad(v) for v in entry["alpha"]]
    d = [v * scale for v in entry["d"]]
    a = [v * scale for v in entry["a"]]
    if entry["convention"] == "modified":
        T_base, table = modified_to_standard(ModifiedDH(types, theta, d, a, alpha))
    else:
        T_base, table = np.eye(4), StandardDH(types, theta, d, a, alpha)
    limits = np.array(
        [
            [rad(lo), rad(hi)] if t is JointType.REVOLUTE else [lo * scale, hi * scale]
            for t, (lo, hi) in zip(types, entry["limits"], strict=True)
        ]
    )
    return Robot(
        name=name,
        title=entry["title"],
        source=entry["source"],
        table=table,
        T_base=T_base,
        tool_point=np.asarray(entry["tool"], dtype=np.float64) * scale,
        limits=limits,
        masses=np.asarray(entry.get("masses", []), dtype=np.float64),
        payload=float(entry.get("payload", 0.0)),
        joint_names=tuple(str(n) for n in entry.get("joint_names", [])),
        checked=str(entry.get("checked", "")),
        velocity_limits=np.array(
            [
                rad(v) if t is JointType.REVOLUTE else v * scale
                for t, v in zip(types, entry.get("velocity", []), strict=True)
            ]
            if "velocity" in entry
            else [],
            dtype=np.float64,
        ),
        effort_limits=np.asarray(entry.get("effort", []), dtype=np.float64),
    )


def merge_library(files: list[tuple[str, str]]) -> dict[str, dict[str, Any]]:
    """The entries of the makers' files (``(file name, TOML text)`` pairs) as one library; a name
    in two files is an error (in the package's own data, so a test catches it before a user)."""
    library: dict[str, dict[str, Any]] = {}
    for file, text in files:
        for name, entry in tomllib.loads(text).items():
            if name in library:
                raise DhlogError(f"the robot library names '{name}' twice (library/{file})")
            library[name] = entry
    return library


@cache
def _library() -> dict[str, dict[str, Any]]:
    folder = resources.files("dhlog").joinpath("library")
    files = sorted(
        (item.name, item.read_text(encoding="utf-8"))
        for item in folder.iterdir()
        if item.name.endswith(".toml")
    )
    return merge_library(files)


def robot_names() -> list[str]:
    """Names of the robots in the library."""
    return sorted(_library())


def library_robots() -> list[Robot]:
    """Every robot in the library, in name order."""
    return [_robot_from_entry(name, _library()[name]) for name in robot_names()]


#: a maker's name before the model's ("ABB IRB 120", "Universal Robots UR5e") is not part of the key
_MAKERS: tuple[str, ...] = ("universalrobots", "abb", "fanuc", "yaskawa", "motoman", "kuka")
_MAKERS += ("franka", "kinova", "staubli", "stäubli")


def _key(name: str) -> str:
    """A name as the library keys it: lower case, letters and digits only."""
    return re.sub(r"[^0-9a-zäöü]", "", name.strip().lower())


def _without_maker(key: str) -> str:
    maker = next((m for m in _MAKERS if key.startswith(m) and len(key) > len(m)), "")
    return key[len(maker) :]


def _aliases() -> dict[str, str]:
    """Each entry's key, its title ("ABB IRB 1200-5/0.9", "FANUC R-2000iC/165F") and any
    ``aliases`` it lists, keyed; a key is never another entry's alias."""
    library = _library()
    out: dict[str, str] = {}
    for name, entry in library.items():
        for alias in [entry.get("title", ""), *entry.get("aliases", [])]:
            out.setdefault(_key(str(alias)), name)
            out.setdefault(_without_maker(_key(str(alias))), name)
    out.update({name: name for name in library})
    return out


def load_robot(name: str) -> Robot:
    """The library robot called ``name`` as users write it: case, spaces and punctuation aside
    ("UR-5e", "R-2000iC/165F"), a maker's name before it ("ABB IRB 120") or a variant's full name
    where the entry lists it as an alias ("IRB 1200-5/0.9"); in SI units."""
    key = _key(name)
    aliases = _aliases()
    if key not in aliases:
        key = _without_maker(key)
    if key not in aliases:
        raise UnknownRobotError(name, robot_names())
    real = aliases[key]
    return _robot_from_entry(real, _library()[real])
