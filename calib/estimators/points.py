"""Point coordinates from two sightings (thesis eq 4.3.1, App A.2, B.3), with their joint covariance.

``X = L tan(b) / (tan(a) + tan(b))``, ``Y = X tan(a)``, ``Z = sqrt(X^2 + Y^2) tan(phi)`` with ``a = alpha' - gamma1``,
``b = beta' - gamma2`` (sine form used: finite at 90 deg).  Every point shares L, gamma1, gamma2, so the points of one
session are *correlated*; :func:`points_from_readings` returns the full ``3N x 3N`` covariance, which the axis and DH
fits need to be honest about (a scale error in L moves every circle centre the same way).

First-order expressions (App B.3, re-derived where printed wrong): ``dX/dL = X/L``,
``dX/da = -X (1 + tan^2 a) / (tan a + tan b)``, ``dX/db = L tan a (1 + tan^2 b) / (tan a + tan b)^2`` (the printed
B.3 drops the square), ``dY = tan a dX + X (1 + tan^2 a) da``, ``dZ = tan(phi) (X dX + Y dY) / rho + rho (1 + tan^2
phi) dphi``, and ``da = d alpha' - d gamma1``, ``db = d beta' - d gamma2``.
"""
from __future__ import annotations

import numpy as np

from ..theodolite import thesis_xyz
from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, angles_in_range, at_least, finite

PROC = "points"


def point_xyz(x: np.ndarray) -> np.ndarray:
    """Vectorised eq 4.3.1: ``x (..., 6) = [alpha', beta', phi, L, gamma1, gamma2]`` -> ``(..., 3)`` mm."""
    x = np.asarray(x, float)
    ap, bp, ph, L, g1, g2 = np.moveaxis(x, -1, 0)
    return thesis_xyz(ap - g1, bp - g2, ph, L)


def point_first_order(x: np.ndarray) -> np.ndarray:
    """App B.3 Jacobian ``d(X, Y, Z)/d(alpha', beta', phi, L, gamma1, gamma2)``, shape ``(..., 3, 6)``."""
    x = np.asarray(x, float)
    ap, bp, ph, L, g1, g2 = np.moveaxis(x, -1, 0)
    a, b = ap - g1, bp - g2
    ta, tb = np.tan(a), np.tan(b)
    X, Y, Z = np.moveaxis(point_xyz(x), -1, 0)
    rho = np.hypot(X, Y)
    dX_dL = X / L
    dX_da = -X * (1 + ta ** 2) / (ta + tb)
    dX_db = L * ta * (1 + tb ** 2) / (ta + tb) ** 2
    z = np.zeros_like(X)
    # derivatives w.r.t. (a, b, phi, L)
    dX = np.stack([dX_da, dX_db, z, dX_dL], -1)
    dY = ta[..., None] * dX + np.stack([X * (1 + ta ** 2), z, z, z], -1)
    dZ = (np.tan(ph) / rho)[..., None] * (X[..., None] * dX + Y[..., None] * dY) \
        + np.stack([z, z, rho * (1 + np.tan(ph) ** 2), z], -1)
    Jabp = np.stack([dX, dY, dZ], -2)                       # (..., 3, 4) w.r.t. (a, b, phi, L)
    # chain to (alpha', beta', phi, L, gamma1, gamma2): a = alpha' - gamma1, b = beta' - gamma2
    C = np.zeros((4, 6))
    C[0, 0], C[0, 4] = 1, -1
    C[1, 1], C[1, 5] = 1, -1
    C[2, 2] = 1
    C[3, 3] = 1
    return Jabp @ C


def _check(ap, bp, ph, theo):
    step = "eq 4.3.1"
    angles_in_range(PROC, step, alpha_prime=ap, beta_prime=bp, phi=ph)
    finite(PROC, step, theodolite_parameters=theo)
    if np.any(np.abs(ph) >= np.pi / 2 - 1e-6):
        raise EstimationError(PROC, step, "an elevation phi is at or beyond +-90 deg (point straight above A)")
    L, g1, g2 = theo
    if L <= 0:
        raise EstimationError(PROC, step, f"baseline L must be positive (got {L} mm)")
    a, b = ap - g1, bp - g2
    bad = (a <= 1e-6) | (b <= 1e-6) | (a + b >= np.pi - 1e-6)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise EstimationError(PROC, step, f"sightings of point {i} do not intersect in front of both stations "
                              f"(alpha {np.degrees(a[i]):.4f} deg, beta {np.degrees(b[i]):.4f} deg)")


def points_from_readings(alpha_p_rad, beta_p_rad, phi_rad, theo_value, theo_cov, sigma_reading_rad: float,
                         n_mc: int = 20_000, rng=0) -> EstimateSet:
    """Coordinates of N points (eq 4.3.1) with their joint ``3N x 3N`` covariance three ways.

    ``theo_value = [L_mm, gamma1_rad, gamma2_rad]`` and ``theo_cov`` (3x3) from the ruler pre-calibration;
    ``sigma_reading_rad`` the 1-sigma noise of each reading.  Output names ``P{i}.X_mm`` ...
    """
    ap, bp, ph = (np.atleast_1d(np.asarray(v, float)).ravel() for v in (alpha_p_rad, beta_p_rad, phi_rad))
    if not (ap.size == bp.size == ph.size):
        raise EstimationError(PROC, "eq 4.3.1", f"alpha', beta', phi must have one reading per point "
                              f"(got {ap.size}, {bp.size}, {ph.size})")
    at_least(PROC, "eq 4.3.1", "point", ap.size, 1)
    theo = np.asarray(theo_value, float).ravel()
    _check(ap, bp, ph, theo)
    N = ap.size
    x = np.concatenate([np.stack([ap, bp, ph], -1).ravel(), theo])
    U = np.zeros((3 * N + 3, 3 * N + 3))
    U[:3 * N, :3 * N] = np.eye(3 * N) * sigma_reading_rad ** 2
    U[3 * N:, 3 * N:] = np.asarray(theo_cov, float)
    f = lambda z: points_vectorised(z, N)
    J1 = points_jacobian_first_order(x, N)
    names = [f"P{i}.{c}_mm" for i in range(N) for c in "XYZ"]
    return propagate(f, x, U, names, ["mm"] * 3 * N, n_mc=n_mc, rng=rng, first_order_cov=J1 @ U @ J1.T,
                     jac=None)


def points_vectorised(z: np.ndarray, N: int) -> np.ndarray:
    """``z (..., 3N + 3) = [alpha'_0, beta'_0, phi_0, ..., L, gamma1, gamma2]`` -> ``(..., 3N)`` coordinates."""
    z = np.asarray(z, float)
    rd = z[..., :3 * N].reshape(z.shape[:-1] + (N, 3))
    th = np.broadcast_to(z[..., None, 3 * N:], z.shape[:-1] + (N, 3))
    return point_xyz(np.concatenate([rd, th], -1)).reshape(z.shape[:-1] + (3 * N,))


def points_jacobian_first_order(x: np.ndarray, N: int) -> np.ndarray:
    """Analytic (App B.3) Jacobian of all N points w.r.t. readings and (L, gamma1, gamma2): ``(3N, 3N + 3)``."""
    rd = x[:3 * N].reshape(N, 3)
    th = np.broadcast_to(x[3 * N:], (N, 3))
    Jp = point_first_order(np.concatenate([rd, th], -1))        # (N, 3, 6)
    J = np.zeros((3 * N, 3 * N + 3))
    for i in range(N):
        J[3 * i:3 * i + 3, 3 * i:3 * i + 3] = Jp[i, :, :3]
        J[3 * i:3 * i + 3, 3 * N:] = Jp[i, :, 3:]
    return J
