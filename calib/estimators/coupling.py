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


def coupling_from_repeats(runs: dict[str, tuple], sigma_reading_rad: float) -> EstimateSet:
    """sigma_jk of several couplings, each from repeated pairs of runs, with errors that include the scatter of the
    repeats (the servo's positioning repeatability), not only the encoder's quantisation.

    ``runs[name] = (theta_k_with (r,), theta_k_alone (r,), theta_j (r,))`` in radians; ``sigma_reading_rad`` the
    1-sigma of one encoder angle difference from quantisation alone (Type B, ``sqrt(2) S / sqrt(12)``).  Each factor
    is the mean of its repeats.  The scatter of ``theta_k,with - theta_k,alone`` about each pair's mean is pooled over
    all couplings (one robot, one encoder, one servo: one repeatability), with ``nu = sum (r - 1)`` degrees of freedom;
    its variance is inflated by ``nu / (nu - 2)`` (the variance of Student's t), so the 1-sigma stays a standard
    deviation with a handful of repeats.  The adopted variance is the larger of that (Type A) and the quantisation
    alone (Type B), over ``r theta_j^2``.  With single runs only the Type B term is available (``extras['type']``).
    """
    step = "eq 4.7.1 (repeats)"
    names, vals, r_count, tj2, ss, dof = [], [], [], [], 0.0, 0
    for name, (w, a, t) in runs.items():
        w, a, t = (np.atleast_1d(np.asarray(v, float)) for v in (w, a, t))
        finite(PROC, step, **{f"{name}_with": w, f"{name}_alone": a, f"{name}_theta_j": t})
        if not (w.size == a.size == t.size) or w.size == 0:
            raise EstimationError(PROC, step, f"{name}: one 'with', one 'alone' and one theta_j per repeat needed")
        if np.any(np.abs(t) < 1e-9):
            raise EstimationError(PROC, step, f"{name}: joint j was not moved (theta_j = 0)")
        ratio = (w - a) / t
        names.append(name)
        vals.append(float(np.mean(ratio)))
        r_count.append(w.size)
        tj2.append(float(np.mean(t * t)))
        d = (w - a) - np.mean(ratio) * t
        ss += float(np.sum(d * d))
        dof += w.size - 1
    type_b = 2 * sigma_reading_rad ** 2                    # with - alone: two differences
    var_a = ss / dof * dof / (dof - 2) if dof > 2 else 0.0
    var = max(var_a, type_b)
    cov = np.diag([var / (r * t2) for r, t2 in zip(r_count, tj2)])
    res = EstimateSet(names, np.array(vals), ["1"] * len(names), cov_first_order=cov)
    res.extras.update(type="A (pooled repeats)" if var_a > type_b else "B (quantisation)", dof=dof,
                      scatter_rad=float(np.sqrt(ss / dof)) if dof else None)
    return res


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


def further_correction(measured: EstimateSet, controller: dict[str, float]) -> EstimateSet:
    """Eq 4.7.2's check of the maker's compensation, from the coupling runs: the controller turns joint k's encoder
    into ``theta_k + sigma_jk theta_j`` with its own ``sigma_jk`` (the robot description's); the further correction the
    calibration model must supply is ``measured - controller`` per factor, with the measured factor's error (the
    controller's value is exact: it is what the controller computes with).  Names ``further{jk}``."""
    names = [n for n in measured.names if n in controller]
    if not names:
        raise EstimationError(PROC, "eq 4.7.2", "none of the measured factors has a controller value to check")
    sub = measured.subset(names)
    value = sub.value - np.array([controller[n] for n in names])
    return EstimateSet([n.replace("sigma", "further") for n in names], value, ["1"] * len(names),
                       cov_first_order=sub.cov.copy())


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
