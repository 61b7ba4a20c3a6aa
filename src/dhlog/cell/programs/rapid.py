"""ABB RAPID modules (``.mod``, ``.modx``, ``.prg``): their motions' targets found and rewritten.

RAPID (ABB's RAPID Reference Manual, data types ``robtarget``, ``jointtarget``, ``confdata``,
``tooldata``; the instructions ``MoveJ``, ``MoveL``, ``MoveC``, ``MoveAbsJ``, ``ConfJ``,
``ConfL``) declares a Cartesian target as

    CONST robtarget p15 := [[600, 500, 225.3], [1, 0, 0, 0], [1, 1, 0, 0], [11, 12.3, 9E9, …]];

the TCP's position in mm, its orientation as a quaternion q1 … q4 (q1 the scalar), the
configuration ``confdata`` [cf1, cf4, cf6, cfx] — cf1, cf4, cf6 the quadrants of axes 1, 4
and 6 (quadrant 0 is 0–90°, 1 is 90–180°, −1 is 0 to −90°: ⌊angle / 90°⌋), cfx the
robot-dependent rest — and the external axes (9E9: none). A joint target ``jointtarget`` is
[[axes 1–6 in degrees], [external axes]]. ``MoveL p10, v1000, z50, tool1\\WObj:=wobj0;``: the
target first (``MoveC``: the circle point, then the target), optional arguments after a
backslash, the tool last among the positional ones; ``ConfL\\Off`` / ``ConfJ\\Off`` stop the
controller checking the configuration written (it then takes the one nearest the current
joints). A ``tooldata`` declared in the module gives its TCP (``[TRUE, [[x, y, z], [q1, q2, q3,
q4]], …]``, mm); ``tool0`` is the flange.

Read here: declarations of ``robtarget``, ``jointtarget`` and ``tooldata`` (``CONST``,
``PERS``, ``VAR``; not arrays) and inline literals, every motion in text order. Written: the
position and quaternion of the corrected pose (the nominal's at the corrected joints), cf1,
cf4 and cf6 of the corrected joints (the same unless a correction crosses a quadrant's edge),
cfx and the external axes as they were (the configuration does not change); a joint target's
axes. With the configuration checked (the default), the nominal's joints for a pose must be in
the quadrants its confdata names — else, from those quadrants, or the target is named. A
target relative to a work object other than ``wobj0``, with a tool not declared here (and no
``--tcp``), or computed when the program runs (``Offs(…)``, ``RelTool(…)``) is named and left.
Comments (``!``) and strings are never read or changed.
"""

from __future__ import annotations

import math
import re

import numpy as np

from dhlog.cell import rotations
from dhlog.cell.programs.common import (
    NUMBER,
    RUNTIME,
    Literal,
    Motion,
    Program,
    ProgramError,
    Units,
    arguments,
    closing,
)
from dhlog.geometry._checks import FloatArray

#: Each motion's target arguments and its positional arguments before the tool.
MOTIONS = {"movej": 1, "movel": 1, "movec": 2, "moveabsj": 1}
_DECLARE = re.compile(
    r"(?im)^[ \t]*(?:(?:LOCAL|TASK)[ \t]+)?(?:CONST|PERS|VAR)[ \t]+"
    r"(robtarget|jointtarget|tooldata)[ \t]+([A-Za-z]\w*)[ \t]*:=[ \t]*(?=\[)"
)
_CALL = re.compile(r"(?i)\b(MoveJ|MoveL|MoveC|MoveAbsJ|ConfL|ConfJ)\b")
#: the shape of each literal: how many numbers each inner list holds
SHAPES = {"robtarget": (3, 4, 4, 6), "jointtarget": (6, 6)}


def _masked(text: str) -> str:
    """``text`` with its comments (``!`` to the end of the line) and strings blanked."""
    out = list(text)
    k, n = 0, len(text)
    while k < n:
        c = text[k]
        if c == "!":
            while k < n and text[k] != "\n":
                out[k] = " "
                k += 1
        elif c == '"':
            out[k] = " "
            k += 1
            while k < n and text[k] != '"' and text[k] != "\n":
                out[k] = " "
                k += 1
            if k < n and text[k] == '"':
                out[k] = " "
                k += 1
        else:
            k += 1
    return "".join(out)


def _quadrant(angle: float) -> int:
    """RAPID's quadrant of a joint angle (rad): ⌊angle / 90°⌋."""
    return math.floor(math.degrees(angle) / 90.0 + 1e-12)


def _pose(values: tuple[float, ...]) -> FloatArray:
    T = np.eye(4)
    T[:3, 3] = np.array(values[:3]) * 1e-3
    T[:3, :3] = rotations.matrices(np.array([values[3:7]]), "quaternion", degrees=False)[0]
    return T


def _pose_values(T: FloatArray, q: FloatArray, old: tuple[float, ...]) -> list[float]:
    quat = rotations.values(T[None, :3, :3], "quaternion", degrees=False)
    quat = rotations.near(quat, np.array([old[3:7]]), "quaternion", degrees=False)[0]
    conf = [_quadrant(q[0]), _quadrant(q[3]), _quadrant(q[5]), old[10]]
    return [*(float(v) for v in T[:3, 3] * 1e3), *(float(v) for v in quat), *conf, *old[11:]]


def _accepts(old: tuple[float, ...], q: FloatArray) -> str | None:
    """Why joints ``q`` are not in the quadrants of axes 1, 4, 6 the confdata names."""
    want = [int(old[7]), int(old[8]), int(old[9])]
    got = [_quadrant(q[0]), _quadrant(q[3]), _quadrant(q[5])]
    if want == got:
        return None
    return (
        f"its confdata puts axes 1, 4, 6 in quadrants {want}, but the nominal reaches it in "
        f"{got} on the configuration it is continued on and in none from those quadrants "
        "(ConfL/ConfJ would stop); correct the confdata or turn the check off"
    )


def _fallback(old: tuple[float, ...], previous: FloatArray | None) -> FloatArray:
    """A start in the confdata's quadrants (their middles) for axes 1, 4, 6."""
    start = np.array(previous, dtype=np.float64) if previous is not None else np.zeros(6)
    for axis, cf in ((0, old[7]), (3, old[8]), (5, old[9])):
        start[axis] = math.radians((cf + 0.5) * 90.0)
    if previous is None:
        start[4] = math.radians(45.0)  # off the wrist's singularity
    return start


def _text(v: float, k: int, kind: str) -> str:
    """A robtarget's numbers as RAPID writes them: mm to 0.1 µm, quaternions to 1e-9,
    confdata whole; a jointtarget's degrees to 1e-7."""
    if kind == "joints":
        s = f"{v:.7f}".rstrip("0").rstrip(".")
        return "0" if s in ("-0", "") else s
    if 7 <= k <= 10 and float(v).is_integer():
        return str(int(v))
    digits = 9 if 3 <= k <= 6 else 4
    s = f"{v:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


UNITS = Units(
    pose=_pose,
    pose_values=_pose_values,
    joints=lambda values: np.radians(np.array(values[:6], dtype=np.float64)),
    joint_values=lambda q, old: [*(float(v) for v in np.degrees(q)), *old[6:]],
    text=_text,
    accepts=_accepts,
    fallback=_fallback,
)


class _Reader:
    """One module's declarations and motions, read from its masked text."""

    def __init__(self, path: str, text: str, n: int) -> None:
        self.path, self.text, self.n = path, text, n
        self.masked = _masked(text)
        self.literals: list[Literal] = []
        self.names: dict[str, int] = {}
        self.tools: dict[str, FloatArray] = {}
        for match in _DECLARE.finditer(self.masked):
            kind, name = match.group(1).lower(), match.group(2)
            start = match.end()
            if kind == "tooldata":
                tcp = self._tool(start)
                if tcp is not None:
                    self.tools[name.lower()] = tcp
                continue
            index = self.literal(kind, start, name)
            if index is not None:
                self.names[name.lower()] = index

    def line(self, pos: int) -> int:
        return self.text.count("\n", 0, pos) + 1

    def _lists(self, start: int) -> list[tuple[int, int]] | None:
        """The spans of the inner lists of the nested literal opening at ``start``."""
        end = closing(self.masked, start + 1)
        if end < 0:
            raise ProgramError(self.path, self.line(start), "a '[' is never closed")
        inner = [m.span(1) for m in re.finditer(r"\[([^\[\]]*)\]", self.masked[start + 1 : end])]
        return [(a + start + 1, b + start + 1) for a, b in inner]

    def literal(self, kind: str, start: int, name: str) -> int | None:
        """The ``robtarget`` or ``jointtarget`` literal at ``start`` (None: not numbers)."""
        lists = self._lists(start)
        shape = SHAPES[kind]
        line = self.line(start)
        if lists is None or len(lists) != len(shape):
            raise ProgramError(
                self.path,
                line,
                f"{name}: a {kind} is {len(shape)} lists ([[x, y, z], [q1, q2, q3, q4], [cf1, "
                "cf4, cf6, cfx], [external axes]] or [[axes], [external axes]])",
            )
        spans, values = [], []
        for (a, b), want in zip(lists, shape, strict=True):
            pieces = self.masked[a:b].split(",")
            if len(pieces) != want:
                raise ProgramError(
                    self.path,
                    self.line(a),
                    f"{name}: '[{self.text[a:b].strip()[:40]}]' has {len(pieces)} values; "
                    f"this part of a {kind} takes {want}",
                )
            offset = a
            for piece in pieces:
                stripped = piece.strip()
                at = offset + (len(piece) - len(piece.lstrip()))
                offset += len(piece) + 1
                if not NUMBER.fullmatch(stripped):
                    return None
                value = float(stripped)
                if not math.isfinite(value):
                    raise ProgramError(
                        self.path, self.line(at), f"'{stripped[:24]}' is not a finite number"
                    )
                spans.append((at, at + len(stripped)))
                values.append(value)
        if kind == "robtarget":
            norm = math.sqrt(sum(v * v for v in values[3:7]))
            if abs(norm - 1.0) > 1e-3:
                raise ProgramError(
                    self.path, line, f"{name}: the quaternion has norm {norm:.6g}, not 1"
                )
        kinds = "pose" if kind == "robtarget" else "joints"
        lit = Literal(kinds, line, tuple(spans), tuple(values), name)
        self.literals.append(lit)
        return len(self.literals) - 1

    def _tool(self, start: int) -> FloatArray | None:
        """The TCP of a tooldata literal (None: not numbers)."""
        body = self.masked[start : closing(self.masked, start + 1) + 1]
        match = re.match(r"\[\s*\w+\s*,\s*\[\s*\[([^\]]*)\]\s*,\s*\[([^\]]*)\]", body)
        if match is None:
            return None
        try:
            xyz = [float(v) for v in match.group(1).split(",")]
            quat = [float(v) for v in match.group(2).split(",")]
        except ValueError:
            return None
        if len(xyz) != 3 or len(quat) != 4 or not all(map(math.isfinite, xyz + quat)):
            return None
        return _pose((*xyz, *quat))


def read_rapid(path: str, text: str, n: int, tcp: FloatArray | None) -> Program:
    """The RAPID module ``text`` (from ``path``) for a robot of ``n`` joints: see the module
    docstring; ``tcp`` (4, 4): the TCP of tools the module does not declare (None: they are
    named). A literal of the wrong shape, a quaternion not of norm 1, a motion without ``;``:
    a :class:`~dhlog.cell.programs.common.ProgramError` naming the line."""
    reader = _Reader(path, text, n)
    masked = reader.masked
    checked = {"movel": True, "movec": True, "movej": True}
    motions: list[Motion] = []
    for call in _CALL.finditer(masked):
        name = call.group(1).lower()
        line = reader.line(call.start())
        end = masked.find(";", call.end())
        if end < 0:
            raise ProgramError(path, line, f"{call.group(1)} has no ';'; end the instruction")
        if name in ("confl", "confj"):
            on = not re.match(r"\s*\\\s*off\b", masked[call.end() : end], re.IGNORECASE)
            for motion in ("movel", "movec") if name == "confl" else ("movej",):
                checked[motion] = on
            continue
        pieces = arguments(masked, call.end(), end)
        optional = " ".join(masked[a:b] for a, b in pieces)
        positional = []
        for a, b in pieces:
            head = masked[a:b].split("\\")[0]
            if head.strip():
                positional.append((a, a + len(head)))
        wanted = MOTIONS[name]
        if len(positional) < wanted + 3:
            raise ProgramError(
                path, line, f"{call.group(1)} needs its target, speed, zone and tool"
            )
        wobj = re.search(r"\\\s*WObj\s*:=\s*(\w+)", optional, re.IGNORECASE)
        tool = masked[positional[wanted + 2][0] : positional[wanted + 2][1]].strip().lower()
        why = None
        if wobj is not None and wobj.group(1).lower() != "wobj0":
            why = (
                f"its target is relative to the work object {wobj.group(1)}; give targets in "
                "the base frame (wobj0)"
            )
        tcp_T = reader.tools.get(tool)
        if tcp_T is None and tool == "tool0":
            tcp_T = np.eye(4)
        if tcp_T is None and tcp is not None:
            tcp_T = tcp
        for a, b in positional[:wanted]:
            kind = "jointtarget" if name == "moveabsj" else "robtarget"
            index, problem = _target(reader, a, b, kind)
            if kind == "robtarget" and tcp_T is None and index is not None:
                problem = f"its tool {tool} is not declared in the module; give its TCP with --tcp"
            problem = why or problem
            motions.append(
                Motion(
                    call.group(1),
                    line,
                    None if problem else index,
                    np.eye(4) if tcp_T is None else tcp_T,
                    why=problem,
                    checked=checked.get(name, True),
                )
            )
    return Program(path, text, reader.literals, motions, UNITS, [])


def _target(reader: _Reader, start: int, end: int, kind: str) -> tuple[int | None, str | None]:
    """The literal a motion's target argument runs, or why none."""
    expr = reader.masked[start:end].strip()
    shown = reader.text[start:end].strip()
    shown = shown if len(shown) <= 40 else shown[:39] + "…"
    if expr.startswith("["):
        lead = start + (len(reader.masked[start:end]) - len(reader.masked[start:end].lstrip()))
        index = reader.literal(kind, lead, "the inline target")
    elif re.fullmatch(r"[A-Za-z]\w*", expr):
        found = reader.names.get(expr.lower())
        if found is None:
            return None, f"its target '{shown}' is not declared in the module with numbers"
        index = found
    else:
        index = None
    if index is None:
        return None, f"its target '{shown}' {RUNTIME}"
    want = "pose" if kind == "robtarget" else "joints"
    if reader.literals[index].kind != want:
        return None, f"its target '{shown}' is not a {kind}"
    return index, None
