"""The passes along an ISO 9283 test's paths in a tracker log.

**Path passes** (clause 8), with the test program (:func:`dhlog.iso9283.program.read_program`:
``--commanded``): each time the commanded joints (else the encoders) come nearest a path's
second target, up to the next time they come nearest its last one, the tracker's samples from
``PASS_MARGIN`` s before to as long after: one cycle's attained path, for
:func:`dhlog.iso9283.formulas.path_accuracy`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.commanded import CommandedProgram

#: A joint stream this close (rad, m) to a path's second and last targets is at them.
PASS_TOLERANCE = 1e-3


#: The tracker's samples kept before and after a pass (s).
PASS_MARGIN = 0.3


@dataclass(frozen=True)
class PathPass:
    """One cycle's run along a test path: the ``path``'s name, its ``cycle`` (1-based), the
    first and last sample's times (ns) and the tracker's positions ``xyz`` (k, 3, measurement
    frame) in time order."""

    path: str
    cycle: int
    t_start_ns: int
    t_end_ns: int
    xyz: FloatArray


def program_parts(
    program: CommandedProgram,
) -> tuple[list[tuple[str, FloatArray]], FloatArray, list[tuple[str, FloatArray]]]:
    """The program's poses (name, joints) in order first commanded, its pose targets in order
    (k, n), and each path's joint targets along it (name, (m, n)) from its first cycle."""
    poses: dict[str, FloatArray] = {}
    sequence = []
    paths: dict[str, list[tuple[int, FloatArray]]] = {}
    first_cycle: dict[str, int] = {}
    for k, kind in enumerate(program.kind):
        name, q = program.name[k], np.asarray(program.q[k], dtype=np.float64)
        if kind == "pose":
            poses.setdefault(name, q)
            sequence.append(q)
        else:
            c = first_cycle.setdefault(name, int(program.cycle[k]))
            if int(program.cycle[k]) == c:
                paths.setdefault(name, []).append((int(program.index[k]), q))
    n = program.q.shape[1]
    return (
        list(poses.items()),
        np.array(sequence) if sequence else np.zeros((0, n)),
        [
            (name, np.array([q for _, q in sorted(rows, key=lambda r: r[0])]))
            for name, rows in paths.items()
        ],
    )


def find_passes(
    stream: tuple[NDArray[np.int64], FloatArray],
    path_q: FloatArray,
    t_ns: NDArray[np.int64],
    xyz: FloatArray,
    name: str,
    *,
    tolerance: float = PASS_TOLERANCE,
    margin: float = PASS_MARGIN,
) -> list[PathPass]:
    """The passes along a path whose joint targets are ``path_q`` (m, n), from a joint
    ``stream`` (times, (k, n): the commanded joints, or the encoders): each time the stream
    comes nearest its second point (the stream taken linearly between its samples; within
    ``tolerance``, rad in joint space, or half the smallest step between the path's targets if
    less), up to the next time it comes nearest its last point, passing
    near its targets at a quarter, half and three quarters of the way (a move between two poses
    may pass near the second target and stop at the last: not a pass); the
    tracker's samples from ``margin`` s before to ``margin`` s after (the path's ends, where the
    crossings of the first and last normal planes lie)."""
    t, Q = stream
    if path_q.shape[0] < 3 or Q.shape[1] != path_q.shape[1] or Q.shape[0] < 2:
        return []
    # below half the smallest step between targets: the second target is told from the first
    # and the last (a closed path's ends are one point)
    steps = np.linalg.norm(np.diff(path_q, axis=0), axis=1)
    tolerance = min(tolerance, 0.5 * float(steps[steps > 0].min(initial=2 * tolerance)))
    A, B = Q[:-1], Q[1:]
    AB = B - A
    length2 = np.einsum("ij,ij->i", AB, AB)

    def distance(target: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Each stream segment's distance (joint space) from ``target``, and the time of its
        nearest point (the stream linearly between its samples: a fast stream's samples may
        straddle a target)."""
        u = np.einsum("ij,ij->i", target - A, AB) / np.where(length2 > 0, length2, 1.0)
        u = np.clip(np.where(length2 > 0, u, 0.0), 0.0, 1.0)
        d = np.linalg.norm(A + u[:, None] * AB - target, axis=1)
        return d, t[:-1] + u * (t[1:] - t[:-1])

    def nearest_times(target: FloatArray) -> NDArray[np.int64]:
        d, when = distance(target)
        near = d < tolerance
        edges = np.flatnonzero(np.diff(np.r_[0, near.astype(np.int8), 0]))
        return np.array(
            [
                int(when[a + int(np.argmin(d[a:b]))])
                for a, b in zip(edges[::2], edges[1::2], strict=True)
            ],
            dtype=np.int64,
        )

    starts, ends = nearest_times(path_q[1]), nearest_times(path_q[-1])
    m = path_q.shape[0]
    inner = [distance(path_q[round(f * (m - 1))]) for f in (0.25, 0.5, 0.75)]

    def along(t1: int, t2: int) -> bool:
        """Whether the stream passes near the path's inner targets between ``t1`` and ``t2``
        (a move between two poses may pass near a path's second target and stop at its end)."""
        for d, when in inner:
            inside = (when >= t1) & (when <= t2)
            if not np.any(inside) or float(d[inside].min()) >= tolerance:
                return False
        return True

    out: list[PathPass] = []
    step = int(margin * 1e9)
    for k, t1 in enumerate(starts):
        later = ends[ends > t1]
        following = starts[k + 1] if k + 1 < len(starts) else None
        if later.size == 0 or (following is not None and later[0] > following):
            continue  # a pass not run to its end
        if not along(int(t1), int(later[0]) + 1):
            continue
        a, b = np.searchsorted(t_ns, [t1 - step, later[0] + step])
        if b - a >= 3:
            out.append(PathPass(name, len(out) + 1, int(t_ns[a]), int(t_ns[b - 1]), xyz[a:b]))
    return out
