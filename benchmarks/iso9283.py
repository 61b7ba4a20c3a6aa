"""dhlog iso9283 against the simulator's truth (issue 34): N seeded ISO 9283 tests
(``dhlog.simulate(..., protocol="iso9283")``: a KR5 off its nominal, the tracker at 100 Hz with
its noise), each analysed as ``dhlog iso9283 LOG --nominal kr5 --result TRUTH`` does
(:func:`dhlog.iso9283.run.run_logs`, the truth's placement and model as the result), and each
characteristic compared with the one the same formulas give on the truth's noise-free attained
positions (``iso9283.visits[].attained``, base frame):

- AP before / after, RP, AD, RD, dAP, dRP: measured − truth (µm), mean and spread over the
  tests' poses;
- overshoot: measured / the simulated peak (``overshoot``);
- the visits found against the truth's visits (pose and cycle of each).

    .venv/bin/python benchmarks/iso9283.py [--tests 5] [--cycles 10] [--noise-um 10]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

import dhlog
from dhlog.io.dhfile import dh_model_from
from dhlog.iso9283.formulas import distance_accuracy, drift, pose_accuracy, pose_repeatability
from dhlog.iso9283.run import DISTANCE_POSES, DRIFT_POSE, run_logs


def one_test(seed: int, cycles: int, noise: float, folder: Path) -> dict[str, list[float]]:
    """Simulate, analyse and compare one test: the differences per characteristic."""
    log = folder / f"iso_{seed}.mcap"
    sim = dhlog.simulate(
        "kr5",
        log,
        protocol="iso9283",
        seed=seed,
        noise=noise,
        iso_cycles=cycles,
        iso_path_cycles=0,
        perturb_length=2e-4,
        perturb_angle=2e-4,
        overwrite=True,
    )
    truth = json.loads(Path(sim.truth).read_text())["iso9283"]
    nominal = dh_model_from("kr5")
    calibrated = dhlog.load(sim.truth).model
    report = run_logs([log], nominal=nominal, calibrated=calibrated)
    visits = truth["visits"]
    out: dict[str, list[float]] = {
        k: [] for k in ("AP", "AP_after", "RP", "AD", "RD", "dAP", "dRP")
    }
    out["overshoot_ratio"] = []
    out["visits_match"] = []
    by_pose: dict[str, np.ndarray] = {}
    commanded: dict[str, np.ndarray] = {}
    true_fk: dict[str, np.ndarray] = {}
    for name in ("P1", "P2", "P3", "P4", "P5"):
        rows = [v for v in visits if v["pose"] == name]
        by_pose[name] = np.array([v["attained"] for v in rows])
        commanded[name] = np.array(rows[0]["commanded"])
        true_fk[name] = np.array(rows[0]["true_fk"])
    peak = truth["settings"]["overshoot_m"]
    for p in report.poses:
        X = by_pose[p.name]
        out["visits_match"].append(float(p.visits == len(X)))
        assert p.before is not None and p.after is not None and p.RP is not None
        out["AP"].append(p.before.AP - pose_accuracy(X, commanded[p.name]).AP_P)
        after_truth = float(np.linalg.norm(X.mean(axis=0) - true_fk[p.name]))
        out["AP_after"].append(p.after.AP - after_truth)
        out["RP"].append(p.RP - pose_repeatability(X).RP_l)
        if p.overshoot is not None:
            out["overshoot_ratio"].append(p.overshoot / peak)
    a, b = DISTANCE_POSES
    d = report.distance
    if d is not None and d.AD is not None and d.RD is not None:
        t = distance_accuracy(by_pose[a], by_pose[b], commanded[a], commanded[b])
        out["AD"].append(d.AD - t.AD_P)
        out["RD"].append(d.RD - t.RD)
    f = report.drift
    if f is not None and f.dAP is not None and f.dRP is not None:
        X = by_pose[DRIFT_POSE]
        t2 = drift([X[: f.group], X[-f.group :]], commanded[DRIFT_POSE])
        out["dAP"].append(f.dAP - t2.dAP)
        out["dRP"].append(f.dRP - t2.dRP)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=5)
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--noise-um", type=float, default=10.0)
    args = parser.parse_args()
    totals: dict[str, list[float]] = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(args.tests):
            got = one_test(seed, args.cycles, args.noise_um * 1e-6, Path(tmp))
            for k, v in got.items():
                totals.setdefault(k, []).extend(v)
    print(
        f"{args.tests} simulated ISO 9283 tests of a KR5 (0.2 mm / 0.2 mrad off its nominal), "
        f"{args.cycles} cycles, tracker 100 Hz, noise {args.noise_um:g} um per coordinate "
        f"({time.perf_counter() - start:.0f} s)"
    )
    print(f"{'characteristic':<16}{'n':>4}{'mean':>12}{'spread':>12}{'largest':>12}")
    for k, v in totals.items():
        a = np.array(v)
        if a.size == 0:
            print(f"{k:<16}{0:>4}")
            continue
        if k in ("overshoot_ratio", "visits_match"):
            print(f"{k:<16}{a.size:>4}{a.mean():>12.4f}{a.std(ddof=1):>12.4f}{a.max():>12.4f}")
        else:
            um = a * 1e6
            big = um[np.argmax(np.abs(um))]
            print(
                f"{k + ' (um)':<16}{a.size:>4}{um.mean():>12.2f}{um.std(ddof=1):>12.2f}{big:>12.2f}"
            )


if __name__ == "__main__":
    main()
