"""ISO 9283 pose repeatability of a real robot: the FANUC R-2000iC/165F set in
../shared/realdata/fanuc_r2000ic (24 joint configurations × 10 measurements, three reflectors
A, B, C; see ../shared/realdata/README.md). dhlog's pose_repeatability against the formula of
ISO 9283:1998, 7.2.2 written out here in plain numpy (no dhlog), for every pose and reflector,
and the orientation repeatability of the frame the three reflectors make. Skipped when the
folder is not beside the checkout. benchmarks/iso9283_fanuc.py prints the figures."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dhlog.iso9283.formulas import pose_repeatability

CSV = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "fanuc_r2000ic"
CSV = CSV / "calibration_dataset.csv"


@pytest.fixture(scope="module")
def fanuc() -> np.ndarray:
    """(24, 10, 3, 3): configuration, repeat, reflector A/B/C, x/y/z (m)."""
    if not CSV.exists():
        pytest.skip("shared/realdata/fanuc_r2000ic is not beside the checkout")
    table = np.genfromtxt(CSV, delimiter=",", names=True)
    out = np.full((24, 10, 3, 3), np.nan)
    for row in table:
        xyz = [[row[f"m{m}_{ax}_m"] for ax in "xyz"] for m in "ABC"]
        out[int(row["config_id"]), int(row["repeat"])] = xyz
    assert np.all(np.isfinite(out)), "every configuration has its 10 repeats"
    return out


def rp_by_hand(p: np.ndarray) -> tuple[float, float, float]:
    """ISO 9283 7.2.2 written out: l_j = distance to the barycentre, RP = l̄ + 3 S_l (n − 1)."""
    n = len(p)
    bary = [sum(p[j, k] for j in range(n)) / n for k in range(3)]
    dist = [math.sqrt(sum((p[j, k] - bary[k]) ** 2 for k in range(3))) for j in range(n)]
    l_mean = sum(dist) / n
    S_l = math.sqrt(sum((lj - l_mean) ** 2 for lj in dist) / (n - 1))
    return l_mean, S_l, l_mean + 3.0 * S_l


def frames(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The reflectors' frame per measurement: x along A→B, z normal to A, B, C, y = z × x."""
    x = (B - A) / np.linalg.norm(B - A, axis=1, keepdims=True)
    z = np.cross(B - A, C - A)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def rp_abc_by_hand(R: np.ndarray) -> np.ndarray:
    """3 S of the fixed-axis X-Y-Z angles (R = Rz(c) Ry(b) Rx(a)) of each frame's deviation
    R_j R̄ᵀ from the mean frame R̄ (the SVD projection of the mean matrix onto the rotations)."""
    U, _, Vt = np.linalg.svd(R.mean(axis=0))
    R_mean = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    abc = []
    for Rj in R:
        d = Rj @ R_mean.T
        abc.append(
            [math.atan2(d[2, 1], d[2, 2]), math.asin(-d[2, 0]), math.atan2(d[1, 0], d[0, 0])]
        )
    a = np.array(abc)
    dev = a - a.mean(axis=0)
    return np.asarray(3.0 * np.sqrt((dev**2).sum(axis=0) / (len(a) - 1)), dtype=np.float64)


def test_pose_repeatability_of_every_pose_and_reflector(fanuc: np.ndarray) -> None:
    for cid in range(24):
        for k, name in enumerate("ABC"):
            p = fanuc[cid, :, k]
            rp = pose_repeatability(p)
            l_mean, S_l, RP = rp_by_hand(p)
            where = f"pose {cid} reflector {name}"
            assert rp.n == 10, where
            assert rp.l_mean == pytest.approx(l_mean, rel=1e-12), where
            assert rp.S_l == pytest.approx(S_l, rel=1e-12), where
            assert rp.RP_l == pytest.approx(RP, rel=1e-12), where


def test_orientation_repeatability_of_the_reflectors_frame(fanuc: np.ndarray) -> None:
    for cid in range(24):
        A, B, C = (fanuc[cid, :, k] for k in range(3))
        R = frames(A, B, C)
        rp = pose_repeatability(A, R)
        assert rp.RP_abc is not None
        np.testing.assert_allclose(rp.RP_abc, rp_abc_by_hand(R), rtol=1e-9, err_msg=f"pose {cid}")
        # the frame's position repeatability is reflector A's
        assert rp.RP_l == pytest.approx(rp_by_hand(A)[2], rel=1e-12)
