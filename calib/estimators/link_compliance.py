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

Units: N, mm, N mm^2 for EI (divide by 1e6 for N m^2); N m/rad for K_j.
"""
from __future__ import annotations

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


def flexural_rigidity(gauge_x_mm, load_x_mm, load_N, deflection_mm, sigma_mm: float, include_joint: bool = False,
                      second_moment_mm4: float | None = None, n_mc: int = 20_000, rng=0) -> EstimateSet:
    """EI (N mm^2) -- and K_j (N m/rad) with ``include_joint`` -- from dial-gauge readings, errors three ways.

    One row per reading: gauge position ``x``, load position ``a``, load ``P`` and measured deflection (mm, positive
    in the load's direction, zero-load reading subtracted).  With ``second_moment_mm4`` the Young's modulus
    ``E = EI / I`` (N/mm^2 = MPa) is reported too.
    """
    step = "cantilever fit"
    x, a, P, y = (np.asarray(v, float).ravel() for v in (gauge_x_mm, load_x_mm, load_N, deflection_mm))
    finite(PROC, step, gauge_x=x, load_x=a, load=P, deflection=y)
    if not (x.size == a.size == P.size == y.size):
        raise EstimationError(PROC, step, "gauge position, load position, load and deflection need one value per "
                              "reading")
    need = 3 if include_joint else 2
    at_least(PROC, step, "readings", y.size, need)
    if np.any(x <= 0) or np.any(a <= 0):
        raise EstimationError(PROC, step, "gauge and load positions must be beyond the clamp (x > 0 mm)")
    if np.all(np.abs(P) == 0):
        raise EstimationError(PROC, step, "no load was applied")
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
