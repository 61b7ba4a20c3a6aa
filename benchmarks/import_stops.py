"""``dhlog import`` of many stops: a generic CSV (x, y, z, j1…j6) and a Leica-style CSV (point
name, X/Y/Z [mm], U95, Q0…Q3, j1…j6), written here, imported by the command in a child process.

    .venv/bin/python benchmarks/import_stops.py [--stops 200000] [--keep FOLDER]

Prints, per export, its size, the import's wall time and the messages written. The whole-process
figures in docs/robustness.md were taken with a repeated-run timer on the two CSVs this writes
(``--keep`` leaves them in a folder).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_exports(folder: Path, stops: int) -> dict[str, tuple[Path, list[str]]]:
    """The two CSVs of ``stops`` random stops (seeded), and the options each is imported with."""
    rng = np.random.default_rng(0)
    xyz = rng.uniform(-1500.0, 1500.0, (stops, 3))
    q = rng.uniform(-90.0, 90.0, (stops, 6))
    generic = folder / f"generic_{stops}.csv"
    table = np.column_stack([xyz, q])
    np.savetxt(
        generic, table, fmt="%.4f", delimiter=",", header="x,y,z,j1,j2,j3,j4,j5,j6", comments=""
    )
    leica = folder / f"leica_{stops}.csv"
    with leica.open("w") as f:
        f.write("Point Name;X [mm];Y [mm];Z [mm];U(95)  [mm];Q0;Q1;Q2;Q3;j1;j2;j3;j4;j5;j6\n")
        for k in range(stops):
            values = ";".join(f"{v:.4f}" for v in xyz[k])
            joints = ";".join(f"{v:.4f}" for v in q[k])
            f.write(f"P{k + 1:06d};{values};0.012;1.0;0.0;0.0;0.0;{joints}\n")
    return {"generic": (generic, []), "leica": (leica, ["--format", "leica"])}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--stops", type=int, default=200_000)
    parser.add_argument("--keep", type=Path, default=None)
    args = parser.parse_args()
    folder = args.keep or Path(tempfile.mkdtemp(prefix="dhlog-import-"))
    folder.mkdir(parents=True, exist_ok=True)
    dhlog = str(Path(sys.executable).with_name("dhlog"))
    for name, (csv, options) in write_exports(folder, args.stops).items():
        out = csv.with_suffix(".mcap")
        start = time.perf_counter()
        done = subprocess.run(
            [dhlog, "import", str(csv), *options, "-o", str(out), "--force"],
            capture_output=True,
            text=True,
        )
        seconds = time.perf_counter() - start
        if done.returncode != 0:
            print(f"{name}: exit {done.returncode}: {done.stderr.strip()}")
            continue
        from dhlog.io.reader import read_log

        log = read_log(out)
        joints = 0 if log.joints is None else log.joints.height
        print(
            f"{name}: {args.stops} stops, {csv.stat().st_size / 1e6:.1f} MB → {seconds:.2f} s, "
            f"{log.points.height} points + {joints} joint states"
        )


if __name__ == "__main__":
    main()
