"""The few test distributions robocal needs (chi-square and F tails, the Kruskal-Wallis and Mann-Whitney tests, the
hypergeometric tail), from scipy.special.

Why not ``scipy.stats``: importing it takes 0.3-1 s (it builds every distribution object at import), more than a
400-pose identification spends computing; scipy.special's functions are the same numerics underneath
(``stats.chi2.isf`` is ``special.chdtri``, ``stats.f.sf`` is ``special.fdtrc``) and cost nothing more once
scipy.optimize is loaded.  The import is inside each function, so a module using these loads no scipy until a test
is actually made.  Checked against scipy.stats in ``tests/test_distributions.py``.
"""
from __future__ import annotations

import math

import numpy as np

#: integer degrees of freedom up to this have their chi-square tail in closed form here (:func:`_chi2_sf_int`)
_CLOSED_FORM_DOF = 200


def chi2_isf(p, dof):
    """The chi-square value exceeded with probability ``p`` at ``dof`` degrees of freedom (``stats.chi2.isf``).

    A scalar ``p`` in (0, 1) at a whole ``dof`` up to :data:`_CLOSED_FORM_DOF` is solved here on the closed-form tail
    (:func:`_chi2_sf_int`, bisected to adjacent floats: ``chdtri``'s figure within 1e-12, 1e-9 where p is within
    1e-6 of 1 and the tail is flat): the one test of an identification
    (the outlier flags at 3 degrees of freedom) then imports no scipy, 0.2-0.3 s of start-up for ``robocal demo``
    and every fit; anything else goes to ``scipy.special.chdtri``."""
    if np.ndim(p) == 0 and np.ndim(dof) == 0 and 0.0 < float(p) < 1.0 and float(dof) == int(dof) \
            and 1 <= int(dof) <= _CLOSED_FORM_DOF:
        return _chi2_isf_int(float(p), int(dof))
    # scipy.special costs ~0.2 s at start-up (identify, diagnose and plan load this module)
    from scipy.special import chdtri
    return chdtri(dof, p)


def _chi2_sf_int(x: float, k: int) -> float:
    """P(chi-square at ``k`` (whole) degrees of freedom > ``x``), in closed form: ``exp(-x/2) sum_{i<k/2} (x/2)^i /
    i!`` for even ``k``; ``erfc(sqrt(x/2)) + exp(-x/2) sum_{i<(k-1)/2} (x/2)^(i+1/2) / Gamma(i+3/2)`` for odd ``k``
    (Abramowitz and Stegun 26.4.4-5): sums of positive terms, no cancellation."""
    if x <= 0.0:
        return 1.0
    h = 0.5 * x
    if k % 2 == 0:
        term, total = 1.0, 1.0
        for i in range(1, k // 2):
            term *= h / i
            total += term
        return math.exp(-h) * total
    term = math.sqrt(h) / math.gamma(1.5)
    total = 0.0
    for i in range((k - 1) // 2):
        total += term
        term *= h / (i + 1.5)
    return math.erfc(math.sqrt(h)) + math.exp(-h) * total


def _chi2_isf_int(p: float, k: int) -> float:
    """The ``x`` with :func:`_chi2_sf_int` (x, k) = p: bracketed by doubling, then bisected to adjacent floats (the
    tail falls monotonically)."""
    lo, hi = 0.0, max(1.0, float(k))
    while _chi2_sf_int(hi, k) > p:
        lo, hi = hi, 2.0 * hi
    while True:
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            return hi
        if _chi2_sf_int(mid, k) > p:
            lo = mid
        else:
            hi = mid


def chi2_median(dof):
    """The median of the chi-square distribution at ``dof`` degrees of freedom (``stats.chi2.median``)."""
    return chi2_isf(0.5, dof)


def chi2_sf(x, dof):
    """P(chi-square at ``dof`` degrees of freedom > ``x``) (``stats.chi2.sf``; 1 for x <= 0)."""
    # scipy.special: lazy for start-up, as in chi2_isf
    from scipy.special import chdtrc
    return chdtrc(dof, np.maximum(x, 0.0))


def f_sf(x, dfn, dfd):
    """P(F(``dfn``, ``dfd``) > ``x``) (``stats.f.sf``; 1 for x <= 0, NaN for NaN)."""
    # scipy.special: lazy for start-up, as in chi2_isf
    from scipy.special import fdtrc
    return fdtrc(dfn, dfd, np.maximum(x, 0.0))


def average_ranks(values: np.ndarray) -> np.ndarray:
    """1-based ranks of ``values``, tied values sharing the mean of their ranks (``stats.rankdata``)."""
    _, inv, counts = np.unique(values, return_inverse=True, return_counts=True)
    return (np.cumsum(counts) - (counts - 1) / 2.0)[inv.ravel()]


def kruskal_p(*samples) -> float:
    """p-value of the Kruskal-Wallis H test that the samples come from one distribution, with the tie correction
    (``stats.kruskal(...).pvalue``): NaN when all values are equal (nothing to rank) or one is NaN; ValueError when
    fewer than two samples or an empty one."""
    groups = [np.asarray(s, float).ravel() for s in samples]
    sizes = np.array([len(g) for g in groups], float)
    if len(groups) < 2 or not np.all(sizes > 0):
        raise ValueError("the Kruskal-Wallis test needs at least two non-empty samples")
    values = np.concatenate(groups)
    if np.isnan(values).any():
        return float("nan")
    n = len(values)
    _, counts = np.unique(values, return_counts=True)
    tie = 1.0 - float(np.sum(counts.astype(float) ** 3 - counts)) / (n ** 3 - n)
    if tie <= 0:
        return float("nan")
    rank_sums = np.array([r.sum() for r in np.split(average_ranks(values), np.cumsum(sizes[:-1]).astype(int))])
    h = (12.0 / (n * (n + 1)) * float(np.sum(rank_sums ** 2 / sizes)) - 3.0 * (n + 1)) / tie
    return float(chi2_sf(h, len(groups) - 1))


def mann_whitney_p(x, y) -> float:
    """Two-sided p-value of the Mann-Whitney U test (``stats.mannwhitneyu(x, y).pvalue``, its default method: the
    exact distribution of U when a sample has at most 8 values and there are no ties, else the normal approximation with
    the tie and continuity corrections)."""
    # scipy.special: lazy for start-up, as in chi2_isf
    from scipy.special import ndtr
    x, y = np.asarray(x, float).ravel(), np.asarray(y, float).ravel()
    n1, n2 = len(x), len(y)
    if n1 == 0 or n2 == 0:
        raise ValueError("the Mann-Whitney test needs two non-empty samples")
    values = np.concatenate([x, y])
    ranks = average_ranks(values)
    u1 = float(ranks[:n1].sum()) - n1 * (n1 + 1) / 2.0
    u = max(u1, n1 * n2 - u1)
    _, counts = np.unique(values, return_counts=True)
    if min(n1, n2) <= 8 and np.all(counts == 1):
        return float(min(1.0, 2.0 * _u_sf(int(round(u)), n1, n2)))
    n = n1 + n2
    tie = float(np.sum(counts.astype(float) ** 3 - counts)) / (n * (n - 1))
    sd = np.sqrt(n1 * n2 / 12.0 * ((n + 1) - tie))
    if sd <= 0:
        return 1.0
    z = (u - n1 * n2 / 2.0 - 0.5) / sd
    return float(min(1.0, 2.0 * ndtr(-z)))


def _u_sf(u: int, n1: int, n2: int) -> float:
    """P(U >= u) under the null (no ties).  The number of arrangements with U = k is the number of partitions of k
    into at most m parts of at most n (m <= n the smaller sample): the coefficients of the Gaussian binomial
    ``prod_{i=1..m} (1 - q^(n+i)) / (1 - q^i)``, multiplied out one factor at a time (m <= 8 here)."""
    m, n = min(n1, n2), max(n1, n2)
    c = np.zeros(m * n + 1)
    c[0] = 1.0
    for i in range(1, m + 1):
        c[n + i:] -= c[: len(c) - n - i].copy()         # times (1 - q^(n+i))
        for k in range(i, len(c)):                      # divided by (1 - q^i): a running sum with stride i
            c[k] += c[k - i]
    return float(c[u:].sum() / c.sum())


def hypergeom_sf(k: int, total: int, successes: int, draws: int) -> float:
    """P(X > k) for X hypergeometric (``stats.hypergeom.sf(k, total, successes, draws)``)."""
    # scipy.special: lazy for start-up, as in chi2_isf
    from scipy.special import gammaln

    def lcomb(a, b):
        return gammaln(a + 1) - gammaln(b + 1) - gammaln(a - b + 1)
    x = np.arange(max(k + 1, 0, draws - (total - successes)), min(successes, draws) + 1)
    if x.size == 0:
        return 0.0
    logp = lcomb(successes, x) + lcomb(total - successes, draws - x) - lcomb(total, draws)
    return float(min(1.0, np.exp(logp).sum()))
