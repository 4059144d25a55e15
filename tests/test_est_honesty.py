"""Are the stated errors honest, end to end?  Per procedure, over seeded runs on independent data (the thesis's
formulas in :mod:`tests.fakes.thesis_procedures`, raw theodolite readings through the ruler fit and the intersection):
the median of |value - truth| / error must lie in 0.55-0.85 (0.67 for a Gaussian) and 90-99 % of the ratios below 2.

``benchmarks/bench_error_honesty.py`` prints the same figures over more seeds."""
from __future__ import annotations

import pytest

from tests.est_honesty_runs import PROCEDURES, honesty

SEEDS = {"ruler": 40, "points": 30, "axes": 30, "transmission": 40, "compliance": 60, "compliance (one slope)": 40,
         "coupling": 100, "link compliance": 200, "encoder resolution": 70, "E_a (commanded angle)": 20}


@pytest.mark.parametrize("procedure", list(PROCEDURES))
def test_stated_errors_are_honest(procedure):
    h = honesty(procedure, range(SEEDS[procedure]))
    assert h["n"] >= 60, h
    assert 0.55 <= h["median_ratio"] <= 0.85, h
    assert 0.90 <= h["within_2sigma"] <= 0.99, h
