"""The few test distributions robocal needs (chi-square and F tails, the Kruskal-Wallis test), from scipy.special.

Why not ``scipy.stats``: importing it takes 0.3-1 s (it builds every distribution object at import), more than a
400-pose identification spends computing; scipy.special's functions are the same numerics underneath
(``stats.chi2.isf`` is ``special.chdtri``, ``stats.f.sf`` is ``special.fdtrc``) and cost nothing more once
scipy.optimize is loaded.  The import is inside each function, so a module using these loads no scipy until a test
is actually made.  Checked against scipy.stats in ``tests/test_distributions.py``.
"""
from __future__ import annotations

import numpy as np


def chi2_isf(p, dof):
    """The chi-square value exceeded with probability ``p`` at ``dof`` degrees of freedom (``stats.chi2.isf``)."""
    from scipy.special import chdtri
    return chdtri(dof, p)


def chi2_median(dof):
    """The median of the chi-square distribution at ``dof`` degrees of freedom (``stats.chi2.median``)."""
    return chi2_isf(0.5, dof)


def chi2_sf(x, dof):
    """P(chi-square at ``dof`` degrees of freedom > ``x``) (``stats.chi2.sf``; 1 for x <= 0)."""
    from scipy.special import chdtrc
    return chdtrc(dof, np.maximum(x, 0.0))


def f_sf(x, dfn, dfd):
    """P(F(``dfn``, ``dfd``) > ``x``) (``stats.f.sf``; 1 for x <= 0, NaN for NaN)."""
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
