"""Joint compliance from loading and unloading series (thesis section 4.5, 5.5).

A load ``N`` hung at ``L`` from the joint centre, with the arm at ``theta_i`` from the horizontal, twists the joint
by ``T = N L cos(theta_i)``; the deflection is the change of the angle between the tool targets A1, A2 (eq 4.4.1).
Eq 4.5.1 lost its division: ``K = N L cos(theta_i) / theta_jn``.

Section 5.5.2 reports two slopes with a breakpoint (K3 = 1.156e5 lb in/rad below 100 lb in, 1.223e5 above;
K4 = 2.275e5 below 45 lb in, 1.698e5 above) and unloading curves parallel to loading ones but offset (dead zone,
backlash).  :func:`two_slope_fit` fits exactly that: ``theta = theta0 + offset [unloading] + c1 min(T, Tb) +
c2 max(T - Tb, 0)``, ``K1 = 1/c1``, ``K2 = 1/c2``: a profile search over the breakpoint ``Tb`` then Gauss-Newton on
all five parameters, so the estimator is smooth in the data and its errors can be propagated.

Units: N m, rad, N m/rad inside; :data:`calib.units.LBIN_PER_NM` converts.  First-order errors: for the single-load
formula, eq 5.5.2 plus the term the thesis leaves out (the deflection's own error, usually the largest); for the
fit, ``sigma^2 (J^T J)^-1`` mapped through ``K = 1/c``.
"""
from __future__ import annotations

import numpy as np

from ..uncertainty import EstimateSet, propagate
from ..units import LBIN_PER_NM
from ._common import EstimationError, at_least, finite

PROC = "joint compliance"
FIT_NAMES = ["K1_Nm_per_rad", "K2_Nm_per_rad", "breakpoint_Nm", "offset_rad", "theta0_rad"]
FIT_UNITS = ["N m/rad", "N m/rad", "N m", "rad", "rad"]


def to_lbin_per_rad(K_Nm_per_rad):
    """N m/rad -> lb in/rad (the thesis's unit)."""
    return np.asarray(K_Nm_per_rad, float) * LBIN_PER_NM


def torque_Nm(load_N, lever_mm, theta_i_rad):
    """Twisting moment ``N L cos(theta_i)`` in N m (lever in mm)."""
    return np.asarray(load_N, float) * np.asarray(lever_mm, float) * 1e-3 * np.cos(theta_i_rad)


def _single(x):
    N, L, th, d = np.moveaxis(np.asarray(x, float), -1, 0)
    return (N * L * 1e-3 * np.cos(th) / d)[..., None]


def stiffness_single(load_N: float, lever_mm: float, theta_i_rad: float, deflection_rad: float,
                     sigmas=(0.0, 0.0, 0.0, 0.0), n_mc: int = 20_000, rng=0) -> EstimateSet:
    """Eq 4.5.1 (with its division restored) for one load, errors three ways; ``sigmas`` = 1-sigma of
    (load N, lever mm, theta_i rad, deflection rad)."""
    x = np.array([load_N, lever_mm, theta_i_rad, deflection_rad], float)
    finite(PROC, "eq 4.5.1", inputs=x)
    if abs(deflection_rad) <= max(3 * sigmas[3], 1e-12):
        raise EstimationError(PROC, "eq 4.5.1", "the load produced no measurable deflection: stiffness undefined")
    U = np.diag(np.asarray(sigmas, float) ** 2)
    N, L, th, d = x
    K = N * L * 1e-3 * np.cos(th) / d
    J = np.array([[K / N, K / L, -K * np.tan(th), -K / d]])
    return propagate(_single, x, U, ["K_Nm_per_rad"], ["N m/rad"], n_mc=n_mc, rng=rng, first_order_cov=J @ U @ J.T)


def _design(T, unload, Tb):
    """Columns [1, unloading, min(T, Tb), max(T - Tb, 0)] (batched over Tb)."""
    Tb = np.asarray(Tb, float)[..., None]
    one = np.ones(np.broadcast_shapes(T.shape, Tb.shape))
    return np.stack([one, np.broadcast_to(unload, one.shape), np.minimum(T, Tb), np.maximum(T - Tb, 0.0)], -1)


def _fit_fixed(T, unload, y, Tb):
    """Linear LSQ for fixed breakpoints: y (..., n), Tb (..., g) -> coef (..., g, 4), sse (..., g)."""
    X = _design(T, unload, Tb)                                       # (..., g, n, 4)
    XtX = np.swapaxes(X, -1, -2) @ X
    Xty = np.swapaxes(X, -1, -2) @ y[..., None, :, None]
    coef = np.linalg.solve(XtX + 1e-18 * np.eye(4), Xty)[..., 0]
    r = y[..., None, :] - np.einsum("...gnk,...gk->...gn", X, coef)
    return coef, np.sum(r * r, -1)


def two_slope_model(p, T, unload):
    """theta for parameters ``p (..., 5) = [theta0, offset, c1, c2, Tb]``."""
    th0, off, c1, c2, Tb = np.moveaxis(p, -1, 0)
    return th0[..., None] + off[..., None] * unload + c1[..., None] * np.minimum(T, Tb[..., None]) \
        + c2[..., None] * np.maximum(T - Tb[..., None], 0.0)


def _model_jac(p, T, unload):
    th0, off, c1, c2, Tb = np.moveaxis(p, -1, 0)
    below = T < Tb[..., None]
    return np.stack([np.ones(below.shape), np.broadcast_to(unload, below.shape), np.minimum(T, Tb[..., None]),
                     np.maximum(T - Tb[..., None], 0.0), np.where(below, 0.0, (c1 - c2)[..., None])], -1)


def _fit(T, unload, y, grid_n: int = 200, min_side: int = 2):
    """Vectorised two-slope estimator over leading batch dims of ``y`` -> ``(..., 5)`` [th0, off, c1, c2, Tb]."""
    Ts = np.unique(T)
    lo, hi = Ts[min_side - 1], Ts[-min_side]
    grid = np.linspace(lo, hi, grid_n)
    coef, sse = _fit_fixed(T, unload, y, np.broadcast_to(grid, y.shape[:-1] + (grid_n,)))
    k = np.argmin(sse, -1)
    c = np.take_along_axis(coef, k[..., None, None], -2)[..., 0, :]
    p = np.concatenate([c, grid[k][..., None]], -1)
    for _ in range(6):                                      # Gauss-Newton polish on all five parameters
        J = _model_jac(p, T, unload)
        r = y - two_slope_model(p, T, unload)
        A = np.swapaxes(J, -1, -2) @ J
        dp = np.linalg.solve(A + 1e-18 * np.eye(5), (np.swapaxes(J, -1, -2) @ r[..., None]))[..., 0]
        p = p + dp
        p[..., 4] = np.clip(p[..., 4], lo, hi)
    return p


def _outputs(p):
    th0, off, c1, c2, Tb = np.moveaxis(p, -1, 0)
    return np.stack([1.0 / c1, 1.0 / c2, Tb, off, th0], -1)


def two_slope_fit(torque_Nm_, deflection_rad, unloading, sigma_deflection_rad: float, n_mc: int = 5000,
                  rng=0) -> EstimateSet:
    """Stiffness below and above a breakpoint, the breakpoint, and the unloading offset (dead zone), three ways.

    ``torque_Nm_ (n,)``, ``deflection_rad (n,)`` (joint angle change from A1, A2), ``unloading (n,)`` bool (the
    decreasing-load series); ``sigma_deflection_rad`` the 1-sigma of each deflection (torques taken as exact: weights
    are calibrated).  Needs at least 3 distinct torques on each side of the breakpoint.
    """
    step = "two-slope fit"
    T = np.asarray(torque_Nm_, float).ravel()
    y = np.asarray(deflection_rad, float).ravel()
    u = np.asarray(unloading, bool).ravel().astype(float)
    finite(PROC, step, torque=T, deflection=y)
    if not (T.size == y.size == u.size):
        raise EstimationError(PROC, step, "torque, deflection and unloading flags need one entry per reading")
    at_least(PROC, step, "distinct torques (3 each side of the breakpoint)", np.unique(T).size, 6)
    if not (u.any() and (1 - u).any()):
        raise EstimationError(PROC, step, "needs both a loading and an unloading series (for the dead zone)")
    if np.ptp(y) <= 3 * sigma_deflection_rad or np.ptp(y) == 0:
        raise EstimationError(PROC, step, f"the loads produced no measurable deflection (spread {np.ptp(y):.3g} rad "
                              f"vs noise {sigma_deflection_rad:.3g} rad)")
    p = _fit(T, u, y, min_side=3)
    if np.any(p[2:4] <= 0):
        raise EstimationError(PROC, step, "a fitted compliance is not positive: deflection does not grow with load")
    J = _model_jac(p, T, u)
    Cp = sigma_deflection_rad ** 2 * np.linalg.inv(J.T @ J)
    th0, off, c1, c2, Tb = p
    G = np.zeros((5, 5))
    G[0, 2], G[1, 3], G[2, 4], G[3, 1], G[4, 0] = -1 / c1 ** 2, -1 / c2 ** 2, 1, 1, 1
    U = np.eye(y.size) * sigma_deflection_rad ** 2
    res = propagate(lambda z: _outputs(_fit(T, u, z, min_side=3)), y, U, FIT_NAMES, FIT_UNITS, n_mc=n_mc, rng=rng,
                    first_order_cov=G @ Cp @ G.T, value=_outputs(p))
    res.extras["residual_rad"] = y - two_slope_model(p, T, u)
    return res
