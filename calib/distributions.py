"""The few test distributions robocal needs (chi-square and F tails, the Kruskal-Wallis and Mann-Whitney tests, the
hypergeometric tail), without scipy.stats.

Why not ``scipy.stats``: importing it takes 0.3-1 s (it builds every distribution object at import), more than a
400-pose identification spends computing.  The tests robocal makes have whole degrees of freedom, whose chi-square
and F tails are computed here (closed form; the incomplete beta function's continued fraction), so a diagnosis
imports no scipy at all (``scipy.special`` alone is 0.3 s of import); anything else goes to scipy.special's functions,
the same numerics as scipy.stats (``stats.chi2.isf`` is ``special.chdtri``, ``stats.f.sf`` is ``special.fdtrc``),
imported inside the function that needs them.  Checked against scipy in ``tests/test_distributions.py``.
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
    """P(chi-square at ``dof`` degrees of freedom > ``x``) (``stats.chi2.sf``; 1 for x <= 0).

    Whole ``dof`` up to :data:`_CLOSED_FORM_DOF` in closed form (:func:`_chi2_sf_int`), anything else by
    ``scipy.special.chdtrc`` (0.2-0.3 s of import a diagnosis need not pay)."""
    x, dof = np.broadcast_arrays(np.asarray(x, float), np.asarray(dof, float))
    if np.all(np.isfinite(x)) and np.all((dof == np.round(dof)) & (dof >= 1) & (dof <= _CLOSED_FORM_DOF)):
        out = np.array([_chi2_sf_int(float(a), int(k)) for a, k in zip(x.ravel(), dof.ravel())]).reshape(x.shape)
        return out if out.ndim else out[()]
    # scipy.special: lazy for start-up, as in chi2_isf
    from scipy.special import chdtrc
    return chdtrc(dof, np.maximum(x, 0.0))


def f_sf(x, dfn, dfd):
    """P(F(``dfn``, ``dfd``) > ``x``) (``stats.f.sf``; 1 for x <= 0, NaN for NaN).

    Whole degrees of freedom (every test robocal makes) by the regularized incomplete beta function here
    (:func:`_f_sf_int`, checked against ``scipy.special.fdtrc`` in tests/test_distributions.py); anything else by
    ``fdtrc``, whose import (0.2-0.3 s) a diagnosis then need not pay."""
    x, dfn, dfd = np.broadcast_arrays(np.asarray(x, float), np.asarray(dfn, float), np.asarray(dfd, float))
    whole = np.all((dfn == np.round(dfn)) & (dfd == np.round(dfd)) & (dfn >= 1) & (dfd >= 1)
                   & (dfn <= _CLOSED_FORM_F) & (dfd <= _CLOSED_FORM_F))
    out = None
    if whole:
        vals = [_f_sf_int(float(a), float(m), float(n)) for a, m, n in zip(x.ravel(), dfn.ravel(), dfd.ravel())]
        if not any(v is None for v in vals):
            out = np.array(vals, float).reshape(x.shape)
    if out is None:
        # scipy.special: lazy for start-up, as in chi2_isf
        from scipy.special import fdtrc
        out = np.asarray(fdtrc(dfn, dfd, np.maximum(x, 0.0)), float)
    return out if out.ndim else out[()]


#: whole degrees of freedom up to this have their F tail computed here (:func:`_f_sf_int`)
_CLOSED_FORM_F = 1e6


def _f_sf_int(x: float, dfn: float, dfd: float) -> float | None:
    """P(F(dfn, dfd) > x) = I_w(dfd/2, dfn/2), w = dfd / (dfd + dfn x) (Abramowitz and Stegun 26.6.2); None when the
    continued fraction does not converge (the caller then asks scipy)."""
    if math.isnan(x):
        return float("nan")
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    den = dfd + dfn * x
    return _beta_inc(0.5 * dfd, 0.5 * dfn, dfd / den, dfn * x / den)


def _beta_inc(a: float, b: float, w: float, wc: float) -> float | None:
    """The regularized incomplete beta function I_w(a, b), ``wc`` = 1 - w given apart (no cancellation): the
    continued fraction on the side where it converges fast (Numerical Recipes' ``betai``), so a small tail comes from
    the fraction itself, not from 1 minus something; its front factor by :func:`_log_beta_front`."""
    if w <= 0.0:
        return 0.0
    if wc <= 0.0:
        return 1.0
    if w < (a + 1.0) / (a + b + 2.0):
        cf = _beta_cf(a, b, w)
        return None if cf is None else math.exp(_log_beta_front(a, b, w, wc) + math.log(cf / a))
    cf = _beta_cf(b, a, wc)
    return None if cf is None else 1.0 - math.exp(_log_beta_front(a, b, w, wc) + math.log(cf / b))


_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


def _log_beta_front(a: float, b: float, w: float, wc: float) -> float:
    """log(w^a wc^b / B(a, b)) without the cancellation of ``lgamma(a + b) - lgamma(a) - lgamma(b) + a log w + ...``
    (terms of 1e5 for 1e5 degrees of freedom, whose rounding alone is 1e-11 of the result): by Stirling's formula,
    ``0.5 log(ab / (2 pi (a+b))) - a phi(w/x0 - 1) - b phi(wc/y0 - 1) + corrections``, x0 = a/(a+b), y0 = b/(a+b),
    phi(e) = e - log(1+e) >= 0 (as TOMS 708's ``brcomp``)."""
    n = a + b
    e1 = (w - a / n) / (a / n)
    e2 = (wc - b / n) / (b / n)
    return (0.5 * math.log(a * b / n) - _HALF_LOG_2PI - a * _phi(e1) - b * _phi(e2)
            + _stirling_rest(n) - _stirling_rest(a) - _stirling_rest(b))


def _phi(e: float) -> float:
    """e - log(1 + e), by its series where the difference would cancel."""
    if abs(e) >= 0.25:
        return e - math.log1p(e)
    total, term = 0.0, -e
    for k in range(2, 60):              # |e| < 1/4: 30 terms reach 1e-17 of the sum
        term *= -e
        total += term / k
    return total


def _stirling_rest(x: float) -> float:
    """lgamma(x) - ((x - 1/2) log x - x + log(2 pi)/2): by its asymptotic series for x >= 15 (the next term under
    3e-14), else from lgamma itself (small terms there, no cancellation to speak of)."""
    if x < 15.0:
        return math.lgamma(x) - ((x - 0.5) * math.log(x) - x + _HALF_LOG_2PI)
    x2 = 1.0 / (x * x)
    return (1.0 / 12.0 - x2 * (1.0 / 360.0 - x2 * (1.0 / 1260.0 - x2 * (1.0 / 1680.0 - x2 / 1188.0)))) / x


def _beta_cf(a: float, b: float, w: float, tol: float = 1e-16, max_iter: int = 100000) -> float | None:
    """The continued fraction of the incomplete beta function, evaluated by the modified Lentz method (Numerical
    Recipes' ``betacf``); None when it has not converged after ``max_iter`` terms."""
    tiny = 1e-300
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * w / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, max_iter + 1):
        m2 = 2 * m
        aa = m * (b - m) * w / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        h *= d * c
        aa = -(a + m) * (qab + m) * w / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        delta = d * c
        h *= delta
        if abs(delta - 1.0) <= tol:
            return h
    return None


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
    return float(min(1.0, 2.0 * _normal_cdf(-z)))


def _normal_cdf(z: float) -> float:
    """P(N(0, 1) < z) by the error function, as cephes' ``ndtr`` (scipy.special) computes it: erf near zero, erfc in
    the tails (no 1 minus a small number)."""
    x = z / math.sqrt(2.0)
    if abs(x) < 1.0 / math.sqrt(2.0):
        return 0.5 + 0.5 * math.erf(x)
    y = 0.5 * math.erfc(abs(x))
    return 1.0 - y if x > 0 else y


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
