"""RMS axis error of each circle fit divided by the Cramér–Rao bound of its own model.

    .venv/bin/python benchmarks/fit_efficiency.py [--trials 1000] [--sigma-um 20]

Reuses the bound and the circle of tests/test_fitting.py (36 points, r = 250 mm).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_fitting import FITS, axis_errors, circle_points, cramer_rao


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--sigma-um", type=float, default=20.0)
    args = parser.parse_args()
    sigma = args.sigma_um * 1e-6
    print(f"trials={args.trials} sigma={args.sigma_um} um, 36 points, r=250 mm")
    print("| arc | fit | dir RMSE (µrad) | dir bound | ratio | pos RMSE (µm) | pos bound | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for arc in (30, 90, 180, 360):
        rng = np.random.default_rng(arc)
        phi = np.linspace(0.0, np.radians(arc), 36, endpoint=arc != 360)
        exact = circle_points(phi)
        errs: dict[str, list[tuple[float, float]]] = {k: [] for k in FITS}
        started = time.perf_counter()
        for _ in range(args.trials):
            noisy = exact + rng.normal(scale=sigma, size=exact.shape)
            for name, fit_fn in FITS.items():
                errs[name].append(axis_errors(fit_fn(noisy, phi)))
        elapsed = time.perf_counter() - started
        for name, values in errs.items():
            rmse = np.sqrt(np.mean(np.square(values), axis=0))
            bound = cramer_rao(phi, sigma, known_angles=name == "encoder")
            print(
                f"| {arc}° | {name} | {rmse[0] * 1e6:.2f} | {bound[0] * 1e6:.2f} | "
                f"{rmse[0] / bound[0]:.3f} | {rmse[1] * 1e6:.2f} | {bound[1] * 1e6:.2f} | "
                f"{rmse[1] / bound[1]:.3f} |"
            )
        per_fit = elapsed / (args.trials * len(FITS)) * 1e3
        print(f"<!-- {arc}°: {per_fit:.2f} ms per fit on average -->")


if __name__ == "__main__":
    main()
