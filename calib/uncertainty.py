"""Estimation errors, three ways: first-order expressions, the GUM law of propagation, and Monte Carlo (GUM-S1).

Every estimator in :mod:`calib.estimators` is written as a *vectorised* function ``f(x (..., m)) -> y (..., k)``
of its raw inputs (readings, ruler lengths, point coordinates, loads ...).  That one function serves both generic
propagations here:

* **GUM** (JCGM 100, law of propagation of uncertainty): ``U_y = J U_x J^T`` with ``J = df/dx`` at the input estimate,
  by central differences evaluated in *one* call of ``f`` on a ``(2m, m)`` batch (or analytic when the caller has it);
* **Monte Carlo** (JCGM 101, GUM Supplement 1): ``n`` Gaussian draws of the inputs, ``f`` evaluated once on the
  ``(n, m)`` batch, output covariance and probabilistically symmetric coverage intervals from the sample.

The third way, the thesis's own first-order expressions (Appendix B), lives with each estimator (it is specific to
each formula) and is passed in as ``first_order_cov``.  Why three: the first-order expressions are what the thesis
printed and what a design-of-experiments search can evaluate cheaply; the GUM form checks them against the actual
estimator code; Monte Carlo checks that linearisation holds at the operating point.  When the three disagree by more
than ~10 %, the linearisation (or a formula) is wrong, and the session layer should say so.

Units are whatever the estimator uses (mm and rad inside robocal).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .errors import RobocalError

VecFn = Callable[[np.ndarray], np.ndarray]

#: default number of Monte Carlo draws: GUM-S1 suggests 1e6 for 95 % intervals to 2 significant digits; 2e4 gives
#: standard deviations to ~1 %, which is what the 10 % agreement check needs.
DEFAULT_MC_DRAWS = 20_000


class UncertaintyError(RobocalError):
    """An uncertainty propagation cannot be done (non-finite estimate, covariance not positive semi-definite ...)."""


# -- result types --------------------------------------------------------------------------------------------------
@dataclass
class Estimate:
    """One estimated quantity with its 1-sigma estimation error, computed up to three ways.

    ``error`` is the adopted standard uncertainty (the GUM value when available, else Monte Carlo, else first order).
    ``interval95`` is the Monte Carlo 95 % probabilistically symmetric coverage interval when computed.
    """

    name: str
    value: float
    error: float
    unit: str
    error_first_order: float | None = None
    error_gum: float | None = None
    error_mc: float | None = None
    interval95: tuple[float, float] | None = None

    def as_dict(self) -> dict:
        """The JSON object the session layer emits: name, value, error (1 sigma), unit, plus the three ways."""
        d = {"name": self.name, "value": float(self.value), "error": float(self.error), "unit": self.unit}
        for k in ("error_first_order", "error_gum", "error_mc"):
            v = getattr(self, k)
            d[k] = None if v is None else float(v)
        d["interval95"] = None if self.interval95 is None else [float(v) for v in self.interval95]
        return d

    def agreement(self) -> float:
        """Largest relative spread between the available error figures (0 when only one is known)."""
        vals = [v for v in (self.error_first_order, self.error_gum, self.error_mc) if v is not None]
        if len(vals) < 2:
            return 0.0
        return float((max(vals) - min(vals)) / max(min(vals), 1e-300))


@dataclass
class EstimateSet:
    """Several estimates of one procedure with their joint covariances (each way, where computed)."""

    names: list[str]
    value: np.ndarray
    units: list[str]
    cov_gum: np.ndarray | None = None
    cov_mc: np.ndarray | None = None
    cov_first_order: np.ndarray | None = None
    interval95: np.ndarray | None = None          # (k, 2), Monte Carlo
    extras: dict = field(default_factory=dict)     # procedure-specific diagnostics (residuals, breakpoints ...)

    @property
    def cov(self) -> np.ndarray:
        """The adopted covariance: GUM, else Monte Carlo, else first order."""
        for c in (self.cov_gum, self.cov_mc, self.cov_first_order):
            if c is not None:
                return c
        raise UncertaintyError("no covariance was computed for " + ", ".join(self.names))

    @property
    def error(self) -> np.ndarray:
        return np.sqrt(np.diag(self.cov))

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"{name!r} is not one of {self.names}") from None

    def __getitem__(self, name: str) -> Estimate:
        i = self.index(name)

        def sd(c):
            return None if c is None else float(np.sqrt(max(c[i, i], 0.0)))

        iv = None if self.interval95 is None else (float(self.interval95[i, 0]), float(self.interval95[i, 1]))
        return Estimate(name, float(self.value[i]), float(np.sqrt(max(self.cov[i, i], 0.0))), self.units[i],
                        sd(self.cov_first_order), sd(self.cov_gum), sd(self.cov_mc), iv)

    def estimates(self) -> list[Estimate]:
        return [self[n] for n in self.names]

    def as_dicts(self) -> list[dict]:
        return [e.as_dict() for e in self.estimates()]

    def correlation(self) -> np.ndarray:
        c = self.cov
        s = np.sqrt(np.diag(c))
        with np.errstate(invalid="ignore", divide="ignore"):
            return c / np.outer(s, s)

    def same_as(self, tol: float = 1e-9) -> dict[str, tuple[str, float]]:
        """Estimates that are another of the set under a second name: ``{name: (first name, sign)}`` for each whose
        correlation with an earlier one is +-1 (a misalignment in both of its parametrisations, a resolution and its
        ratio to the design value).  Why: ``(value - truth) / error`` of such a pair is the same number (opposite
        signs when the parametrisations are), so a count of estimates must take it once; found here from the
        covariance where the set is made, not by matching values downstream."""
        c = self.correlation()
        out: dict[str, tuple[str, float]] = {}
        for i in range(len(self.names)):
            for k in range(i):
                if self.names[k] not in out and np.isfinite(c[i, k]) and abs(c[i, k]) >= 1.0 - tol:
                    out[self.names[i]] = (self.names[k], float(np.sign(c[i, k])))
                    break
        return out

    def subset(self, names: Sequence[str]) -> "EstimateSet":
        idx = [self.index(n) for n in names]
        pick = (lambda c: None if c is None else c[np.ix_(idx, idx)])
        return EstimateSet(list(names), self.value[idx], [self.units[i] for i in idx], pick(self.cov_gum),
                           pick(self.cov_mc), pick(self.cov_first_order),
                           None if self.interval95 is None else self.interval95[idx], dict(self.extras))


# -- the machinery ---------------------------------------------------------------------------------------------
def default_steps(x: np.ndarray, cov: np.ndarray | None = None) -> np.ndarray:
    """Central-difference steps: a tenth of the input's standard uncertainty (so the step probes the same region the
    uncertainty does), falling back to ~1e-6 relative for inputs without uncertainty."""
    x = np.asarray(x, float)
    h = 1e-6 * np.maximum(np.abs(x), 1.0)
    if cov is not None:
        s = np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0.0, None))
        h = np.where(s > 0, 0.1 * s, h)
    return h


def jacobian(f: VecFn, x: np.ndarray, steps: np.ndarray | None = None) -> np.ndarray:
    """Central-difference Jacobian of a vectorised ``f`` at ``x (..., m)``: returns ``(..., k, m)``.

    All ``2m`` perturbed inputs go through ``f`` in one call, so the cost is one batched evaluation.
    Leading batch dimensions are kept (a Jacobian per run for the 200-run coverage tests).
    """
    x = np.asarray(x, float)
    m = x.shape[-1]
    h = default_steps(x) if steps is None else np.broadcast_to(np.asarray(steps, float), x.shape)
    eye = np.eye(m)
    dx = h[..., None, :] * eye                          # (..., m, m)
    xp = np.concatenate([x[..., None, :] + dx, x[..., None, :] - dx], axis=-2)   # (..., 2m, m)
    y = np.asarray(f(xp), float)                        # (..., 2m, k)
    J = (y[..., :m, :] - y[..., m:, :]) / (2 * h[..., :, None])                    # (..., m, k)
    return np.swapaxes(J, -1, -2)


def gum_covariance(J: np.ndarray, cov_x: np.ndarray) -> np.ndarray:
    """Law of propagation of uncertainty, ``J U_x J^T`` (JCGM 100 eq 13), batched."""
    return J @ cov_x @ np.swapaxes(J, -1, -2)


def sample_inputs(x: np.ndarray, cov: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` Gaussian draws ``(n, m)`` of inputs with mean ``x`` and covariance ``cov`` (semi-definite allowed).

    Uses the symmetric square root from an eigen-decomposition, so exact inputs (zero variance) and perfectly
    correlated inputs (shared ruler length, shared L) need no special casing.
    """
    x = np.asarray(x, float)
    cov = np.asarray(cov, float)
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    if np.min(w) < -1e-9 * max(np.max(np.abs(w)), 1e-300):
        raise UncertaintyError("input covariance is not positive semi-definite")
    A = V * np.sqrt(np.clip(w, 0.0, None))
    return x + rng.standard_normal((n, x.size)) @ A.T


def mc_summary(y: np.ndarray, p: float = 0.95):
    """Mean, covariance and probabilistically symmetric ``p`` coverage intervals of Monte Carlo outputs ``(n, k)``."""
    y = np.asarray(y, float)
    ok = np.all(np.isfinite(y), axis=-1)
    if ok.mean() < 0.999:
        raise UncertaintyError(f"{(~ok).sum()} of {len(y)} Monte Carlo draws gave no finite result; "
                               f"the measurement geometry is too close to a singular one for this input uncertainty")
    y = y[ok]
    lo, hi = np.quantile(y, [(1 - p) / 2, (1 + p) / 2], axis=0)
    return y.mean(0), np.atleast_2d(np.cov(y, rowvar=False)), np.stack([lo, hi], -1)


def propagate(f: VecFn, x: np.ndarray, cov_x: np.ndarray, names: Sequence[str], units: Sequence[str], *,
              n_mc: int = DEFAULT_MC_DRAWS, rng: np.random.Generator | int | None = 0,
              jac: np.ndarray | None = None, first_order_cov: np.ndarray | None = None,
              steps: np.ndarray | None = None, value: np.ndarray | None = None) -> EstimateSet:
    """Propagate the input covariance through a vectorised estimator ``f`` both ways (GUM and Monte Carlo).

    ``f(x (..., m)) -> y (..., k)``; ``x``, ``cov_x`` the input estimate and covariance.  ``jac`` overrides the
    central-difference Jacobian; ``first_order_cov`` carries the estimator's own first-order expression (thesis App B
    or derived) into the result.  ``n_mc = 0`` skips Monte Carlo.  The reported value is ``f(x)`` (the GUM estimate),
    not the Monte Carlo mean.
    """
    x = np.asarray(x, float)
    cov_x = np.asarray(cov_x, float)
    if x.ndim != 1 or cov_x.shape != (x.size, x.size):
        raise UncertaintyError(f"inputs must be a vector with a matching covariance (got {x.shape}, {cov_x.shape})")
    y0 = np.asarray(f(x[None]), float)[0] if value is None else np.asarray(value, float)
    require_finite(y0, names)
    if jac is None:
        jac = jacobian(f, x, default_steps(x, cov_x) if steps is None else steps)
    cov_gum = gum_covariance(jac, cov_x)
    cov_mc = iv = None
    if n_mc:
        g = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        _, cov_mc, iv = mc_summary(f(sample_inputs(x, cov_x, n_mc, g)))
    return EstimateSet(list(names), y0, list(units), cov_gum, cov_mc, first_order_cov, iv)


def require_finite(value: np.ndarray, names: Sequence[str]) -> None:
    """Refuse an estimate with a non-finite entry (naming them): nothing can be propagated from it."""
    if not np.all(np.isfinite(value)):
        raise UncertaintyError("the estimate itself is not finite: " + ", ".join(
            n for n, v in zip(names, value) if not np.isfinite(v)))


def spread_sd(f: VecFn, x: np.ndarray, cov_x: np.ndarray, n: int, rng) -> np.ndarray:
    """Half the central 68 % of ``f``'s outputs over ``n`` draws of the inputs: a standard deviation that a few
    wild draws (a nonlinear fit running off) cannot inflate, unlike the sample covariance."""
    drawn = f(sample_inputs(np.asarray(x, float), np.asarray(cov_x, float), n, np.random.default_rng(rng)))
    lo, hi = np.nanquantile(drawn, [0.15866, 0.84134], axis=0)
    return 0.5 * (hi - lo)


def widen(cov: np.ndarray, sd_floor: np.ndarray) -> None:
    """Scale rows and columns of ``cov`` in place so that each standard deviation is at least ``sd_floor``
    (correlations kept; a zero variance becomes the floor).  Why: where an estimator is not linear in its data
    the linearised covariance can be far too small, and its Monte Carlo spread is the honest error."""
    for i, f in enumerate(np.asarray(sd_floor, float)):
        if not np.isfinite(f) or cov[i, i] >= f ** 2:
            continue
        if cov[i, i] > 1e-12 * f ** 2:
            k = f / np.sqrt(cov[i, i])
            cov[i, :] *= k
            cov[:, i] *= k
        else:
            cov[i, :] = cov[:, i] = 0.0
            cov[i, i] = f ** 2


def coverage_fraction(estimates: np.ndarray, errors: np.ndarray, truth: np.ndarray, k: float = 1.959964) -> np.ndarray:
    """Fraction of runs (axis 0) whose ``estimate +- k error`` interval covers the truth, per quantity."""
    return np.mean(np.abs(np.asarray(estimates) - np.asarray(truth)) <= k * np.asarray(errors), axis=0)


def block_diag(blocks: Sequence[np.ndarray]) -> np.ndarray:
    """Block-diagonal matrix from square blocks (covariances of independent input groups)."""
    n = sum(b.shape[0] for b in blocks)
    out = np.zeros((n, n))
    i = 0
    for b in blocks:
        k = b.shape[0]
        out[i:i + k, i:i + k] = b
        i += k
    return out
