"""Option values given as text (numbers, joint lists, the term model, a DH model or pipeline by
name or file) turned into what the library takes; exit 1 naming the option when one is wrong."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import typer

from dhlog.cli.common import EXIT_USAGE, plain, stderr

if TYPE_CHECKING:
    from dhlog.io.dhfile import DHModel
    from dhlog.io.pipeline import Pipeline


def triples(text: str, what: str) -> list[tuple[float, float, float]]:
    """``'x,y,z;x,y,z'`` as number triples (exit 1 naming the option otherwise)."""
    out = []
    for group in (g for g in text.split(";") if g.strip()):
        values = floats(group, what)
        if len(values) != 3:
            stderr.print(
                f"error: {what} takes x,y,z triples separated by ';', not '{plain(group.strip())}'."
            )
            raise typer.Exit(EXIT_USAGE)
        out.append((values[0], values[1], values[2]))
    return out


def tuples(text: str, what: str, size: int) -> list[tuple[float, ...]]:
    """``'j:v,j:v'`` as tuples of ``size`` numbers, the first a whole joint number (exit 1
    naming the option otherwise)."""
    out = []
    for group in (g.strip() for g in text.split(",") if g.strip()):
        try:
            values = tuple(float(v) for v in group.split(":"))
        except ValueError:
            values = ()
        if len(values) != size or not math.isfinite(values[0]) or values[0] != int(values[0]):
            form = ":".join(["J", "C"] if size == 2 else ["J", "A", "B"])
            stderr.print(
                f"error: {what} takes {form} groups separated by ',', not '{plain(group)}'."
            )
            raise typer.Exit(EXIT_USAGE)
        out.append(values)
    return out


def floats(text: str, what: str, *, finite: bool = True) -> list[float]:
    """Comma-separated numbers, finite unless ``finite`` is False (exit 1 naming the option
    otherwise: ``nan`` or ``inf`` in a joint vector printed NaN matrices, in a reference pose
    failed far from the option)."""
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        values = [math.nan]
    if finite and not all(math.isfinite(v) for v in values):
        stderr.print(
            f"error: {what} must be finite numbers separated by commas, not '{plain(text)}'."
        )
        raise typer.Exit(EXIT_USAGE) from None
    return values


PIPELINE_HELP = (
    "A shipped pipeline's name (dhlog pipelines lists them) or a pipeline file (default: "
    "the shipped one whose topics the log holds)."
)


def load_pipeline(spec: str) -> Pipeline:
    """A pipeline file, or a shipped pipeline by name (``dhlog pipelines`` lists them)."""
    from dhlog.io.pipeline import pipeline_from

    return pipeline_from(spec)


def load_model(spec: str) -> DHModel:
    """A DH model from a DH file or a library robot name."""
    from dhlog.io.dhfile import dh_model_from

    return dh_model_from(spec)


def model_request(model: str, gravity: str | None, harmonic_joints: str | None) -> Any:
    """``--model``, ``--gravity`` and ``--harmonic-joints`` as a request (exit 1 naming the
    option when one is wrong)."""
    from dhlog.identify.model.select import MODELS, ModelRequest

    if model not in MODELS:
        stderr.print(f"error: --model must be one of {', '.join(MODELS)}, not '{plain(model)}'.")
        raise typer.Exit(EXIT_USAGE)
    g = None
    if gravity is not None:
        values = floats(gravity, "--gravity")
        if len(values) != 3 or not all(math.isfinite(v) for v in values) or not any(values):
            stderr.print(
                f"error: --gravity takes three numbers x,y,z, not all zero, not '{plain(gravity)}'."
            )
            raise typer.Exit(EXIT_USAGE)
        g = (values[0], values[1], values[2])
    joints = None
    if harmonic_joints is not None:
        numbers = joint_numbers(harmonic_joints, "--harmonic-joints")
        if not numbers or any(not 1 <= j <= 64 for j in numbers):
            stderr.print(
                "error: --harmonic-joints takes joint numbers (1, 2, …), not "
                f"'{plain(harmonic_joints)}'."
            )
            raise typer.Exit(EXIT_USAGE)
        joints = tuple(sorted({j - 1 for j in numbers}))
    return ModelRequest(model, g, joints)


def joint_numbers(text: str, what: str) -> list[int]:
    """Joint numbers (1, 2, …), comma-separated (exit 1 naming the option when one is not a
    whole number; their range is the robot's to check)."""
    values = floats(text, what, finite=False)
    if not all(math.isfinite(v) and v == int(v) for v in values):
        stderr.print(f"error: {what} takes joint numbers (1, 2, …), not '{plain(text)}'.")
        raise typer.Exit(EXIT_USAGE)
    return [int(v) for v in values]


def parked_joints(text: str) -> tuple[tuple[int, float], ...]:
    """``--park-joints``: 'J' or 'J:VALUE' items, comma-separated (exit 1 naming the option
    when one is not a joint number with an optional finite value)."""
    out = []
    for item in listed(text):
        joint, _, value = item.partition(":")
        try:
            j, v = float(joint), float(value) if value else 0.0
        except ValueError:
            j, v = math.nan, math.nan
        if not (math.isfinite(j) and j == int(j) and math.isfinite(v)):
            stderr.print(
                f"error: --park-joints takes J or J:VALUE (a joint number, a value in rad or "
                f"m), comma-separated, not '{plain(item)}'."
            )
            raise typer.Exit(EXIT_USAGE)
        out.append((int(j), v))
    return tuple(out)


def angles(values: np.ndarray, unit: str, types: Sequence[object] | None) -> np.ndarray:
    """``values`` in radians: revolute entries (all but declared prismatic ones) from degrees
    when ``unit`` is deg."""
    if unit != "deg":
        return values
    prismatic = [str(getattr(t, "value", t)) == "prismatic" for t in (types or [])]
    prismatic += [False] * (values.size - len(prismatic))
    return np.where(prismatic[: values.size], values, np.radians(values))


def listed(text: str | None) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()] if text else []
