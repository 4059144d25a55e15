"""Two theodolites by plain trigonometry (section 4.2, eq 4.3.1 and its inverse, section 5.3.1).

Station A at the origin, B at (L, 0, hB) on the X axis.  The thesis's interior angles are alpha at A and beta at B
from the baseline, phi the elevation.  The instruments read clockwise seen from above (Hz) and the zenith angle (V):
A's circle zero sits at yaw ``-gamma1`` and B's at ``pi + gamma2``, so ``Hz_A = -(alpha + gamma1)``,
``Hz_B = beta + gamma2`` (the thesis's alpha' = alpha + gamma1, beta' = beta + gamma2) and ``V = pi/2 - phi``.
"""
from __future__ import annotations

import numpy as np

TWO_PI = 2 * np.pi


def thesis_angles(points_mm, L_mm: float, height_b_mm: float = 0.0):
    """Interior angles alpha (at A), beta (at B) from the baseline and the elevations phi_A, phi_B of points (N, 3)."""
    X, Y, Z = np.atleast_2d(np.asarray(points_mm, float)).T
    alpha = np.arctan2(Y, X)              # tan^-1(Y / X), in the right quadrant when the point is behind A or B
    beta = np.arctan2(Y, L_mm - X)
    phi_a = np.arctan2(Z, np.hypot(X, Y))
    phi_b = np.arctan2(Z - height_b_mm, np.hypot(L_mm - X, Y))
    return alpha, beta, phi_a, phi_b


def station_angles(points_mm, L_mm: float, gamma1: float, gamma2: float, height_b_mm: float = 0.0):
    """(Hz_A, V_A, Hz_B, V_B) in radians that levelled, error-free instruments read for points (N, 3)."""
    alpha, beta, phi_a, phi_b = thesis_angles(points_mm, L_mm, height_b_mm)
    return (np.mod(-(alpha + gamma1), TWO_PI), np.pi / 2 - phi_a, np.mod(beta + gamma2, TWO_PI), np.pi / 2 - phi_b)


def leica_readings(points_mm, L_mm: float, gamma1: float, gamma2: float, height_b_mm: float = 0.0) -> np.ndarray:
    """(N, 4) readings Hz_A, V_A, Hz_B, V_B (see :func:`station_angles`)."""
    return np.stack(station_angles(points_mm, L_mm, gamma1, gamma2, height_b_mm), -1)


def face_two(hz, v):
    """The same sighting read on face II: ``Hz + 180 deg``, ``360 deg - V``."""
    return np.mod(np.asarray(hz) + np.pi, TWO_PI), TWO_PI - np.asarray(v)


def point_from_angles(alpha, beta, phi, L_mm: float) -> np.ndarray:
    """Eq 4.3.1 as printed: X = L tan b / (tan a + tan b), Y = L tan a tan b / (...), Z = L tan b tan phi /
    ((tan a + tan b) cos a)."""
    ta, tb = np.tan(alpha), np.tan(beta)
    X = L_mm * tb / (ta + tb)
    Y = L_mm * ta * tb / (ta + tb)
    Z = L_mm * tb * np.tan(phi) / ((ta + tb) * np.cos(alpha))
    return np.stack([X, Y, Z], -1)
