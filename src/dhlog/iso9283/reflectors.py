"""The tool's orientation from three reflectors (or more) on it: at each visit, the frame the
first three targets' attained positions make — origin the first, x along first → second, z
normal to their plane (first → second × first → third), y = z × x. With it, clause 7.2.2's
orientation repeatability RP_a, RP_b, RP_c is computed per pose as for a 6-DoF target
(:func:`dhlog.iso9283.formulas.pose_repeatability` on the frames), about the report's axes.

The frame is the reflectors', not the tool's own: its orientation differs from the tool frame by
a fixed rotation, so the spreads of a, b, c about the base's axes are the tool's (a deviation
R_j R̄ᵀ does not depend on a fixed rotation on the right).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.cycles import Segmented

#: The three reflectors must span a triangle: each side this long (m) and the smallest angle's
#: sine this large, at every visit.
MIN_SIDE = 0.01
MIN_SINE = 0.1


def reflector_frame(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray | None:
    """The rotation (3, 3) of the frame three points make (see the module docstring); None when
    they are too close or too nearly on one line."""
    ab, ac = b - a, c - a
    sides = [float(np.linalg.norm(v)) for v in (ab, ac, c - b)]
    if min(sides) < MIN_SIDE:
        return None
    z = np.cross(ab, ac)
    if float(np.linalg.norm(z)) < MIN_SINE * sides[0] * sides[1]:
        return None
    x = ab / sides[0]
    z = z / float(np.linalg.norm(z))
    return np.asarray(np.column_stack([x, np.cross(z, x), z]), dtype=np.float64)


def with_reflector_frames(
    primary: Segmented, further: Sequence[Segmented], notes: list[str]
) -> Segmented:
    """``primary`` with each visit's rotation the frame of the first three targets (itself and
    the first two of ``further``), where the log has no 6-DoF target and the three targets'
    visits are the same (the same count, poses and cycles: the same stops); unchanged
    otherwise, a note saying why when it had three targets."""
    if primary.orientation or len(further) < 2:
        return primary
    b_seg, c_seg = further[0], further[1]
    same = [(v.pose, v.cycle) for v in primary.visits]
    if same != [(v.pose, v.cycle) for v in b_seg.visits] or same != [
        (v.pose, v.cycle) for v in c_seg.visits
    ]:
        notes.append(
            "orientation (RP_a, RP_b, RP_c) from the reflectors: their visits differ (not the "
            "same stops); not computed."
        )
        return primary
    frames = [
        reflector_frame(a.position, b.position, c.position)
        for a, b, c in zip(primary.visits, b_seg.visits, c_seg.visits, strict=True)
    ]
    if any(f is None for f in frames):
        notes.append(
            "orientation (RP_a, RP_b, RP_c) from the reflectors: the first three are too close "
            f"or nearly on one line (sides under {MIN_SIDE * 1e3:g} mm); not computed."
        )
        return primary
    visits = [replace(v, rotation=f) for v, f in zip(primary.visits, frames, strict=True)]
    notes.append(
        "RP_a, RP_b, RP_c: of the frame targets 1, 2, 3 make at each visit (origin 1, x along "
        "1 → 2, z normal to their plane): the tool's orientation repeatability."
    )
    return replace(primary, visits=visits, orientation=True)
