"""Joint axes from a swept target: least-squares plane and circle over any number (>= 3) of points.

Thesis sections 4.3.1-4.3.2 locate a joint from 3-4 positions of a target while that joint turns: the orientation
from two extreme points (eq 4.3.2, whose printed forms conflict with App B.4) and the centre from the circle through
three points (A.3; B.5.2 is garbled).  Here instead (circle point analysis):

1. **plane**: the centroid and the smallest right-singular vector of the centred points give the plane of the circle
   and so the axis direction; collinear or coincident points are refused;
2. **circle**: an algebraic (Kasa) circle in that plane starts a geometric (orthogonal-distance) fit of the 3-D
   circle -- centre ``c``, unit normal ``n``, radius ``r`` -- minimising, per point, its distance from the plane and
   its in-plane distance from the circle;
3. the normal's sign follows the right-hand rule of the sweep: points must be given in the order of increasing
   joint angle, so ``n`` is the joint's positive rotation axis.

With exactly three points this is the thesis's circle through three points.  Everything is vectorised over leading
batch dimensions (Monte Carlo draws, the GUM Jacobian's perturbations, 200 coverage runs at once).

First-order covariance (the thesis's B.4-B.5 are garbled, so derived here): the fit minimises ``|r(theta, P)|^2`` with
residual Jacobians ``J = dr/dtheta`` and ``G = dr/dP``, so ``cov(theta) = A^-1 J^T G U_P G^T J A^-1`` with
``A = J^T J`` (the sandwich form: right for any point covariance ``U_P``, including the correlations the shared
L, gamma1, gamma2 put between points).
"""
from __future__ import annotations

import numpy as np

from ..uncertainty import EstimateSet, propagate, require_finite
from ._common import EstimationError, at_least, finite

PROC = "axes"
AXIS_NAMES = ["c_x_mm", "c_y_mm", "c_z_mm", "n_x", "n_y", "n_z", "r_mm"]
AXIS_UNITS = ["mm", "mm", "mm", "1", "1", "1", "mm"]


def _plane(P):
    """Centroid, in-plane basis e1, e2, normal n0 and singular values of points (..., N, 3)."""
    m = P.mean(-2)
    Q = P - m[..., None, :]
    _, s, Vt = np.linalg.svd(Q, full_matrices=False)
    return m, Vt[..., 0, :], Vt[..., 1, :], Vt[..., 2, :], s


def _kasa(u, v):
    """Algebraic circle in 2-D (batched): centre (a, b) and radius."""
    A = np.stack([2 * u, 2 * v, np.ones_like(u)], -1)
    y = u * u + v * v
    AtA = np.swapaxes(A, -1, -2) @ A
    sol = np.linalg.solve(AtA, (np.swapaxes(A, -1, -2) @ y[..., None]))[..., 0]
    a, b, c = sol[..., 0], sol[..., 1], sol[..., 2]
    return a, b, np.sqrt(np.clip(c + a * a + b * b, 0, None))


def _unpack(q, n0, e1, e2):
    c = q[..., :3]
    n = n0 + q[..., 3:4] * e1 + q[..., 4:5] * e2
    n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return c, n, q[..., 5]


def _residual(q, P, n0, e1, e2):
    """Out-of-plane distance and in-plane radial misfit of every point: (..., 2N)."""
    c, n, r = _unpack(q, n0, e1, e2)
    d = P - c[..., None, :]
    h = np.sum(d * n[..., None, :], -1)
    rho = np.linalg.norm(d - h[..., None] * n[..., None, :], axis=-1)
    return np.concatenate([h, rho - r[..., None]], -1)


def _basis_batched(n):
    ref = np.where((np.abs(n[..., 0]) < 0.9)[..., None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = np.cross(n, ref)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    return e1, np.cross(n, e1)


def _circle_gn(P, c, n, r, iterations):
    """Gauss-Newton on the orthogonal-distance circle with the analytic Jacobian, re-based on the current normal
    every iteration (tilts t1, t2 of n along e1, e2 are then zero at the linearisation point, so the Jacobian is
    exact).  Batched over leading dimensions."""
    for _ in range(iterations):
        e1, e2 = _basis_batched(n)
        d = P - c[..., None, :]
        h = np.sum(d * n[..., None, :], -1)
        w = d - h[..., None] * n[..., None, :]
        rho = np.linalg.norm(w, axis=-1)
        er = w / rho[..., None]
        res = np.concatenate([h, rho - r[..., None]], -1)
        zero = np.zeros_like(h)
        Jh = np.concatenate([np.broadcast_to(-n[..., None, :], d.shape), np.sum(d * e1[..., None, :], -1)[..., None],
                             np.sum(d * e2[..., None, :], -1)[..., None], zero[..., None]], -1)
        Jr = np.concatenate([-er, (-h * np.sum(er * e1[..., None, :], -1))[..., None],
                             (-h * np.sum(er * e2[..., None, :], -1))[..., None], -np.ones_like(h)[..., None]], -1)
        J = np.concatenate([Jh, Jr], -2)
        A = np.swapaxes(J, -1, -2) @ J
        g = np.swapaxes(J, -1, -2) @ res[..., None]
        dp = -np.linalg.solve(A, g)[..., 0]
        c = c + dp[..., :3]
        n = n + dp[..., 3:4] * e1 + dp[..., 4:5] * e2
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
        r = r + dp[..., 5]
        if np.all(np.abs(dp[..., :3]) < 1e-10 * (1 + np.abs(r[..., None]))) and np.all(np.abs(dp[..., 3:5]) < 1e-13):
            break
    return c, n, r


def fit_circle(P: np.ndarray, iterations: int = 10) -> np.ndarray:
    """Vectorised 3-D circle fit: points ``(..., N, 3)`` in sweep order -> ``(..., 7) = [c (3), n (3), r]``.

    No input checks (see :func:`fit_axis`); returns NaN for degenerate members of a batch.
    """
    P = np.asarray(P, float)
    m, e1, e2, n0, _ = _plane(P)
    Q = P - m[..., None, :]
    u, v = np.sum(Q * e1[..., None, :], -1), np.sum(Q * e2[..., None, :], -1)
    a, b, r0 = _kasa(u, v)
    c0 = m + a[..., None] * e1 + b[..., None] * e2
    c, n, r = _circle_gn(P, c0, n0, r0, iterations)
    # right-hand rule of the sweep: consecutive radius vectors turn positively about n
    d = P - c[..., None, :]
    turn = np.sum(np.cross(d[..., :-1, :], d[..., 1:, :]), -2)
    sgn = np.where(np.sum(turn * n, -1) < 0, -1.0, 1.0)
    return np.concatenate([c, n * sgn[..., None], r[..., None]], -1)


def fit_circle_flat(x: np.ndarray, N: int) -> np.ndarray:
    """:func:`fit_circle` on flattened points ``(..., 3N)`` (the form the generic propagation needs)."""
    x = np.asarray(x, float)
    return fit_circle(x.reshape(x.shape[:-1] + (N, 3)))


def circle_first_order(P: np.ndarray, theta: np.ndarray, U_P: np.ndarray) -> np.ndarray:
    """Sandwich covariance (7x7) of ``[c, n, r]`` from the point covariance ``U_P (3N, 3N)`` (derived, see module)."""
    P = np.asarray(P, float)
    N = len(P)
    c, n, r = theta[:3], theta[3:6], theta[6]
    # local parameterisation: c (3), two tilts of n along e1, e2 (orthonormal to n), r
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    d = P - c
    h = d @ n
    w = d - h[:, None] * n
    rho = np.linalg.norm(w, axis=1)
    er = w / rho[:, None]                                       # radial unit vectors
    J = np.zeros((2 * N, 6))
    J[:N, :3] = -n
    J[:N, 3] = d @ e1
    J[:N, 4] = d @ e2
    J[N:, :3] = -er
    # d rho / d tilt: rho changes with n through h: d rho = -(h/rho) (w . dn) ... = -h (er . e_k)
    J[N:, 3] = -h * (er @ e1)
    J[N:, 4] = -h * (er @ e2)
    J[N:, 5] = -1.0
    G = np.zeros((2 * N, 3 * N))
    for i in range(N):
        G[i, 3 * i:3 * i + 3] = n
        G[N + i, 3 * i:3 * i + 3] = er[i]
    Ainv = np.linalg.inv(J.T @ J)
    H = Ainv @ J.T @ G                                          # d(local params)/dP
    # map local params to the reported [c, n, r]: dn = e1 t1 + e2 t2
    M = np.zeros((7, 6))
    M[:3, :3] = np.eye(3)
    M[3:6, 3] = e1
    M[3:6, 4] = e2
    M[6, 5] = 1.0
    K = M @ H
    return K @ U_P @ K.T


def check_sweep(P: np.ndarray, sigma_mm: float = 0.0, min_span_deg: float = 5.0, joint: str = "") -> None:
    """Refuse point sets that cannot define a circle: too few, coincident, collinear, or a sweep too short."""
    step = f"circle fit{(' of ' + joint) if joint else ''}"
    P = np.asarray(P, float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise EstimationError(PROC, step, f"points must be an (N, 3) array, got shape {P.shape}")
    finite(PROC, step, points=P)
    at_least(PROC, step, "target positions", len(P), 3)
    tol = max(1e-6 * max(np.ptp(P, axis=0).max(), 1.0), 3 * sigma_mm)
    dist = np.linalg.norm(P[:, None] - P[None], axis=-1)
    distinct = sum(1 for i in range(len(P)) if np.all(dist[i, :i] > tol))
    if distinct < 3:
        raise EstimationError(PROC, step, f"only {distinct} distinct target positions (others coincide within "
                              f"{tol:.3g} mm); a circle needs 3")
    _, _, _, _, s = _plane(P)
    if s[1] <= max(1e-9 * s[0], 3 * sigma_mm * np.sqrt(len(P))):
        raise EstimationError(PROC, step, "the target positions are collinear (within the measurement noise): "
                              "no circle is defined; sweep the joint further")
    theta = fit_circle(P)
    c, n = theta[:3], theta[3:6]
    d = P - c
    d = d - np.outer(d @ n, n)
    ang = np.arctan2(np.cross(d[:-1], d[1:]) @ n, np.sum(d[:-1] * d[1:], 1))
    span = np.degrees(np.sum(np.abs(ang)))
    if span < min_span_deg:
        raise EstimationError(PROC, step, f"the sweep spans only {span:.2f} deg (< {min_span_deg} deg): too short "
                              "to define a circle")


def fit_axis(points_mm: np.ndarray, points_cov_mm2: np.ndarray, n_mc: int = 20_000, rng=0,
             joint: str = "", min_span_deg: float = 5.0) -> EstimateSet:
    """Axis of a joint from the target's positions ``(N, 3)`` (sweep order) with their ``(3N, 3N)`` covariance.

    Returns centre ``c_*_mm``, unit direction ``n_*`` and radius ``r_mm`` with covariances three ways; extras
    carry the fit residuals (out-of-plane and radial, mm), the sweep span and the plane's singular values.
    """
    P, U, theta = _checked_circle(points_mm, points_cov_mm2, joint, min_span_deg)
    N = len(P)
    x = P.ravel()
    cov1 = circle_first_order(P, theta, U)
    res = propagate(lambda z: fit_circle_flat(z, N), x, U, _axis_names(joint), AXIS_UNITS, n_mc=n_mc, rng=rng,
                    first_order_cov=cov1, value=theta)
    res.extras["residual_mm"] = _residual(np.r_[theta[:3], 0, 0, theta[6]], P, theta[3:6], *_basis(theta[3:6]))
    return res


def check_axis(points_mm: np.ndarray, points_cov_mm2: np.ndarray, joint: str = "",
               min_span_deg: float = 5.0) -> np.ndarray:
    """:func:`fit_axis`'s refusals without its errors (the circle's Jacobian over every coordinate): the points define
    a circle, the covariance fits them, the circle is finite -- for a caller that needs the points checked but takes
    the axis's error through its own propagation (the transmission run's angles).  Returns ``[c, n, r]``."""
    _, _, theta = _checked_circle(points_mm, points_cov_mm2, joint, min_span_deg)
    require_finite(theta, _axis_names(joint))
    return theta


def _axis_names(joint: str) -> list[str]:
    return [f"{joint}.{k}" if joint else k for k in AXIS_NAMES]


def _checked_circle(points_mm, points_cov_mm2, joint: str, min_span_deg: float):
    """The points and covariance as arrays, checked (:func:`check_sweep`, the covariance's shape), and the circle."""
    P = np.asarray(points_mm, float)
    U = np.asarray(points_cov_mm2, float)
    sig = float(np.sqrt(np.mean(np.diag(U)))) if U.size else 0.0
    check_sweep(P, sig, min_span_deg, joint)
    N = len(P)
    if U.shape != (3 * N, 3 * N):
        raise EstimationError(PROC, f"circle fit{(' of ' + joint) if joint else ''}",
                              f"point covariance must be {3 * N}x{3 * N}, got {U.shape}")
    return P, U, fit_circle(P)


def _basis(n):
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)
