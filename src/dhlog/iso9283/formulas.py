"""The ISO 9283:1998 performance characteristics, each as the standard defines it, on plain
arrays: pose accuracy and repeatability (7.2.1, 7.2.2), multi-directional pose accuracy
variation (7.2.3), distance accuracy and repeatability (7.3), pose stabilisation time and
overshoot (7.4, 7.5), drift of pose characteristics (7.6), path accuracy and repeatability (8.2)
and path velocity characteristics (8.4).

Units are SI throughout: positions in m, orientation components in rad, times in s (mm and °
only where the results are shown). Every standard deviation is the sample one (divisor n − 1),
as the standard writes it. Where the standard leaves a choice (how the orientation components
a, b, c are taken from a rotation, the stabilisation band, which deviation is the overshoot) the
function's docstring says what is done here; docs/iso9283.md ("The formulas") lists the choices.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import Iso9283Error, NonFiniteError, ShapeError
from dhlog.geometry._checks import FloatArray, nearest_rotation, rotation_from_vector

__all__ = [
    "DistanceCharacteristics",
    "Drift",
    "MultiDirectional",
    "PathCharacteristics",
    "PathVelocity",
    "PoseAccuracy",
    "PoseRepeatability",
    "Stabilisation",
    "distance_accuracy",
    "drift",
    "matrix_from_abc",
    "multi_directional",
    "orientation_abc",
    "orientation_deviation",
    "path_accuracy",
    "path_velocity",
    "pose_accuracy",
    "pose_repeatability",
    "speeds_from_positions",
    "stabilisation",
    "stabilisation_over_cycles",
]

#: tolerance of the orthonormality check of given rotation matrices
_ROTATION_TOL = 1e-6


# ---------------------------------------------------------------------------------------------
# input checks


def _finite(what: str, arr: FloatArray) -> FloatArray:
    bad = int(np.count_nonzero(~np.isfinite(arr)))
    if bad:
        raise NonFiniteError(what, bad)
    return arr


def _points(what: str, value: ArrayLike, *, at_least: int, unit: str = "cycles") -> FloatArray:
    """``value`` as a finite (n, 3) float64 array with n ≥ ``at_least``."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ShapeError(what, "an (n, 3) array of positions (m)", f"shape {arr.shape}")
    if arr.shape[0] < at_least:
        raise Iso9283Error(
            what,
            f"{arr.shape[0]} {unit} given, at least {at_least} are needed",
            f"measure at least {at_least} {unit} (the standard prescribes 30 for poses, 10 for "
            "paths)",
        )
    return _finite(what, arr)


def _vector(what: str, value: ArrayLike) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,):
        raise ShapeError(what, "a 3-vector (m)", f"shape {arr.shape}")
    return _finite(what, arr)


def _rotations(what: str, value: ArrayLike, n: int | None = None) -> FloatArray:
    """``value`` as finite rotation matrices (…, 3, 3) (n of them when ``n`` is given)."""
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
        raise ShapeError(what, "rotation matrices (..., 3, 3)", f"shape {arr.shape}")
    if n is not None and arr.shape != (n, 3, 3):
        raise ShapeError(what, f"one rotation per position, ({n}, 3, 3)", f"shape {arr.shape}")
    _finite(what, arr)
    gram = np.einsum("...ji,...jk->...ik", arr, arr)
    if not np.allclose(gram, np.eye(3), atol=_ROTATION_TOL) or np.any(np.linalg.det(arr) < 0.0):
        raise ShapeError(what, "proper rotation matrices (orthonormal, det +1)", "other")
    return arr


def _sample_std(x: FloatArray) -> FloatArray:
    """The sample standard deviation along axis 0 (divisor n − 1), as ISO 9283 writes S."""
    return np.asarray(np.std(x, axis=0, ddof=1), dtype=np.float64)


def _floats(x: FloatArray | None) -> list[Any] | None:
    return None if x is None else np.asarray(x, dtype=np.float64).tolist()


# ---------------------------------------------------------------------------------------------
# orientation components


def orientation_abc(R: ArrayLike) -> FloatArray:
    """The orientation components a, b, c (rad) of rotation matrices ``R`` (…, 3, 3): rotations
    about the base frame's x, y and z axes, ISO 9283:1998 clause 5.2 (a, b, c), taken here as
    fixed-axis X-Y-Z angles, ``R = Rz(c) Ry(b) Rx(a)`` (the standard names the axes but not the
    sequence: this choice is documented in docs/iso9283.md). Returns (…, 3) with
    b ∈ [−π/2, π/2], a, c ∈ (−π, π]; at b = ±π/2 the whole turn about z is put in c (a = 0)."""
    Rm = _rotations("orientation_abc: R", R)
    b = np.arcsin(np.clip(-Rm[..., 2, 0], -1.0, 1.0))
    a = np.arctan2(Rm[..., 2, 1], Rm[..., 2, 2])
    c = np.arctan2(Rm[..., 1, 0], Rm[..., 0, 0])
    gimbal = np.abs(np.cos(b)) < 1e-9
    a = np.where(gimbal, 0.0, a)
    c = np.where(gimbal, np.arctan2(-Rm[..., 0, 1], Rm[..., 1, 1]), c)
    return np.asarray(np.stack([a, b, c], axis=-1), dtype=np.float64)


def matrix_from_abc(abc: ArrayLike) -> FloatArray:
    """The rotation ``Rz(c) Ry(b) Rx(a)`` of orientation components ``abc`` (…, 3) (rad): the
    inverse of :func:`orientation_abc`."""
    v = _finite("matrix_from_abc: abc", np.asarray(abc, dtype=np.float64))
    if v.shape[-1:] != (3,):
        raise ShapeError("matrix_from_abc: abc", "(..., 3) angles (rad)", f"shape {v.shape}")
    ca, sa = np.cos(v[..., 0]), np.sin(v[..., 0])
    cb, sb = np.cos(v[..., 1]), np.sin(v[..., 1])
    cc, sc = np.cos(v[..., 2]), np.sin(v[..., 2])
    R = np.empty((*v.shape[:-1], 3, 3))
    R[..., 0, 0] = cc * cb
    R[..., 0, 1] = cc * sb * sa - sc * ca
    R[..., 0, 2] = cc * sb * ca + sc * sa
    R[..., 1, 0] = sc * cb
    R[..., 1, 1] = sc * sb * sa + cc * ca
    R[..., 1, 2] = sc * sb * ca - cc * sa
    R[..., 2, 0] = -sb
    R[..., 2, 1] = cb * sa
    R[..., 2, 2] = cb * ca
    return R


def orientation_deviation(R: ArrayLike, R_ref: ArrayLike) -> FloatArray:
    """The orientation components a, b, c (rad) of ``R`` (…, 3, 3) relative to ``R_ref`` (3, 3)
    or (…, 3, 3), in the base frame: :func:`orientation_abc` of ``ΔR = R R_refᵀ`` (so that
    ``R = ΔR R_ref``). For the small deviations of a robot these are the rotations about the
    base's x, y, z that carry the reference orientation onto the attained one.

    This is what every orientation characteristic here is computed from (AP_a = mean of the
    attained orientations' deviations from the commanded one, S_a of their deviations from the
    mean orientation, …). ISO 9283 writes AP_a = ā − a_c of the components themselves; taken
    literally on Euler angles, a difference of angles is a rotation about the base's x only at
    the identity (the angles' rates mix elsewhere, and wrap at ±π), so the deviation is taken
    first: the same to first order in the deviation where the reference is the identity, and a
    rotation about the named axis everywhere."""
    Rm = _rotations("orientation_deviation: R", R)
    Rr = _rotations("orientation_deviation: R_ref", R_ref)
    dR = np.einsum("...ij,...kj->...ik", Rm, Rr)
    return orientation_abc(dR)


def _mean_rotation(R: FloatArray) -> FloatArray:
    """The chordal mean of rotations (n, 3, 3): the rotation nearest their arithmetic mean."""
    return nearest_rotation(np.asarray(R.mean(axis=0), dtype=np.float64))


# ---------------------------------------------------------------------------------------------
# 7.2 pose accuracy, repeatability, multi-directional variation


@dataclass(frozen=True)
class PoseAccuracy:
    """Pose accuracy (ISO 9283:1998, 7.2.1) of ``n`` attained poses of one commanded pose:
    ``barycentre`` (3,) of the attained positions, ``AP_P`` = its distance from the commanded
    position, ``AP_xyz`` (3,) = barycentre − commanded, and ``AP_abc`` (3,) the mean deviation
    of the attained orientations from the commanded one (None without orientations). m, rad."""

    n: int
    barycentre: FloatArray
    AP_P: float
    AP_xyz: FloatArray
    AP_abc: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m, rad)."""
        return {
            "n": self.n,
            "barycentre_m": _floats(self.barycentre),
            "AP_P_m": self.AP_P,
            "AP_xyz_m": _floats(self.AP_xyz),
            "AP_abc_rad": _floats(self.AP_abc),
        }


def pose_accuracy(
    attained: ArrayLike,
    commanded: ArrayLike,
    R_attained: ArrayLike | None = None,
    R_commanded: ArrayLike | None = None,
) -> PoseAccuracy:
    """Pose accuracy, ISO 9283:1998 clause 7.2.1, of the attained positions ``attained``
    (n, 3) of the commanded position ``commanded`` (3,):

        x̄ = (1/n) Σ x_j (likewise ȳ, z̄), AP_x = x̄ − x_c, AP_y = ȳ − y_c, AP_z = z̄ − z_c,
        AP_P = √(AP_x² + AP_y² + AP_z²);

    with the attained orientations ``R_attained`` (n, 3, 3) and the commanded ``R_commanded``
    (3, 3): AP_a = ā − a_c, AP_b, AP_c, computed as the mean of the deviations
    :func:`orientation_deviation` (R_j, R_c) (the rotations about the base's x, y, z; see
    there). One attained pose is enough for a barycentre (n ≥ 1)."""
    pts = _points("pose accuracy: attained positions", attained, at_least=1)
    c = _vector("pose accuracy: commanded position", commanded)
    bary = np.asarray(pts.mean(axis=0), dtype=np.float64)
    ap_xyz = bary - c
    ap_abc = None
    if (R_attained is None) != (R_commanded is None):
        raise Iso9283Error(
            "pose accuracy",
            "an attained orientation was given without a commanded one (or the reverse)",
            "give both R_attained and R_commanded, or neither",
        )
    if R_attained is not None and R_commanded is not None:
        Ra = _rotations("pose accuracy: attained orientations", R_attained, len(pts))
        Rc = _rotations("pose accuracy: commanded orientation", R_commanded)
        if Rc.shape != (3, 3):
            raise ShapeError("pose accuracy: commanded orientation", "(3, 3)", Rc.shape)
        ap_abc = np.asarray(orientation_deviation(Ra, Rc).mean(axis=0), dtype=np.float64)
    return PoseAccuracy(len(pts), bary, float(np.linalg.norm(ap_xyz)), ap_xyz, ap_abc)


@dataclass(frozen=True)
class PoseRepeatability:
    """Pose repeatability (ISO 9283:1998, 7.2.2) of ``n`` attained poses: ``barycentre`` (3,),
    the distances ``l_j`` (n,) of the attained positions from it, their mean ``l_mean`` and
    sample standard deviation ``S_l``, ``RP_l`` = l̄ + 3 S_l; with orientations ``S_abc`` (3,)
    and ``RP_abc`` = 3 S_a, 3 S_b, 3 S_c (the standard's ±3 S_a: the half-width). m, rad."""

    n: int
    barycentre: FloatArray
    l_j: FloatArray
    l_mean: float
    S_l: float
    RP_l: float
    S_abc: FloatArray | None = None
    RP_abc: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m, rad); ``RP_abc_rad`` is the half-width of ±3 S."""
        return {
            "n": self.n,
            "barycentre_m": _floats(self.barycentre),
            "l_mean_m": self.l_mean,
            "S_l_m": self.S_l,
            "RP_l_m": self.RP_l,
            "S_abc_rad": _floats(self.S_abc),
            "RP_abc_rad": _floats(self.RP_abc),
        }


def pose_repeatability(
    attained: ArrayLike, R_attained: ArrayLike | None = None
) -> PoseRepeatability:
    """Pose repeatability, ISO 9283:1998 clause 7.2.2, of the attained positions ``attained``
    (n, 3), n ≥ 2:

        l_j = √((x_j − x̄)² + (y_j − ȳ)² + (z_j − z̄)²), l̄ = (1/n) Σ l_j,
        S_l = √(Σ (l_j − l̄)² / (n − 1)), RP_l = l̄ + 3 S_l;

    with the attained orientations ``R_attained`` (n, 3, 3):

        RP_a = ±3 S_a, S_a = √(Σ (a_j − ā)² / (n − 1)) (likewise b, c),

    where a_j, b_j, c_j are the :func:`orientation_deviation` of each attained orientation from
    their mean (the rotation nearest the mean of the matrices): rotations about the base's
    x, y, z, so that a spread is not changed by where the mean orientation lies. RP_abc holds
    the half-widths 3 S_a, 3 S_b, 3 S_c. No commanded pose is needed."""
    pts = _points("pose repeatability: attained positions", attained, at_least=2)
    bary = np.asarray(pts.mean(axis=0), dtype=np.float64)
    l_j = np.asarray(np.linalg.norm(pts - bary, axis=1), dtype=np.float64)
    l_mean = float(l_j.mean())
    S_l = float(_sample_std(l_j))
    S_abc = RP_abc = None
    if R_attained is not None:
        Ra = _rotations("pose repeatability: attained orientations", R_attained, len(pts))
        dev = orientation_deviation(Ra, _mean_rotation(Ra))
        S_abc = _sample_std(dev)
        RP_abc = 3.0 * S_abc
    return PoseRepeatability(len(pts), bary, l_j, l_mean, S_l, l_mean + 3.0 * S_l, S_abc, RP_abc)


@dataclass(frozen=True)
class MultiDirectional:
    """Multi-directional pose accuracy variation (ISO 9283:1998, 7.2.3): ``vAP_P`` the largest
    distance between the barycentres reached from the different approach directions, and
    ``vAP_abc`` (3,) the largest difference of their mean orientation components. m, rad."""

    directions: int
    vAP_P: float
    vAP_abc: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m, rad)."""
        return {
            "directions": self.directions,
            "vAP_P_m": self.vAP_P,
            "vAP_abc_rad": _floats(self.vAP_abc),
        }


def multi_directional(
    barycentres: ArrayLike, mean_abc: ArrayLike | None = None
) -> MultiDirectional:
    """Multi-directional pose accuracy variation, ISO 9283:1998 clause 7.2.3, from the
    barycentres ``barycentres`` (h, 3) of the attained positions of one commanded pose reached
    from h approach directions (the standard's three, h ≥ 2):

        vAP_P = max √((x̄_h − x̄_k)² + (ȳ_h − ȳ_k)² + (z̄_h − z̄_k)²), h, k = 1 … 3;

    with ``mean_abc`` (h, 3), each direction's mean orientation components (the ``AP_abc`` of
    :func:`pose_accuracy` against one commanded orientation, so their differences are
    ā_h − ā_k): vAP_a = max |ā_h − ā_k| (likewise b, c)."""
    bary = _points(
        "multi-directional pose accuracy variation: barycentres",
        barycentres,
        at_least=2,
        unit="approach directions",
    )
    diff = bary[:, None, :] - bary[None, :, :]
    vap = float(np.linalg.norm(diff, axis=2).max())
    vabc = None
    if mean_abc is not None:
        abc = np.asarray(mean_abc, dtype=np.float64)
        if abc.shape != bary.shape:
            raise ShapeError(
                "multi-directional pose accuracy variation: mean_abc",
                f"one (a, b, c) per direction, {bary.shape}",
                f"shape {abc.shape}",
            )
        _finite("multi-directional pose accuracy variation: mean_abc", abc)
        vabc = np.asarray(np.abs(abc[:, None, :] - abc[None, :, :]).max(axis=(0, 1)))
    return MultiDirectional(len(bary), vap, vabc)


# ---------------------------------------------------------------------------------------------
# 7.3 distance accuracy and repeatability


@dataclass(frozen=True)
class DistanceCharacteristics:
    """Distance accuracy and repeatability (ISO 9283:1998, 7.3) between two commanded poses
    over ``n`` cycles: the attained distances ``D`` (n,), their mean ``D_mean``, the commanded
    distance ``D_c``, ``AD_P`` = D̄ − D_c, ``AD_xyz`` (3,) per axis, ``RD`` = 3 S_D and
    ``RD_xyz`` (3,) = 3 S_Dx … (the standard's ±3 S: the half-width). m."""

    n: int
    D: FloatArray
    D_mean: float
    D_c: float
    AD_P: float
    AD_xyz: FloatArray
    RD: float
    RD_xyz: FloatArray

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m); ``RD_m`` is the half-width of ±3 S_D."""
        return {
            "n": self.n,
            "D_mean_m": self.D_mean,
            "D_c_m": self.D_c,
            "AD_P_m": self.AD_P,
            "AD_xyz_m": _floats(self.AD_xyz),
            "RD_m": self.RD,
            "RD_xyz_m": _floats(self.RD_xyz),
        }


def distance_accuracy(
    attained_1: ArrayLike,
    attained_2: ArrayLike,
    commanded_1: ArrayLike,
    commanded_2: ArrayLike,
) -> DistanceCharacteristics:
    """Distance accuracy and repeatability, ISO 9283:1998 clause 7.3, from the attained
    positions of the two commanded poses in the same n cycles, ``attained_1`` and
    ``attained_2`` (n, 3) (row j of each from cycle j), n ≥ 2:

        D_j = |P1_j − P2_j|, D̄ = (1/n) Σ D_j, D_c = |P_c1 − P_c2|, AD_P = D̄ − D_c;
        AD_x = D̄_x − D_cx with D_xj = |x_1j − x_2j|, D_cx = |x_c1 − x_c2| (likewise y, z);
        RD = ±3 S_D, S_D = √(Σ (D_j − D̄)² / (n − 1)); RD_x = ±3 S_Dx (likewise y, z).

    The orientation's distance characteristics (AD_a …) are not computed here."""
    p1 = _points("distance accuracy: attained positions of pose 1", attained_1, at_least=2)
    p2 = _points("distance accuracy: attained positions of pose 2", attained_2, at_least=2)
    if p1.shape != p2.shape:
        raise Iso9283Error(
            "distance accuracy",
            f"{len(p1)} attained positions of pose 1 but {len(p2)} of pose 2",
            "give both poses' attained positions from the same cycles, one row per cycle",
        )
    c1 = _vector("distance accuracy: commanded position 1", commanded_1)
    c2 = _vector("distance accuracy: commanded position 2", commanded_2)
    D = np.asarray(np.linalg.norm(p1 - p2, axis=1), dtype=np.float64)
    D_axes = np.abs(p1 - p2)
    D_c = float(np.linalg.norm(c1 - c2))
    D_mean = float(D.mean())
    ad_xyz = np.asarray(D_axes.mean(axis=0) - np.abs(c1 - c2), dtype=np.float64)
    return DistanceCharacteristics(
        len(p1),
        D,
        D_mean,
        D_c,
        D_mean - D_c,
        ad_xyz,
        3.0 * float(_sample_std(D)),
        3.0 * _sample_std(D_axes),
    )


# ---------------------------------------------------------------------------------------------
# 7.4, 7.5 stabilisation time and overshoot


@dataclass(frozen=True)
class Stabilisation:
    """One arrival's pose stabilisation time (ISO 9283:1998, 7.4) and overshoot (7.5):
    ``time`` (s) from the attained-pose signal until the position stays within ``band`` (m) of
    the attained position (from ``settled_at``, s), ``overshoot`` (m) past the attained
    position along the approach direction (0 when the approach does not go past), and
    ``excursion`` (m), the largest distance from the attained position after the first crossing
    of the band (at ``entered_at``, s; in any direction, not a characteristic of the standard:
    shown beside it)."""

    time: float
    overshoot: float
    excursion: float
    band: float
    settled_at: float
    entered_at: float

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (s, m)."""
        return {
            "time_s": self.time,
            "overshoot_m": self.overshoot,
            "excursion_m": self.excursion,
            "band_m": self.band,
            "settled_at_s": self.settled_at,
            "entered_at_s": self.entered_at,
        }


def stabilisation(
    t: ArrayLike,
    p: ArrayLike,
    final: ArrayLike,
    arrival_t: float,
    *,
    band: float,
) -> Stabilisation:
    """Pose stabilisation time (ISO 9283:1998, 7.4) and pose overshoot (7.5) of one arrival,
    from the measured positions ``p`` (k, 3) at the times ``t`` (k,) (s, increasing) of the
    approach and what follows, the attained (settled) position ``final`` (3,) and the instant
    ``arrival_t`` (s) of the robot's attained-pose signal (the end of the commanded motion).
    The samples must begin on the approach, outside the band.

    With d_i = |p_i − final| and u the approach direction, the unit vector from the first
    sample to ``final``:

    - stabilisation time = t_s − arrival_t (0 if negative), where t_s is the first sample time
      from which every later sample lies within the limit band, d_i ≤ ``band``. The standard
      leaves the band to the manufacturer: the caller states it (m).
    - overshoot OV = max(0, max_i D_i), D_i = (p_i − final) · u: the largest deviation past
      the attained position along the approach, zero when the robot never goes past (the
      standard's OV_j = max D_ij if max D_ij > 0, else 0; "the maximum deviation between the
      approach path and the attained pose after the robot first crosses the limit band": the
      samples before the crossing are behind the band, D_i < −band, so they never set the
      maximum — a crossing between two samples counts, too).
    - excursion = max d_i over the samples from the first crossing on (the first with
      d_i ≤ band or D_i ≥ −band): the largest distance in any direction, shown beside OV.

    The resolution of both times is the sample period (no interpolation between samples). The
    standard measures three cycles per pose; see :func:`stabilisation_over_cycles`.
    """
    what = "pose stabilisation"
    tt = _finite(f"{what}: times", np.asarray(t, dtype=np.float64))
    pts = _points(f"{what}: positions", p, at_least=2, unit="samples")
    if tt.shape != (len(pts),):
        raise ShapeError(f"{what}: times", f"one time per position, ({len(pts)},)", tt.shape)
    if np.any(np.diff(tt) <= 0.0):
        raise Iso9283Error(what, "the sample times do not increase", "sort the samples by time")
    fin = _vector(f"{what}: attained position", final)
    if not np.isfinite(arrival_t):
        raise NonFiniteError(f"{what}: arrival time", 1)
    if not (np.isfinite(band) and band > 0.0):
        raise Iso9283Error(what, f"the limit band {band!r} m is not positive", "give band > 0 m")
    d = np.linalg.norm(pts - fin, axis=1)
    if d[0] <= band:
        raise Iso9283Error(
            what,
            f"the first sample (t = {tt[0]:.6g} s) is already within the band "
            f"({d[0] * 1e3:.4g} mm of the attained position, band {band * 1e3:.4g} mm), so the "
            "approach is not in the samples",
            "give the samples from before the robot reaches the band",
        )
    inside = d <= band
    if not inside[-1]:
        raise Iso9283Error(
            what,
            f"the position is still {d[-1] * 1e3:.4g} mm from the attained position at the last "
            f"sample (t = {tt[-1]:.6g} s; band {band * 1e3:.4g} mm)",
            "give the samples until the robot has settled, or a wider band",
        )
    outside = np.flatnonzero(~inside)
    settled_at = float(tt[int(outside[-1]) + 1])
    u = (fin - pts[0]) / d[0]
    D = (pts - fin) @ u
    crossed = inside | (D >= -band)
    entry = int(np.argmax(crossed))
    return Stabilisation(
        time=max(0.0, settled_at - float(arrival_t)),
        overshoot=max(0.0, float(D.max())),
        excursion=float(d[entry:].max()),
        band=float(band),
        settled_at=settled_at,
        entered_at=float(tt[entry]),
    )


def stabilisation_over_cycles(arrivals: Sequence[Stabilisation]) -> dict[str, float]:
    """The stabilisation time and overshoot of one pose over its measured cycles (ISO 9283
    measures three): their means (``time_mean_s``, ``overshoot_mean_m``) and maxima
    (``time_max_s``, ``overshoot_max_m``)."""
    if not arrivals:
        raise Iso9283Error(
            "pose stabilisation", "no arrival was measured", "record the arrivals at >= 100 Hz"
        )
    times = np.array([a.time for a in arrivals])
    ovs = np.array([a.overshoot for a in arrivals])
    return {
        "cycles": float(len(arrivals)),
        "time_mean_s": float(times.mean()),
        "time_max_s": float(times.max()),
        "overshoot_mean_m": float(ovs.mean()),
        "overshoot_max_m": float(ovs.max()),
    }


# ---------------------------------------------------------------------------------------------
# 7.6 drift


@dataclass(frozen=True)
class Drift:
    """Drift of pose characteristics (ISO 9283:1998, 7.6) over T groups of cycles taken at
    increasing times: ``AP`` (T,) and ``RP`` (T,) of each group, ``dAP`` = |AP_1 − AP_T|,
    ``dRP`` = |RP_1 − RP_T|, with orientations ``dAP_abc``, ``dRP_abc`` (3,) likewise; and
    ``shift``, the distance between the first and the last barycentre (not a characteristic of
    the standard: shown beside dAP, which only sees a drift that changes the distance to the
    commanded position). m, rad."""

    groups: int
    AP: FloatArray
    RP: FloatArray
    dAP: float
    dRP: float
    shift: float
    dAP_abc: FloatArray | None = None
    dRP_abc: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m, rad)."""
        return {
            "groups": self.groups,
            "AP_m": _floats(self.AP),
            "RP_m": _floats(self.RP),
            "dAP_m": self.dAP,
            "dRP_m": self.dRP,
            "shift_m": self.shift,
            "dAP_abc_rad": _floats(self.dAP_abc),
            "dRP_abc_rad": _floats(self.dRP_abc),
        }


def drift(
    groups: Sequence[ArrayLike],
    commanded: ArrayLike,
    R_groups: Sequence[ArrayLike] | None = None,
    R_commanded: ArrayLike | None = None,
) -> Drift:
    """Drift of pose accuracy and pose repeatability, ISO 9283:1998 clause 7.6, from the
    attained positions of one commanded pose ``commanded`` (3,) in T ≥ 2 groups of cycles
    ``groups`` (each (n_t, 3), n_t ≥ 2, in time order: the standard's groups of cycles at
    intervals over hours of running):

        dAP = |AP_t=1 − AP_t=T|, dRP = |RP_t=1 − RP_t=T|,

    with AP_t (7.2.1) and RP_t (7.2.2) of group t; with the orientations (``R_groups``, each
    (n_t, 3, 3), and ``R_commanded``) dAP_a = |AP_a,t=1 − AP_a,t=T| and dRP_a likewise (b, c)."""
    if len(groups) < 2:
        raise Iso9283Error(
            "drift",
            f"{len(groups)} group(s) of cycles given, at least 2 are needed (first and last time)",
            "measure the pose at the start and at the end of the drift test",
        )
    if R_groups is not None and len(R_groups) != len(groups):
        raise Iso9283Error(
            "drift",
            f"{len(R_groups)} groups of orientations for {len(groups)} groups of positions",
            "give one group of orientations per group of positions",
        )
    acc = [
        pose_accuracy(g, commanded, None if R_groups is None else R_groups[i], R_commanded)
        for i, g in enumerate(groups)
    ]
    rep = [
        pose_repeatability(g, None if R_groups is None else R_groups[i])
        for i, g in enumerate(groups)
    ]
    AP = np.array([a.AP_P for a in acc])
    RP = np.array([r.RP_l for r in rep])
    dAP_abc = dRP_abc = None
    first_abc, last_abc = acc[0].AP_abc, acc[-1].AP_abc
    first_rp, last_rp = rep[0].RP_abc, rep[-1].RP_abc
    if first_abc is not None and last_abc is not None:
        dAP_abc = np.abs(first_abc - last_abc)
    if first_rp is not None and last_rp is not None:
        dRP_abc = np.abs(first_rp - last_rp)
    return Drift(
        len(groups),
        AP,
        RP,
        float(abs(AP[0] - AP[-1])),
        float(abs(RP[0] - RP[-1])),
        float(np.linalg.norm(acc[0].barycentre - acc[-1].barycentre)),
        dAP_abc,
        dRP_abc,
    )


# ---------------------------------------------------------------------------------------------
# 8.2 path accuracy and repeatability


@dataclass(frozen=True)
class PathCharacteristics:
    """Path accuracy and repeatability (ISO 9283:1998, 8.2) of n cycles of one path at m
    commanded points: ``crossings`` (m, n, 3), each cycle's attained point in the plane normal
    to the command path at each commanded point; ``barycentres`` (m, 3); ``deviation`` (m,), the
    barycentre's distance from the commanded point; ``repeatability`` (m,), l̄_i + 3 S_li;
    ``AT_P`` = max deviation, ``RT_P`` = max repeatability. With orientations:
    ``deviation_abc`` (m, 3), the mean deviation of the attained orientations from the
    commanded one at each point, ``repeatability_abc`` (m, 3), 3 S_ai …, and ``AT_abc``,
    ``RT_abc`` (3,) their largest absolute values over the points. m, rad."""

    cycles: int
    commanded: FloatArray
    crossings: FloatArray
    barycentres: FloatArray
    deviation: FloatArray
    repeatability: FloatArray
    AT_P: float
    RT_P: float
    deviation_abc: FloatArray | None = None
    repeatability_abc: FloatArray | None = None
    AT_abc: FloatArray | None = None
    RT_abc: FloatArray | None = None

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m), with the per-point deviation and repeatability."""
        return {
            "cycles": self.cycles,
            "points": len(self.commanded),
            "AT_P_m": self.AT_P,
            "RT_P_m": self.RT_P,
            "AT_at_point": int(np.argmax(self.deviation)),
            "RT_at_point": int(np.argmax(self.repeatability)),
            "deviation_m": _floats(self.deviation),
            "repeatability_m": _floats(self.repeatability),
            "barycentres_m": _floats(self.barycentres),
            "AT_abc_rad": _floats(self.AT_abc),
            "RT_abc_rad": _floats(self.RT_abc),
            "deviation_abc_rad": _floats(self.deviation_abc),
            "repeatability_abc_rad": _floats(self.repeatability_abc),
        }


def _tangents(commanded: FloatArray) -> FloatArray:
    """Unit tangents of a commanded polyline (m, 3) by central differences (second-order
    one-sided ones at the ends, first-order for two points)."""
    if np.any(np.linalg.norm(np.diff(commanded, axis=0), axis=1) <= 0.0):
        raise Iso9283Error(
            "path accuracy",
            "two consecutive commanded path points coincide, so the path has no direction there",
            "give distinct commanded points, or their tangents",
        )
    g = np.gradient(commanded, axis=0, edge_order=2 if len(commanded) > 2 else 1)
    norm = np.linalg.norm(g, axis=1)
    if np.any(norm <= 0.0):
        raise Iso9283Error(
            "path accuracy",
            "the commanded path turns back on itself, so it has no direction at a point",
            "give the tangents of the commanded path",
        )
    return np.asarray(g / norm[:, None], dtype=np.float64)


def _crossing(
    path: FloatArray, point: FloatArray, normal: FloatArray
) -> tuple[FloatArray, int, float] | None:
    """Where the polyline ``path`` (k, 3) crosses the plane through ``point`` normal to
    ``normal``, nearest ``point`` (linear interpolation between the two bracketing samples):
    the point, the index s of the sample before it and the fraction λ of the way to sample
    s + 1; None when the path never reaches the plane."""
    side = (path - point) @ normal
    on = np.flatnonzero(side == 0.0)
    seg = np.flatnonzero(side[:-1] * side[1:] < 0.0)
    lam = side[seg] / (side[seg] - side[seg + 1])
    cand = path[seg] + lam[:, None] * (path[seg + 1] - path[seg])
    cand = np.concatenate([cand, path[on]])
    if len(cand) == 0:
        return None
    best = int(np.argmin(np.linalg.norm(cand - point, axis=1)))
    if best < len(seg):
        return np.asarray(cand[best], dtype=np.float64), int(seg[best]), float(lam[best])
    return np.asarray(cand[best], dtype=np.float64), int(on[best - len(seg)]), 0.0


def _rotation_vector(R: FloatArray) -> FloatArray:
    """The rotation vector (axis × angle, rad) of a rotation of less than 90°."""
    w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    sin = float(np.linalg.norm(w))
    angle = float(np.arctan2(sin, (np.trace(R) - 1.0) / 2.0))  # not arccos: exact when small
    return w if sin < 1e-15 else w * (angle / sin)


def _interpolated_rotation(Rs: FloatArray, seg: int, lam: float, what: str) -> FloatArray:
    """The rotation a fraction ``lam`` of the way from ``Rs[seg]`` to ``Rs[seg + 1]`` along
    the shortest turn between them (as slerp)."""
    if lam == 0.0:
        return np.asarray(Rs[seg], dtype=np.float64)
    step = Rs[seg].T @ Rs[seg + 1]
    if np.trace(step) < 1.0:  # a turn of more than 90° between two samples
        raise Iso9283Error(
            what,
            f"the orientation turns by more than 90° between samples {seg + 1} and {seg + 2}",
            "record the path's orientations at a higher rate",
        )
    return np.asarray(Rs[seg] @ rotation_from_vector(lam * _rotation_vector(step)))


def path_accuracy(
    attained_paths: Sequence[ArrayLike],
    commanded: ArrayLike,
    tangents: ArrayLike | None = None,
    R_paths: Sequence[ArrayLike] | None = None,
    R_commanded: ArrayLike | None = None,
) -> PathCharacteristics:
    """Path accuracy AT_P and path repeatability RT_P, ISO 9283:1998 clause 8.2, from the n ≥ 2
    attained paths ``attained_paths`` (each (k_j, 3), the measured positions of one cycle in
    time order) of the command path through the commanded points ``commanded`` (m, 3), whose
    unit ``tangents`` (m, 3) give the normal planes (by default central differences of the
    commanded points, second-order one-sided at the ends: give the tangents where the ends
    matter on a coarsely sampled curve).

    For each commanded point i, each cycle's attained point x_ij is where its path crosses the
    plane through the commanded point normal to the command path (linearly interpolated between
    the two samples on either side of the plane; of several crossings, the nearest the
    commanded point), and

        x̄_i = (1/n) Σ_j x_ij, AT_P = max_i √((x̄_i − x_ci)² + (ȳ_i − y_ci)² + (z̄_i − z_ci)²),
        l_ij = |x_ij − x̄_i|, S_li = √(Σ_j (l_ij − l̄_i)² / (n − 1)),
        RT_P = max_i (l̄_i + 3 S_li).

    With the attained orientations ``R_paths`` (each (k_j, 3, 3), one per sample) and the
    commanded ones ``R_commanded`` (m, 3, 3), each cycle's orientation at the crossing is
    interpolated along the shortest turn between the two samples (as slerp), and

        AT_a = max_i |ā_i − a_ci|, RT_a = max_i 3 S_ai (likewise b, c),

    with ā_i − a_ci the mean :func:`orientation_deviation` of the cycles' orientations from the
    commanded one and S_ai the sample standard deviation of their deviations from their mean
    orientation (as in :func:`pose_repeatability`)."""
    what = "path accuracy"
    if len(attained_paths) < 2:
        raise Iso9283Error(
            what,
            f"{len(attained_paths)} attained path(s) given, at least 2 cycles are needed",
            "measure the path in several cycles (the standard prescribes 10)",
        )
    cmd = _points(f"{what}: commanded path points", commanded, at_least=2, unit="points")
    if tangents is None:
        tan = _tangents(cmd)
    else:
        tan = np.asarray(tangents, dtype=np.float64)
        if tan.shape != cmd.shape:
            raise ShapeError(
                f"{what}: tangents", f"one per commanded point, {cmd.shape}", tan.shape
            )
        _finite(f"{what}: tangents", tan)
        norm = np.linalg.norm(tan, axis=1)
        if np.any(norm <= 0.0):
            raise ShapeError(f"{what}: tangents", "non-zero directions", "a zero vector")
        tan = tan / norm[:, None]
    paths = [
        _points(f"{what}: attained path of cycle {j + 1}", p, at_least=2, unit="samples")
        for j, p in enumerate(attained_paths)
    ]
    m, n = len(cmd), len(paths)
    if (R_paths is None) != (R_commanded is None):
        raise Iso9283Error(
            what,
            "attained orientations were given without commanded ones (or the reverse)",
            "give both R_paths and R_commanded, or neither",
        )
    Rp: list[FloatArray] = []
    Rc = None
    if R_paths is not None and R_commanded is not None:
        if len(R_paths) != n:
            raise Iso9283Error(
                what,
                f"{len(R_paths)} cycles of orientations for {n} attained paths",
                "give one array of orientations per attained path",
            )
        Rp = [
            _rotations(f"{what}: orientations of cycle {j + 1}", R, len(paths[j]))
            for j, R in enumerate(R_paths)
        ]
        Rc = _rotations(f"{what}: commanded orientations", R_commanded, m)
    crossings = np.empty((m, n, 3))
    R_cross = np.empty((m, n, 3, 3))
    for i in range(m):
        for j, path in enumerate(paths):
            hit = _crossing(path, cmd[i], tan[i])
            if hit is None:
                raise Iso9283Error(
                    what,
                    f"the attained path of cycle {j + 1} never crosses the plane normal to the "
                    f"command path at commanded point {i + 1} of {m}",
                    "give the whole pass of each cycle, or drop the commanded points it does "
                    "not reach",
                )
            crossings[i, j] = hit[0]
            if Rp:
                R_cross[i, j] = _interpolated_rotation(
                    Rp[j], hit[1], hit[2], f"{what}: cycle {j + 1}"
                )
    bary = crossings.mean(axis=1)
    deviation = np.linalg.norm(bary - cmd, axis=1)
    l_ij = np.linalg.norm(crossings - bary[:, None, :], axis=2)
    rt = l_ij.mean(axis=1) + 3.0 * np.std(l_ij, axis=1, ddof=1)
    dev_abc = rep_abc = at_abc = rt_abc = None
    if Rc is not None:
        dev_abc = np.array(
            [orientation_deviation(R_cross[i], Rc[i]).mean(axis=0) for i in range(m)]
        )
        rep_abc = np.array(
            [
                3.0 * _sample_std(orientation_deviation(R_cross[i], _mean_rotation(R_cross[i])))
                for i in range(m)
            ]
        )
        at_abc = np.abs(dev_abc).max(axis=0)
        rt_abc = rep_abc.max(axis=0)
    return PathCharacteristics(
        n,
        cmd,
        crossings,
        bary,
        deviation,
        rt,
        float(deviation.max()),
        float(rt.max()),
        dev_abc,
        rep_abc,
        at_abc,
        rt_abc,
    )


# ---------------------------------------------------------------------------------------------
# 8.4 path velocity


@dataclass(frozen=True)
class PathVelocity:
    """Path velocity characteristics (ISO 9283:1998, 8.4) of n cycles at the commanded speed
    ``v_c`` (m/s): ``v_mean`` (n,), each cycle's mean speed; ``AV`` = (v̄ − v_c)/v_c and
    ``RV`` = 3 S_v / v_c (ratios; the standard states them in per cent of v_c), and ``FV``
    (m/s) the largest speed range within one cycle."""

    cycles: int
    v_c: float
    v_mean: FloatArray
    AV: float
    RV: float
    FV: float

    def document(self) -> dict[str, Any]:
        """The JSON-ready figures (m/s; AV and RV in per cent of the commanded speed, as the
        standard states them)."""
        return {
            "cycles": self.cycles,
            "v_c_m_per_s": self.v_c,
            "v_mean_m_per_s": _floats(self.v_mean),
            "AV_percent": 100.0 * self.AV,
            "RV_percent": 100.0 * self.RV,
            "FV_m_per_s": self.FV,
        }


def speeds_from_positions(t: ArrayLike, p: ArrayLike) -> FloatArray:
    """The speeds (m/s) between consecutive samples of positions ``p`` (k, 3) at times ``t``
    (k,): |p_{i+1} − p_i| / (t_{i+1} − t_i), (k − 1,)."""
    pts = _points("path velocity: positions", p, at_least=2, unit="samples")
    tt = _finite("path velocity: times", np.asarray(t, dtype=np.float64))
    if tt.shape != (len(pts),) or np.any(np.diff(tt) <= 0.0):
        raise ShapeError("path velocity: times", f"({len(pts)},) increasing", tt.shape)
    return np.asarray(np.linalg.norm(np.diff(pts, axis=0), axis=1) / np.diff(tt), dtype=np.float64)


def path_velocity(speeds: Sequence[ArrayLike], commanded_speed: float) -> PathVelocity:
    """Path velocity accuracy AV, repeatability RV and fluctuation FV, ISO 9283:1998 clause 8.4,
    from the speeds measured along the steady part of the path in each of n ≥ 2 cycles
    (``speeds``, each (k_j,), m/s) at the commanded speed v_c = ``commanded_speed``:

        v̄_j = mean speed of cycle j, v̄ = (1/n) Σ v̄_j, AV = (v̄ − v_c) / v_c × 100 %,
        S_v = √(Σ (v̄_j − v̄)² / (n − 1)), RV = ±3 S_v / v_c × 100 %,
        FV = max_j (max_i v_ij − min_i v_ij).

    The ratios are returned as fractions (``document()`` gives per cent)."""
    what = "path velocity"
    if len(speeds) < 2:
        raise Iso9283Error(
            what,
            f"{len(speeds)} cycle(s) given, at least 2 are needed",
            "measure the path in several cycles (the standard prescribes 10)",
        )
    if not (np.isfinite(commanded_speed) and commanded_speed > 0.0):
        raise Iso9283Error(
            what, f"the commanded speed {commanded_speed!r} m/s is not positive", "give v_c > 0"
        )
    v = []
    for j, s in enumerate(speeds):
        arr = _finite(f"{what}: speeds of cycle {j + 1}", np.asarray(s, dtype=np.float64))
        if arr.ndim != 1 or len(arr) == 0:
            raise ShapeError(
                f"{what}: speeds of cycle {j + 1}", "a non-empty (k,) array", arr.shape
            )
        v.append(arr)
    v_mean = np.array([a.mean() for a in v])
    vbar = float(v_mean.mean())
    vc = float(commanded_speed)
    fv = float(max(a.max() - a.min() for a in v))
    return PathVelocity(
        len(v), vc, v_mean, (vbar - vc) / vc, 3.0 * float(_sample_std(v_mean)) / vc, fv
    )
