"""What every program format shares: the literals a reader found, the motions that run them,
the correction of the whole program in order and the text written back.

A reader returns a :class:`Program`: the program's text, its target literals (each number's
place in the text and value as written), its motions in the order of the text (each naming the
literal it runs, the joint literal its pose is solved near, the TCP then in force — or why it
cannot be corrected: a target computed when the program runs) and the format's units
(:class:`Units`). :func:`filtered` corrects the motions through
:func:`dhlog.cell.sequence.filter_targets` and writes the same text with only the corrected
literals' numbers replaced.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable
from dataclasses import dataclass, field

from dhlog.cell.sequence import Filtered, Target, filter_targets
from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray
from dhlog.io.dhfile import DHModel

#: A number as a program writes it (sign, digits, decimals, exponent).
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def closing(masked: str, after: int) -> int:
    """The index of the bracket closing the one opened just before ``after`` in the program's
    masked text (comments and strings blanked), -1: none."""
    depth = 1
    for k in range(after, len(masked)):
        c = masked[k]
        if c in "([":
            depth += 1
        elif c in ")]":
            depth -= 1
            if depth == 0:
                return k
    return -1


def arguments(masked: str, start: int, end: int) -> list[tuple[int, int]]:
    """The spans of the top-level, comma-separated arguments between ``start`` and ``end``."""
    spans, depth, begin = [], 0, start
    for k in range(start, end):
        c = masked[k]
        if c in "([":
            depth += 1
        elif c in ")]":
            depth -= 1
        elif c == "," and depth == 0:
            spans.append((begin, k))
            begin = k + 1
    spans.append((begin, end))
    return spans


class ProgramError(InputError):
    """A program that cannot be read as its format: the message names the file and line."""

    def __init__(self, path: str, line: int, problem: str) -> None:
        self.path = path
        self.line = line
        super().__init__(f"{path}, line {line}: {problem}.")


@dataclass(frozen=True)
class Literal:
    """A target literal of the text: ``kind`` ``pose`` or ``joints``, the ``line`` it is on,
    each number's ``spans`` (start, end) in the text and its ``values`` as written (the
    format's units), ``name`` as a message shows it (``Waypoint_1_p``, ``p[…]``)."""

    kind: str
    line: int
    spans: tuple[tuple[int, int], ...]
    values: tuple[float, ...]
    name: str


@dataclass(frozen=True)
class Motion:
    """One motion of the program, in text order: the ``instruction`` (``movel``), its
    ``line``, the ``literal`` it runs (an index into :attr:`Program.literals`; None with
    ``why``: its target is computed when the program runs), ``hint`` (a joint literal near
    which its pose is solved: ``get_inverse_kin(…, qnear=…)``) and the ``tcp`` in force (4, 4:
    the TCP in the flange frame)."""

    instruction: str
    line: int
    literal: int | None
    tcp: FloatArray
    hint: int | None = None
    why: str | None = None
    #: the controller checks the configuration written with the pose (RAPID's ConfL/ConfJ on)
    checked: bool = True


@dataclass(frozen=True)
class Units:
    """A format's numbers as SI and back: ``pose`` (the literal's values → the TCP pose, 4, 4,
    m), ``pose_values`` (a pose, the corrected joints and the old values → the new values, in
    the representation nearest the old one, configuration data made the joints'), ``joints`` /
    ``joint_values`` (the literal's values ↔ rad or m; the old values given) and ``text`` (the
    k-th value of a literal of a kind as the program writes it). A format whose poses carry their
    configuration: ``accepts`` (the old values and nominal joints → why those joints are not
    the configuration written, or None) and ``fallback`` (the old values and the previous
    target's joints → where to solve from instead)."""

    pose: Callable[[tuple[float, ...]], FloatArray]
    pose_values: Callable[[FloatArray, FloatArray, tuple[float, ...]], list[float]]
    joints: Callable[[tuple[float, ...]], FloatArray]
    joint_values: Callable[[FloatArray, tuple[float, ...]], list[float]]
    text: Callable[[float, int, str], str]
    accepts: Callable[[tuple[float, ...], FloatArray], str | None] | None = None
    fallback: Callable[[tuple[float, ...], FloatArray | None], FloatArray] | None = None


@dataclass(frozen=True)
class Program:
    """A program as its reader found it (see the module docstring); ``notes``: what the reader
    assumed (no TCP set before the first pose, …)."""

    path: str
    text: str
    literals: list[Literal]
    motions: list[Motion]
    units: Units
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Corrected:
    """A program corrected: the ``text`` to write, the motions' correction (``filtered``, one
    row per motion with a literal, in order; ``lines`` their line numbers), ``problems``
    (line, why) for every motion not corrected, ``notes`` and ``changed`` (the literals
    whose numbers were replaced)."""

    text: str
    filtered: Filtered
    lines: list[int]
    problems: list[tuple[int, str]]
    notes: list[str]
    changed: int


#: Why a motion whose target (or TCP) is an expression is not corrected, and what to do.
NUMBERS = "give it as numbers to correct it"
RUNTIME = f"is computed when the program runs: {NUMBERS}"

#: Corrected numbers of one literal needed by two motions agree to this (the format's units).
AGREE = 1e-9


def filtered(
    program: Program,
    result: DHModel,
    nominal: DHModel,
    *,
    limits: FloatArray | None = None,
) -> Corrected:
    """``program`` corrected for ``result`` on a controller running ``nominal`` (see the module
    docstring): every motion's target through :func:`~dhlog.cell.sequence.filter_targets` in
    order; a literal run by several motions takes the first one's numbers, and a later motion
    needing others is a problem. The text changes only inside the literals corrected."""
    units = program.units
    problems: list[tuple[int, str]] = []
    targets: list[Target] = []
    runs: list[Motion] = []
    for motion in program.motions:
        if motion.literal is None:
            problems.append((motion.line, motion.why or "its target is not a literal"))
            continue
        lit = program.literals[motion.literal]
        where = f"line {motion.line}"
        if lit.kind == "joints":
            targets.append(Target(where, joints=units.joints(lit.values)))
        else:
            hint = None
            if motion.hint is not None:
                hint = units.joints(program.literals[motion.hint].values)
            accepts = fallback = None
            if units.accepts is not None and motion.checked:
                accepts = functools.partial(units.accepts, lit.values)
            if units.fallback is not None:
                fallback = functools.partial(units.fallback, lit.values)
            targets.append(
                Target(
                    where,
                    pose=units.pose(lit.values),
                    tcp=motion.tcp,
                    hint=hint,
                    accepts=accepts,
                    fallback=fallback,
                )
            )
        runs.append(motion)
    done = filter_targets(result, nominal, targets, limits=limits)
    new: dict[int, tuple[list[float], int]] = {}

    def put(index: int, values: list[float], line: int) -> str | None:
        if index in new:
            before, first = new[index]
            if max(abs(a - b) for a, b in zip(before, values, strict=True)) > AGREE:
                name = program.literals[index].name
                return (
                    f"runs {name} (line {program.literals[index].line}) again, which line "
                    f"{first}'s correction set; here it would need other numbers — give this "
                    "motion its own target"
                )
            return None
        new[index] = (values, line)
        return None

    for i, motion in enumerate(runs):
        if i in done.problems:
            problems.append((motion.line, done.problems[i]))
            continue
        assert motion.literal is not None
        lit = program.literals[motion.literal]
        q = done.joints[i]
        if lit.kind == "joints":
            clash = put(motion.literal, units.joint_values(q, lit.values), motion.line)
        else:
            shown = units.pose_values(done.commanded[i], q, lit.values)
            clash = put(motion.literal, shown, motion.line)
            if clash is None and motion.hint is not None:
                near = program.literals[motion.hint].values
                clash = put(motion.hint, units.joint_values(q, near), motion.line)
        if clash is not None:
            problems.append((motion.line, clash))
    text = program.text
    edits: list[tuple[int, int, str]] = []
    for index, (values, _) in new.items():
        lit = program.literals[index]
        for k, ((start, end), v) in enumerate(zip(lit.spans, values, strict=True)):
            if v != lit.values[k]:  # a number unchanged keeps its spelling
                edits.append((start, end, units.text(v, k, lit.kind)))
    for start, end, written in sorted(edits, reverse=True):
        text = text[:start] + written + text[end:]
    notes = [*program.notes, *done.notes]
    return Corrected(text, done, [m.line for m in runs], sorted(problems), notes, changed=len(new))
