"""Joints in the wrong order, as the data reveal it when no names decide the order.

A joint-state stream whose names cannot be matched to the nominal's (no names, or numbered ones)
is taken in its own order. When that order is not the chain's — a driver's alphabetical order,
columns exported out of order — the nominal placed on the points misses them by decimetres
under the stream's order and by millimetres under the right one. :func:`suspected_permutation`
places the nominal on a few hundred of the session's samples under every permutation of the
joint columns that keeps each joint's type (all of them up to :data:`MAX_ALL` joints: 720 for a
6-axis arm, 5040 for 7; beyond, every swap of two columns) and reports the one that explains the
points far better than the stream's order. Each placement is the one placement's closed form
(:func:`~dhlog.identify.fit.placement.closed_form_placements`): the base by Kabsch's SVD, the
target point on the flange by linear least squares, alternated (:data:`ROUNDS`), every
permutation at once.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray
from dhlog.identify.fit.placement import closed_form_placements
from dhlog.identify.segment.segment import Segmentation
from dhlog.io.dhfile import DHModel
from dhlog.model.dh import JointType, StandardDH

#: Every permutation is tried up to this many joints; beyond, every swap of two columns.
MAX_ALL = 7
#: Samples the nominal is placed on (fewer for 7 joints: 5040 permutations).
SAMPLES = 100
SAMPLES_LARGE = 40
#: Alternations of the base's and the target point's least-squares placements.
ROUNDS = 10
#: Share of the samples scored (the worst left out: outliers).
SCORED = 0.9
#: A permutation is suspected when it explains the points this many times better than the
#: stream's order, and the stream's order misses them by more than :data:`FLOOR` (m, RMS): a
#: robot's published nominal misses its points by a few mm; a wrong order by decimetres.
RATIO = 10.0
FLOOR = 5e-3
#: Permutations placed at once (memory: about 8 kB per permutation and sample).
BATCH = 120


@dataclass(frozen=True)
class Permutation:
    """The chain's joint k is the stream's column ``order[k]`` (0-based): the nominal placed on
    the points misses them by ``rms`` (m) so, by ``as_given`` in the stream's order."""

    order: tuple[int, ...]
    rms: float
    as_given: float

    def reason(self, names: Sequence[str]) -> str:
        """One sentence naming the permutation, the evidence and the fix."""
        chain = ", ".join(f'"{names[k]}"' for k in self.order)
        moved = ", ".join(
            f"joint {k + 1} = column {c + 1} ({names[c]})"
            for k, c in enumerate(self.order)
            if c != k
        )
        return (
            f"the joint values look permuted: the nominal placed on the points misses them by "
            f"{self.as_given * 1e3:.1f} mm (RMS) with the joints in the log's order "
            f"({', '.join(names)}) but by {self.rms * 1e3:.2f} mm with {moved}; name the "
            f"joints so they are matched by name (the DH file's joints[].name, or [joints] "
            f"names = [{chain}] in chain order in a pipeline file, --pipeline), or reorder the "
            "columns (dhlog import --joint-columns)."
        )


def candidate_orders(types: Sequence[JointType]) -> NDArray[np.intp]:
    """The permutations tried (p, n), the identity first: those mapping every joint onto a
    joint of its own type; all of them up to :data:`MAX_ALL` joints, else every swap."""
    n = len(types)
    if n <= MAX_ALL:
        perms = [p for p in itertools.permutations(range(n))]
    else:
        perms = [tuple(range(n))]
        for i, j in itertools.combinations(range(n), 2):
            p = list(range(n))
            p[i], p[j] = j, i
            perms.append(tuple(p))
    kept = [p for p in perms if all(types[c] is types[k] for k, c in enumerate(p))]
    return np.array(kept, dtype=np.intp).reshape(len(kept), n)


def _flange(table: StandardDH, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rotations (..., 3, 3) and origins (..., 3) of the last frame at joint values q (..., n)."""
    shape = q.shape[:-1]
    links = table.link_transforms(q.reshape(-1, table.n))  # (N, n, 4, 4)
    T = np.ascontiguousarray(links[:, 0])
    for i in range(1, table.n):
        T = T @ np.ascontiguousarray(links[:, i])
    return T[:, :3, :3].reshape(*shape, 3, 3), T[:, :3, 3].reshape(*shape, 3)


def placed_rms(R: FloatArray, p: FloatArray, y: FloatArray, start: FloatArray) -> FloatArray:
    """RMS (per permutation, the best :data:`SCORED` share of the samples) of the points ``y``
    (m, 3) from the flange frames ``R`` (P, m, 3, 3), ``p`` (P, m, 3) rigidly placed on them, with
    the target point on the flange fitted too (started at ``start``): the placement's closed
    form (:func:`~dhlog.identify.fit.placement.closed_form_placements`, :data:`ROUNDS`
    alternations), every permutation at once."""
    P, m = p.shape[:2]
    t0 = np.broadcast_to(np.asarray(start, dtype=np.float64), (P, 3))
    Rb, tb, t = closed_form_placements(R, p, y, t0, rounds=ROUNDS)
    x = (R @ t[:, None, :, None])[..., 0] + p  # the target in the base frame (P, m, 3)
    r = x @ np.swapaxes(Rb, 1, 2) + tb[:, None] - y[None]
    err = np.sort(np.einsum("pmi,pmi->pm", r, r), axis=1)[:, : max(3, int(SCORED * m))]
    return np.asarray(np.sqrt(err.mean(axis=1)), dtype=np.float64)


def _samples(seg: Segmentation, count: int) -> tuple[FloatArray, FloatArray]:
    """Up to ``count`` samples spread over the log with encoder values (of the primary target
    where there are several): their encoder values (m, n) and points (m, 3)."""
    rows = np.unique(np.linspace(0, seg.height - 1, min(seg.height, 8 * count)).astype(np.intp))
    rows = rows[seg.has_q(rows)]
    if "target" in seg.points.columns:
        label = np.asarray(seg.points["target"].to_numpy())[rows]
        rows = rows[label == 0]
    rows = rows[np.unique(np.linspace(0, rows.size - 1, min(rows.size, count)).astype(np.intp))]
    return seg.q(rows), seg.xyz(rows)


def suspected_permutation(seg: Segmentation, nominal: DHModel) -> Permutation | None:
    """The permutation of the stream's joint columns under which the nominal explains the
    session's points far better (:data:`RATIO`) than under the stream's order, or None."""
    n = nominal.table.n
    if seg.n_joints != n or not seg.has_encoders or n < 2:
        return None
    orders = candidate_orders(nominal.table.joint_types)
    if len(orders) < 2:
        return None
    Q, y = _samples(seg, SAMPLES if n < MAX_ALL else SAMPLES_LARGE)
    keep = np.all(np.isfinite(Q), axis=1) & np.all(np.isfinite(y), axis=1)
    Q, y = Q[keep], y[keep]
    if Q.shape[0] < 3 * n or float(np.ptp(y, axis=0).max()) <= 0.0:
        return None
    # the stream's order first: where the nominal explains the points within FLOOR under it, no
    # permutation is suspected whatever the others give (the rule below), so none is placed
    # (0.004 s against 0.5 s for the 720 orders of six joints on every honest log)
    if float(_placed(nominal, orders[:1], Q, y, nominal.tool_point)[0]) <= FLOOR:
        return None
    rms = np.empty(len(orders))
    for lo in range(0, len(orders), BATCH):
        rms[lo : lo + BATCH] = _placed(nominal, orders[lo : lo + BATCH], Q, y, nominal.tool_point)
    best = int(np.argmin(rms))
    if best == 0 or rms[0] <= FLOOR or rms[best] * RATIO > rms[0]:
        return None
    # the two again from another start of the target point: a placement's local minimum is
    # not taken for the stream's order's miss
    again = _placed(nominal, orders[[0, best]], Q, y, np.zeros(3))
    as_given, found = min(rms[0], again[0]), min(rms[best], again[1])
    if as_given <= FLOOR or found * RATIO > as_given:
        return None
    return Permutation(tuple(int(c) for c in orders[best]), float(found), float(as_given))


def _placed(
    nominal: DHModel, orders: NDArray[np.intp], Q: FloatArray, y: FloatArray, start: FloatArray
) -> FloatArray:
    """:func:`placed_rms` of the nominal at the samples' joint values ``Q`` (m, n) under each
    permutation ``orders`` (P, n)."""
    q = nominal.joint_values(Q[:, orders].transpose(1, 0, 2))  # (P, m, n)
    R, p = _flange(nominal.table, q)
    return placed_rms(R, p, y, start)
