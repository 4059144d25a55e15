"""Transmission error (thesis section 4.4, 5.4): the joint angle from two tool targets vs the encoder reading.

**Joint angle** (eq 4.4.1, generalised): the line A1->A2 of an extended tool, projected on the plane perpendicular to
the joint axis ``n`` (from :mod:`.axes`), turns with the joint; the angle turned from a reference pose is
``atan2(n . (v0 x v), v0 . v)``.  The thesis's eq 4.4.1 is the special case of an axis along a coordinate axis of
the compensated frame.  First order (B.7 drops the chain factors, so re-derived): with ``v_perp`` the projected
A1->A2, ``d theta = (n x v_perp) . (dA2 - dA1) / |v_perp|^2`` (minus the same for the reference pose).

**Error curve**: ``e(theta) = c + sum_k a_k sin(k w theta) + b_k cos(k w theta)`` with the fundamental ``w``
*estimated* (a periodogram-like profile over w, then Gauss-Newton on all parameters) and the number of harmonics
chosen by BIC.  The thesis's fits ``K_theta4 = 0.050 deg sin(0.9 theta4)`` and ``K_theta6 = 0.047 deg sin(1.8
theta6)`` have w = 0.9 and 1.8 (dimensionless: periods of 400 and 200 deg of joint angle).  First-order errors:
``sigma^2 (J^T J)^-1`` of the nonlinear model (sigma known, or from the residuals), amplitude
``A_k = sqrt(a_k^2 + b_k^2)`` by the chain rule.
"""
from __future__ import annotations

import numpy as np

from ..angles import wrap_angle
from ..uncertainty import EstimateSet, default_steps, jacobian, propagate, spread_sd, widen
from ._common import EstimationError, angles_in_range, at_least, error_covariance, finite
from .axes import fit_circle

PROC = "transmission error"


# -- joint angle from two targets ------------------------------------------------------------------------------
def joint_angle(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Vectorised: ``x (..., 12) = [A1_ref, A2_ref, A1, A2]`` (mm) -> ``(..., 1)`` angle (rad) turned about ``n``
    (``(3,)``, or ``(..., 3)`` broadcasting with ``x``: an axis that is itself estimated, per Monte Carlo draw)."""
    x = np.asarray(x, float)
    n = np.asarray(n, float)
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    v0 = x[..., 3:6] - x[..., 0:3]
    v = x[..., 9:12] - x[..., 6:9]
    return np.arctan2(np.sum(np.cross(v0, v) * n, -1),
                      np.sum(v0 * v, -1) - np.sum(v0 * n, -1) * np.sum(v * n, -1))[..., None]


def joint_angle_first_order(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Derived first-order Jacobian (1, 12) of :func:`joint_angle`."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    v0 = x[3:6] - x[0:3]
    v = x[9:12] - x[6:9]
    p0 = v0 - (v0 @ n) * n
    p = v - (v @ n) * n
    g = np.cross(n, p) / (p @ p)          # d theta / d v
    g0 = -np.cross(n, p0) / (p0 @ p0)     # d theta / d v0
    return np.concatenate([-g0, g0, -g, g])[None, :]


def joint_angles(A1_mm: np.ndarray, A2_mm: np.ndarray, cov_mm2: np.ndarray, axis_n: np.ndarray,
                 d_station: np.ndarray | None = None, station_cov: np.ndarray | None = None):
    """Angle turned about ``axis_n`` from the first pose, per pose, with the angles' covariance.

    ``A1_mm``, ``A2_mm`` (N, 3); ``cov_mm2`` (N, 6, 6) the reading-noise covariance of ``[A1, A2]`` of each pose;
    ``d_station (N, 6, P)`` their sensitivity to the stations' parameters and ``station_cov (P, P)`` those
    parameters' covariance (the term every pose shares).  First order (:func:`joint_angle_first_order`) in each
    pose's own targets: the reference pose's error is the same for every angle, an offset every fit of these angles
    absorbs.  Why not ``sqrt(trace)``: only the target motion across the A1->A2 line and the axis turns the angle;
    the along-line and axial components (the sight-line depth, the largest) do not.  Returns ``(angles (N,),
    cov (N, N))``.
    """
    A1, A2 = np.atleast_2d(np.asarray(A1_mm, float)), np.atleast_2d(np.asarray(A2_mm, float))
    n = np.asarray(axis_n, float) / np.linalg.norm(axis_n)
    x = np.concatenate([np.broadcast_to(np.r_[A1[0], A2[0]], (len(A1), 6)), A1, A2], -1)
    ang = joint_angle(x, n)[:, 0]
    g = np.stack([joint_angle_first_order(xi, n)[0, 6:] for xi in x])
    cov = np.diag(np.einsum("ni,nij,nj->n", g, np.asarray(cov_mm2, float), g))
    if d_station is not None and station_cov is not None and np.size(station_cov):
        G = np.einsum("ni,nip->np", g, np.asarray(d_station, float))
        cov = cov + G @ np.asarray(station_cov, float) @ G.T
    return ang, cov


def angles_about_fitted_axis(z, N: int, ref=None):
    """Targets ``z (..., 6N) = [A1_0, A2_0, A1_1, A2_1, ...]`` -> angles ``(..., N)`` turned about the axis of the
    circle through the A2 positions (the run's own axis), from the reference line ``ref = [A1, A2]`` (6,) -- default
    the first pose's own targets, so the first angle is 0."""
    pts = z.reshape(z.shape[:-1] + (N, 2, 3))
    n = fit_circle(pts[..., 1, :])[..., 3:6]
    if ref is None:
        ref = pts[..., :1, :, :].reshape(z.shape[:-1] + (1, 6))
    ref = np.broadcast_to(ref, z.shape[:-1] + (N, 6))
    x = np.concatenate([ref, pts.reshape(z.shape[:-1] + (N, 6))], -1)
    return joint_angle(x, n[..., None, :])[..., 0]


def joint_angles_fitted_axis(A1_mm: np.ndarray, A2_mm: np.ndarray, points_cov_mm2: np.ndarray):
    """:func:`joint_angles` about the run's own axis (the circle through the A2 positions, in sweep order), with the
    axis's error in the angles' covariance: ``(angles (N,), cov (N, N), axis_n (3,))``.

    Why: the axis and the angles come from the same targets, and a tilt of the fitted axis turns the A1->A2 line's
    component along the axis into a once-per-turn error of every angle -- an error a fit of order 0.9 (the Puma's
    joint 4) cannot tell from its own curve.  With the axis held fixed the joint-4 amplitude of the demo scattered
    1.5 times its stated error.  ``points_cov_mm2 (6N, 6N)`` is the targets' joint covariance in the order
    ``[A1_0, A2_0, A1_1, A2_1, ...]`` (the stations' common term included); it is propagated (central differences)
    through the circle fit and the angles together.  Each angle is measured from the first pose's line taken as a
    fixed reference, so every angle (the first too) carries its own targets' noise and the reference's error is an
    offset common to all, which a fit of these angles absorbs (as :func:`joint_angles`)."""
    A1, A2 = (np.atleast_2d(np.asarray(v, float)) for v in (A1_mm, A2_mm))
    N = len(A1)
    z = np.concatenate([A1, A2], -1).ravel()
    U = np.asarray(points_cov_mm2, float)
    ref = z[:6].copy()

    def f(v):
        return angles_about_fitted_axis(v, N, ref)

    G = jacobian(f, z, default_steps(z, U))
    n = fit_circle(A2)[3:6]
    return f(z[None])[0], G @ U @ G.T, n


def measure_joint_angle(A1_ref, A2_ref, A1, A2, axis_n, points_cov_mm2: np.ndarray, n_mc: int = 20_000,
                        rng=0) -> EstimateSet:
    """Angle turned by a joint between two poses of the targets A1, A2 (rad), errors three ways.

    ``points_cov_mm2 (12, 12)`` covers [A1_ref, A2_ref, A1, A2] (correlations through L, gamma included if known).
    """
    x = np.concatenate([np.asarray(v, float).ravel() for v in (A1_ref, A2_ref, A1, A2)])
    finite(PROC, "eq 4.4.1", targets=x, axis=axis_n)
    n = np.asarray(axis_n, float)
    for nm, a, b in (("reference", x[0:3], x[3:6]), ("measured", x[6:9], x[9:12])):
        d = b - a
        perp = d - (d @ n) * n / (n @ n)
        if np.linalg.norm(perp) < 1e-3:
            raise EstimationError(PROC, "eq 4.4.1", f"targets A1, A2 of the {nm} pose coincide or lie along the joint "
                                  "axis: their line does not turn with the joint")
    J = joint_angle_first_order(x, n)
    U = np.asarray(points_cov_mm2, float)
    return propagate(lambda z: joint_angle(z, n), x, U, ["theta_m_rad"], ["rad"], n_mc=n_mc, rng=rng,
                     first_order_cov=J @ U @ J.T)


def commanded_angle_errors(theta_measured_rad, cov_rad2, theta_desired_rad) -> EstimateSet:
    """Section 4.4's ``E_a = measured - desired`` per pose, with errors: angles turned from the first pose (measured
    from A1, A2, :func:`joint_angles`; ``cov_rad2`` their covariance) against the commanded ones.  Unlike a fit with
    an offset, ``E_a`` of one pose carries the first pose's error too, so the covariance used is that of the
    differences ``angle_i - angle_0``.  Reports ``E_a{i}_rad`` for poses 1.. and ``E_a_slope``, the least-squares
    proportional error of the commanded angle (a gear-ratio or scale error of the controller), with errors."""
    step = "E_a"
    m, d = (np.atleast_1d(np.asarray(v, float)).ravel() for v in (theta_measured_rad, theta_desired_rad))
    angles_in_range(PROC, step, limit_rad=8 * np.pi, measured=m, desired=d)
    if m.shape != d.shape:
        raise EstimationError(PROC, step, "one commanded angle per measured angle needed")
    at_least(PROC, step, "poses", m.size, 2)
    C = np.asarray(cov_rad2, float)
    C = np.diag(np.broadcast_to(C, m.shape).astype(float)) if C.ndim < 2 else C
    A = np.eye(m.size)[1:] - np.eye(m.size)[:1]                # rows: angle_i - angle_0
    K = A @ C @ A.T
    rel = (d - d[0])[1:]
    if np.all(rel == 0):
        raise EstimationError(PROC, step, "the commanded angles do not change: no E_a slope")
    Ki = np.linalg.inv(K)
    P = (rel @ Ki) / (rel @ Ki @ rel)                          # GLS slope through the origin

    def f(z):
        e = wrap_angle(z[..., 1:] - z[..., :1] - rel)      # measured angles wrap past 180 deg
        return np.concatenate([e, (e @ P)[..., None]], -1)

    names = [f"E_a{i}_rad" for i in range(1, m.size)] + ["E_a_slope"]
    return propagate(f, m, C, names, ["rad"] * (m.size - 1) + ["1"], n_mc=0)


def angle_errors(theta_measured_rad, theta_encoder_rad, theta_desired_rad=None) -> dict:
    """Section 4.4's two errors per pose: ``E_c = measured - controller (encoder) reading`` (the transmission error
    curve fitted below) and, when the commanded angles are given, ``E_a = measured - desired``."""
    m, e = (np.atleast_1d(np.asarray(v, float)) for v in (theta_measured_rad, theta_encoder_rad))
    angles_in_range(PROC, "joint angle errors", limit_rad=8 * np.pi, measured=m, encoder=e)
    if m.shape != e.shape:
        raise EstimationError(PROC, "joint angle errors", "one encoder reading per measured angle needed")
    out = {"E_c_rad": m - e}
    if theta_desired_rad is not None:
        d = np.atleast_1d(np.asarray(theta_desired_rad, float))
        angles_in_range(PROC, "joint angle errors", limit_rad=8 * np.pi, desired=d)
        out["E_a_rad"] = m - d
    return out


# -- harmonic error curve ----------------------------------------------------------------------------------------
def _basis(theta, w, H):
    """[1, sin(w t), cos(w t), ..., sin(H w t), cos(H w t)] for w (...,) -> (..., n, 1 + 2H)."""
    w = np.asarray(w, float)[..., None]
    cols = [np.ones(np.broadcast_shapes(theta.shape, w.shape))]
    for k in range(1, H + 1):
        cols += [np.sin(k * w * theta), np.cos(k * w * theta)]
    return np.stack(cols, -1)


def _solve(A, g):
    """``A x = g`` batched, never raising: a singular member (a vanished amplitude leaves omega free) gets the
    minimum-norm step through a tiny ridge, so one degenerate draw cannot take the whole stage down."""
    n = A.shape[-1]
    scale = np.sqrt(np.clip(np.diagonal(A, axis1=-2, axis2=-1), 1e-300, None))
    An = A / (scale[..., :, None] * scale[..., None, :])
    return np.linalg.solve(An + 1e-12 * np.eye(n), (g / scale)[..., None])[..., 0] / scale


def _linear(theta, y, w, H, W):
    """Generalised linear LSQ for fixed fundamentals ``w`` (...,): coefficients and whitened SSE (``W`` whitens the
    errors: ``W C W^T = I``)."""
    X = W @ _basis(theta, w, H)
    yw = y @ W.T
    XtX = np.swapaxes(X, -1, -2) @ X
    coef = _solve(XtX, (np.swapaxes(X, -1, -2) @ yw[..., None])[..., 0])
    r = yw - (X @ coef[..., None])[..., 0]
    return coef, np.sum(r * r, -1)


def _model(p, theta, H):
    return (_basis(theta, p[..., 0], H) @ p[..., 1:, None])[..., 0]


def _model_jac(p, theta, H, X=None):
    """d model / d [w, c, a1, b1, ...] (..., n, 2 + 2H).  ``X``: :func:`_basis` at ``p`` when the caller has it
    already (the fit's cost evaluated it): its sine and cosine columns are the very values the derivative in w needs,
    so no angle is evaluated twice."""
    X = _basis(theta, p[..., 0], H) if X is None else X
    dw = np.zeros(X.shape[:-1])
    for k in range(1, H + 1):
        a, b = p[..., 2 * k][..., None], p[..., 2 * k + 1][..., None]
        dw = dw + k * theta * (a * X[..., 2 * k] - b * X[..., 2 * k - 1])
    return np.concatenate([dw[..., None], X], -1)


def _profile(theta, y, H, w_grid, W):
    """Best w on a grid (linear LSQ for the rest) -> start parameters (2 + 2H,) [w, c, a1, b1, ...]."""
    coef, sse = _linear(theta, y[None, :], w_grid, H, W)
    k = int(np.argmin(sse))
    return np.concatenate([[w_grid[k]], coef[k]])


def _gn(p0, theta, y, H, W, iterations: int = 12):
    """Damped Gauss-Newton (Levenberg) on all parameters from ``p0``, vectorised over leading dims of ``y``.

    Monte Carlo draws and the GUM Jacobian's perturbations start from the estimate itself, so the estimator stays
    on one branch of the (multi-modal) profile in w and is smooth in the data.  A step that raises the cost is
    refused and the damping raised, so a draw cannot jump to another branch of the profile."""
    p = np.array(np.broadcast_to(p0, y.shape[:-1] + p0.shape[-1:]), float)
    lam = np.full(p.shape[:-1], 1e-9)

    def cost(q):
        # the basis at q is kept: the next step's Jacobian at an accepted q is built from it (one sine and cosine
        # per angle and step, not three; :func:`_model`'s very products, so the fit is the same to the last bit)
        X = _basis(theta, q[..., 0], H)
        r = (y - (X @ q[..., 1:, None])[..., 0]) @ W.T
        return np.sum(r * r, -1), r, X

    c, r, X = cost(p)
    eye = np.eye(p.shape[-1])
    for _ in range(iterations):
        J = W @ _model_jac(p, theta, H, X)
        A = np.swapaxes(J, -1, -2) @ J
        dp = _solve(A + lam[..., None, None] * np.diagonal(A, axis1=-2, axis2=-1)[..., None, :] * eye,
                    (np.swapaxes(J, -1, -2) @ r[..., None])[..., 0])
        cn, rn, Xn = cost(p + dp)
        better = np.isfinite(cn) & (cn <= c * (1 + 1e-12))
        p = np.where(better[..., None], p + dp, p)
        r = np.where(better[..., None], rn, r)
        c = np.where(better, cn, c)
        X = np.where(better[..., None, None], Xn, X)
        lam = np.clip(np.where(better, lam * 0.1, lam * 10.0), 1e-12, 1e6)
        if np.all(np.abs(dp) < 1e-13 * (1 + np.abs(p))):
            break
    neg = p[..., 0] < 0                     # sin(-w t) = -sin(w t): keep the fundamental positive
    p[..., 0] = np.abs(p[..., 0])
    p[..., 2::2] = np.where(neg[..., None], -p[..., 2::2], p[..., 2::2])
    return p


def _outputs(p, H):
    out = [p[..., 0], 2 * np.pi / p[..., 0], p[..., 1]]
    for k in range(1, H + 1):
        a, b = p[..., 2 * k], p[..., 2 * k + 1]
        out += [np.hypot(a, b), np.arctan2(b, a)]
    return np.stack(out, -1)


#: Monte Carlo draws behind the harmonic fit's stated errors
TE_MC_DRAWS = 400


def te_names(H):
    names = ["omega", "period_rad", "offset_rad"]
    units = ["1", "rad", "rad"]
    for k in range(1, H + 1):
        names += [f"amplitude{k}_rad", f"phase{k}_rad"]
        units += ["rad", "rad"]
    return names, units


def fit_transmission_error(theta_rad, error_rad, sigma_rad=None, max_harmonics: int = 3,
                           omega_range: tuple[float, float] | None = None, n_grid: int = 300,
                           n_mc: int = 5000, rng=0, max_omega_rel_error: float = 0.25) -> EstimateSet:
    """Harmonic fit of a transmission-error curve ``error(theta)`` with the fundamental estimated.

    ``theta_rad`` the encoder (or commanded) joint angle, ``error_rad`` measured minus encoder angle, ``sigma_rad``
    the 1-sigma of each error (scalar, one per angle, or their full covariance: angles measured with the same
    stations share those stations' errors; None: from the residuals).  The fit is generalised least squares.  The number of harmonics (0 .. ``max_harmonics``) is chosen by BIC, with ``omega``
    (the thesis's 0.9 in ``sin(0.9 theta)``) searched over ``omega_range`` (default: from half a cycle over the span
    to a quarter of the sampling limit).  Output: omega, period, offset, then amplitude and phase of each harmonic
    (``e = c + sum A_k sin(k w theta + phase_k)``).  ``extras['harmonics']`` is the chosen count.

    When the data cannot pin the order down (its 1-sigma above ``max_omega_rel_error`` of its value: a sweep shorter
    than a period confounds omega with the amplitude and phase), omega and the period are left out of the result and
    ``extras['not_determined']`` says why; the amplitude is then reported with the error that confounding gives it.
    """
    step = "harmonic fit"
    th = np.asarray(theta_rad, float).ravel()
    y = np.asarray(error_rad, float).ravel()
    angles_in_range(PROC, step, limit_rad=8 * np.pi, theta=th)
    finite(PROC, step, error=y)
    if th.size != y.size:
        raise EstimationError(PROC, step, f"one error per joint angle needed (got {th.size} angles, {y.size} errors)")
    at_least(PROC, step, "joint angles", th.size, 8)
    span = np.ptp(th)
    if span < np.radians(10):
        raise EstimationError(PROC, step, f"the joint angles span only {np.degrees(span):.2f} deg: too short to fit "
                              "a periodic error")
    known = sigma_rad is not None
    C = error_covariance(PROC, step, sigma_rad if known else 1.0, y.size)
    W = np.linalg.inv(np.linalg.cholesky(C))
    dth = np.median(np.diff(np.sort(th)))
    lo, hi = omega_range if omega_range else (np.pi / span, np.pi / max(dth, 1e-9) / 4)
    grid = np.linspace(lo, hi, n_grid)
    n = y.size
    # H = 1 locates the fundamental over the whole range; higher harmonic counts refine around it, so a sub-harmonic
    # with more terms cannot masquerade as the fundamental when the sweep covers less than a period
    p1 = _gn(_profile(th, y, 1, grid, W), th, y, 1, W)
    best = None
    for H in range(0, max_harmonics + 1):
        if 2 + 2 * H >= n - 2:
            break
        if H == 0:
            chi2, p, k_par = float(_linear(th, y[None], np.ones(1), 0, W)[1][0]), None, 1
        else:
            local = np.linspace(0.85 * p1[0], 1.15 * p1[0], 31)
            p = _gn(_profile(th, y, H, local, W), th, y, H, W) if H > 1 else p1
            chi2 = float(np.sum(((y - _model(p, th, H)) @ W.T) ** 2))
            k_par = 2 + 2 * H
        bic = chi2 + k_par * np.log(n) if known else n * np.log(max(chi2 / n, 1e-300)) + k_par * np.log(n)
        if best is None or bic < best[0] - 1e-9:
            best = (bic, H, p, chi2)
    _, H, p, chi2 = best
    if H == 0:
        raise EstimationError(PROC, step, "no periodic error is detectable above the measurement noise (BIC prefers "
                              "a constant)")
    amp = np.hypot(p[2], p[3])
    if not (0.5 * lo <= p[0] <= 2 * hi) or amp > 5 * np.ptp(y):
        raise EstimationError(PROC, step, f"the order of the error is not determined: the fit runs off to omega "
                              f"{p[0]:.3g} with amplitude {amp:.3g} rad (a sweep of {np.degrees(span):.0f} deg is "
                              f"much shorter than the period); sweep the joint further")
    C = C * (1.0 if known else chi2 / (n - (2 + 2 * H)))
    J = _model_jac(p, th, H)
    Cp = np.linalg.pinv(J.T @ np.linalg.solve(C, J))
    G = _jac_outputs(p, H)
    names, units = te_names(H)
    res = propagate(lambda z: _outputs(_gn(p, th, z, H, W), H), y, C, names, units,
                    n_mc=n_mc, rng=rng, first_order_cov=G @ Cp @ G.T, value=_outputs(p, H))
    # order, amplitude and phase are not linear in the data (a sweep shorter than a period trades the order against
    # the amplitude): each error is at least the fit's own Monte Carlo spread (central 68 %)
    spread = spread_sd(lambda z: _outputs(_gn(p, th, z, H, W), H), y, C, TE_MC_DRAWS, rng)
    for cov in (res.cov_gum, res.cov_first_order):
        if cov is not None:
            widen(cov, spread)
    res.extras.update(harmonics=H, sigma_rad=np.sqrt(np.diag(C)), residual_rad=y - _model(p, th, H),
                      not_determined={})
    w_err = res["omega"].error
    if not np.isfinite(w_err) or w_err > max_omega_rel_error * p[0]:
        why = (f"the order (omega {p[0]:.3g} +- {w_err:.2g}) is not determined: the sweep of "
               f"{np.degrees(span):.0f} deg does not separate it from the amplitude and phase; sweep further")
        keep = [k for k in names if k not in ("omega", "period_rad")]
        extras = res.extras
        res = res.subset(keep)
        res.extras = {**extras, "not_determined": {"omega": why, "period_rad": why}}
    return res


def _jac_outputs(p, H):
    m = 2 + 2 * H
    G = np.zeros((3 + 2 * H, m))
    G[0, 0] = 1
    G[1, 0] = -2 * np.pi / p[0] ** 2
    G[2, 1] = 1
    for k in range(1, H + 1):
        a, b = p[2 * k], p[2 * k + 1]
        A2 = a * a + b * b
        G[1 + 2 * k, [2 * k, 2 * k + 1]] = [a / np.sqrt(A2), b / np.sqrt(A2)]
        G[2 + 2 * k, [2 * k, 2 * k + 1]] = [-b / A2, a / A2]
    return G
