"""The one placement of a model on measured poses: where the tracker stands relative to the
robot (``T_measurement_base``) and, where the probe was re-mounted, its point and frame on the
flange — what every caller that puts a nominal or a result on a session uses (the start of a
calibration from random poses, the nominal on a calibration session, a held-out log's footing,
the cross-validation's folds, ISO 9283's registration, a camera's start in 3-D, the tracker's
``Measurement.place``; the joint-permutation check its closed form alone, every joint order
at once).

:func:`place_on` takes the model's flange frames at the poses (in its frame 1), the measured
positions and, for a 6-DoF probe, the measured orientations, and uses what they determine
(:func:`conditioning`: the singular values of the centred positions):

- **positions that span a plane or a volume** fix the base's rotation (Kabsch on the points);
- **positions on one line** fix it up to a turn about the line; the **measured orientation**
  fixes it whatever the positions' shape (the chordal mean of ``R_meas (F R_tool)ᵀ``), a single
  point included;
- the tool point and the probe's frame on the flange are placed where asked; what the poses do
  not determine (a tool point on a path at constant orientation, which a translation of the base
  takes up; the probe's frame against the base's turn about a line) stays where the model put it
  (increments held towards zero with the weight :data:`PRIOR`).

It starts in closed form, from every start the data allow — the model's own base, Kabsch on
the positions, the rotation read off the orientations (on a line without orientation: the
model's rotation turned to carry its line onto the measured one) — each followed by the tool
point by linear least squares alternated with Kabsch (:func:`closed_form_placements`, over a
batch of models at once) and a robust (soft-L1) nonlinear least squares over the freedoms,
then plain least squares without the poses beyond :data:`OUTLIER_SCALE` robust scales; the start
leaving the smallest error wins. A local search from one start alone can stop hundreds of
millimetres from the answer when the tracker was re-stationed (turned far about its vertical).
Over :data:`SOLVED_POSES` poses it is solved on that many, evenly strided, and its residuals,
inliers and RMS are those of every pose.

Pure numpy/scipy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial

import numpy as np
from numpy.typing import NDArray

from dhlog.geometry._checks import FloatArray, nearest_rotation, rotation_from_vector

#: Samples beyond this many robust scales (median 3-D residual × 1.5) are outliers of the
#: placement.
OUTLIER_SCALE = 5.0
#: The soft-L1 loss switches from quadratic to linear at this 3-D residual (m): the nominal's own
#: error at a pose is typically a millimetre, a gross outlier (a beam break) centimetres.
ROBUST_SCALE = 2e-3
#: The robust scale is never taken below this (m): no tracker measures better.
SCALE_FLOOR = 1e-6
#: Metres per radian when orientation and position errors are weighed together: 1 mrad of the
#: probe's frame counts as 0.1 mm (a T-Mac's σ is about 0.2 mrad beside a tracker's 0.01–0.02 mm).
LEVER = 0.1
#: The placement's increments are held towards zero with this weight, so that what the poses do
#: not determine (the rotation about a line, a tool point at constant orientation) stays where
#: the start put it.
PRIOR = 1e-3
#: The flange's orientation must vary by this much (rad, RMS about its mean along a direction)
#: for the poses to determine the tool point along that direction.
TOOL_SPREAD = 0.02
#: A further closed-form start is refined only when its median error is within this factor of
#: the best placement's (a start far off, e.g. the model's old base after the tracker turned,
#: gains nothing).
FAR_START = 100.0
#: Positions whose spread is less than this (m, RMS along the widest direction) are one point.
POINT_SPREAD = 1e-3
#: Positions whose spread across their widest direction is below this fraction of the spread
#: along it lie on one line.
LINE_RATIO = 0.01
#: A placement is solved on at most this many poses, evenly strided over the session (a rigid
#: transform and a tool point from 2000 poses: their noise enters it /√2000); its residuals,
#: inliers and RMS are of every pose. A camera log's 10 000 board poses or a long session of
#: still poses held at 100 Hz otherwise cost seconds of finite differences.
SOLVED_POSES = 2000
#: The closed form alternates the tool point and the base's rotation this many times from each
#: start (where the tool point is placed).
ALTERNATIONS = 5


@dataclass(frozen=True)
class Conditioning:
    """What positions determine: ``kind`` ``"spread"`` (a plane or a volume: the base's rotation),
    ``"line"`` (``direction``: its unit vector; the rotation but for a turn about it), ``"point"``
    (no rotation); ``spread``: the RMS spread (m) along the three principal directions (the
    singular values of the centred positions over √k)."""

    kind: str
    spread: FloatArray
    direction: FloatArray | None = None


def conditioning(P: FloatArray) -> Conditioning:
    """What the positions ``P`` (k, 3) determine (:class:`Conditioning`)."""
    centred = P - P.mean(axis=0)
    _, s, Vt = np.linalg.svd(centred, full_matrices=False)
    spread = np.zeros(3)
    spread[: s.size] = s / np.sqrt(max(P.shape[0], 1))
    if spread[0] < POINT_SPREAD:
        return Conditioning("point", spread)
    if spread[1] < LINE_RATIO * spread[0]:
        return Conditioning("line", spread, np.asarray(Vt[0], dtype=np.float64))
    return Conditioning("spread", spread)


@dataclass(frozen=True)
class Stand:
    """Where a model stands in M: its frame 1 ``T`` (4×4), the target in its last frame
    ``tool`` (m) and the target frame's orientation there ``R_tool`` (None without); by default
    the identity, the flange's origin and no frame."""

    T: FloatArray = field(default_factory=lambda: np.eye(4))
    tool: FloatArray = field(default_factory=lambda: np.zeros(3))
    R_tool: FloatArray | None = None


class Standing:
    """Read-through of a record's ``stand`` (:class:`Stand`): ``T``, ``tool``, ``R_tool``."""

    stand: Stand

    @property
    def T(self) -> FloatArray:
        return self.stand.T

    @property
    def tool(self) -> FloatArray:
        return self.stand.tool

    @property
    def R_tool(self) -> FloatArray | None:
        return self.stand.R_tool


@dataclass(frozen=True)
class Placement(Standing):
    """A model placed on poses: where it stands (``stand``: ``T``, its frame 1 in M, the target
    in the last frame ``tool`` and the target frame there ``R_tool``, read through), each pose's
    3-D position residual (``residuals``, m), the poses kept (``inliers``) and the RMS over them
    (``rms``); ``start``: the start it was reached from (``"model"``, ``"positions"``,
    ``"orientation"``, ``"line"``)."""

    stand: Stand
    residuals: FloatArray
    inliers: NDArray[np.bool_]
    rms: float
    start: str


def _kabsch(A: FloatArray, B: FloatArray) -> FloatArray:
    """The rotation carrying the centred points ``A`` (m, 3) onto the centred ``B``."""
    return nearest_rotation((B - B.mean(axis=0)).T @ (A - A.mean(axis=0)))


def _turned_onto(a: FloatArray, b: FloatArray) -> FloatArray:
    """The smallest rotation carrying the unit vector ``a`` onto ``b``."""
    v, c = np.cross(a, b), float(a @ b)
    s = float(np.linalg.norm(v))
    if s < 1e-12:
        return np.eye(3) if c > 0 else rotation_from_vector(np.pi * _normal_to(a))
    return rotation_from_vector(v / s * np.arctan2(s, c))


def _normal_to(a: FloatArray) -> FloatArray:
    """A unit vector normal to ``a``."""
    n = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    return np.asarray(n / np.linalg.norm(n), dtype=np.float64)


def _skew_part(R: FloatArray) -> FloatArray:
    """The rotation vector of small rotations (k, 3, 3) from their antisymmetric part."""
    return 0.5 * np.stack(
        [R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1
    )


def angles(R: FloatArray) -> FloatArray:
    """The angle (rad) of each rotation (k, 3, 3)."""
    c = (np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0
    return np.asarray(np.arccos(np.clip(c, -1.0, 1.0)), dtype=np.float64)


@dataclass(frozen=True)
class _Problem:
    """A placement's data and freedoms."""

    F: FloatArray  # (k, 3, 3) the flange's rotation in frame 1
    f: FloatArray  # (k, 3) its origin
    P: FloatArray  # (k, 3) measured positions
    R: FloatArray | None  # (k, 3, 3) measured orientations, used (the model has a tool frame)
    base: bool
    point: bool
    frame: bool
    #: the tool point's directions the poses determine (3, d): those along which the flange's
    #: orientation varies enough (:func:`tool_directions`)
    tool_basis: FloatArray

    def local(self, tool: FloatArray) -> FloatArray:
        return _carried(self.F, self.f, tool)


def _carried(F: FloatArray, f: FloatArray, tool: FloatArray) -> FloatArray:
    """The tool point at each pose in the model's frame 1 (k, 3): the flange's frames ``F``,
    ``f`` carrying ``tool``."""
    return np.asarray(np.einsum("kij,j->ki", F, tool) + f, dtype=np.float64)


def _inliers(dist: FloatArray) -> NDArray[np.bool_]:
    """The poses within :data:`OUTLIER_SCALE` robust scales (1.5 × the median residual, never
    below :data:`SCALE_FLOOR`)."""
    return np.asarray(dist <= OUTLIER_SCALE * max(1.5 * float(np.median(dist)), SCALE_FLOOR))


def _starts(
    pb: _Problem, T: FloatArray, tool: FloatArray, R_tool: FloatArray | None
) -> list[tuple[str, FloatArray]]:
    """The base rotations to start from: the model's, and those the data give in closed form."""
    out = [("model", np.asarray(T[:3, :3], dtype=np.float64))]
    if not pb.base:
        return out
    shape = conditioning(pb.P)
    local = pb.local(tool)
    if shape.kind == "spread" and conditioning(local).kind == "spread":
        out.append(("positions", _kabsch(local, pb.P)))
    if pb.R is not None and R_tool is not None:
        # R_meas = R_B F R_tool at every pose: R_B the chordal mean of R_meas (F R_tool)ᵀ
        A = np.einsum("kij,klj->il", pb.R, np.einsum("kij,jl->kil", pb.F, R_tool))
        out.append(("orientation", nearest_rotation(A)))
    if shape.kind == "line" and shape.direction is not None:
        # the model's rotation turned so that its line of targets lies along the measured one
        lc = local - local.mean(axis=0)
        u_local = np.linalg.svd(lc, full_matrices=False)[2][0]
        u_meas = shape.direction
        if float(((pb.P - pb.P.mean(axis=0)) @ u_meas) @ (lc @ u_local)) < 0:
            u_meas = -u_meas
        R0 = np.asarray(T[:3, :3], dtype=np.float64)
        out.append(("line", _turned_onto(R0 @ u_local, u_meas) @ R0))
    return out


def tool_directions(F: FloatArray) -> FloatArray:
    """The tool point's directions (3, d) the flange frames ``F`` (k, 3, 3) determine: a point
    on the flange moves apart from the flange's origin only as the orientation varies, so the
    directions of the centred stack ``F − F̄`` with an RMS of :data:`TOOL_SPREAD` rad or more
    (none at a constant orientation: a line or a curve of a task, where the base's translation
    takes up the tool point)."""
    s, Vt = _orientation_spread(F[None])
    return np.asarray(Vt[0][s[0] >= TOOL_SPREAD].T, dtype=np.float64)


def _orientation_spread(F: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The RMS spread (B, 3) of the flange frames ``F`` (B, k, 3, 3) about their mean along
    the principal directions ``Vt`` (B, 3, 3) (rows): the singular values of the centred stack
    over √k."""
    k = max(F.shape[1], 1)
    centred = (F - F.mean(axis=1, keepdims=True)).reshape(F.shape[0], -1, 3)
    _, s, Vt = np.linalg.svd(centred, full_matrices=False)
    return np.asarray(s / np.sqrt(k), dtype=np.float64), np.asarray(Vt, dtype=np.float64)


def _rotations_nearest(A: FloatArray) -> FloatArray:
    """The rotations (B, 3, 3) nearest the matrices ``A`` (B, 3, 3): each one's polar factor by
    SVD (:func:`~dhlog.geometry._checks.nearest_rotation`, a batch at once)."""
    U, _, Vt = np.linalg.svd(A)
    U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    return np.asarray(U @ Vt, dtype=np.float64)


def closed_form_placements(
    F: FloatArray,
    f: FloatArray,
    P: FloatArray,
    tool: FloatArray,
    *,
    rounds: int,
    R_B: FloatArray | None = None,
    rotate: bool = True,
    directions: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A batch of rigid placements in closed form: B models' flange frames ``F`` (B, k, 3, 3)
    and origins ``f`` (B, k, 3) at the same k poses placed on the points ``P`` (k, 3), the
    tool point on the flange (start ``tool``, (B, 3)) placed with them. From the base rotation
    ``R_B`` (B, 3, 3; None: Kabsch of the model's points at ``tool`` onto ``P``, the identity
    where the rotation is not to be turned, below), ``rounds`` alternations of

    - the tool point by linear least squares with the base's rotation held and its translation
      eliminated (centred: ``(F − F̄) t = R_Bᵀ (P − P̄) − (f − f̄)``), changed only along
      ``directions`` (B, 3, 3: projectors; None: the directions the flange's orientation
      determines, as :func:`tool_directions`);
    - the base's rotation by Kabsch where ``rotate`` (the points span a plane or more) and the
      model's points at that tool point do too (:func:`conditioning`), else held.

    Each step lowers the sum of squared distances, so the alternation converges on a
    stationary point of it. Returns the base rotations (B, 3, 3), translations (B, 3) and
    tool points (B, 3)."""
    B, k = F.shape[:2]
    F_mean, f_mean, P_mean = F.mean(axis=1), f.mean(axis=1), P.mean(axis=0)
    A = (F - F_mean[:, None]).reshape(B, 3 * k, 3)  # the centred rotations, stacked
    fc, Pc = f - f_mean[:, None], P - P_mean
    if directions is None:
        s, Vt = _orientation_spread(F)
        directions = np.einsum("bji,bj,bjl->bil", Vt, (s >= TOOL_SPREAD).astype(float), Vt)
    At = np.swapaxes(A, 1, 2)
    normal = At @ A
    # the least squares restricted to the directions: (Π N Π + I − Π)⁻¹ Π (Π a projector)
    rest = np.eye(3) - directions
    solve = np.linalg.solve(directions @ normal @ directions + rest, directions)
    t = np.array(tool, dtype=np.float64, copy=True)

    def turned(R: FloatArray | None) -> FloatArray:
        local = (A @ t[..., None]).reshape(B, k, 3) + fc  # centred
        held = np.broadcast_to(np.eye(3), (B, 3, 3)) if R is None else R
        if not rotate:
            return np.array(held, dtype=np.float64)
        spread = np.sqrt(np.maximum(np.linalg.eigvalsh(np.swapaxes(local, 1, 2) @ local), 0))
        spread = spread[:, ::-1] / np.sqrt(max(k, 1))
        planar = (spread[:, 0] >= POINT_SPREAD) & (spread[:, 1] >= LINE_RATIO * spread[:, 0])
        kabsch = _rotations_nearest(Pc.T @ local)
        return np.asarray(np.where(planar[:, None, None], kabsch, held), dtype=np.float64)

    R = turned(None) if R_B is None else np.array(R_B, dtype=np.float64, copy=True)
    for _ in range(rounds):
        g = (At @ (Pc @ R - fc).reshape(B, 3 * k, 1))[..., 0]
        t = t + (solve @ (g - (normal @ t[..., None])[..., 0])[..., None])[..., 0]
        R = turned(R)
    c = P_mean - (R @ ((F_mean @ t[..., None])[..., 0] + f_mean)[..., None])[..., 0]
    return R, np.asarray(c, dtype=np.float64), t


def _tool_by_lstsq(pb: _Problem, R_B: FloatArray, tool: FloatArray, c: FloatArray) -> FloatArray:
    """The tool point that best carries the flange onto the points with the base held (its
    rotation ``R_B``, its translation ``c``): ``R_B F t = P − c − R_B f``, changed from ``tool``
    only along the directions the poses determine (``pb.tool_basis``)."""
    V = pb.tool_basis
    if V.shape[1] == 0:
        return tool
    G = np.einsum("ij,kjl->kil", R_B, pb.F)
    b = (pb.P - c - pb.f @ R_B.T).reshape(-1)
    A = G.reshape(-1, 3) @ V
    y, *_ = np.linalg.lstsq(A, b - G.reshape(-1, 3) @ tool, rcond=None)
    return np.asarray(tool + V @ y, dtype=np.float64)


def _closed_form(
    pb: _Problem, R_B: FloatArray, tool: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """From the base rotation ``R_B``: the translation and (where placed) the tool point,
    alternated with Kabsch where the positions fix the rotation
    (:func:`closed_form_placements`, a batch of one). Returns the base's rotation, its
    translation and the tool point."""
    V = pb.tool_basis
    R, c, t = closed_form_placements(
        pb.F[None],
        pb.f[None],
        pb.P,
        tool[None],
        rounds=ALTERNATIONS if pb.point else 0,
        R_B=R_B[None],
        rotate=conditioning(pb.P).kind == "spread",
        directions=(V @ V.T)[None],
    )
    return R[0], c[0], t[0]


class _Fit:
    """The nonlinear least squares of one start: increments of the base (turn about the points'
    centroid, shift), the tool point and the probe's frame."""

    def __init__(
        self,
        pb: _Problem,
        R_B: FloatArray,
        c: FloatArray,
        tool: FloatArray,
        R_tool: FloatArray | None,
    ) -> None:
        self.pb, self.R_B, self.c, self.tool, self.R_tool = pb, R_B, c, tool, R_tool
        self.m = pb.P.mean(axis=0)
        self.nb = 6 if pb.base else 0
        self.np_ = pb.tool_basis.shape[1] if pb.point else 0
        self.nf = 3 if (pb.frame and R_tool is not None and pb.R is not None) else 0
        self.size = self.nb + self.np_ + self.nf

    def unpack(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray | None]:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R_B, self.c
        if self.pb.base:
            W = rotation_from_vector(x[:3])
            T[:3, :3] = W @ self.R_B
            T[:3, 3] = W @ (self.c - self.m) + self.m + x[3:6]
        t = self.tool + (self.pb.tool_basis @ x[self.nb : self.nb + self.np_] if self.np_ else 0.0)
        Rt = self.R_tool
        if self.nf:
            assert Rt is not None
            Rt = Rt @ rotation_from_vector(x[self.nb + self.np_ :])
        return T, np.asarray(t, dtype=np.float64), Rt

    def residual(self, x: FloatArray) -> FloatArray:
        T, t, Rt = self.unpack(x)
        pos = self.pb.local(t) @ T[:3, :3].T + T[:3, 3]
        parts = [(pos - self.pb.P).reshape(-1)]
        if self.pb.R is not None and Rt is not None:
            frame = np.einsum("ij,kjl,lm->kim", T[:3, :3], self.pb.F, Rt)
            turn = _skew_part(np.einsum("kji,kjl->kil", self.pb.R, frame))
            parts.append(LEVER * turn.reshape(-1))
        prior = x.copy()
        if self.pb.base:
            prior[:3] *= LEVER
        if self.nf:
            prior[self.nb + self.np_ :] *= LEVER
        parts.append(PRIOR * prior)
        return np.concatenate(parts)

    def distances(self, x: FloatArray) -> FloatArray:
        k = self.pb.P.shape[0]
        return np.asarray(
            np.linalg.norm(self.residual(x)[: 3 * k].reshape(-1, 3), axis=1), dtype=np.float64
        )

    def kept(self, x: FloatArray, keep: NDArray[np.bool_]) -> FloatArray:
        r, k = self.residual(x), keep.size
        parts = [r[: 3 * k].reshape(-1, 3)[keep].reshape(-1)]
        rest = r[3 * k :]
        if self.pb.R is not None and self.R_tool is not None:
            parts.append(rest[: 3 * k].reshape(-1, 3)[keep].reshape(-1))
            rest = rest[3 * k :]
        return np.concatenate([*parts, rest])

    def solve(self) -> tuple[FloatArray, NDArray[np.bool_], float]:
        """The increments, the poses kept and the cost over them (positions and orientations)."""
        from scipy.optimize import least_squares

        k = self.pb.P.shape[0]
        x = np.zeros(self.size)
        keep = np.ones(k, dtype=bool)
        if self.size:
            x = least_squares(
                self.residual, x, loss="soft_l1", f_scale=ROBUST_SCALE, x_scale="jac"
            ).x
        for round_ in range(3):  # the robust loss still leans towards gross outliers: refit
            dist = self.distances(x)
            new = _inliers(dist)
            if round_ > 0 and np.array_equal(new, keep):
                break
            keep = new
            if not self.size:
                break
            x = least_squares(partial(self.kept, keep=keep), x, x_scale="jac").x
        return x, keep, self.median_error(x)

    def median_error(self, x: FloatArray) -> float:
        """The median over the poses of the squared position error and :data:`LEVER` × the
        orientation error: how starts are compared (a start stuck far away keeps most poses;
        the right one sets gross outliers aside)."""
        e2 = self.distances(x) ** 2
        T, _, Rt = self.unpack(x)
        if self.pb.R is not None and Rt is not None:
            frame = np.einsum("ij,kjl,lm->kim", T[:3, :3], self.pb.F, Rt)
            e2 = e2 + (LEVER * angles(np.einsum("kji,kjl->kil", self.pb.R, frame))) ** 2
        return float(np.median(e2))


def place_on(
    F: FloatArray,
    f: FloatArray,
    P: FloatArray,
    R: FloatArray | None = None,
    *,
    stand: Stand | None = None,
    base: bool = True,
    point: bool = False,
    frame: bool = False,
) -> Placement:
    """A model placed on measured poses (see the module docstring): ``F`` (k, 3, 3) and ``f``
    (k, 3) its flange's frame at each pose in its frame 1, ``P`` (k, 3) the measured positions,
    ``R`` (k, 3, 3) the measured orientations (a 6-DoF probe; used where the model has a tool
    frame). ``stand``: the model as it stands (its base, tool point and frame; None:
    :class:`Stand`'s defaults). ``base``: place its ``T``; ``point``: the tool point;
    ``frame``: the tool frame (with ``R`` and a ``R_tool``). Every start is tried and the one
    leaving the smallest cost (over the poses kept) is returned. Over :data:`SOLVED_POSES`
    poses, it is solved on that many evenly strided, and judged on all."""
    k = P.shape[0]
    if k > SOLVED_POSES:
        pick = np.linspace(0, k - 1, SOLVED_POSES).round().astype(np.intp)
        got = place_on(
            F[pick],
            f[pick],
            P[pick],
            None if R is None else R[pick],
            stand=stand,
            base=base,
            point=point,
            frame=frame,
        )
        dist = np.linalg.norm(_carried(F, f, got.tool) @ got.T[:3, :3].T + got.T[:3, 3] - P, axis=1)
        keep = _inliers(dist)
        rms = float(np.sqrt(np.mean(dist[keep] ** 2))) if np.any(keep) else float("nan")
        return Placement(got.stand, dist, keep, rms, got.start)
    stand = Stand() if stand is None else stand
    T0 = np.asarray(stand.T, dtype=np.float64)
    t0 = np.asarray(stand.tool, dtype=np.float64)
    Rt0 = None if stand.R_tool is None else np.asarray(stand.R_tool, dtype=np.float64)
    used = R if (R is not None and Rt0 is not None) else None
    basis = tool_directions(F) if base else np.eye(3)  # a held base: the point is fixed
    pb = _Problem(F, f, P, used, base, point, frame, basis)
    best: tuple[float, FloatArray, _Fit, NDArray[np.bool_], str] | None = None
    fits = []
    for name, R_start in _starts(pb, T0, t0, Rt0):
        if base:
            R_B, c, t = _closed_form(pb, R_start, t0)
        else:  # the base held: the tool point alone, linear
            R_B, c = T0[:3, :3], T0[:3, 3]
            t = _tool_by_lstsq(pb, R_B, t0, c) if point else t0
        fit = _Fit(pb, R_B, c, t, Rt0)
        fits.append((fit.median_error(np.zeros(fit.size)), name, fit))
    # the best start in closed form refined first; another only where its closed form misses
    # within FAR_START of the best placement found (one far off would crawl, and gain nothing)
    for cost0, name, fit in sorted(fits, key=lambda c: c[0]):
        if best is not None and cost0 > FAR_START**2 * max(best[0], SCALE_FLOOR**2):
            continue
        x, keep, cost = fit.solve()
        if best is None or cost < best[0]:
            best = (cost, x, fit, keep, name)
    assert best is not None
    _, x, fit, keep, name = best
    Tp, tp, Rtp = fit.unpack(x)
    dist = fit.distances(x)
    rms = float(np.sqrt(np.mean(dist[keep] ** 2))) if np.any(keep) else float("nan")
    return Placement(Stand(Tp, tp, Rtp), dist, keep, rms, name)
