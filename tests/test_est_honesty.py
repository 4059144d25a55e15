"""Are the stated errors honest, end to end?  Per procedure, over seeded runs on independent data (the thesis's
formulas in :mod:`tests.fakes.thesis_procedures`, raw theodolite readings through the ruler fit and the intersection):
the median of |value - truth| / error must lie in 0.55-0.85 (0.67 for a Gaussian) and 90-99 % of the ratios below 2.

``benchmarks/bench_error_honesty.py`` prints the same figures over more seeds."""
from __future__ import annotations

import numpy as np
import pytest

from tests.est_honesty_runs import PROCEDURES, honesty, run_transmission_own_axis

SEEDS = {"ruler": 40, "points": 30, "axes": 30, "transmission": 40, "transmission, axis fitted from the run": 40,
         "compliance": 60, "compliance (one slope)": 40,
         "coupling": 100, "link compliance": 200, "encoder resolution": 70, "E_a (commanded angle)": 20}


@pytest.mark.parametrize("procedure", list(PROCEDURES))
def test_stated_errors_are_honest(procedure):
    h = honesty(procedure, range(SEEDS[procedure]))
    assert h["n"] >= 60, h
    assert 0.55 <= h["median_ratio"] <= 0.85, h
    assert 0.90 <= h["within_2sigma"] <= 0.99, h


def test_the_fitted_axis_error_is_what_makes_the_amplitude_honest():
    """The same runs with the run's own axis taken as exact (the angles' covariance about a fixed axis, as reprocess
    did): the order-0.9 amplitude absorbs the axis tilt's once-per-turn error and its stated error is too small
    (about 1.0 and 85 % over 60 seeds, against 0.78 and 95 % with the axis's error): the check can fail."""
    def amplitude_ratios(fixed):
        return np.array([abs(v - t) / e for s in range(60)
                         for n, v, e, t in run_transmission_own_axis(np.random.default_rng(s), fixed_axis=fixed)
                         if n == "amplitude1_rad"])
    fixed, own = amplitude_ratios(True), amplitude_ratios(False)
    assert np.median(fixed) > 0.85 or np.mean(fixed < 2) < 0.90, (np.median(fixed), np.mean(fixed < 2))
    assert 0.55 <= np.median(own) <= 0.85 and np.mean(own < 2) >= 0.90, (np.median(own), np.mean(own < 2))
