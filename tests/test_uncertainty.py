"""The reported σ match reality: Monte Carlo over 500 seeded sessions of KR5 and PUMA 560."""

from __future__ import annotations

import numpy as np
import pytest

from montecarlo import calibration


@pytest.mark.parametrize("robot", ["kr5", "puma560"])
def test_reported_sigma_is_within_15_percent_of_the_empirical_spread(robot: str) -> None:
    """Over 500 sessions the standard error of an empirical σ is 1/sqrt(2·500) = 3.2 %, so a
    15 % band is 4.7 standard errors. Parameters fixed by a convention or by the nominal (σ = 0)
    must have no error at all."""
    reported, empirical = calibration(robot, 500, workers=2)
    fixed = reported < 1e-12
    assert np.all(empirical[fixed] < 1e-9)
    ratio = reported[~fixed] / empirical[~fixed]
    assert np.all(np.abs(ratio - 1.0) <= 0.15), ratio
    # all but row 6 (set by the nominal), θ1 and d of parallel pairs (conventions) are free
    assert (~fixed).sum() >= 3 * (reported.size // 4 - 1)


@pytest.mark.parametrize("robot", ["kr5", "puma560"])
def test_five_percent_gross_outliers_cost_at_most_20_percent(robot: str) -> None:
    """The same 40 seeded sessions with and without 5 % gross outliers (3-9 mm): every
    parameter's RMS error with outliers stays within 1.2x its clean-data RMS error."""
    from montecarlo import sessions

    clean, _ = sessions(robot, 40, workers=2)
    dirty, _ = sessions(robot, 40, workers=2, outliers=0.05)
    free = np.sqrt(np.mean(clean**2, axis=0)) > 1e-9
    rms_clean = np.sqrt(np.mean(clean[:, free] ** 2, axis=0))
    rms_dirty = np.sqrt(np.mean(dirty[:, free] ** 2, axis=0))
    assert np.all(rms_dirty <= 1.2 * rms_clean), rms_dirty / rms_clean
