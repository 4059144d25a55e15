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

from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, at_least, finite

PROC = "link compliance"


def cantilever_shape(x_mm, a_mm):
    """``y * 6 EI / P``: the deflection shape (mm^3) at ``x`` for a unit load at ``a`` on a clamped cantilever."""
    x, a = np.asarray(x_mm, float), np.asarray(a_mm, float)
    return np.where(x <= a, x * x * (3 * a - x), a * a * (3 * x - a))


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


def _compliance_fit(x, a, P, y, sigma_mm):
    """Least-squares ``c = 1/EI`` of ``y = c P shape / 6`` and its 1-sigma error (gauge noise ``sigma_mm``)."""
    s = _design(x, a, P, False)[:, 0]
    ss = float(s @ s)
    return float(s @ y) / ss, sigma_mm / np.sqrt(ss)


def rigidity_lower_bound(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float,
                         confidence: float = 0.95) -> RigidityBound:
    """EI >= bound at ``confidence`` (one-sided) from dial-gauge readings that show no significant bending.

    The upper confidence limit of the compliance is ``c_U = max(c, 0) + z sigma_c`` (``z`` the one-sided normal
    quantile: 1.645 at 95 %); a compliance cannot be negative, so clipping a negative fit to zero only makes the bound
    conservative; ``EI >= 1 / c_U``.  With ``c <= 0`` the bound is the detection limit ``1 / (z sigma_c)``."""
    step = "lower bound on EI"
    x, a, P, y = _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, step)
    if not 0.5 < confidence < 1.0:
        raise EstimationError(PROC, step, f"confidence {confidence:g} must lie between 0.5 and 1")
    c, sc = _compliance_fit(x, a, P, y, sigma_mm)
    z = NormalDist().inv_cdf(confidence)
    return RigidityBound(1.0 / (max(c, 0.0) + z * sc), confidence, c, sc, 1.0 / (z * sc),
                         float(np.max(np.abs(y))), float(sigma_mm))


def link_rigidity(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float,
                  second_moment_mm4: float | None = None, n_mc: int = 20_000, rng=0,
                  confidence: float = 0.95) -> EstimateSet | RigidityBound:
    """What the gauges say about the link: EI with its error (:func:`flexural_rigidity`) when the fitted compliance
    is significant (:data:`SIGNIFICANT` of its errors) and the deflections rise above the gauge noise, else the
    one-sided lower bound (:func:`rigidity_lower_bound`): a stiff link is a result, not a failure."""
    x, a, P, y = _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, "cantilever fit")
    c, sc = _compliance_fit(x, a, P, y, sigma_mm)
    if c < SIGNIFICANT * sc or np.max(np.abs(y)) <= 3 * sigma_mm:
        return rigidity_lower_bound(x, a, P, y, sigma_mm, confidence)
    return flexural_rigidity(x, a, P, y, sigma_mm, second_moment_mm4=second_moment_mm4, n_mc=n_mc, rng=rng)


def flexural_rigidity(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float, include_joint: bool = False,
                      second_moment_mm4: float | None = None, n_mc: int = 20_000, rng=0) -> EstimateSet:
    """EI (N mm^2) -- and K_j (N m/rad) with ``include_joint`` -- from dial-gauge readings, errors three ways.

    One row per reading: gauge position ``x``, load position ``a``, load ``P`` and measured deflection (mm, positive
    in the load's direction, zero-load reading subtracted).  With ``second_moment_mm4`` the Young's modulus
    ``E = EI / I`` (N/mm^2 = MPa) is reported too.
    """
    step = "cantilever fit"
    x, a, P, y = _readings(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm, step)
    at_least(PROC, step, "readings", y.size, 3 if include_joint else 2)
    if np.max(np.abs(y)) <= 3 * sigma_mm:
        raise EstimationError(PROC, step, f"the loads produced no measurable deflection (largest {np.max(np.abs(y)):.3g}"
                              f" mm vs gauge noise {sigma_mm:.3g} mm): EI is not determined")
    if include_joint and np.unique(x).size < 2:
        raise EstimationError(PROC, step, "separating joint from link compliance needs gauges at 2 or more positions")
    X = _design(x, a, P, include_joint)
    XtX = X.T @ X
    if np.linalg.cond(XtX) > 1e12:
        raise EstimationError(PROC, step, "the readings cannot separate the unknowns (move gauges or loads)")
    names = ["EI_Nmm2"] + (["K_joint_Nm_per_rad"] if include_joint else [])
    units = ["N mm^2"] + (["N m/rad"] if include_joint else [])
    if second_moment_mm4:
        names.append("E_MPa")
        units.append("N/mm^2")
    Xp = np.linalg.pinv(X)

    def f(z):
        c = np.einsum("kn,...n->...k", Xp, z)
        out = [1.0 / c[..., 0]]
        if include_joint:
            out.append(1.0 / c[..., 1])
        if second_moment_mm4:
            out.append(1.0 / c[..., 0] / second_moment_mm4)
        return np.stack(out, -1)

    c = Xp @ y
    if np.any(c <= 0):
        raise EstimationError(PROC, step, "a fitted compliance is not positive: deflections do not follow the loads")
    Cc = sigma_mm ** 2 * np.linalg.inv(XtX)
    G = np.zeros((len(names), c.size))
    G[0, 0] = -1 / c[0] ** 2
    if include_joint:
        G[1, 1] = -1 / c[1] ** 2
    if second_moment_mm4:
        G[-1, 0] = -1 / c[0] ** 2 / second_moment_mm4
    res = propagate(f, y, np.eye(y.size) * sigma_mm ** 2, names, units, n_mc=n_mc, rng=rng,
                    first_order_cov=G @ Cc @ G.T)
    res.extras["residual_mm"] = y - X @ c
    return res
