"""Does the fit land on the same estimate from other starts?  (``robocal identify --starts N``, issue 24.4.)

A least-squares fit reports the point where its solver stopped.  For a model that is nearly linear in its parameters
(the geometry, single-slope compliances) that point does not depend on where the solver started; for a product of
unknowns (a compliance times an identified mass), a kink (a breakpoint torque) or a parameter the data barely see, it
may: the solver stops in another valley, or anywhere along a flat one.  A metrologist cannot see that from one fit.

The check refits from N - 1 further starts, each free parameter moved from the estimate by a uniform draw within
+-w (w = 10 sigma; for an effect's parameter at least half its value, so a compliance restarts anywhere from half to
one and a half times itself, or from the other sign), with the same kept set, priors and loss.  A start *lands on
the same estimate* when its whitened sum of squares is within :data:`SAME_CHI2` of the estimate's and every
parameter within :data:`SAME_SIGMA` of its sigma.  Otherwise the report says which starts stopped elsewhere (a higher
residual: another valley), whether one went lower (the reported fit is not the best: not determined by one fit), and
which parameters move by more than their sigma between starts that fit equally well (flat: their sigma understates
what the data leave open).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .identify import Identification, _Problem, _solve

#: whitened sum-of-squares difference below which two fits are equally good (one unit: a one-sigma change of one
#: parameter; the solver stops within a few tenths of it along directions the data barely see)
SAME_CHI2 = 1.0
#: parameter difference (in sigma) below which two starts landed on the same estimate (the solver's own stopping
#: leaves a few tenths of sigma along nearly degenerate directions: two offsets along one axis, measured ~ 0.4)
SAME_SIGMA = 0.5
#: the half-width of the starts, in sigma
SPREAD_SIGMA = 10.0


@dataclass
class Starts:
    n: int                                   # starts, the reported fit included
    same: int                                # of them landing on the reported estimate
    chi2: list[float]                        # whitened sum of squares where each start stopped (the first: the fit)
    worst_sigma: float                       # largest parameter difference (sigma) over the equally good starts
    flat: list[tuple[str, float]] = field(default_factory=list)   # (parameter, spread in sigma) at equal residual

    @property
    def stable(self) -> bool:
        return self.same == self.n

    @property
    def lower(self) -> float:
        """How much lower than the reported fit's the best start's sum of squares is (0: none lower)."""
        return max(0.0, self.chi2[0] - min(self.chi2))

    def lines(self) -> list[str]:
        if self.stable:
            return [f"starts: all {self.n} land on the same estimate (largest difference {self.worst_sigma:.2g} "
                    f"sigma)"]
        out = [f"starts: the fit is not determined by one start: {self.same} of {self.n} land on the reported "
               f"estimate"]
        higher = sum(c > self.chi2[0] + SAME_CHI2 for c in self.chi2)
        if higher:
            out.append(f"  {higher} stop at a higher residual (another valley: up to chi-square "
                       f"+{max(self.chi2) - self.chi2[0]:.3g})")
        if self.lower > SAME_CHI2:
            out.append(f"  a start reached a lower residual (chi-square -{self.lower:.3g}): the reported estimate is "
                       f"not the best fit")
        if self.flat:
            out.append("  not determined (moves by more than its sigma between equally good fits): " +
                       ", ".join(f"{n} ({s:.3g} sigma)" for n, s in self.flat))
        return out

    def as_dict(self) -> dict:
        return {"n": self.n, "same": self.same, "stable": self.stable, "chi2": self.chi2,
                "worst_sigma": self.worst_sigma, "lower_chi2": self.lower,
                "not_determined": [{"parameter": n, "spread_sigma": s} for n, s in self.flat]}


def check_starts(model, obs, ident: Identification, n: int, priors: dict | None = None, loss: str = "linear",
                 max_nfev: int = 200, seed: int = 0) -> Starts:
    """Refit ``ident``'s free parameters from ``n - 1`` further starts (see the module docstring)."""
    rejected = set(ident.outlier_report.rejected) if ident.outlier_report is not None else set()
    if rejected:
        obs = obs.subset(np.array([i for i in range(obs.n) if i not in rejected], int))
    prob = _Problem(model, obs, ident.theta[: model.P], priors or {})
    theta = ident.theta.copy()
    kidx = np.array([ident.names.index(name) for name in ident.free], int)
    sigma = np.where(ident.sigma[kidx] > 0, ident.sigma[kidx], 1.0)
    effect = kidx >= model.n_geometric
    width = np.where(effect, np.maximum(SPREAD_SIGMA * sigma, 0.5 * np.abs(theta[kidx])), SPREAD_SIGMA * sigma)
    width = np.where(np.isfinite(width), width, 0.0)
    rng = np.random.default_rng(seed)
    found = [theta]
    for _ in range(n - 1):
        start = theta.copy()
        start[kidx] += rng.uniform(-1.0, 1.0, len(kidx)) * width
        found.append(_solve(prob, start, kidx, loss, max_nfev))
    chi2 = [float(np.sum(prob.residuals(t, jac=False)[0] ** 2)) for t in found]
    diff = np.array([np.abs(t[kidx] - theta[kidx]) / sigma for t in found])     # (n, k) in sigma
    same = sum(abs(c - chi2[0]) <= SAME_CHI2 and d.max(initial=0.0) <= SAME_SIGMA for c, d in zip(chi2, diff))
    equal = [i for i, c in enumerate(chi2) if c <= min(chi2) + SAME_CHI2 or c <= chi2[0] + SAME_CHI2]
    spread = np.ptp(np.array([found[i][kidx] for i in equal]), axis=0) / sigma
    flat = [(ident.free[k], float(spread[k])) for k in np.argsort(-spread) if spread[k] > 1.0]
    return Starts(n, int(same), chi2, float(diff[equal].max(initial=0.0)), flat)
