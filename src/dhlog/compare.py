"""Has the robot changed? Two results compared parameter by parameter and over the joint range.

Each parameter's change is judged by its significance, the difference over the combined σ of
the two sessions (independent measurements: ``√(σ_A² + σ_B²)``); parameters fixed by a
convention in either are not compared. The rows are compared in the form the results show them
(the Hayati–Mirmirani form where both have the same nearly parallel rows, else standard DH).
The forward-kinematics difference is taken in the robot's own base frame (frame 1), so a tracker
placed elsewhere in the second session is no change of the robot.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dhlog.dhfile import DHFileError, parse_dh
from dhlog.geometry._checks import FloatArray, wrap_angle
from dhlog.kinematics import fk_point

NAMES = ("theta_offset", "d_offset", "a", "alpha")


@dataclass(frozen=True)
class Change:
    """One parameter's change: name (``a_2``, ``beta_2``, ``tool_x``), A, B, B − A, the
    combined σ (None where either is fixed), and whether it is angular."""

    name: str
    a: float
    b: float
    diff: float
    sigma: float | None
    angular: bool

    @property
    def significance(self) -> float | None:
        """|B − A| over the combined σ."""
        if self.sigma is None or self.sigma <= 0:
            return None
        return abs(self.diff) / self.sigma


@dataclass(frozen=True)
class Comparison:
    """The parameter changes and the FK difference over the joint range (RMS, max, the joint
    vector of the max), in metres."""

    changes: list[Change]
    fk_rms: float
    fk_max: float
    fk_max_at: FloatArray
    samples: int


def _load(path: str | Path) -> dict[str, Any]:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DHFileError(str(path), f"cannot be read as JSON ({exc}).") from None
    if not isinstance(data, dict) or not isinstance(data.get("standard_dh"), list):
        raise DHFileError(str(path), "is not a dhlog result (no 'standard_dh').")
    return data


def _rows(data: dict[str, Any], hayati: bool) -> list[dict[str, Any]]:
    return list(data["hayati_dh"]["rows"]) if hayati else list(data["standard_dh"])


def _std(row: dict[str, Any], key: str) -> float | None:
    value = (row.get("std") or {}).get(key.removesuffix("_offset"))
    held = key.removesuffix("_offset") in (row.get("fixed") or [])
    return None if value is None or held else float(value)


def compare(
    a_path: str | Path, b_path: str | Path, *, limits: FloatArray | None = None, points: int = 2000
) -> Comparison:
    """Compare two results of the same robot (``limits`` (n, 2): the joint range; default ±π
    and ±0.1 m)."""
    A, B = _load(a_path), _load(b_path)
    if len(A["standard_dh"]) != len(B["standard_dh"]):
        raise DHFileError(
            str(b_path), f"has {len(B['standard_dh'])} joints, {a_path} {len(A['standard_dh'])}."
        )
    forms = [
        [r["form"] for r in d["hayati_dh"]["rows"]] if d.get("hayati_dh") else None for d in (A, B)
    ]
    hayati = forms[0] is not None and forms[0] == forms[1]
    changes = []
    for i, (ra, rb) in enumerate(zip(_rows(A, hayati), _rows(B, hayati), strict=True)):
        for key in NAMES:
            if key == "d_offset" and ra.get("form") == "hayati":
                key = "beta"
            angular = key in ("theta_offset", "alpha", "beta")
            va, vb = float(ra[key]), float(rb[key])
            diff = wrap_angle(vb - va) if angular else vb - va
            sa, sb = _std(ra, key), _std(rb, key)
            sigma = None if sa is None or sb is None else math.hypot(sa, sb)
            name = key.removesuffix("_offset")
            changes.append(Change(f"{name}_{i + 1}", va, vb, diff, sigma, angular))
    tool_a, tool_b = A.get("tool") or {}, B.get("tool") or {}
    for k, axis in enumerate("xyz"):
        if tool_a.get("point") is None or tool_b.get("point") is None:
            break
        va, vb = float(tool_a["point"][k]), float(tool_b["point"][k])
        sa = (tool_a.get("std") or [None] * 3)[k]
        sb = (tool_b.get("std") or [None] * 3)[k]
        sigma = None if sa is None or sb is None else math.hypot(sa, sb)
        changes.append(Change(f"tool_{axis}", va, vb, vb - va, sigma, False))
    ma, mb = parse_dh(A, str(a_path)), parse_dh(B, str(b_path))
    n = ma.table.n
    if limits is None:
        revolute = [t.value == "revolute" for t in ma.table.joint_types]
        limits = np.array([[-math.pi, math.pi] if r else [-0.1, 0.1] for r in revolute])
    Q = np.random.default_rng(0).uniform(limits[:, 0], limits[:, 1], (points, n))
    diff = np.linalg.norm(
        fk_point(ma.table, Q, ma.tool_point) - fk_point(mb.table, Q, mb.tool_point), axis=1
    )
    worst = int(np.argmax(diff))
    return Comparison(
        changes, float(np.sqrt(np.mean(diff**2))), float(diff[worst]), Q[worst], points
    )
