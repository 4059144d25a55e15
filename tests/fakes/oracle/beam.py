"""A link bending as a beam: the deflection of a clamped cantilever under point loads, by integrating
``EI y'' = M`` twice on a fine grid -- deliberately not the closed form ``P x^2 (3a - x) / (6 EI)`` the production
code uses, so a slip in either shows."""
from __future__ import annotations

import numpy as np


def cantilever_deflection(x_mm, a_mm, P_N, EI):
    """Deflection (mm) at x of a cantilever clamped at 0 under a point load P at a (N, N mm^2 for EI).

    Trapezoid rule, y(0) = y'(0) = 0; the arguments broadcast against each other."""
    grid = np.linspace(0.0, max(np.max(x_mm), np.max(a_mm)) * 1.001, 20001)
    out = []
    for x, a, P in np.broadcast(x_mm, a_mm, P_N):
        M = P * np.clip(a - grid, 0, None)                 # moment about the section at s: P (a - s) for s < a
        slope = np.concatenate([[0], np.cumsum(0.5 * (M[1:] + M[:-1]) * np.diff(grid))]) / EI
        y = np.concatenate([[0], np.cumsum(0.5 * (slope[1:] + slope[:-1]) * np.diff(grid))])
        out.append(np.interp(x, grid, y))
    return np.reshape(out, np.broadcast(x_mm, a_mm, P_N).shape)
