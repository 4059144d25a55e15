"""The encoder-resolution run (thesis Fig 5.14, section 5.4.2): the joint angle one encoder count is worth.

The joint is stepped by a few counts at a time while the theodolites measure its angle from the targets A1, A2
(eq 4.4.1).  The slope of measured angle on counts is the resolution actually achieved at the joint (the design value
is ``2 pi / (counts per motor turn x gear ratio)``); the scatter about the line shows what the encoder cannot resolve.
Generalised least squares on the angles' covariance (the stations' errors are shared by every step), so the error of
the slope is honest; the intercept is the reference pose's own angle error.
"""
from __future__ import annotations

import numpy as np

from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, at_least, finite

PROC = "encoder resolution"


def design_resolution_rad(counts_per_rev: float, gear_ratio: float) -> float:
    """Joint radians per encoder count by design."""
    return float(2 * np.pi / abs(counts_per_rev * gear_ratio))


def encoder_resolution(counts, measured_rad, cov_rad2, design_rad_per_count: float | None = None,
                       n_mc: int = 0, rng=0) -> EstimateSet:
    """Slope of the measured joint angle on the encoder counts (rad per count) with its error; with the design value
    also the ratio measured / design (``scale``: 1 when the gear ratio and counts per turn are as described)."""
    step = "slope of angle on counts"
    c = np.asarray(counts, float).ravel()
    y = np.asarray(measured_rad, float).ravel()
    finite(PROC, step, counts=c, measured=y)
    if c.size != y.size:
        raise EstimationError(PROC, step, "one measured angle per encoder reading needed")
    at_least(PROC, step, "distinct encoder readings", np.unique(c).size, 3)
    C = np.asarray(cov_rad2, float)
    C = np.diag(np.broadcast_to(C, y.shape).astype(float)) if C.ndim < 2 else C      # variances given
    if C.shape != (y.size, y.size) or np.any(np.diag(C) <= 0):
        raise EstimationError(PROC, step, f"the angles' covariance must be {y.size}x{y.size} and positive")
    X = np.stack([np.ones_like(c), c - c[0]], -1)
    Ci = np.linalg.inv(C)
    P = np.linalg.solve(X.T @ Ci @ X, X.T @ Ci)                 # coefficients = P y

    def f(z):
        k = z @ P.T
        out = [k[..., 1], k[..., 0]]
        if design_rad_per_count:
            out.append(k[..., 1] / design_rad_per_count)
        return np.stack(out, -1)

    names = ["rad_per_count", "offset_rad"] + (["scale"] if design_rad_per_count else [])
    units = ["rad", "rad"] + (["1"] if design_rad_per_count else [])
    res = propagate(f, y, C, names, units, n_mc=n_mc, rng=rng)
    k = P @ y
    if abs(k[1]) <= 2 * res["rad_per_count"].error:
        raise EstimationError(PROC, step, "the measured angle does not follow the counts: the resolution is not "
                              "determined (step the joint over more counts)")
    r = y - X @ k
    res.extras.update(residual_rad=r, chi2=float(r @ Ci @ r), dof=y.size - 2)
    return res
