"""The commanded ISO 9283 program as a file: its rows in cycle order (:func:`program_rows`), the CSV
``dhlog plan --iso9283`` writes (:func:`program_csv`) and the program read back from one
(:func:`read_program` → :class:`CommandedProgram`: each pose's joint targets, checked; at most
:data:`MAX_PROGRAM_BYTES`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.cube import (
    CYCLE_ORDER,
    TestProgram,
)


@dataclass(frozen=True)
class CommandedProgram:
    """The cycle program as :func:`program_csv` writes it and :func:`read_program` reads it, one
    row per commanded target: ``cycle`` (m,), ``step`` (m,: within its cycle, from 1), ``kind``
    (``pose`` or ``path``), ``name`` (P1 … P5, ``line``, ``circle_large``, ``circle_small``),
    ``index`` (m,: the point's number along its path, 0 for a pose), the joint targets ``q``
    (m, n; rad or m) and the commanded tool point ``xyz`` (m, 3; m, base frame)."""

    cycle: np.ndarray
    step: np.ndarray
    kind: list[str]
    name: list[str]
    index: np.ndarray
    q: FloatArray
    xyz: FloatArray


def program_rows(program: TestProgram) -> CommandedProgram:
    """The cycle program, one row per commanded target: ``cycles`` pose cycles (P1 → P5 → P4 →
    P3 → P2 each, :data:`CYCLE_ORDER`), then ``path_cycles`` path cycles (the line, the large
    circle, the small circle each, every commanded point in turn)."""
    cycle: list[int] = []
    step: list[int] = []
    kind: list[str] = []
    name: list[str] = []
    index: list[int] = []
    q: list[FloatArray] = []
    xyz: list[FloatArray] = []
    names = [pose.name for pose in program.poses]
    ordered = (
        [program.poses[names.index(n)] for n in CYCLE_ORDER]
        if sorted(names) == sorted(CYCLE_ORDER)
        else program.poses
    )
    for c in range(1, program.cycles + 1):
        for s, pose in enumerate(ordered, start=1):
            cycle.append(c)
            step.append(s)
            kind.append("pose")
            name.append(pose.name)
            index.append(0)
            q.append(pose.q[None])
            xyz.append(pose.T[None, :3, 3])
    for c in range(1, program.path_cycles + 1):
        s = 0
        for path in program.paths:
            k = len(path.points)
            cycle += [c] * k
            step += list(range(s + 1, s + k + 1))
            s += k
            kind += ["path"] * k
            name += [path.name] * k
            index += list(range(k))
            q.append(path.q)
            xyz.append(path.points)
    return CommandedProgram(
        np.array(cycle),
        np.array(step),
        kind,
        name,
        np.array(index),
        np.vstack(q),
        np.vstack(xyz),
    )


#: The largest program CSV :func:`read_program` reads (a 30-cycle program is about 0.6 MB).
MAX_PROGRAM_BYTES = 64 * 2**20


#: The columns before and after the joints in :func:`program_csv`.
HEAD = ("cycle", "step", "kind", "name", "index")


TAIL = ("x", "y", "z")


NAMES = ("P1", "P2", "P3", "P4", "P5", "line", "circle_large", "circle_small")


def program_csv(program: TestProgram) -> str:
    """The cycle program as CSV (docs/iso9283.md, "The test program"): a header row, then one
    row per commanded target (:func:`program_rows`): ``cycle, step, kind, name, index``, the
    joint targets ``j1 … jn`` (rad or m) and the commanded tool point ``x, y, z`` (m, base
    frame). Numbers are written to round-trip exactly."""
    rows = program_rows(program)
    n = rows.q.shape[1]
    lines = [",".join([*HEAD, *(f"j{j + 1}" for j in range(n)), *TAIL])]
    for k in range(len(rows.kind)):
        values = [*rows.q[k], *rows.xyz[k]]
        lines.append(
            ",".join(
                [
                    str(rows.cycle[k]),
                    str(rows.step[k]),
                    rows.kind[k],
                    rows.name[k],
                    str(rows.index[k]),
                    *(repr(float(v)) for v in values),
                ]
            )
        )
    return "\n".join(lines) + "\n"


def read_program(path: str | Path, n: int) -> CommandedProgram:
    """A cycle program as :func:`program_csv` writes it, for a robot of ``n`` joints (untrusted:
    every row and field is checked; one-line errors name the file, line and field)."""
    from dhlog.io.textfile import decode_utf8, read_capped

    name = str(path)

    def fail(problem: str) -> InputError:
        return InputError(f"{name}: {problem}")

    hint = "give the test program `dhlog plan ROBOT --iso9283 -o CSV` wrote."
    data = read_capped(path, MAX_PROGRAM_BYTES, fail, what="test program CSV", hint=hint)
    text = decode_utf8(data, fail, what="test program CSV")
    expected = [*HEAD, *(f"j{j + 1}" for j in range(n)), *TAIL]
    lines = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError(f"{name}: is empty; give the test program `dhlog plan --iso9283` wrote.")
    number, header = lines[0]
    cells = [c.strip() for c in header.split(",")]
    if cells != expected:
        raise InputError(
            f"{name}, line {number}: the header is not {','.join(expected)} (a test program "
            f"for {n} joints); give the program `dhlog plan ROBOT --iso9283` wrote for this robot."
        )
    ints: list[list[int]] = []
    words: list[tuple[str, str]] = []
    values: list[list[float]] = []
    for number, line in lines[1:]:
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != len(expected):
            raise InputError(
                f"{name}, line {number}: has {len(cells)} fields, the header {len(expected)}; "
                "give one commanded target per row."
            )
        row_ints = []
        for field_name, cell in zip(("cycle", "step"), cells[:2], strict=True):
            if not cell.isdigit() or int(cell) < 1:
                raise InputError(
                    f"{name}, line {number}: {field_name} '{cell[:20]}' is not a whole number ≥ 1."
                )
            row_ints.append(int(cell))
        kind, target = cells[2], cells[3]
        if kind not in ("pose", "path"):
            raise InputError(f"{name}, line {number}: kind '{kind[:20]}' is not pose or path.")
        poses = NAMES[:5] if kind == "pose" else NAMES[5:]
        if target not in poses:
            raise InputError(
                f"{name}, line {number}: name '{target[:20]}' is not one of {', '.join(poses)} "
                f"(kind {kind})."
            )
        if not cells[4].isdigit():
            raise InputError(
                f"{name}, line {number}: index '{cells[4][:20]}' is not a whole number ≥ 0."
            )
        row_ints.append(int(cells[4]))
        numbers = []
        for field_name, cell in zip(expected[5:], cells[5:], strict=True):
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v) or abs(v) > 1e3:
                raise InputError(
                    f"{name}, line {number}: {field_name} '{cell[:20]}' is not a finite number "
                    "(rad or m, within 1000)."
                )
            numbers.append(v)
        ints.append(row_ints)
        words.append((kind, target))
        values.append(numbers)
    if not values:
        raise InputError(f"{name}: holds no commanded target after its header.")
    whole = np.array(ints, dtype=np.int64)
    V = np.array(values)
    return CommandedProgram(
        whole[:, 0],
        whole[:, 1],
        [w[0] for w in words],
        [w[1] for w in words],
        whole[:, 2],
        V[:, :n],
        V[:, n:],
    )
