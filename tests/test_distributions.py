"""calib.distributions (the chi-square and F tails and the Kruskal-Wallis test robocal uses instead of importing
scipy.stats) against scipy.stats itself, the independent reference."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from calib import distributions as d


@pytest.mark.parametrize("p", [1e-6, 1e-3, 0.05, 0.5, 0.9])
@pytest.mark.parametrize("dof", [1, 2, 3, 7, 40, np.array([1, 3, 6])])
def test_chi2_quantiles_and_tails(p, dof):
    np.testing.assert_allclose(d.chi2_isf(p, dof), stats.chi2.isf(p, dof), rtol=1e-12)
    np.testing.assert_allclose(d.chi2_median(dof), stats.chi2.median(dof), rtol=1e-12)
    x = stats.chi2.isf(p, dof)
    np.testing.assert_allclose(d.chi2_sf(x, dof), stats.chi2.sf(x, dof), rtol=1e-9)


@pytest.mark.parametrize("x", [-1.0, 0.0, 0.3, 1.0, 4.5, 40.0, np.inf, np.nan])
@pytest.mark.parametrize("dfn, dfd", [(1, 5), (3, 100), (2.5, 7.5), (12, 3000)])
def test_f_tail(x, dfn, dfd):
    np.testing.assert_allclose(d.f_sf(x, dfn, dfd), stats.f.sf(x, dfn, dfd), rtol=1e-12, equal_nan=True)


def test_kruskal_matches_scipy_with_and_without_ties():
    rng = np.random.default_rng(7)
    for trial in range(60):
        k = int(rng.integers(2, 6))
        groups = [rng.normal(rng.normal(0, 0.3), 1.0, int(rng.integers(1, 30))) for _ in range(k)]
        if trial % 2:                       # ties: rounded values, and some identical groups
            groups = [np.round(g, 0) for g in groups]
        if sum(len(g) for g in groups) < 3 or len(np.unique(np.concatenate(groups))) < 2:
            continue
        assert d.kruskal_p(*groups) == pytest.approx(stats.kruskal(*groups).pvalue, rel=1e-10, abs=1e-300)


def test_kruskal_refuses_what_cannot_be_tested():
    assert np.isnan(d.kruskal_p([1.0, 1.0], [1.0, 1.0, 1.0]))         # all equal: nothing to rank (scipy: NaN too)
    assert np.isnan(d.kruskal_p([1.0, np.nan], [2.0, 3.0]))
    with pytest.raises(ValueError):
        d.kruskal_p([1.0, 2.0])
    with pytest.raises(ValueError):
        d.kruskal_p([1.0, 2.0], [])


def test_average_ranks():
    v = np.array([3.0, 1.0, 3.0, 2.0, 3.0, -1.0])
    np.testing.assert_array_equal(d.average_ranks(v), stats.rankdata(v))
