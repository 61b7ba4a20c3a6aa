"""Per-parameter accuracy of dhlog against seed 002's Table 2 and against the reported σ.

    .venv/bin/python benchmarks/parameters.py [--trials 200] [--table2-trials 100] [--workers 2]

(The FK accuracy against the achievable limit is ``benchmarks/accuracy.py``.)

1. Seed 002, Table 2, side by side. KUKA KR5 at the specification, uniform noise of ±0.01 mm and
   ±0.1 mm (as in the paper). Protocol: every joint swept 90° from the home pose (joint 3 60°,
   its limit) at 100 Hz tracker / 250 Hz encoders, about 250–500 samples per joint; target
   60, 40, 100 mm off the flange centre; 12 points probed on the base plane; the specification as
   nominal. The paper reports one run; dhlog is shown as the RMS error over ``--table2-trials``
   sessions, for the seed-002 method (SVD + algebraic circle, free angles, line geometry) and
   dhlog's default (the whole-model maximum-likelihood fit).
2. Against the reported σ. KR5, Gaussian σ = 20 µm, 30 Hz tracker, arcs of 30°, 90°, 180°: per
   DH parameter, RMSE over ``--trials`` sessions divided by the RMS of the σ each method reports
   (the seed method: each fit's covariance propagated through the extraction; the analytic
   method with encoder-aided fits the same; the default: the whole-model fit's (JᵀWJ)⁻¹).
3. The gains: RMSE of the seed method over the analytic method with encoder-aided fits, and of
   the analytic method over the whole-model fit, per parameter (median and range).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dhlog.model.robots import load_robot
from montecarlo import sessions

NAMES = ("θ", "d", "a", "α")
# seed 002, Table 2: measured − specification (mm, mm, degrees), joints 1–6
PAPER = {
    0.01: {
        "d": [399.985 - 400, 0, 0.027, 620.036 - 620, -0.131, 0],
        "a": [179.983 - 180, 600.006 - 600, 120.044 - 120, 0, 0, 0],
        "alpha": [89.998 - 90, 0, 89.996 - 90, 89.996 - 90, 89.997 - 90, 0],
    },
    0.1: {
        "d": [399.955 - 400, 0, 0.092, 620.144 - 620, -0.1, 0],
        "a": [180.099 - 180, 599.992 - 600, 119.984 - 120, 0, 0, 0],
        "alpha": [90.002 - 90, 0, 90.005 - 90, 90.023 - 90, 90.022 - 90, 0],
    },
}


def table2(trials: int, workers: int) -> None:
    print("## Seed 002, Table 2, side by side (KR5, errors against the specification)\n")
    for noise in (0.01, 0.1):
        rows = {}
        for method in ("algebraic", "auto"):
            err, _ = sessions(
                "kr5",
                trials,
                workers=workers,
                analytic_only=method == "algebraic",
                noise=noise * 1e-3,
                rate=100.0,
                noise_kind="uniform",
                sweep=math.radians(90),
                fit_method=method,
                first_seed=2000,
            )
            rows[method] = np.sqrt(np.mean(err**2, axis=0)).reshape(-1, 4)
        print(f"### ±{noise} mm uniform noise ({trials} sessions per method)\n")
        print(
            "| joint | b: paper | b: seed method RMS | b: dhlog RMS | a: paper | a: seed method "
            "RMS | a: dhlog RMS | α: paper | α: seed method RMS | α: dhlog RMS |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for i in range(6):
            p = PAPER[noise]
            s, d = rows["algebraic"][i], rows["auto"][i]
            print(
                f"| {i + 1} | {p['d'][i]:+.3f} | {s[1] * 1e3:.4f} | {d[1] * 1e3:.4f} | "
                f"{p['a'][i]:+.3f} | {s[2] * 1e3:.4f} | {d[2] * 1e3:.4f} | "
                f"{p['alpha'][i]:+.3f} | {math.degrees(s[3]):.5f} | {math.degrees(d[3]):.5f} |"
            )
        print()


def against_bound(trials: int, workers: int) -> dict[tuple[int, str], np.ndarray]:
    print("## RMSE / bound per DH parameter (KR5, σ = 20 µm Gaussian, 30 Hz)\n")
    errors: dict[tuple[int, str], np.ndarray] = {}
    for arc in (30, 90, 180):
        ratios = {}
        for method, options in (
            ("seed 002", {"fit_method": "algebraic", "analytic_only": True}),
            ("analytic", {"fit_method": "auto", "analytic_only": True}),
            ("whole model", {"fit_method": "auto"}),
        ):
            started = time.perf_counter()
            err, std = sessions(
                "kr5",
                trials,
                workers=workers,
                sweep=math.radians(arc),
                first_seed=5000 + arc,
                **options,
            )
            rmse = np.sqrt(np.mean(err**2, axis=0))
            bound = np.sqrt(np.mean(std**2, axis=0))
            errors[(arc, method)] = rmse
            ratios[method] = np.where(bound > 1e-12, rmse / np.where(bound > 0, bound, 1), np.nan)
            print(f"<!-- {arc}° {method}: {time.perf_counter() - started:.0f} s -->")
        print(f"### {arc}° arcs ({trials} sessions per method)\n")
        print("| joint | " + " | ".join(f"{m}: {p}" for m in ratios for p in NAMES) + " |")
        print("|---|" + "---|" * (4 * len(ratios)))
        n = len(next(iter(ratios.values()))) // 4
        for i in range(n):
            cells = []
            for r in ratios.values():
                cells += [
                    "fixed" if not np.isfinite(v) else f"{v:.3f}" for v in r[4 * i : 4 * i + 4]
                ]
            print(f"| {i + 1} | " + " | ".join(cells) + " |")
        for m, r in ratios.items():
            finite = r[np.isfinite(r)]
            print(f"\n{m}: max RMSE/bound {finite.max():.3f}, median {np.median(finite):.3f}")
        print()
    return errors


def gains(errors: dict[tuple[int, str], np.ndarray]) -> None:
    print("## Gains (RMSE ratio per free parameter: median [min – max])\n")
    print("| arc | seed 002 / analytic (encoder-aided) | analytic / whole model |")
    print("|---|---|---|")
    for arc in (30, 90, 180):
        seed, enc, ref = (errors[(arc, m)] for m in ("seed 002", "analytic", "whole model"))
        free = enc > 1e-12
        g1, g2 = seed[free] / enc[free], enc[free] / ref[free]
        print(
            f"| {arc}° | {np.median(g1):.2f} [{g1.min():.2f} – {g1.max():.2f}] | "
            f"{np.median(g2):.2f} [{g2.min():.2f} – {g2.max():.2f}] |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=200)
    parser.add_argument("--table2-trials", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    assert load_robot("kr5").n == 6
    table2(args.table2_trials, args.workers)
    gains(against_bound(args.trials, args.workers))


if __name__ == "__main__":
    main()
