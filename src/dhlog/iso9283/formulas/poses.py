"""The ISO 9283:1998 pose characteristics on plain arrays: pose accuracy and repeatability (7.2.1,
7.2.2), multi-directional pose accuracy variation (7.2.3), distance accuracy and repeatability
(7.3) and the drift of pose characteristics (7.6).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from dhlog.errors import Iso9283Error, ShapeError
from dhlog.geometry._checks import FloatArray
from dhlog.iso9283.formulas.checks import (
    _finite,
    _floats,
    _points,
    _rotations,
    _sample_std,
    _vector,
)
from dhlog.iso9283.formulas.orientation import (
    _mean_rotation,
    orientation_deviation,
)


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
