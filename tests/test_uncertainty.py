"""The reported σ match reality: Monte Carlo over seeded sessions of KR5 and PUMA 560 (500 of each
in ``benchmarks/uncertainty.py``; fewer here, for the suite's time)."""

from __future__ import annotations

import numpy as np
import pytest

from montecarlo import calibration

#: Sessions a robot: the standard error of an empirical σ is 1/sqrt(2·200) = 5 %, so the 15 %
#: band is 3 standard errors (the sessions are seeded: the figures are the same every run).
SESSIONS = 200


@pytest.mark.parametrize("robot", ["kr5", "puma560"])
def test_reported_sigma_is_within_15_percent_of_the_empirical_spread(robot: str) -> None:
    """Over :data:`SESSIONS` sessions the reported σ lies within 15 % of the empirical spread
    (see :data:`SESSIONS` for the band). Parameters fixed by a convention or by the nominal (σ = 0)
    must have no error at all."""
    reported, empirical = calibration(robot, SESSIONS, workers=2)
    fixed = reported < 1e-12
    assert np.all(empirical[fixed] < 1e-9)
    ratio = reported[~fixed] / empirical[~fixed]
    assert np.all(np.abs(ratio - 1.0) <= 0.15), ratio
    print(f"{robot}: reported / empirical σ {ratio.min():.3f} – {ratio.max():.3f}")
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
