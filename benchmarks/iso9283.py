"""dhlog iso9283 against the simulator's truth (issue 34): N seeded ISO 9283 tests
(``dhlog.simulate(..., protocol="iso9283")``: a KR5 off its nominal, the tracker at 100 Hz with
its noise), each analysed as ``dhlog iso9283 LOG --nominal kr5 --result TRUTH`` does
(:func:`dhlog.iso9283.run.run_logs`, the truth's placement and model as the result), and each
characteristic compared with the one the same formulas give on the truth's noise-free attained
positions (``iso9283.visits[].attained``, base frame):

- AP before / after, RP, AD, RD, dAP, dRP: measured − truth (µm), mean and spread over the
  tests' poses;
- AT before / after, RT (with the program ``dhlog plan --iso9283`` writes as ``--commanded``):
  measured − the formulas on the truth's noise-free attained paths (µm); RT carries the
  tracker's noise (each crossing is one interpolated sample), so it reads high; RT_own is
  √(RT² − RT_noise²), the robot's own RT to first order, against the same truth;
- overshoot: measured / the simulated peak (``overshoot``); stabilisation time: measured −
  the simulator's noise-free one in the same band (``stabilisation_truth``), ms;
- the visits and passes found against the truth's (their count per pose and path).

    .venv/bin/python benchmarks/iso9283.py [--tests 5] [--cycles 10] [--path-cycles 3]
        [--noise-um 10] [--rate 100]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

import dhlog
from dhlog.errors import DhlogError
from dhlog.io.dhfile import dh_model_from
from dhlog.io.reader import read_log
from dhlog.iso9283.cycles import segment_log
from dhlog.iso9283.formulas import (
    distance_accuracy,
    drift,
    path_accuracy,
    pose_accuracy,
    pose_repeatability,
)
from dhlog.iso9283.poses import DISTANCE_POSES, DRIFT_POSE
from dhlog.iso9283.program import program_csv, test_program
from dhlog.iso9283.run import run_logs
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.iso9283 import stabilisation_truth


def one_test(
    seed: int,
    cycles: int,
    path_cycles: int,
    noise: float,
    folder: Path,
    program: Path,
    rate: float = 100.0,
) -> dict[str, list[float]]:
    """Simulate, analyse and compare one test: the differences per characteristic."""
    log = folder / f"iso_{seed}.mcap"
    sim = dhlog.simulate(
        "kr5",
        log,
        protocol="iso9283",
        seed=seed,
        noise=noise,
        iso_cycles=cycles,
        iso_path_cycles=path_cycles,
        tracker_rate=rate,
        perturb_length=2e-4,
        perturb_angle=2e-4,
        overwrite=True,
    )
    truth = json.loads(Path(sim.truth).read_text())["iso9283"]
    nominal = dh_model_from("kr5")
    calibrated = dhlog.load(sim.truth).model
    report = run_logs(
        [log],
        nominal=nominal,
        calibrated=calibrated,
        commanded_csv=program if path_cycles else None,
    )
    visits = truth["visits"]
    keys = ("AP", "AP_after", "RP", "AD", "RD", "dAP", "dRP", "AT", "AT_after", "RT", "RT_own")
    out: dict[str, list[float]] = {k: [] for k in keys}
    out["overshoot_ratio"] = []
    out["t_stab (ms)"] = []
    out["visits_match"] = []
    by_pose: dict[str, np.ndarray] = {}
    commanded: dict[str, np.ndarray] = {}
    true_fk: dict[str, np.ndarray] = {}
    for name in ("P1", "P2", "P3", "P4", "P5"):
        rows = [v for v in visits if v["pose"] == name]
        by_pose[name] = np.array([v["attained"] for v in rows])
        commanded[name] = np.array(rows[0]["commanded"])
        true_fk[name] = np.array(rows[0]["true_fk"])
    settings = truth["settings"]
    peak = settings["overshoot_m"]
    freq, damping = settings["overshoot_frequency_hz"], settings["overshoot_damping"]
    report_visits = segment_log(read_log(log)).visits  # the bands the report used
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
        if p.stabilisation_time is not None:
            bands = [v.band for v in report_visits if v.pose == p.name]
            truth_t = float(np.mean([stabilisation_truth(peak, freq, damping, b) for b in bands]))
            out["t_stab (ms)"].append((p.stabilisation_time - truth_t) * 1e3)
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
    out["passes_match"] = []
    programs = {p["name"]: p for p in truth["program"]["paths"]}
    T_base_m = np.linalg.inv(np.array(truth["T_measurement_base"]))
    for path in report.paths:
        q = np.array(programs[path.path]["q"])
        if path.cycles < 2:
            continue
        c = fk_point(nominal.table, q, nominal.tool_point)
        runs = [np.array(r["attained"]) for r in truth["paths"] if r["path"] == path.path]
        out["passes_match"].append(float(path.cycles == len(runs)))
        got = None
        for lo in [path.first_point]:  # the report's points (ends left out)
            hi = len(q) - path.points - lo
            try:
                got = path_accuracy(runs, c[lo : len(q) - hi])
            except DhlogError:
                continue
            q, c = q[lo : len(q) - hi], c[lo : len(q) - hi]
            break
        if got is None:
            continue
        # the truth's paths hold only the samples between the path's start and end: a closed
        # path's end planes may be crossed at the wrong end there, so its figures are the
        # largest over the inner points (the measured pass has samples beyond both ends)
        out["AT"].append(path.AT - float(got.deviation[1:-1].max()))
        out["RT"].append(path.RT - float(got.repeatability[1:-1].max()))
        if path.RT_noise is not None:  # the robot's own RT to first order: noise in quadrature
            own = float(np.sqrt(max(path.RT**2 - path.RT_noise**2, 0.0)))
            out["RT_own"].append(own - float(got.repeatability[1:-1].max()))
        true_m = fk_point(calibrated.table, q, calibrated.tool_point, T_base=calibrated.T_base)
        correction = true_m @ T_base_m[:3, :3].T + T_base_m[:3, 3] - c
        tangent = np.gradient(c, axis=0, edge_order=2)
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        correction -= np.sum(correction * tangent, axis=1, keepdims=True) * tangent
        if path.AT_after is not None:
            left = (got.barycentres - correction - c)[1:-1]
            out["AT_after"].append(path.AT_after - float(np.linalg.norm(left, axis=1).max()))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tests", type=int, default=5)
    parser.add_argument("--cycles", type=int, default=10)
    parser.add_argument("--path-cycles", type=int, default=3)
    parser.add_argument("--noise-um", type=float, default=10.0)
    parser.add_argument("--rate", type=float, default=100.0, help="tracker rate (Hz)")
    args = parser.parse_args()
    totals: dict[str, list[float]] = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "program.csv"
        plan = test_program(load_robot("kr5"), cycles=args.cycles, path_cycles=args.path_cycles)
        program.write_text(program_csv(plan), encoding="utf-8")
        for seed in range(args.tests):
            got = one_test(
                seed,
                args.cycles,
                args.path_cycles,
                args.noise_um * 1e-6,
                Path(tmp),
                program,
                args.rate,
            )
            for k, v in got.items():
                totals.setdefault(k, []).extend(v)
    print(
        f"{args.tests} simulated ISO 9283 tests of a KR5 (0.2 mm / 0.2 mrad off its nominal), "
        f"{args.cycles} pose and {args.path_cycles} path cycles, tracker {args.rate:g} Hz, noise "
        f"{args.noise_um:g} um per coordinate "
        f"({time.perf_counter() - start:.0f} s)"
    )
    print(f"{'characteristic':<16}{'n':>4}{'mean':>12}{'spread':>12}{'largest':>12}")
    for k, v in totals.items():
        a = np.array(v)
        if a.size == 0:
            print(f"{k:<16}{0:>4}")
            continue
        if k in ("overshoot_ratio", "visits_match", "passes_match", "t_stab (ms)"):
            print(f"{k:<16}{a.size:>4}{a.mean():>12.4f}{a.std(ddof=1):>12.4f}{a.max():>12.4f}")
        else:
            um = a * 1e6
            big = um[np.argmax(np.abs(um))]
            print(
                f"{k + ' (um)':<16}{a.size:>4}{um.mean():>12.2f}{um.std(ddof=1):>12.2f}{big:>12.2f}"
            )


if __name__ == "__main__":
    main()
