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

from ..uncertainty import EstimateSet, propagate, spread_sd, widen
from ..units import LBIN_PER_NM
from ._common import EstimationError, at_least, error_covariance, finite

PROC = "joint compliance"
FIT_NAMES = ["K1_Nm_per_rad", "K2_Nm_per_rad", "breakpoint_Nm", "offset_rad", "theta0_rad"]
FIT_UNITS = ["N m/rad", "N m/rad", "N m", "rad", "rad"]
#: a stiffness whose 1-sigma exceeds this share of its value is "not determined" (linearised errors mean nothing there)
MAX_REL_ERROR = 0.5
#: the two slopes are reported only when each is known to better than this share of its value; otherwise the one slope
#: over every load (a stiffness known to 30 % or worse on one side of a breakpoint is not a result a cell can use)
MAX_REL_ERROR_TWO_SLOPES = 0.3
#: Monte Carlo draws of the two-slope fit behind its stated errors (its breakpoint makes it nonlinear)
TWO_SLOPE_MC_DRAWS = 1000
#: a Monte Carlo spread this many times the linearised error means the linearisation failed (then it is the error)
NONLINEAR_FACTOR = 2.0


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


def _fit_fixed(T, unload, y, Tb, W=None):
    """Generalised linear LSQ for fixed breakpoints: y (..., n), Tb (..., g) -> coef (..., g, 4), whitened SSE
    (..., g).  ``W`` whitens the deflections' errors (``W C W^T = I``; None: unit weights)."""
    X = _design(T, unload, Tb)                                       # (..., g, n, 4)
    yy = y[..., None, :]
    if W is not None:
        X, yy = W @ X, yy @ W.T
    XtX = np.swapaxes(X, -1, -2) @ X
    Xty = np.swapaxes(X, -1, -2) @ yy[..., None]
    coef = np.linalg.solve(XtX + 1e-18 * np.eye(4), Xty)[..., 0]
    r = yy - (X @ coef[..., None])[..., 0]
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


def _search_range(T, min_side):
    Ts = np.unique(T)
    return Ts[min_side - 1], Ts[-min_side]


def _fit(T, unload, y, grid_n: int = 200, min_side: int = 2, W=None):
    """Vectorised two-slope estimator over leading batch dims of ``y`` -> ``(..., 5)`` [th0, off, c1, c2, Tb]:
    the breakpoint by its profile on a grid (linear LSQ for the rest), then Gauss-Newton on all five."""
    lo, hi = _search_range(T, min_side)
    grid = np.linspace(lo, hi, grid_n)
    coef, sse = _fit_fixed(T, unload, y, np.broadcast_to(grid, y.shape[:-1] + (grid_n,)), W)
    k = np.argmin(sse, -1)
    c = np.take_along_axis(coef, k[..., None, None], -2)[..., 0, :]
    p = np.concatenate([c, grid[k][..., None]], -1)
    for _ in range(6):                                      # Gauss-Newton polish on all five parameters
        J = _model_jac(p, T, unload)
        r = y - two_slope_model(p, T, unload)
        if W is not None:
            J, r = W @ J, r @ W.T
        A = np.swapaxes(J, -1, -2) @ J
        dp = np.linalg.solve(A + 1e-18 * np.eye(5), (np.swapaxes(J, -1, -2) @ r[..., None]))[..., 0]
        p = p + dp
        p[..., 4] = np.clip(p[..., 4], lo, hi)
    return p


def _outputs(p):
    th0, off, c1, c2, Tb = np.moveaxis(p, -1, 0)
    return np.stack([1.0 / c1, 1.0 / c2, Tb, off, th0], -1)


def _torque_cov(load_N, lever_mm, theta_i_rad, sigma_load_N, sigma_lever_mm, sigma_theta_i_rad) -> np.ndarray:
    """Covariance of the torques ``T = N L cos(theta_i)`` from the thesis's Delta N (each load), Delta L_j (one
    lever for the series: a common scale) and Delta theta_ij (each set-up angle), first order."""
    N, L, th = (np.asarray(v, float) for v in np.broadcast_arrays(load_N, lever_mm, theta_i_rad))
    sN, sth = (np.broadcast_to(np.asarray(v, float), N.shape) for v in (sigma_load_N, sigma_theta_i_rad))
    dT_dN = L * 1e-3 * np.cos(th)
    dT_dth = -N * L * 1e-3 * np.sin(th)
    dT_dL = N * 1e-3 * np.cos(th)
    return np.diag((dT_dN * sN) ** 2 + (dT_dth * sth) ** 2) + np.outer(dT_dL, dT_dL) * float(sigma_lever_mm) ** 2


def _profile_interval(T, u, y, W, min_side, Tb_hat, n_grid: int = 400):
    """Profile likelihood of the breakpoint: the range of Tb whose best chi^2 is within 1 of the minimum (the
    1-sigma interval), and whether its 2-sigma interval reaches an end of the search range (then the data do not
    determine it)."""
    lo, hi = _search_range(T, min_side)
    grid = np.union1d(np.linspace(lo, hi, n_grid), [Tb_hat])
    _, chi2 = _fit_fixed(T, u, y, grid, W)
    inside = grid[chi2 <= chi2.min() + 1.0]
    a, b = float(inside.min()), float(inside.max())
    wide = grid[chi2 <= chi2.min() + 4.0]            # the 2-sigma interval must stay inside the loads applied
    step = (hi - lo) / n_grid
    return a, b, bool(wide.min() <= lo + step or wide.max() >= hi - step)


def two_slope_fit(torque_Nm_, deflection_rad, unloading, sigma_deflection_rad, n_mc: int = 5000, rng=0, *,
                  load_N=None, lever_mm=None, theta_i_rad=0.0, sigma_load_N=0.0, sigma_lever_mm=0.0,
                  sigma_theta_i_rad=0.0, sigma_torque_Nm=None) -> EstimateSet:
    """Stiffness below and above a breakpoint, the breakpoint, and the unloading offset (dead zone), three ways.

    ``torque_Nm_ (n,)`` -- or ``load_N``, ``lever_mm``, ``theta_i_rad`` to compute ``T = N L cos(theta_i)`` --,
    ``deflection_rad (n,)`` (joint angle change from A1, A2), ``unloading (n,)`` bool (the decreasing-load series);
    ``sigma_deflection_rad``: scalar, one per reading, or their full covariance (angles measured with the same
    stations share their errors).  The thesis's error terms enter as the torques' covariance (Delta N per load,
    Delta L_j common to the series, Delta theta_ij per set-up; or ``sigma_torque_Nm`` directly), mapped into deflection
    through the fitted slopes (effective variance) before the generalised least-squares fit.

    The breakpoint comes from its profile likelihood.  When its 1-sigma interval reaches an end of the search range
    (the two slopes are not told apart), no breakpoint is reported: ``K1`` is then the single slope over every load,
    and ``K2`` and the breakpoint are listed in ``extras['not_determined']`` with the reason -- never a value at a
    bound with an error of 0.
    """
    step = "two-slope fit"
    y = np.asarray(deflection_rad, float).ravel()
    if load_N is not None:
        if lever_mm is None:
            raise EstimationError(PROC, step, "loads were given without their lever arm")
        T = torque_Nm(load_N, lever_mm, theta_i_rad) * np.ones(y.size)
        CT = _torque_cov(load_N, lever_mm, theta_i_rad, sigma_load_N, sigma_lever_mm, sigma_theta_i_rad)
        CT = np.broadcast_to(CT, (y.size, y.size)) if CT.size == 1 else CT
    else:
        T = np.asarray(torque_Nm_, float).ravel()
        CT = np.zeros((T.size, T.size)) if sigma_torque_Nm is None else error_covariance(PROC, "two-slope fit", sigma_torque_Nm, T.size)
    u = np.asarray(unloading, bool).ravel().astype(float)
    finite(PROC, step, torque=T, deflection=y)
    if not (T.size == y.size == u.size):
        raise EstimationError(PROC, step, "torque, deflection and unloading flags need one entry per reading")
    at_least(PROC, step, "distinct torques (3 each side of the breakpoint)", np.unique(T).size, 6)
    if not (u.any() and (1 - u).any()):
        raise EstimationError(PROC, step, "needs both a loading and an unloading series (for the dead zone)")
    Cy = error_covariance(PROC, step, sigma_deflection_rad, y.size)
    noise = float(np.sqrt(np.mean(np.diag(Cy))))
    if np.ptp(y) <= 3 * noise or np.ptp(y) == 0:
        raise EstimationError(PROC, step, f"the loads produced no measurable deflection (spread {np.ptp(y):.3g} rad "
                              f"vs noise {noise:.3g} rad): the stiffness is not determined")
    W = np.linalg.inv(np.linalg.cholesky(Cy))
    p = _fit(T, u, y, min_side=3, W=W)
    for _ in range(2):              # effective variance: torque errors through the fitted slopes
        S = np.where(T < p[4], p[2], p[3])
        C = Cy + S[:, None] * CT * S[None, :]
        W = np.linalg.inv(np.linalg.cholesky(C))
        p = _fit(T, u, y, min_side=3, W=W)
    a, b, at_bound = _profile_interval(T, u, y, W, 3, p[4])
    lo, hi = _search_range(T, 3)
    tol = 1e-3 * (hi - lo)
    if at_bound or not (lo + tol < p[4] < hi - tol):
        return _single_slope(T, u, y, C, a, b, n_mc, rng)
    if np.any(p[2:4] <= 0):
        raise EstimationError(PROC, step, "a fitted compliance is not positive: deflection does not grow with load")
    J = _model_jac(p, T, u)
    Cp = np.linalg.pinv(J.T @ np.linalg.solve(C, J))
    th0, off, c1, c2, Tb = p
    G = np.zeros((5, 5))
    G[0, 2], G[1, 3], G[2, 4], G[3, 1], G[4, 0] = -1 / c1 ** 2, -1 / c2 ** 2, 1, 1, 1
    res = propagate(lambda z: _outputs(_fit(T, u, z, min_side=3, W=W)), y, C, FIT_NAMES, FIT_UNITS, n_mc=n_mc,
                    rng=rng, first_order_cov=G @ Cp @ G.T, value=_outputs(p))
    # the fit is not linear in the breakpoint: with the breakpoint near the end of the loads, a breakpoint placed a
    # little wrong moves a slope far more than the linearised errors say (the demo's joint 4 read K1 at a quarter of
    # its Monte Carlo spread).  Where the central 68 % of the fit's own Monte Carlo spread is over twice the
    # linearised error, the linearisation has failed and that spread is the error; the breakpoint's error is at
    # least its profile-likelihood half-width
    spread = spread_sd(lambda z: _outputs(_fit(T, u, z, min_side=3, W=W)), y, C, TWO_SLOPE_MC_DRAWS, rng)
    for cov in (res.cov_gum, res.cov_first_order):
        if cov is not None:
            sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
            floor = np.where(spread > NONLINEAR_FACTOR * sd, spread, 0.0)
            floor[2] = max(floor[2], 0.5 * (b - a))
            widen(cov, floor)
    res.extras.update(residual_rad=y - two_slope_model(p, T, u), breakpoint_interval_Nm=(a, b), not_determined={})
    if any(res[k].error > MAX_REL_ERROR_TWO_SLOPES * abs(res[k].value) for k in ("K1_Nm_per_rad", "K2_Nm_per_rad")):
        return _single_slope(T, u, y, C, a, b, n_mc, rng, "a slope on one side of the breakpoint has an error over "
                             f"{MAX_REL_ERROR_TWO_SLOPES:.0%} of its value")
    return res


def single_slope_fit(torque_Nm_, deflection_rad, unloading, cov_rad2, n_mc: int = 0, rng=0) -> EstimateSet:
    """One stiffness over every load and the unloading offset, whatever the data say of a breakpoint: what
    :func:`two_slope_fit` reports when it cannot place the breakpoint, on demand.  Why: the truth of that estimate
    for simulated data is this fit on the noise-free deflections, with the same weights."""
    T = np.asarray(torque_Nm_, float).ravel()
    y = np.asarray(deflection_rad, float).ravel()
    u = np.asarray(unloading, bool).ravel().astype(float)
    C = error_covariance(PROC, "single-slope fit", cov_rad2, y.size)
    return _single_slope(T, u, y, C, float(T.min()), float(T.max()), n_mc, rng)


def _single_slope(T, u, y, C, a, b, n_mc, rng, reason: str = "") -> EstimateSet:
    """One stiffness over every load (the breakpoint is not determined), with the unloading offset."""
    X = np.stack([np.ones_like(T), u, T], -1)
    W = np.linalg.inv(np.linalg.cholesky(C))
    Xw = W @ X
    P = np.linalg.pinv(Xw.T @ Xw) @ Xw.T @ W           # coefficients = P y

    def f(z):
        c = z @ P.T
        return np.stack([1.0 / c[..., 2], c[..., 1], c[..., 0]], -1)

    c = P @ y
    Cc = P @ C @ P.T
    if c[2] <= 0 or np.sqrt(Cc[2, 2]) > MAX_REL_ERROR * c[2]:
        raise EstimationError(PROC, "two-slope fit", f"the stiffness is not determined: compliance {c[2]:.3g} +- "
                              f"{np.sqrt(Cc[2, 2]):.2g} rad/N m (the loads barely twist this joint at this pose: is "
                              f"its axis vertical, or the lever along the axis?)")
    G = np.array([[0, 0, -1 / c[2] ** 2], [0, 1, 0], [1, 0, 0]])
    names = ["K1_Nm_per_rad", "offset_rad", "theta0_rad"]
    res = propagate(f, y, C, names, ["N m/rad", "rad", "rad"], n_mc=n_mc, rng=rng, first_order_cov=G @ Cc @ G.T)
    why = reason or (f"its profile-likelihood interval ({a:.3g} .. {b:.3g} N m) reaches the end of the loads applied")
    why = f"the breakpoint is not determined: {why}, so the two slopes are not told apart; K1 is the single slope " \
          f"over every load"
    res.extras.update(residual_rad=y - X @ c, breakpoint_interval_Nm=(a, b), single_slope=True, cov_rad2=C,
                      torque_range_Nm=(float(T.min()), float(T.max())),
                      not_determined={"K2_Nm_per_rad": why, "breakpoint_Nm": why})
    return res
