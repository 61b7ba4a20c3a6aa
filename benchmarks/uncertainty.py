"""Are the reported σ right? Monte Carlo over seeded simulated sessions.

    .venv/bin/python benchmarks/uncertainty.py [--robot kr5] [--sessions 500] [--workers 2]

For each session (the robot's own table as truth and as nominal, Gaussian noise σ = 20 µm,
30 Hz tracker, 60° sweeps, 12 base points) dhlog identifies the model in memory; the script
prints, for every parameter, the RMS of the σ dhlog reported divided by the empirical standard
deviation of its error (``tests/montecarlo.py``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from montecarlo import calibration

NAMES = ("θ", "d", "a", "α")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robot", default="kr5")
    parser.add_argument("--sessions", type=int, default=500)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    started = time.perf_counter()
    reported, empirical = calibration(args.robot, args.sessions, workers=args.workers)
    elapsed = time.perf_counter() - started
    n = reported.size // 4
    print(f"{args.robot}: {args.sessions} sessions in {elapsed:.0f} s")
    print("| joint | " + " | ".join(f"{p} reported / empirical" for p in NAMES) + " |")
    print("|---|" + "---|" * 4)
    for i in range(n):
        cells = []
        for k in range(4):
            r, e = reported[4 * i + k], empirical[4 * i + k]
            cells.append("fixed" if r < 1e-12 and e < 1e-9 else f"{r / e:.3f}")
        print(f"| {i + 1} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
