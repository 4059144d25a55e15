"""Wrist cross coupling from tapped encoder readings (thesis section 4.7, 5.6).

``sigma_jk = (theta_k,with - theta_k,alone) / theta_j``: joint k's encoder reading when joint j turns through
``theta_j`` together with k, minus its reading when k turns alone through the same commanded angle, per unit of
joint j.  Eq 4.7.1 prints ``360 S_k xi_k / theta_j``: the factor 360 is stray (the worked example of section 5.6 is
``1.802 deg / 10 deg = 0.1802``), and ``S_k xi_k`` (resolution x counts) is just the encoder angle.

The thesis's printed sigma45 (0.0141) comes from "Delta = 0.141 deg", but its own readings (10.073 - 9.934 deg)
give 0.139 deg, i.e. sigma45 = 0.0139.

Errors: each encoder reading carries quantisation ``S/sqrt(12)`` (S = degrees per count) plus any reading noise;
first order ``d sigma = (d with - d alone)/theta_j - Delta d theta_j / theta_j^2`` (section 5.6.1 says none is
needed; derived here).  Eq 4.7.2 (``theta_k,enc = theta_k + sigma_jk theta_j``) checks a manufacturer's
compensation: :func:`check_compensation` returns the further correction the calibration model must supply.
"""
from __future__ import annotations

import numpy as np

from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, at_least, finite

PROC = "coupling"


def _ratio(x):
    x = np.asarray(x, float)
    return ((x[..., 0] - x[..., 1]) / x[..., 2])[..., None]


def coupling_factor(theta_k_with_rad: float, theta_k_alone_rad: float, theta_j_rad: float,
                    sigma_reading_rad: float, sigma_theta_j_rad: float = 0.0, name: str = "sigma_jk",
                    n_mc: int = 20_000, rng=0) -> EstimateSet:
    """sigma_jk from one pair of runs (section 5.6.3), errors three ways.  Angles in radians; sigma dimensionless."""
    step = "eq 4.7.1"
    x = np.array([theta_k_with_rad, theta_k_alone_rad, theta_j_rad], float)
    finite(PROC, step, readings=x)
    if abs(theta_j_rad) < 1e-9:
        raise EstimationError(PROC, step, "joint j was not moved (theta_j = 0): no coupling can be computed")
    U = np.diag([sigma_reading_rad ** 2, sigma_reading_rad ** 2, sigma_theta_j_rad ** 2])
    d = x[0] - x[1]
    J = np.array([[1 / x[2], -1 / x[2], -d / x[2] ** 2]])
    return propagate(_ratio, x, U, [name], ["1"], n_mc=n_mc, rng=rng, first_order_cov=J @ U @ J.T)


def quantisation_sigma(rad_per_count: float) -> float:
    """Standard uncertainty of a reading from a counter with resolution ``rad_per_count`` (uniform, GUM 4.3.7)."""
    return rad_per_count / np.sqrt(12.0)


def _slope(x, n):
    """Least-squares slope of d = k_with - k_alone on theta_j (with intercept): x = [d (n), theta_j (n)]."""
    d, t = x[..., :n], x[..., n:]
    tm, dm = t.mean(-1, keepdims=True), d.mean(-1, keepdims=True)
    return (np.sum((t - tm) * (d - dm), -1) / np.sum((t - tm) ** 2, -1))[..., None]


def coupling_from_streams(time_with_s, theta_k_with_rad, theta_j_with_rad, time_alone_s, theta_k_alone_rad,
                          sigma_reading_rad: float, name: str = "sigma_jk", n_mc: int = 20_000,
                          rng=0) -> EstimateSet:
    """sigma_jk from encoder streams: joint k's stream with j moving is compared, at the same times, with its
    stream when k moves alone; the difference regressed on joint j's angle gives the slope sigma_jk.

    Uses every sample (not just the end points) so the quantisation averages down; the first-order error is the
    regression's ``sigma^2 (X^T X)^-1`` with the known reading noise on both streams.
    """
    step = "encoder streams"
    tw, kw, jw = (np.asarray(v, float).ravel() for v in (time_with_s, theta_k_with_rad, theta_j_with_rad))
    ta, ka = (np.asarray(v, float).ravel() for v in (time_alone_s, theta_k_alone_rad))
    finite(PROC, step, time_with=tw, theta_k_with=kw, theta_j_with=jw, time_alone=ta, theta_k_alone=ka)
    if not (tw.size == kw.size == jw.size) or ta.size != ka.size:
        raise EstimationError(PROC, step, "each stream needs one reading per time stamp")
    at_least(PROC, step, "samples per stream", min(tw.size, ta.size), 3)
    if np.any(np.diff(ta) <= 0) or np.any(np.diff(tw) <= 0):
        raise EstimationError(PROC, step, "time stamps must increase")
    inside = (tw >= ta[0]) & (tw <= ta[-1])
    at_least(PROC, step, "overlapping samples between the two runs", int(inside.sum()), 3)
    tw, kw, jw = tw[inside], kw[inside], jw[inside]
    if np.ptp(jw) < 1e-9:
        raise EstimationError(PROC, step, "joint j did not move in the combined run")
    d = kw - np.interp(tw, ta, ka)
    n = d.size
    x = np.concatenate([d, jw])
    U = np.zeros((2 * n, 2 * n))
    U[:n, :n] = np.eye(n) * 2 * sigma_reading_rad ** 2      # difference of two readings
    tc = jw - jw.mean()
    var1 = 2 * sigma_reading_rad ** 2 / np.sum(tc ** 2)
    return propagate(lambda z: _slope(z, n), x, U, [name], ["1"], n_mc=n_mc, rng=rng,
                     first_order_cov=np.array([[var1]]))


def check_compensation(theta_k_encoder_rad, theta_k_rad, theta_j_rad, sigma_jk: float) -> dict:
    """Eq 4.7.2: the encoder of k should read ``theta_k + sigma_jk theta_j`` when j and k turn together.

    Returns the predicted readings, the residual (measured - predicted) and the further correction factor
    (least-squares slope of the residual on theta_j) the calibration model must add to the manufacturer's.
    """
    enc, tk, tj = (np.atleast_1d(np.asarray(v, float)) for v in (theta_k_encoder_rad, theta_k_rad, theta_j_rad))
    finite(PROC, "eq 4.7.2", encoder=enc, theta_k=tk, theta_j=tj)
    pred = tk + sigma_jk * tj
    res = enc - pred
    if np.allclose(tj, 0):
        raise EstimationError(PROC, "eq 4.7.2", "joint j was not moved: the compensation cannot be checked")
    extra = float(np.sum(res * tj) / np.sum(tj * tj))
    return {"predicted_rad": pred, "residual_rad": res, "further_correction": extra}
