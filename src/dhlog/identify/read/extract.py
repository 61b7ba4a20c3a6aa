"""Exact DH parameters from measured joint axes by line geometry (seed 000, Sec. 3.1).

Frames 1 … n+1 are built recursively from the oriented joint axes at the reference pose
(Eq. 16–20) and the four parameters of each row read off consecutive frames (Eq. 21–24:
:func:`~dhlog.identify.read.hayati.table_from_frames`).
The ambiguous choices follow ``shared/DESIGN.md`` and are deterministic:

* intersecting axes: ``x_{i+1} = z_i × z_{i+1}`` (Eq. 17), origin at the intersection;
* skew axes: ``x_{i+1}`` along the common normal from axis i to axis i+1 (Eq. 19), so ``a_i > 0``;
* parallel axes: the common normal through ``o_i`` (Eq. 11–13, 18), so ``d_i = 0``;
* collinear axes (and a target on the last axis): ``x_{i+1}`` is ``x_i`` turned by ``θ_i`` at the
  reference pose (``θ_offset_i = 0``), and ``a_i = d_i = 0``;
* frame 1: origin at axis 1 ∩ base plane (seed 002, Eq. 7) when a base plane is given, else at
  the foot of the common normal to axis 2, else (axes 1 and 2 parallel, or nearly: below
  :data:`NEAR_PARALLEL`) at the point of axis 1 nearest the measurement origin; ``x_1`` such
  that ``θ_offset_1 = 0`` (axes 1 and 2 nearly parallel: ``θ_1`` of the Hayati–Mirmirani row);
* frame n+1: ``z_{n+1} ∥ z_n`` through the target (Sec. 3.1), common normal through ``o_n``; the
  target in frame n+1 is the tool point;
* prismatic joints: only the direction is physical (an anchor line nearly parallel to it is met at
  its own point). The axis is placed to meet the previous axis
  (``a_{i−1} = 0``) and, where possible, the next revolute axis (``a_i = 0``); a last prismatic
  axis passes as close to the target as meeting the previous axis allows; a first one meets axis 2
  and passes as close to the measurement origin as that allows. Without a neighbour to meet, the
  axis passes as close to the measurement origin as the remaining constraint allows.

With a nominal table every ambiguous choice takes the branch that matches it: the sign of each
``x_{i+1}`` (the one that puts row i's θ, a and α nearer the nominal's: :func:`_nearest_branch`),
``d_i`` of parallel
axes, ``d_1`` without base plane, ``θ_offset_1``, prismatic axes placed at the nominal ``a``/``d``,
the last frame as frame n times the nominal ``A_n``, and angles reported nearest the nominal.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import ShapeError
from dhlog.geometry._checks import (
    FloatArray,
    check_vector3,
    cross3,
    perpendicular_basis,
    rotation_about,
    wrap_angle,
)
from dhlog.geometry.lines import (
    ANGLE_TOL,
    DISTANCE_TOL,
    Line,
    LineRelation,
    Plane,
    RelationKind,
    classify_lines,
    common_normal_feet,
    intersect_line_plane,
)
from dhlog.identify.read.hayati import NEAR_PARALLEL, table_from_frames
from dhlog.model.dh import (
    JointType,
    ModifiedDH,
    StandardDH,
    standard_dh_transform,
    standard_to_modified,
)


@dataclass(frozen=True, eq=False)
class PairRelation:
    """How the axes of joints ``joints = (i, i+1)`` (1-based) lie relative to each other."""

    joints: tuple[int, int]
    relation: LineRelation


@dataclass(frozen=True, eq=False)
class Extraction:
    """The DH model recovered from the joint axes.

    ``frames`` (n+1, 4, 4) are frames 1 … n+1 in the measurement frame at the reference pose;
    ``axes`` are the joint axes used (prismatic ones as placed); ``T_modified_tool`` is the fixed
    transform the modified table leaves at the tool end (see :func:`standard_to_modified`).
    """

    standard: StandardDH
    modified: ModifiedDH
    T_modified_tool: FloatArray
    T_measurement_base: FloatArray
    tool_point: FloatArray
    reference_pose: FloatArray
    frames: FloatArray
    axes: tuple[Line, ...]
    relations: tuple[PairRelation, ...]


def _nearly_parallel(a: FloatArray, b: FloatArray) -> bool:
    return float(np.linalg.norm(cross3(a, b))) < math.sin(NEAR_PARALLEL)


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v), dtype=np.float64)


def _reject(v: FloatArray, axis: FloatArray) -> FloatArray:
    return np.asarray(v - (v @ axis) * axis, dtype=np.float64)


def place_prismatic_axis(
    direction: FloatArray, anchors: Sequence[Line | FloatArray], *, angle_tol: float = ANGLE_TOL
) -> Line:
    """A line along ``direction`` meeting the anchors in priority order (see the module rules).

    Works in the plane perpendicular to ``direction``: a line anchor projects to a 2D line (or to
    a point when parallel to ``direction``), a point anchor to a point. The first anchor is met
    exactly; a second is met if it crosses the first, else approached as closely as possible;
    what freedom remains is spent approaching the measurement origin.
    """
    e = _unit(direction)
    u, v = perpendicular_basis(e)
    P = np.stack([u, v])
    constraint: tuple[FloatArray, FloatArray] | None = None
    point: FloatArray | None = None
    for anchor in anchors:
        if isinstance(anchor, Line):
            d2 = P @ anchor.direction
            p2 = P @ anchor.point
            if np.linalg.norm(d2) < np.sin(max(angle_tol, NEAR_PARALLEL)):
                # (nearly) along the direction: meet it at its own point, not where the noise
                # of a nearly parallel line would put the crossing
                item: tuple[FloatArray, FloatArray | None] = (p2, None)
            else:
                item = (p2, d2 / np.linalg.norm(d2))
        else:
            item = (P @ check_vector3("anchor", anchor), None)
        p2, d2_or_none = item
        if constraint is None:
            if d2_or_none is None:
                point = p2
                break
            constraint = (p2, d2_or_none)
            continue
        c0, cd = constraint
        if d2_or_none is None:
            point = c0 + ((p2 - c0) @ cd) * cd
            break
        cross = cd[0] * d2_or_none[1] - cd[1] * d2_or_none[0]
        if abs(cross) < np.sin(angle_tol):
            continue
        diff = p2 - c0
        t = (diff[0] * d2_or_none[1] - diff[1] * d2_or_none[0]) / cross
        point = c0 + t * cd
        break
    if point is None:
        point = (
            np.zeros(2)
            if constraint is None
            else constraint[0] - (constraint[0] @ constraint[1]) * constraint[1]
        )
    return Line(point[0] * u + point[1] * v, e)


def _frame(origin: FloatArray, x: FloatArray, z: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, cross3(z, x), z, origin
    return T


def extract_dh(
    axes: Sequence[Line],
    joint_types: Sequence[JointType | str],
    *,
    target: ArrayLike,
    reference_pose: ArrayLike,
    base_plane: Plane | None = None,
    nominal: StandardDH | None = None,
    angle_tol: float = ANGLE_TOL,
    distance_tol: float = DISTANCE_TOL,
    pair_tolerances: Sequence[tuple[float, float]] | None = None,
) -> Extraction:
    """Standard and modified DH tables, base transform and tool point from oriented joint axes.

    ``angle_tol`` (rad) and ``distance_tol`` (m) decide when two axes count as parallel or
    meeting; ``pair_tolerances[i]`` (angle, distance) overrides them for axes i+1, i+2 (1-based),
    e.g. with tolerances from the fits' uncertainty.

    ``axes``: joint 1 … n axes in the measurement frame M at ``reference_pose`` (n,), each oriented
    along positive joint motion; ``target`` (3,) the target point in M at that pose. Seed 000,
    Sec. 3.1: Plücker lines (Eq. 16), pair classification (Eq. 3), intersection (Eq. 4–10), parallel
    (Eq. 11–13, 18) and skew (Eq. 14–15, 19) common normals, ``y = z × x`` (Eq. 20) and the
    parameters ``d_i = (o_{i+1} − o_i)·z_i`` (Eq. 21), ``θ_i`` (Eq. 22),
    ``a_i = (o_{i+1} − o_i)·x_{i+1}``
    (Eq. 23), ``α_i`` (Eq. 24). The tie-breaks are listed in the module docstring.
    """
    types = tuple(JointType.parse(str(t)) for t in joint_types)
    n = len(types)
    if len(axes) != n or n == 0:
        raise ShapeError("axes", f"one axis per joint ({n})", f"{len(axes)} axes")
    q_ref = np.asarray(reference_pose, dtype=np.float64).reshape(-1)
    if q_ref.shape != (n,) or not np.all(np.isfinite(q_ref)):
        raise ShapeError("reference_pose", f"{n} finite joint values", q_ref.tolist())
    p_target = check_vector3("target", target)
    if nominal is not None and nominal.joint_types != types:
        raise ShapeError(
            "nominal table",
            f"joint types {[t.value for t in types]}",
            [t.value for t in nominal.joint_types],
        )
    revolute = [t is JointType.REVOLUTE for t in types]
    if nominal is not None:
        desired_theta = nominal.theta(q_ref)
        nominal_d = nominal.d(q_ref)
    else:
        desired_theta = np.where(revolute, q_ref, 0.0)
        nominal_d = np.zeros(n)
    aim = _Aim(nominal, desired_theta, nominal_d)
    lines: list[Line] = list(axes)
    placed = [revolute[i] for i in range(n)]

    def anchor_place(i: int) -> None:
        """Place prismatic axis i (0-based) by the anchor rule."""
        anchors: list[Line | FloatArray] = []
        if i > 0:  # a parallel previous axis is met at its well-conditioned origin
            prev, o_prev = lines[i - 1], steady[i - 1]
            anchors.append(prev if o_prev is None else Line(o_prev, prev.direction))
        if i + 1 < n and placed[i + 1]:
            anchors.append(lines[i + 1])
        if i == n - 1:
            anchors.append(p_target)
        lines[i] = place_prismatic_axis(lines[i].direction, anchors, angle_tol=angle_tol)
        placed[i] = True

    def tolerance(i: int) -> tuple[float, float]:
        if pair_tolerances is not None and i < len(pair_tolerances) and i < n - 1:
            return pair_tolerances[i]
        return angle_tol, distance_tol

    z = [line.direction for line in lines] + [lines[-1].direction]
    origins: list[FloatArray | None] = [None] * (n + 1)
    xs: list[FloatArray | None] = [None] * (n + 1)
    # the origins of the Hayati–Mirmirani chain (hayati_table): the DH ones, except after a
    # nearly parallel pair, where the plane normal to z_i through the previous one meets the
    # next axis (the common normal's feet run off with the noise there)
    steady: list[FloatArray | None] = [None] * (n + 1)

    for i in range(n if nominal is None else 1):
        # one nearly parallel to the previous axis waits for that axis' steady origin
        if not placed[i] and not (i > 0 and _nearly_parallel(z[i - 1], z[i])):
            anchor_place(i)
            if i == 0 and nominal is not None and n > 1 and placed[1]:
                cross = cross3(lines[0].direction, lines[1].direction)
                if np.linalg.norm(cross) >= np.sin(angle_tol):  # meet the nominal a_1
                    x2 = _unit(cross) * (1.0 if np.sin(nominal.alpha[0]) >= 0.0 else -1.0)
                    anchor = lines[0].point
                else:  # parallel: x_1 has no physical anchor; take the default one
                    x2 = rotation_about(z[0], float(desired_theta[0])) @ _default_x(z[0])
                    anchor = lines[1].point
                lines[0] = Line(anchor - nominal.a[0] * x2, lines[0].direction)
    origins[0] = _frame1_origin(lines, placed, base_plane, nominal_d, tolerance)
    steady[0] = origins[0]

    relations: list[PairRelation] = []
    for i in range(n):
        o_i = origins[i]
        assert o_i is not None
        z_i = z[i]
        line_i = Line(o_i, z_i)
        if i == n - 1:
            if nominal is not None:
                break  # the last frame follows the nominal A_n, built once x_n is known
            line_next = Line(p_target, z_i)
        else:
            if not placed[i + 1]:
                _place_with_nominal(i, lines, xs, origins, z, aim, angle_tol, anchor_place)
                placed[i + 1] = True
            line_next = lines[i + 1]
        a_tol, d_tol = tolerance(i)
        rel = classify_lines(line_i, line_next, angle_tol=a_tol, distance_tol=d_tol)
        if i < n - 1:
            rel_fitted = classify_lines(lines[i], lines[i + 1], angle_tol=a_tol, distance_tol=d_tol)
            relations.append(PairRelation((i + 1, i + 2), rel_fitted))
        z_next = line_next.direction
        if rel.kind is RelationKind.COLLINEAR:
            origins[i + 1] = line_next.project(o_i + nominal_d[i] * z_i)
            xs[i + 1] = None
        elif rel.kind.is_parallel:
            base = o_i + nominal_d[i] * z_i
            # the common normal lies in the plane through o_i (+ d) normal to z_i, so d_i is the
            # convention exactly even when the axes are only parallel within the tolerance
            o_next = intersect_line_plane(line_next, Plane(base, z_i))
            x_next = _unit(_reject(_reject(o_next - base, z_i), z_next))  # Eq. 18
            if nominal is not None:
                x_next = _nearest_branch(
                    x_next, xs[i], z_i, z_next, o_next - o_i, nominal, i, desired_theta
                )
            origins[i + 1], xs[i + 1] = o_next, x_next
        else:
            p_i, p_next = common_normal_feet(line_i, line_next)  # Eq. 14-15
            normal = _unit(cross3(z_i, z_next))
            if rel.kind is RelationKind.INTERSECTING:
                sign = 1.0  # Eq. 17
            else:
                sign = 1.0 if (p_next - p_i) @ normal >= 0.0 else -1.0  # Eq. 19
            x_next = sign * normal
            if nominal is not None:
                x_next = _nearest_branch(
                    x_next, xs[i], z_i, z_next, p_next - o_i, nominal, i, desired_theta
                )
            origins[i + 1], xs[i + 1] = p_next, x_next
        s_i = steady[i]
        if s_i is not None and i < n - 1 and _nearly_parallel(z_i, z_next):
            steady[i + 1] = intersect_line_plane(line_next, Plane(s_i, z_i))
        else:
            steady[i + 1] = origins[i + 1]

    _resolve_x(xs, z, desired_theta, n if nominal is not None else n + 1)
    if (
        n > 1
        and revolute[0]
        and _nearly_parallel(z[0], z[1])
        and not relations[0].relation.kind.is_parallel
    ):
        # x_1 by the Hayati–Mirmirani row 1 (toward where axis 2 crosses the plane normal to
        # z_1 through o_1), not by the ill-conditioned common normal
        o_1 = origins[0]
        assert o_1 is not None
        toward = _reject(intersect_line_plane(lines[1], Plane(o_1, z[0])) - o_1, z[0])
        if np.linalg.norm(toward) > distance_tol:
            xs[0] = rotation_about(z[0], -float(desired_theta[0])) @ _unit(toward)
    frames = np.empty((n + 1, 4, 4))
    for i in range(n + 1 if nominal is None else n):
        o_i, x_i = origins[i], xs[i]
        assert o_i is not None and x_i is not None
        frames[i] = _frame(o_i, x_i, z[i])
    if nominal is not None:
        frames[n] = frames[n - 1] @ standard_dh_transform(
            desired_theta[n - 1], nominal_d[n - 1], nominal.a[n - 1], nominal.alpha[n - 1]
        )
    table = table_from_frames(frames, types, q_ref, nominal)
    modified, T_post = standard_to_modified(table)
    T_last_inv = np.linalg.inv(frames[n])
    tool = T_last_inv[:3, :3] @ p_target + T_last_inv[:3, 3]
    return Extraction(
        standard=table,
        modified=modified,
        T_modified_tool=T_post,
        T_measurement_base=frames[0].copy(),
        tool_point=np.asarray(tool, dtype=np.float64),
        reference_pose=q_ref,
        frames=frames,
        axes=tuple(lines),
        relations=tuple(relations),
    )


def _frame1_origin(
    lines: list[Line],
    placed: list[bool],
    base_plane: Plane | None,
    nominal_d: FloatArray,
    tolerance: Callable[[int], tuple[float, float]],
) -> FloatArray:
    """Origin of frame 1: axis 1 ∩ base plane (seed 002, Eq. 7); else the foot on axis 1 of the
    common normal to axis 2 (Eq. 14), carried through a run of parallel axes 1 … k to the first
    defined common normal (axes k, k+1) so that the parallel rows keep ``d = 0`` (or the nominal
    ``d``); else the point of axis 1 nearest the measurement origin."""
    if base_plane is not None:
        return intersect_line_plane(lines[0], base_plane)
    shift = np.zeros(3)
    for k in range(len(lines) - 1):
        if not placed[k + 1]:
            break
        shift = shift + nominal_d[k] * lines[k].direction
        a_tol, d_tol = tolerance(k)
        relation = classify_lines(lines[k], lines[k + 1], angle_tol=a_tol, distance_tol=d_tol)
        nearly = _nearly_parallel(lines[k].direction, lines[k + 1].direction)
        if not relation.kind.is_parallel and not nearly:
            foot = common_normal_feet(lines[k], lines[k + 1])[0]
            return lines[0].project(foot - shift)
    return lines[0].project(np.zeros(3))


@dataclass(frozen=True)
class _Aim:
    """The rows the extraction aims at, at the reference pose: the ``nominal`` table (None:
    none) and its ``theta`` and ``d`` there (without a nominal: θ the joint values of revolute
    joints, else 0; d 0)."""

    nominal: StandardDH | None
    theta: FloatArray
    d: FloatArray


def _place_with_nominal(
    i: int,
    lines: list[Line],
    xs: list[FloatArray | None],
    origins: list[FloatArray | None],
    z: list[FloatArray],
    aim: _Aim,
    angle_tol: float,
    anchor_place: Callable[[int], None],
) -> None:
    """Place prismatic axis i+1 (0-based) so that row i matches the nominal d_i, a_i, α_i (the
    anchor rule, ``anchor_place``, without a nominal)."""
    o_i = origins[i]
    assert o_i is not None
    z_i, e = z[i], lines[i + 1].direction
    nominal, desired_theta, nominal_d = aim.nominal, aim.theta, aim.d
    if nominal is None:
        anchor_place(i + 1)
        return
    cross = cross3(z_i, e)
    if np.linalg.norm(cross) >= np.sin(angle_tol):
        x_next = _unit(cross) * (1.0 if np.sin(nominal.alpha[i]) >= 0.0 else -1.0)
    else:
        if xs[i] is None and i == 0:
            xs[0] = _default_x(z_i)  # x_1 has no physical anchor before axis 2 is placed
        x_i = xs[i]
        if x_i is None:
            anchor_place(i + 1)
            return
        x_next = rotation_about(z_i, float(desired_theta[i])) @ x_i
    point = o_i + nominal_d[i] * z_i + nominal.a[i] * x_next
    lines[i + 1] = Line(point, e)


#: The length (m) that weighs as one radian when a row's two branches are compared with the
#: nominal's (:func:`_nearest_branch`).
BRANCH_LENGTH = 0.1


def _nearest_branch(
    x_next: FloatArray,
    x_i: FloatArray | None,
    z_i: FloatArray,
    z_next: FloatArray,
    offset: FloatArray,
    nominal: StandardDH,
    i: int,
    desired_theta: FloatArray,
) -> FloatArray:
    """``x_next`` or its reverse, whichever makes row i nearer the nominal's: reversing
    ``x_{i+1}`` turns ``a_i`` and ``α_i`` to ``−a_i`` and ``−α_i`` and adds π to ``θ_i``, so the
    row's distance from the nominal, ``|Δθ_i| + |Δα_i| + |Δa_i| / BRANCH_LENGTH`` (angles
    wrapped; θ_i from ``x_i``, left out while ``x_i`` is not known yet), decides; a term the
    reversal leaves equal (a nominal ``a_i`` or ``α_i`` of zero) does not. ``offset`` is
    ``o_{i+1} − o_i``."""

    def distance(x: FloatArray) -> float:
        a = float(offset @ x)  # Eq. 23
        alpha = float(np.arctan2(cross3(z_i, z_next) @ x, z_i @ z_next))  # Eq. 24
        out = abs(wrap_angle(alpha - float(nominal.alpha[i])))
        out += abs(a - float(nominal.a[i])) / BRANCH_LENGTH
        if x_i is not None:
            theta = float(np.arctan2(cross3(x_i, x) @ z_i, x_i @ x))  # Eq. 22
            out += abs(wrap_angle(theta - float(desired_theta[i])))
        return out

    return x_next if distance(x_next) <= distance(-x_next) else -x_next


def _default_x(z: FloatArray) -> FloatArray:
    """The measurement x axis (or y, when z is near x) made perpendicular to ``z``."""
    seed = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    return _unit(_reject(seed, z))


def _resolve_x(
    xs: list[FloatArray | None], z: list[FloatArray], desired_theta: FloatArray, limit: int
) -> None:
    """Fill the x axes left open by collinear axes: ``x_{i+1} = Rot(z_i, θ_i) x_i`` at the
    reference pose; ``x_1`` from the first known x further up the chain, turned back."""
    known = [k for k in range(1, limit) if xs[k] is not None]
    if known:
        for j in range(known[0] - 1, -1, -1):
            x_next = xs[j + 1]
            assert x_next is not None
            xs[j] = rotation_about(z[j], -float(desired_theta[j])) @ x_next
    elif xs[0] is None:
        xs[0] = _default_x(z[0])
    for j in range(limit - 1):
        if xs[j + 1] is None:
            x_j = xs[j]
            assert x_j is not None
            xs[j + 1] = rotation_about(z[j], float(desired_theta[j])) @ x_j


def hayati_table(
    ex: Extraction, rows: frozenset[int], nominal: StandardDH | None = None
) -> StandardDH:
    """The extracted model with ``rows`` (0-based) in the Hayati–Mirmirani form: same frames 1
    and n+1, same forward kinematics (a :class:`HayatiDH`, or the standard table without rows)."""
    return table_from_frames(ex.frames, ex.standard.joint_types, ex.reference_pose, nominal, rows)


@dataclass(frozen=True)
class Tolerances:
    """When the extraction calls two axes parallel or meeting: ``angle_tol`` (rad) and
    ``distance_tol`` (m), and per pair of neighbouring axes its own (angle, distance) where the
    fits' uncertainty or a decision from held-out poses gives one (``pair_tolerances[i]``: axes
    i+1, i+2)."""

    angle_tol: float = ANGLE_TOL
    distance_tol: float = DISTANCE_TOL
    pair_tolerances: Sequence[tuple[float, float]] | None = None

    def extract(
        self,
        axes: Sequence[Line],
        joint_types: Sequence[JointType | str],
        *,
        target: ArrayLike,
        reference_pose: ArrayLike,
        base_plane: Plane | None = None,
        nominal: StandardDH | None = None,
    ) -> Extraction:
        """:func:`extract_dh` with these tolerances."""
        return extract_dh(
            axes,
            joint_types,
            target=target,
            reference_pose=reference_pose,
            base_plane=base_plane,
            nominal=nominal,
            angle_tol=self.angle_tol,
            distance_tol=self.distance_tol,
            pair_tolerances=self.pair_tolerances,
        )
