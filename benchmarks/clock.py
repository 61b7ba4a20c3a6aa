"""Clock offsets between tracker and joint states: recovered offset and FK error, over sessions.

    .venv/bin/python benchmarks/clock.py [--sessions 10] [--workers 2] [--points 300] [--only TEXT]

For each case (a KR5 off its nominal: lengths σ 0.2 mm, angles σ 0.02°; tracker σ 10 µm) and
seeded session, the same motion is simulated twice: joint-state stamps right, and written early
by the case's offset. ``dhlog process`` (in memory: ``process_data``) runs on both; printed per
case: the recovered offset against the truth (mean error, largest error, mean reported σ, the
largest error in σ), and the RMS FK error against the simulator's truth at ``--points`` random
joint vectors within the limits, with and without the offset, and their ratio (target ≤ 1.5).
The issue's case: 20 ms at 20°/s with a 100 Hz tracker.
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from dhlog.identify.run import DEFAULTS, ProcessOptions, process_data
from dhlog.io.dhfile import DHModel
from dhlog.io.memory import log_data_from_session
from dhlog.model.fk import fk_point
from dhlog.model.robots import load_robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

ROBOT = load_robot("kr5")
NOMINAL = DHModel(
    ROBOT.table, ROBOT.T_base, ROBOT.tool_point, tuple(f"joint_{i + 1}" for i in range(6)), "kr5"
)

CASES: dict[str, dict[str, object]] = {
    "+20 ms, 20°/s, 100 Hz tracker": {"clock_offset": 0.02, "speed": math.radians(20)},
    "−20 ms, 20°/s, 100 Hz tracker": {"clock_offset": -0.02, "speed": math.radians(20)},
    "+30 ms, 28.6°/s (default speed), 100 Hz": {"clock_offset": 0.03},
    "+100 ms, 20°/s, 100 Hz": {"clock_offset": 0.1, "speed": math.radians(20)},
    "+5 ms, 20°/s, 1 kHz tracker": {
        "clock_offset": 0.005,
        "speed": math.radians(20),
        "tracker_rate": 1000.0,
    },
    "+30 ms, step-and-measure (8 stops)": {"clock_offset": 0.03, "motion": "step", "steps": 8},
    "+50 ms, 28.6°/s, 100 Hz": {"clock_offset": 0.05},
    "+70 ms, 28.6°/s, 100 Hz": {"clock_offset": 0.07},
    "−70 ms, 28.6°/s, 100 Hz": {"clock_offset": -0.07},
    "+90 ms, 28.6°/s, 100 Hz": {"clock_offset": 0.09},
    "+60 ms, 28.6°/s, 1 kHz tracker": {"clock_offset": 0.06, "tracker_rate": 1000.0},
    "+50 ms, 60 random poses held 0.3 s, 100 Hz": {
        "clock_offset": 0.05,
        "protocol": "random-poses",
        "poses": 60,
    },
    "+20 ms, 40 random poses held 1 s, 1 kHz": {
        "clock_offset": 0.02,
        "protocol": "random-poses",
        "poses": 40,
        "dwell": 1.0,
        "tracker_rate": 1000.0,
    },
    "50 ppm, 200 random poses (27 min), 100 Hz": {
        "clock_offset": 0.0,
        "clock_drift": 50e-6,
        "protocol": "random-poses",
        "poses": 200,
    },
    "300 ppm, 200 random poses (27 min), 100 Hz": {
        "clock_offset": 0.0,
        "clock_drift": 300e-6,
        "protocol": "random-poses",
        "poses": 200,
    },
    "1 000 ppm, 60 random poses held 1 s (8 min), 100 Hz": {
        "clock_offset": 0.0,
        "clock_drift": 1000e-6,
        "protocol": "random-poses",
        "poses": 60,
        "dwell": 1.0,
    },
    "1 000 ppm, 60 random poses held 0.3 s (7 min), 100 Hz": {
        "clock_offset": 0.0,
        "clock_drift": 1000e-6,
        "protocol": "random-poses",
        "poses": 60,
    },
    "+90 ms, 40 random poses held 1 s, 1 kHz": {
        "clock_offset": 0.09,
        "protocol": "random-poses",
        "poses": 40,
        "dwell": 1.0,
        "tracker_rate": 1000.0,
    },
}


def one(args: tuple[str, int, int]) -> tuple[str, float, float | None, str, float, float]:
    """(case, true offset, recovered offset, source, FK RMS with offset, FK RMS without)."""
    case, seed, points = args
    extra = dict(CASES[case])
    offset = float(extra.pop("clock_offset"))  # type: ignore[arg-type]
    base = {"seed": seed, "perturb_length": 2e-4, "perturb_angle": math.radians(0.02), **extra}
    rob = load_robot("kr5")
    rng = np.random.default_rng(1000 + seed)
    Q = rng.uniform(rob.limits[:, 0], rob.limits[:, 1], (points, rob.n))
    errors = []
    timing = None
    drift = float(base.pop("clock_drift", 0.0))  # type: ignore[arg-type]
    for k, shift in enumerate((offset, 0.0)):
        faults = {"clock_offset": shift, "clock_drift": drift if k == 0 else 0.0}
        session = simulate_session(rob, SimulationConfig(**base, **faults))  # type: ignore[arg-type]
        # random poses need a start for the joints no sweep shows: the robot's nominal
        posed = extra.get("protocol") == "random-poses"
        result = process_data(
            log_data_from_session(session), ProcessOptions(nominal=NOMINAL) if posed else DEFAULTS
        )
        ex = result.extraction
        assert ex is not None
        got = fk_point(ex.standard, Q, ex.tool_point, T_base=ex.T_measurement_base)
        want = fk_point(session.table, Q, session.tool_point, T_base=session.T_measurement_base)
        errors.append(float(np.mean(np.sum((got - want) ** 2, axis=1))))
        if k == 0:
            timing = result.timing
    assert timing is not None
    got_offset = timing.offset if timing.source == "estimated" else None  # at the stops too
    std = timing.std if timing.std is not None else float("nan")
    return case, offset, got_offset, f"{timing.source}:{std}", errors[0], errors[1]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--sessions", type=int, default=10)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--points", type=int, default=300)
    parser.add_argument("--only", default="", help="the cases whose name holds this text")
    args = parser.parse_args()
    cases = [case for case in CASES if args.only in case]
    jobs = [(case, seed, args.points) for case in cases for seed in range(args.sessions)]
    start = time.time()
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(one, jobs))
    print(f"{args.sessions} sessions per case, {time.time() - start:.0f} s\n")
    print(
        "| case | offset error mean / max (ms) | reported σ (ms) | max error / σ "
        "| FK RMS with offset (µm) | without (µm) | ratio |"
    )
    print("|---|---|---|---|---|---|---|")
    for case in cases:
        mine = [r for r in rows if r[0] == case]
        with_, without = (math.sqrt(np.mean([r[k] for r in mine])) * 1e6 for k in (4, 5))
        found = [r for r in mine if r[2] is not None]
        if found:
            err = np.array([r[2] - r[1] for r in found]) * 1e3  # type: ignore[operator]
            sd = np.array([float(r[3].split(":")[1]) for r in found]) * 1e3
            timed = np.isfinite(sd)  # a step-and-measure offset found at the stops has no σ
            cells = (
                f"{err.mean():+.4f} / {np.abs(err).max():.4f}",
                f"{sd[timed].mean():.4f}" if timed.all() else "none (at the stops)",
                f"{np.max(np.abs(err) / sd):.2f}" if timed.all() else "–",
            )
        else:
            cells = (f"not estimated ({mine[0][3].split(':')[0]})", "–", "–")
        print(
            f"| {case} | {cells[0]} | {cells[1]} | {cells[2]} | {with_:.1f} | {without:.1f} "
            f"| {with_ / without:.2f} |"
        )


if __name__ == "__main__":
    main()
