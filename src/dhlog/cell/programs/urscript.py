"""URScript programs (``.script``, ``.urscript``): their motions' targets found and rewritten.

URScript (Universal Robots' Script Manual, the motion functions; the UR client library's
``resources/external_control.urscript``, UniversalRobots/Universal_Robots_Client_Library
93800a5, uses the same calls) moves with ``movej(q, a, v, t, r)``, ``movel(pose, …)``,
``movep(pose, …)`` and ``movec(pose_via, pose_to, …)``. A pose is ``p[x, y, z, rx, ry, rz]``:
the TCP in the robot's base frame, m, and its orientation as a rotation vector (rad); joint
positions are a list ``[q1, …, q6]`` in rad. ``movej`` given a pose solves its inverse
kinematics near the current joints, ``movel`` given joints moves to their forward kinematics.
Programs PolyScope writes hold their waypoints in variables (``global Waypoint_1_p=p[…]``,
``global Waypoint_1_q=[…]``) and move to ``get_inverse_kin(Waypoint_1_p,
qnear=Waypoint_1_q)``; ``set_tcp(p[…])`` sets the TCP (in the flange frame, tool0).

Read here: every motion in text order; its target a literal (``p[…]`` or ``[…]`` of numbers),
a variable assigned such a literal (the last assignment before the motion, else the first),
or ``get_inverse_kin`` of those (its ``qnear`` the configuration the pose is solved near, and
corrected too); the TCP is the last literal ``set_tcp`` before the motion. A target computed
when the program runs (``pose_trans(…)``, ``p[x + 0.1, …]``) is named and left as it is.
Comments (``#``) and strings are never read or changed. Only the literals' numbers are
rewritten (to 0.1 nm and 1e-10 rad); every other character stays.
"""

from __future__ import annotations

import math
import re

import numpy as np

from dhlog.cell import rotations
from dhlog.cell.programs.common import (
    NUMBER,
    NUMBERS,
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

#: The motion functions and the names of their target arguments, in order.
MOTIONS = {
    "movej": ("q",),
    "movel": ("pose",),
    "movep": ("pose",),
    "movec": ("pose_via", "pose_to"),
}
_NOT_FINITE = re.compile(r"[-+]?(?:nan|inf|infinity)", re.IGNORECASE)
_LIST = re.compile(r"(\bp\s*)?\[([^\[\]]*)\]")
_ASSIGN = re.compile(
    r"(?m)^[ \t]*(?:(?:global|local)[ \t]+)?([A-Za-z_]\w*)[ \t]*=[ \t]*(?=p?[ \t]*\[)"
)
_CALL = re.compile(r"\b(movej|movel|movep|movec|set_tcp)\s*\(")
_NAME = re.compile(r"[A-Za-z_]\w*")
_IK = re.compile(r"get_inverse_kin\s*\(")


def _masked(text: str) -> str:
    """``text`` with its comments and strings blanked (same length, newlines kept)."""
    out = list(text)
    k, n = 0, len(text)
    while k < n:
        c = text[k]
        if c == "#":
            while k < n and text[k] != "\n":
                out[k] = " "
                k += 1
        elif c in "\"'":
            quote, out[k] = c, " "
            k += 1
            while k < n and text[k] != quote and text[k] != "\n":
                if text[k] == "\\":
                    out[k] = " "
                    k += 1
                if k < n and text[k] != "\n":
                    out[k] = " "
                k += 1
            if k < n and text[k] == quote:
                out[k] = " "
                k += 1
        else:
            k += 1
    return "".join(out)


def _number_text(v: float) -> str:
    """A value as the program gets it: fixed point, 10 decimals, trailing zeros dropped."""
    s = f"{v:.10f}".rstrip("0")
    s = s + "0" if s.endswith(".") else s
    return "0.0" if s in ("-0.0", "0.0") else s


def _pose(values: tuple[float, ...]) -> FloatArray:
    T = np.eye(4)
    T[:3, 3] = values[:3]
    T[:3, :3] = rotations.matrices(np.array([values[3:]]), "rotvec", degrees=False)[0]
    return T


def _pose_values(T: FloatArray, q: FloatArray, old: tuple[float, ...]) -> list[float]:
    r = rotations.values(T[None, :3, :3], "rotvec", degrees=False)
    r = rotations.near(r, np.array([old[3:]]), "rotvec", degrees=False)[0]
    return [*(float(v) for v in T[:3, 3]), *(float(v) for v in r)]


UNITS = Units(
    pose=_pose,
    pose_values=_pose_values,
    joints=lambda values: np.array(values, dtype=np.float64),
    joint_values=lambda q, old: [float(v) for v in q],
    text=lambda v, k, kind: _number_text(v),
)


class _Reader:
    """One program's literals, assignments and motions, read from its masked text."""

    def __init__(self, path: str, text: str, n: int) -> None:
        self.path, self.text, self.n = path, text, n
        self.masked = _masked(text)
        self.literals: list[Literal] = []
        #: literal index by the position of its opening bracket, and whether each is all numbers
        self.at: dict[int, int] = {}
        self.numeric: list[bool] = []
        for match in _LIST.finditer(self.masked):
            self._literal(match)
        self.assigned: dict[str, list[tuple[int, int]]] = {}
        for match in _ASSIGN.finditer(self.masked):
            bracket = self.masked.index("[", match.end())
            if bracket in self.at:
                self.assigned.setdefault(match.group(1), []).append(
                    (match.start(), self.at[bracket])
                )

    def line(self, pos: int) -> int:
        return self.text.count("\n", 0, pos) + 1

    def _literal(self, match: re.Match[str]) -> None:
        body_start = match.start(2)
        spans, values, numeric = [], [], True
        begin = body_start
        for piece in [*match.group(2).split(","), None][:-1]:
            assert piece is not None
            stripped = piece.strip()
            offset = begin + (len(piece) - len(piece.lstrip()))
            begin += len(piece) + 1
            if _NOT_FINITE.fullmatch(stripped):
                raise ProgramError(
                    self.path,
                    self.line(offset),
                    f"'{stripped[:12]}' is not a finite number; give the target's numbers",
                )
            if not NUMBER.fullmatch(stripped):
                numeric = False
                continue
            value = float(stripped)
            if not math.isfinite(value):
                raise ProgramError(
                    self.path, self.line(offset), f"'{stripped[:24]}' is beyond a float"
                )
            spans.append((offset, offset + len(stripped)))
            values.append(value)
        kind = "pose" if match.group(1) else "joints"
        shown = "p[…]" if kind == "pose" else "[…]"
        self.at[self.masked.index("[", match.start())] = len(self.literals)
        self.literals.append(
            Literal(kind, self.line(match.start()), tuple(spans), tuple(values), shown)
        )
        self.numeric.append(numeric and bool(values))

    def resolve(
        self, start: int, end: int, kind: str, before: int
    ) -> tuple[int | None, str | None]:
        """The literal (of ``kind``) the expression in ``start:end`` runs, or why none."""
        expr = self.masked[start:end].strip()
        shown = self.text[start:end].strip()
        shown = shown if len(shown) <= 40 else shown[:39] + "…"
        lead = start + (len(self.masked[start:end]) - len(self.masked[start:end].lstrip()))
        index: int | None = None
        name: str | None = None
        if re.fullmatch(r"(p\s*)?\[[^\[\]]*\]", expr):
            index = self.at.get(self.masked.index("[", lead))
        elif _NAME.fullmatch(expr):
            found = self.assigned.get(expr)
            if not found:
                return None, f"its target '{shown}' is not assigned numbers: {NUMBERS}"
            earlier = [i for pos, i in found if pos < before]
            index, name = (earlier[-1] if earlier else found[0][1]), expr
        if index is None:
            return None, f"its target '{shown}' {RUNTIME}"
        lit = self.literals[index]
        if not self.numeric[index]:
            return None, f"its target '{shown}' {RUNTIME}"
        if lit.kind != kind and kind == "pose" and lit.kind == "joints":
            pass  # a motion given joints moves to their forward kinematics: a joint target
        want = 6 if lit.kind == "pose" else self.n
        if len(lit.values) != want:
            what = "a pose p[x, y, z, rx, ry, rz]" if lit.kind == "pose" else f"{self.n} joints"
            raise ProgramError(
                self.path,
                lit.line,
                f"'{shown}' has {len(lit.values)} numbers; {what} takes {want} (m, rad)",
            )
        if name is not None:
            self.literals[index] = Literal(lit.kind, lit.line, lit.spans, lit.values, name)
        return index, None


def _tcp_of(reader: _Reader, start: int, end: int) -> FloatArray | None:
    """The TCP ``set_tcp``'s argument gives (None: computed when the program runs)."""
    index, _ = reader.resolve(start, end, "pose", start)
    if index is None or reader.literals[index].kind != "pose":
        return None
    return _pose(reader.literals[index].values)


def read_urscript(path: str, text: str, n: int, tcp: FloatArray | None) -> Program:
    """The URScript program ``text`` (from ``path``) for a robot of ``n`` joints: see the
    module docstring; ``tcp`` (4, 4): the TCP before the program sets one (None: the
    flange). A motion call that does not close, a target of the wrong arity or a number that
    is not finite: a :class:`~dhlog.cell.programs.common.ProgramError` naming the line."""
    reader = _Reader(path, text, n)
    masked = reader.masked
    motions: list[Motion] = []
    notes: list[str] = []
    current = np.eye(4) if tcp is None else tcp
    tcp_known: bool | int = True  # True, or the line of a set_tcp computed at run time
    told = tcp is not None
    for call in _CALL.finditer(masked):
        name = call.group(1)
        close = closing(masked, call.end())
        line = reader.line(call.start())
        if close < 0:
            raise ProgramError(path, line, f"{name}( is never closed; close its parenthesis")
        args = [
            span
            for span in arguments(masked, call.end(), close)
            if not re.match(r"\s*[A-Za-z_]\w*\s*=(?!=)", masked[span[0] : span[1]])
            or re.match(r"\s*(q|pose|pose_via|pose_to)\s*=", masked[span[0] : span[1]])
        ]
        if name == "set_tcp":
            if not args or not masked[args[0][0] : args[0][1]].strip():
                raise ProgramError(path, line, "set_tcp() takes the TCP pose p[…]")
            found = _tcp_of(reader, *args[0])
            if found is None:
                tcp_known = line
            else:
                current, tcp_known, told = found, True, True
            continue
        wanted = MOTIONS[name]
        if len(args) < len(wanted) or not all(masked[a:b].strip() for a, b in args[: len(wanted)]):
            raise ProgramError(
                path, line, f"{name}(…) needs {', '.join(wanted)}; give the target first"
            )
        for a, b in args[: len(wanted)]:
            a += len(re.match(r"\s*(?:(?:q|pose|pose_via|pose_to)\s*=)?", masked[a:b]).group(0))  # type: ignore[union-attr]
            motions.append(_motion(reader, name, line, a, b, current, tcp_known, call.start()))
            if not told and motions[-1].literal is not None:
                if reader.literals[motions[-1].literal].kind == "pose":
                    notes.append(
                        f"line {line}: no set_tcp before it and no --tcp: its pose is taken as "
                        "the flange's (tool0)"
                    )
                    told = True
    return Program(path, text, reader.literals, motions, UNITS, notes)


def _motion(
    reader: _Reader,
    name: str,
    line: int,
    start: int,
    end: int,
    tcp: FloatArray,
    tcp_known: bool | int,
    before: int,
) -> Motion:
    """One motion's target (and ``qnear``) resolved."""
    expr = reader.masked[start:end]
    ik = _IK.match(expr.lstrip())
    hint: int | None = None
    if ik is not None:
        open_at = start + (len(expr) - len(expr.lstrip())) + ik.end()
        close = closing(reader.masked, open_at)
        if close < 0 or close > end:
            raise ProgramError(reader.path, line, "get_inverse_kin( is never closed")
        inner = [
            s
            for s in arguments(reader.masked, open_at, close)
            if reader.masked[s[0] : s[1]].strip()
        ]
        near = None
        for a, b in inner[1:]:
            piece = reader.masked[a:b]
            keyword = re.match(r"\s*(\w+)\s*=", piece)
            if keyword is None or keyword.group(1) == "qnear":
                near = (a + (keyword.end() if keyword else 0), b)
                break
        if near is not None:
            hint, why = reader.resolve(*near, "joints", before)
            if hint is None or reader.literals[hint].kind != "joints":
                return Motion(name, line, None, tcp, why=why or "its qnear is not a joint list")
        start, end = inner[0] if inner else (open_at, close)
    index, why = reader.resolve(start, end, "pose", before)
    if index is None:
        return Motion(name, line, None, tcp, why=why)
    if reader.literals[index].kind == "pose" and tcp_known is not True:
        return Motion(
            name,
            line,
            None,
            tcp,
            why=f"the TCP set at line {tcp_known} {RUNTIME}",
        )
    return Motion(name, line, index, tcp, hint=hint)
