"""Link compliance from dial-gauge deflections (thesis section 4.6), by standard cantilever theory.

The printed eq 4.6.1 is garbled (its bracket mixes X and L powers that do not come from integrating
``EI y'' = M`` twice).  For a cantilever of flexural rigidity ``EI`` clamped at the joint (x = 0) with a point load
``P`` at ``x = a``, the deflection at a gauge at ``x`` is

    y(x) = P x^2 (3a - x) / (6 EI)        for x <= a
    y(x) = P a^2 (3x - a) / (6 EI)        for x >= a

(Timoshenko; the tip case x = a gives ``P a^3 / (3 EI)``).  A compliant joint adds a rigid rotation ``P a / K_j`` of
the whole link, i.e. ``x P a / K_j`` at the gauge; with gauges at several x the two are separable (x^2-x^3 vs x),
so :func:`flexural_rigidity` optionally fits ``1/K_j`` alongside ``1/EI``.  Both enter linearly, so this is weighted
linear least squares: first order ``(X^T W X)^-1`` mapped through ``EI = 1/c``; GUM and Monte Carlo as usual.
``E_j`` follows from ``EI`` when the section's second moment ``I_j`` is known.

When the gauges show no significant bending (the thesis's own finding on the Puma: "effect of link compliance was
found to be negligible compared to the joint compliance", section 5.7) there is no EI to estimate, but there is a
result: a one-sided lower bound, "the link is at least this stiff", from the same cantilever formula
(:func:`link_rigidity` decides which, :class:`RigidityBound` is the bound).

Units: N, mm, N mm^2 for EI (divide by 1e6 for N m^2); N m/rad for K_j.
"""
from __future__ import annotations

from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from ..effects.link_compliance import cantilever_shape  # noqa: F401 (the one formula; tests import it here)
from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, at_least, finite

PROC = "link compliance"


def _design(x, a, P, joint):
    cols = [P * cantilever_shape(x, a) / 6.0]
    if joint:
        cols.append(P * a * x * 1e-3)            # rad per (N m) x mm lever -> with 1/K in rad/(N m)
    return np.stack(cols, -1)


#: the fitted compliance must exceed this many of its own errors for EI to be estimated (a smaller one gives EI's
#: error above a third of its value, where 1/c is no longer near-linear): else the lower bound is the result
SIGNIFICANT = 3.0


@dataclass(frozen=True)
class RigidityBound:
    """A one-sided lower bound on a link's flexural rigidity: no significant bending was seen.

    ``compliance`` is the least-squares ``1/EI`` (N^-1 mm^-2, may be <= 0: noise) with its 1-sigma error;
    ``detection_limit_Nmm2`` the largest EI these loads and gauge positions could tell from a rigid link at this
    confidence -- it uses no reading, only the geometry and the gauge noise, and the bound never exceeds it."""

    EI_lower_bound_Nmm2: float
    confidence: float
    compliance_per_Nmm2: float
    compliance_error_per_Nmm2: float
    detection_limit_Nmm2: float
    largest_deflection_mm: float
    sigma_mm: float


def _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, step):
    """The four reading columns as checked float vectors (one value per reading, positions beyond the clamp), and
    a gauge noise that is a positive number (0 would state EI with no error, a negative one a nonsense interval)."""
    x, a, P, y = (np.asarray(v, float).ravel() for v in (gauge_x_mm, load_x_mm, load_N, deflection_mm))
    finite(PROC, step, gauge_x=x, load_x=a, load=P, deflection=y, gauge_noise=np.asarray(sigma_mm, float))
    if not sigma_mm > 0:
        raise EstimationError(PROC, step, f"the gauge noise must be positive (got {sigma_mm:g} mm)")
    if not (x.size == a.size == P.size == y.size):
        raise EstimationError(PROC, step, "gauge position, load position, load and deflection need one value per "
                              "reading")
    at_least(PROC, step, "readings", y.size, 1)
    if np.any(x <= 0) or np.any(a <= 0):
        raise EstimationError(PROC, step, "gauge and load positions must be beyond the clamp (x > 0 mm)")
    if np.all(np.abs(P) == 0):
        raise EstimationError(PROC, step, "no load was applied")
    return x, a, P, y


def _wls(X: np.ndarray, y: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least squares of ``y = X c`` with the readings' covariance ``C``: ``(c, cov_c)``."""
    Ci = np.linalg.inv(C)
    cov = np.linalg.inv(X.T @ Ci @ X)
    return cov @ X.T @ Ci @ y, cov


def _check_design(X, y, C, step):
    X = np.asarray(X, float).reshape(len(np.ravel(y)), -1)
    y, C = np.asarray(y, float).ravel(), np.asarray(C, float)
    finite(PROC, step, design=X, deflection=y, covariance=C)
    at_least(PROC, step, "readings", y.size, X.shape[1])
    if C.shape != (y.size, y.size) or np.any(np.diag(C) <= 0):
        raise EstimationError(PROC, step, "the readings' covariance must be square and every reading's variance "
                              "positive")
    if not np.any(X[:, 0]):
        raise EstimationError(PROC, step, "no load was applied")
    return X, y, C


def bound_from_design(X, y, C, confidence: float = 0.95) -> RigidityBound:
    """EI >= bound at ``confidence`` (one-sided) from readings that show no significant bending.

    ``X`` (N, K): per reading its deflection per unit compliance ``1/EI`` (mm per mm^-2 N^-1: ``P shape / 6`` on a
    cantilever; from the model's geometry in a session) in column 0, other compliances fitted alongside in the rest
    (a joint's, which the gauges separate from the link's by the deflection's shape); ``y`` (N,) the deflections
    (mm); ``C`` their covariance.  The upper confidence limit of the compliance is ``c_U = max(c, 0) + z sigma_c``
    (``z`` the one-sided normal quantile: 1.645 at 95 %); a compliance cannot be negative, so clipping a negative fit
    to zero only makes the bound conservative; ``EI >= 1 / c_U``.  With ``c <= 0`` the bound is the detection limit
    ``1 / (z sigma_c)``."""
    step = "lower bound on EI"
    X, y, C = _check_design(X, y, C, step)
    if not 0.5 < confidence < 1.0:
        raise EstimationError(PROC, step, f"confidence {confidence:g} must lie between 0.5 and 1")
    c, cov = _wls(X, y, C)
    sc = float(np.sqrt(cov[0, 0]))
    z = NormalDist().inv_cdf(confidence)
    return RigidityBound(1.0 / (max(c[0], 0.0) + z * sc), confidence, float(c[0]), sc, 1.0 / (z * sc),
                         float(np.max(np.abs(y))), float(np.sqrt(np.mean(np.diag(C)))))


def rigidity_lower_bound(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float,
                         confidence: float = 0.95) -> RigidityBound:
    """:func:`bound_from_design` for a cantilever: gauges at ``x``, the load ``P`` at ``a`` (one row per reading)."""
    x, a, P, y = _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, "lower bound on EI")
    return bound_from_design(_design(x, a, P, False), y, sigma_mm ** 2 * np.eye(y.size), confidence)


def rigidity_from_design(X, y, C, names=("EI_Nmm2",), second_moment_mm4: float | None = None,
                         n_mc: int = 20_000, rng=0, confidence: float = 0.95) -> EstimateSet | RigidityBound:
    """What the gauges say about the link (design ``X``, readings ``y``, covariance ``C`` as in
    :func:`bound_from_design`): EI with its error (:func:`flexural_rigidity_from_design`) when the fitted compliance
    is significant (:data:`SIGNIFICANT` of its errors) and the deflections rise above the gauge noise, else the
    one-sided lower bound: a stiff link is a result, not a failure."""
    X, y, C = _check_design(X, y, C, "cantilever fit")
    c, cov = _wls(X, y, C)
    if c[0] < SIGNIFICANT * np.sqrt(cov[0, 0]) or np.max(np.abs(y)) <= 3 * np.sqrt(np.max(np.diag(C))):
        return bound_from_design(X, y, C, confidence)
    return flexural_rigidity_from_design(X, y, C, names, second_moment_mm4, n_mc, rng)


def link_rigidity(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float,
                  second_moment_mm4: float | None = None, n_mc: int = 20_000, rng=0,
                  confidence: float = 0.95) -> EstimateSet | RigidityBound:
    """:func:`rigidity_from_design` for a cantilever: gauges at ``x``, the load ``P`` at ``a``."""
    x, a, P, y = _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, "cantilever fit")
    return rigidity_from_design(_design(x, a, P, False), y, sigma_mm ** 2 * np.eye(y.size),
                                second_moment_mm4=second_moment_mm4, n_mc=n_mc, rng=rng, confidence=confidence)


def flexural_rigidity_from_design(X, y, C, names=("EI_Nmm2",), second_moment_mm4: float | None = None,
                                  n_mc: int = 20_000, rng=0) -> EstimateSet:
    """EI (N mm^2) from deflections ``y`` with covariance ``C`` (design ``X`` as in :func:`bound_from_design`),
    errors three ways; the stiffness of the next columns too when ``names`` names them (N m/rad; a column not named is
    fitted alongside and not reported: a joint's turn that is no more than noise may come out negative); with
    ``second_moment_mm4`` the Young's modulus ``E = EI / I`` (N/mm^2 = MPa) too."""
    step = "cantilever fit"
    X, y, C = _check_design(X, y, C, step)
    k = X.shape[1]
    if np.max(np.abs(y)) <= 3 * np.sqrt(np.max(np.diag(C))):
        raise EstimationError(PROC, step, f"the loads produced no measurable deflection (largest {np.max(np.abs(y)):.3g}"
                              f" mm vs gauge noise {np.sqrt(np.max(np.diag(C))):.3g} mm): EI is not determined")
    XtX = X.T @ X
    if np.linalg.cond(XtX / np.outer(np.sqrt(np.diag(XtX)), np.sqrt(np.diag(XtX)))) > 1e12:
        raise EstimationError(PROC, step, "the readings cannot separate the unknowns (move gauges or loads)")
    names = list(names)[:k]
    r = len(names)
    units = ["N mm^2"] + ["N m/rad"] * (r - 1)
    if second_moment_mm4:
        names.append("E_MPa")
        units.append("N/mm^2")
    c, Cc = _wls(X, y, C)
    A = Cc @ X.T @ np.linalg.inv(C)                 # c = A y

    def f(z):
        cz = np.einsum("kn,...n->...k", A, z)
        out = [1.0 / cz[..., i] for i in range(r)]
        if second_moment_mm4:
            out.append(1.0 / cz[..., 0] / second_moment_mm4)
        return np.stack(out, -1)

    if np.any(c[:r] <= 0):
        raise EstimationError(PROC, step, "a fitted compliance is not positive: deflections do not follow the loads")
    G = np.zeros((len(names), k))
    G[np.arange(r), np.arange(r)] = -1 / c[:r] ** 2
    if second_moment_mm4:
        G[-1, 0] = -1 / c[0] ** 2 / second_moment_mm4
    res = propagate(f, y, C, names, units, n_mc=n_mc, rng=rng, first_order_cov=G @ Cc @ G.T)
    res.extras["residual_mm"] = y - X @ c
    return res


def flexural_rigidity(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float, include_joint: bool = False,
                      second_moment_mm4: float | None = None, n_mc: int = 20_000, rng=0) -> EstimateSet:
    """:func:`flexural_rigidity_from_design` for a cantilever: one row per reading, gauge position ``x``, load
    position ``a``, load ``P`` and measured deflection (mm, positive in the load's direction, zero-load reading
    subtracted); with ``include_joint`` the joint's stiffness ``K_joint`` (its rigid turn ``x P a / K``) too."""
    step = "cantilever fit"
    x, a, P, y = _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, step)
    at_least(PROC, step, "readings", y.size, 3 if include_joint else 2)
    if include_joint and np.unique(x).size < 2:
        raise EstimationError(PROC, step, "separating joint from link compliance needs gauges at 2 or more positions")
    return flexural_rigidity_from_design(_design(x, a, P, include_joint), y, sigma_mm ** 2 * np.eye(y.size),
                                         ("EI_Nmm2", "K_joint_Nm_per_rad"), second_moment_mm4, n_mc, rng)
