"""The encoder-resolution run (thesis Fig 5.14, section 5.4.2): the joint angle one encoder count is worth.

The joint is stepped by a few counts at a time while the theodolites measure its angle from the targets A1, A2
(eq 4.4.1).  The slope of measured angle on counts is the resolution actually achieved at the joint (the design value
is ``2 pi / (counts per motor turn x gear ratio)``); the scatter about the line shows what the encoder cannot resolve.
Generalised least squares on the angles' covariance (the stations' errors are shared by every step), so the error of
the slope is honest; the intercept is the reference pose's own angle error.

The angles are measured about the joint's axis, and a session fits that axis from the run's own A2 positions
(:func:`encoder_resolution_fitted_axis`): a tilted axis changes every angle (the A1->A2 line has a component along the
axis, which a tilt turns into a rotating offset), and the same A2 readings fix both the axis and the angles.  So the
slope is a function of every located target -- circle fit, then angles, then the GLS line -- and its error is the
targets' full covariance propagated through all three (the axis's error and its correlation with the angles
included), not the angles' covariance about a fixed axis.
"""
from __future__ import annotations

import numpy as np

from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, at_least, finite
from .axes import check_axis
from .transmission import angles_about_fitted_axis, joint_angle_first_order

PROC = "encoder resolution"
STEP = "slope of angle on counts"


def design_resolution_rad(counts_per_rev: float, gear_ratio: float) -> float:
    """Joint radians per encoder count by design."""
    return float(2 * np.pi / abs(counts_per_rev * gear_ratio))


def _line(counts, n_angles: int, cov_rad2):
    """Checked counts, the design matrix ``[1, c - c0]``, the angles' covariance and the GLS operator ``P``
    (coefficients ``[offset, slope] = P y``)."""
    c = np.asarray(counts, float).ravel()
    finite(PROC, STEP, counts=c)
    if c.size != n_angles:
        raise EstimationError(PROC, STEP, "one measured angle per encoder reading needed")
    at_least(PROC, STEP, "distinct encoder readings", np.unique(c).size, 3)
    C = np.asarray(cov_rad2, float)
    C = np.diag(np.broadcast_to(C, c.shape).astype(float)) if C.ndim < 2 else C      # variances given
    if C.shape != (c.size, c.size) or np.any(np.diag(C) <= 0):
        raise EstimationError(PROC, STEP, f"the angles' covariance must be {c.size}x{c.size} and positive")
    X = np.stack([np.ones_like(c), c - c[0]], -1)
    Ci = np.linalg.inv(C)
    return X, Ci, np.linalg.solve(X.T @ Ci @ X, X.T @ Ci)


def _outputs(k, design_rad_per_count):
    """``[rad_per_count, offset_rad(, scale)]`` from line coefficients ``k (..., 2)``."""
    out = [k[..., 1], k[..., 0]]
    if design_rad_per_count:
        out.append(k[..., 1] / design_rad_per_count)
    return np.stack(out, -1)


def _names(design_rad_per_count):
    names = ["rad_per_count", "offset_rad"] + (["scale"] if design_rad_per_count else [])
    return names, ["rad", "rad"] + (["1"] if design_rad_per_count else [])


def _finish(res: EstimateSet, y, X, Ci, P) -> EstimateSet:
    k = P @ y
    if abs(k[1]) <= 2 * res["rad_per_count"].error:
        raise EstimationError(PROC, STEP, "the measured angle does not follow the counts: the resolution is not "
                              "determined (step the joint over more counts)")
    r = y - X @ k
    res.extras.update(residual_rad=r, chi2=float(r @ Ci @ r), dof=y.size - 2)
    return res


def encoder_resolution(counts, measured_rad, cov_rad2, design_rad_per_count: float | None = None,
                       n_mc: int = 0, rng=0) -> EstimateSet:
    """Slope of the measured joint angle on the encoder counts (rad per count) with its error; with the design value
    also the ratio measured / design (``scale``: 1 when the gear ratio and counts per turn are as described).  The
    angles are taken as measured about a known axis (their covariance ``cov_rad2`` is all there is)."""
    y = np.asarray(measured_rad, float).ravel()
    finite(PROC, STEP, measured=y)
    X, Ci, P = _line(counts, y.size, cov_rad2)
    names, units = _names(design_rad_per_count)
    res = propagate(lambda z: _outputs(z @ P.T, design_rad_per_count), y, np.linalg.inv(Ci), names, units,
                    n_mc=n_mc, rng=rng)
    return _finish(res, y, X, Ci, P)


def encoder_resolution_fitted_axis(counts, A1_mm, A2_mm, points_cov_mm2, design_rad_per_count: float | None = None,
                                   n_mc: int = 0, rng=0, joint: str = "") -> EstimateSet:
    """:func:`encoder_resolution` of a run whose axis is fitted from its own A2 positions (what a session does).

    ``A1_mm``, ``A2_mm`` (N, 3) per step in step order (increasing joint angle: the axis's sign follows the sweep);
    ``points_cov_mm2 (6N, 6N)`` the joint covariance of ``[A1_0, A2_0, A1_1, A2_1, ...]`` with the stations' common
    term.  The line is weighted with the angles' covariance from each step's own targets (as
    :func:`calib.estimators.transmission.joint_angles`); its error propagates the targets' covariance through the
    axis fit, the angles and the line together.  ``extras``: ``angle_rad``, ``angle_cov_rad2`` (the weights),
    ``axis_n``, residuals.  ``joint`` names the joint in a refusal."""
    A1, A2 = (np.atleast_2d(np.asarray(v, float)) for v in (A1_mm, A2_mm))
    finite(PROC, STEP, A1=A1, A2=A2)
    N = len(A1)
    if A2.shape != A1.shape or A1.shape[-1] != 3:
        raise EstimationError(PROC, STEP, "A1 and A2 need one (x, y, z) each per step")
    U = np.asarray(points_cov_mm2, float)
    if U.shape != (6 * N, 6 * N):
        raise EstimationError(PROC, STEP, f"the targets' covariance must be {6 * N}x{6 * N}")
    at_least(PROC, STEP, "steps with A1 and A2", N, 3)
    iA2 = (np.arange(N)[:, None] * 6 + np.arange(3, 6)).ravel()
    n = check_axis(A2, U[np.ix_(iA2, iA2)], joint=joint)[3:6]         # the points lie on a circle: its axis
    z = np.concatenate([A1, A2], -1).ravel()
    y = angles_about_fitted_axis(z, N)
    G = np.zeros((N, 6 * N))
    for i in range(N):
        xi = np.r_[A1[0], A2[0], A1[i], A2[i]]
        G[i, 6 * i:6 * i + 6] = joint_angle_first_order(xi, n)[0, 6:]
    X, Ci, P = _line(counts, N, G @ U @ G.T)
    names, units = _names(design_rad_per_count)
    res = propagate(lambda v: _outputs(angles_about_fitted_axis(v, N) @ P.T, design_rad_per_count), z, U, names,
                    units, n_mc=n_mc, rng=rng)
    res.extras.update(angle_rad=y, angle_cov_rad2=np.linalg.inv(Ci), axis_n=n)
    return _finish(res, y, X, Ci, P)
