"""A calibration from a script, with nothing but ``import dhlog``: the bundled sample processed
with a held-out check, its table printed, the model exported as a URDF, ten joint targets
compensated for a controller that keeps the nominal model.

Run from the repository's root: ``.venv/bin/python docs/examples/user_script.py [OUT_DIR]``."""

import sys
import tempfile
from pathlib import Path

import numpy as np

import dhlog

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp())
out.mkdir(parents=True, exist_ok=True)

calibration: dhlog.Calibration = dhlog.process(
    "sample_logs/kr5_0.01mm.mcap", nominal="kr5", holdout=5
)

# the error at poses the fit did not use (5-fold cross-validation), nominal and calibrated
print(f"{'check':<8} {'model':<10} {'poses':>6} {'RMS mm':>8} {'p95 mm':>8} {'max mm':>8}")
for row in calibration.holdout.iter_rows(named=True):
    mm = [1e3 * row[k] for k in ("rms", "p95", "max")]
    print(
        f"{row['check']:<8} {row['model']:<10} {row['n_poses']:>6} "
        + " ".join(f"{v:8.4f}" for v in mm)
    )
if calibration.fk_rms is not None:
    print(f"in-sample FK RMS {1e3 * calibration.fk_rms:.4f} mm")

urdf = calibration.export("urdf", out / "kr5_calibrated.urdf", overwrite=True)
print(f"URDF: {out / 'kr5_calibrated.urdf'} ({len(urdf)} characters)")

robot: dhlog.Robot = dhlog.robot("kr5")
rng = np.random.default_rng(0)
targets = rng.uniform(robot.limits[:, 0], robot.limits[:, 1], (10, robot.n)) * 0.5
compensated: dhlog.Compensation = calibration.compensate(targets)
print(np.degrees(compensated.targets - targets).round(4))
print(f"{np.count_nonzero(np.isfinite(compensated.targets).all(axis=1))} of 10 targets compensated")
