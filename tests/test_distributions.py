"""calib.distributions (the chi-square and F tails, the Kruskal-Wallis and Mann-Whitney tests and the hypergeometric
tail robocal uses instead of importing scipy.stats) against scipy.stats itself, the independent reference."""
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


def test_chi2_closed_form_tail_against_scipy():
    """The whole-dof quantiles solved without scipy (the outlier flags' test) against scipy.stats, wide grid."""
    for dof in [*range(1, 41), 41, 99, 100, 157, 200]:
        for p in (1e-12, 1e-9, 1e-6, 1e-4, 1e-3, 0.01, 0.05, 0.1, 0.5, 0.9, 0.99):
            assert d._chi2_isf_int(p, dof) == pytest.approx(stats.chi2.isf(p, dof), rel=1e-12), (p, dof)
            x = stats.chi2.isf(p, dof)
            assert d._chi2_sf_int(x, dof) == pytest.approx(p, rel=1e-9), (p, dof)
    assert d._chi2_sf_int(0.0, 3) == 1.0 and d._chi2_sf_int(-2.0, 4) == 1.0


@pytest.mark.parametrize("x", [-1.0, 0.0, 0.3, 1.0, 4.5, 40.0, np.inf, np.nan])
@pytest.mark.parametrize("dfn, dfd", [(1, 5), (3, 100), (2.5, 7.5), (12, 3000)])
def test_f_tail(x, dfn, dfd):
    np.testing.assert_allclose(d.f_sf(x, dfn, dfd), stats.f.sf(x, dfn, dfd), rtol=1e-12, equal_nan=True)


#: whole degrees of freedom from one to the rows of a 3000-pose fit
_DOFS = [1, 2, 3, 4, 5, 7, 10, 15, 29, 30, 31, 60, 100, 300, 1000, 1200, 3000, 10000]


def test_f_tail_by_the_continued_fraction_against_scipy():
    """The F tail computed without scipy (whole degrees of freedom: every test a diagnosis makes) against
    ``scipy.special.fdtrc`` over a wide grid: within 1e-11 relative where the tail is above 1e-30 (measured: 6e-12
    at worst, dfn 10000 / dfd 15), within 1e-9 down to 1e-200 (the exponent is hundreds there: one rounding of x
    moves the tail by more than that in either implementation)."""
    from scipy.special import fdtrc
    x = np.concatenate([np.geomspace(1e-6, 1e4, 80), [0.5, 1.0, 2.0]])
    for dfn in _DOFS:
        for dfd in _DOFS:
            mine = np.array([d._f_sf_int(float(v), float(dfn), float(dfd)) for v in x])
            ref = fdtrc(dfn, dfd, x)
            wide = ref > 1e-30
            np.testing.assert_allclose(mine[wide], ref[wide], rtol=1e-11, err_msg=f"{dfn}, {dfd}")
            deep = ref > 1e-200
            np.testing.assert_allclose(mine[deep], ref[deep], rtol=1e-9, err_msg=f"{dfn}, {dfd}")


def test_f_tail_vectorised_and_at_the_edges():
    """Arrays of x and degrees of freedom broadcast as scipy's do; x <= 0 gives 1, infinity 0, NaN NaN."""
    from scipy.special import fdtrc
    x = np.array([[-1.0, 0.0, 0.7, 3.0, np.inf, np.nan]])
    dfn = np.array([[1], [4], [9]])
    out = d.f_sf(x, dfn, 57)
    assert out.shape == (3, 6)
    np.testing.assert_allclose(out, fdtrc(dfn, 57, np.maximum(x, 0.0)), rtol=1e-12, equal_nan=True)
    assert isinstance(d.f_sf(2.0, 3, 40), float)


def test_chi2_tail_closed_form_broadcasts():
    x = np.array([0.5, 3.0, 11.0])
    np.testing.assert_allclose(d.chi2_sf(x, np.array([1, 4, 9])), stats.chi2.sf(x, [1, 4, 9]), rtol=1e-12)
    assert d.chi2_sf(-1.0, 3) == 1.0


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


def test_mann_whitney_matches_scipy_exact_and_asymptotic():
    """The outlier cluster test's rank-sum: exact distribution (a small sample, no ties) and the normal approximation
    with tie and continuity corrections, as scipy.stats.mannwhitneyu's default chooses."""
    rng = np.random.default_rng(3)
    for trial in range(200):
        n1, n2 = int(rng.integers(1, 14)), int(rng.integers(1, 60))
        if trial % 2:
            n1, n2 = n2, n1
        x, y = rng.normal(0.0, 1.0, n1), rng.normal(0.4, 1.0, n2)
        if trial % 3 == 0:
            x, y = np.round(x), np.round(y)
        assert d.mann_whitney_p(x, y) == pytest.approx(stats.mannwhitneyu(x, y).pvalue, rel=1e-9, abs=1e-12)


def test_hypergeometric_tail_matches_scipy():
    rng = np.random.default_rng(4)
    for _ in range(200):
        M = int(rng.integers(2, 200))
        n, N = int(rng.integers(0, M + 1)), int(rng.integers(0, M + 1))
        k = int(rng.integers(-1, min(n, N) + 1))
        assert d.hypergeom_sf(k, M, n, N) == pytest.approx(stats.hypergeom.sf(k, M, n, N), rel=1e-9, abs=1e-14)
