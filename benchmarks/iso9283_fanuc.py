"""ISO 9283 pose repeatability of the FANUC R-2000iC/165F set (../shared/realdata/fanuc_r2000ic:
24 joint configurations, each measured 10 times, three reflectors A, B, C on the tool, positions
in m in the tracker's frame).

    .venv/bin/python benchmarks/iso9283_fanuc.py

For every configuration: RP_l = l̄ + 3 S_l (ISO 9283:1998, 7.2.2) of each reflector with
dhlog.iso9283.formulas.pose_repeatability, and the orientation repeatability RP_a, RP_b, RP_c
(± 3 S) of the tool frame built from the three reflectors in each measurement (origin A, x along
A→B, z normal to the plane A, B, C), its a, b, c about the tracker's x, y, z. Nothing is fitted:
repeatability needs neither the model nor the registration (RP_l is the same in any frame; the
orientation components are about the tracker's axes, as the set has no base frame).
tests/test_iso9283_realdata.py checks every figure against the formula written out in plain numpy.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path

import numpy as np

from dhlog.iso9283.formulas import pose_repeatability

DATA = Path(__file__).resolve().parents[2] / "shared" / "realdata" / "fanuc_r2000ic"
CSV = DATA / "calibration_dataset.csv"


def load(path: Path = CSV) -> dict[int, dict[str, np.ndarray]]:
    """The set by configuration: {config_id: {"A": (10, 3), "B": …, "C": …}} (m), repeats in
    order."""
    rows: dict[int, list[tuple[int, list[float]]]] = {}
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            xyz = [float(r[f"m{m}_{ax}_m"]) for m in "ABC" for ax in "xyz"]
            rows.setdefault(int(r["config_id"]), []).append((int(r["repeat"]), xyz))
    out = {}
    for cid, reps in sorted(rows.items()):
        arr = np.array([xyz for _, xyz in sorted(reps)])
        out[cid] = {m: arr[:, 3 * k : 3 * k + 3] for k, m in enumerate("ABC")}
    return out


def reflector_frames(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Rotations (n, 3, 3) of the frames of three reflectors: x along A→B, z normal to the
    plane A, B, C, y = z × x."""
    x = B - A
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z = np.cross(B - A, C - A)
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def main() -> int:
    if not CSV.exists():
        print(f"{CSV} is not there: the FANUC set lies in ../shared/realdata beside the checkout")
        return 1
    data = load()
    print("ISO 9283:1998 7.2.2 pose repeatability, FANUC R-2000iC/165F (n = 10 per pose)")
    print(
        f"{'pose':>4} {'RP_A mm':>8} {'l̄_A mm':>8} {'S_l,A mm':>8} {'RP_B mm':>8} {'RP_C mm':>8}"
        f" {'RP_a °':>8} {'RP_b °':>8} {'RP_c °':>8}"
    )
    worst = np.zeros(6)
    for cid, m in data.items():
        ra, rb, rc = (pose_repeatability(m[k]) for k in "ABC")
        ro = pose_repeatability(m["A"], reflector_frames(m["A"], m["B"], m["C"]))
        assert ro.RP_abc is not None
        deg = np.degrees(ro.RP_abc)
        print(
            f"{cid:>4} {ra.RP_l * 1e3:8.4f} {ra.l_mean * 1e3:8.4f} {ra.S_l * 1e3:8.4f}"
            f" {rb.RP_l * 1e3:8.4f} {rc.RP_l * 1e3:8.4f}"
            f" {deg[0]:8.5f} {deg[1]:8.5f} {deg[2]:8.5f}"
        )
        worst = np.maximum(worst, [ra.RP_l * 1e3, rb.RP_l * 1e3, rc.RP_l * 1e3, *deg])
    print(
        f"{'max':>4} {worst[0]:8.4f} {'':>8} {'':>8} {worst[1]:8.4f} {worst[2]:8.4f}"
        f" {worst[3]:8.5f} {worst[4]:8.5f} {worst[5]:8.5f}"
    )
    print(f"(RP_a … in degrees; 0.001° = {math.radians(1e-3) * 1e6:.2f} µrad)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
