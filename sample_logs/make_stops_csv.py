"""Write a simulated step-and-measure session as a tracker program's CSV export (the sample for
the README's "your own data" walkthrough):

    dhlog simulate kr5 -o /tmp/kr5_stops.mcap --motion step --steps 8 --tracker-rate 3.3333 \
        --perturb-mm 0.2 --perturb-deg 0.02 --seed 21
    python sample_logs/make_stops_csv.py /tmp/kr5_stops.mcap sample_logs/kr5_stops.csv

One row per measured point: its name, x, y, z in mm (the tracker's frame) and the robot's six
joint values in degrees at that point (the controller's position at the stop).
"""

from __future__ import annotations

import sys

import numpy as np

from dhlog.io.reader import read_log


def main(log_path: str, csv_path: str) -> None:
    log = read_log(log_path)
    assert log.joints is not None
    t = log.points["t_ns"].to_numpy().astype(float)
    jt = log.joints["t_ns"].to_numpy().astype(float)
    q = np.column_stack([np.interp(t, jt, c) for c in log.joints.drop("t_ns").to_numpy().T])
    xyz = log.points.select(["x", "y", "z"]).to_numpy() * 1e3
    lines = ["Point,X [mm],Y [mm],Z [mm],A1,A2,A3,A4,A5,A6"]
    for k, (p, r) in enumerate(zip(xyz, np.degrees(q), strict=True)):
        lines.append(
            f"P{k + 1:03d},"
            + ",".join(f"{v:.4f}" for v in p)
            + ","
            + ",".join(f"{v:.5f}" for v in r)
        )
    with open(csv_path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
