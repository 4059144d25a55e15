"""Are the stated errors honest?  Over 200 seeded twin runs the 95 % intervals (estimate +- 1.96 x the error each
run computes from its own data) must cover the truth in 90-99 % of runs.  Vectorised: all runs in one batch."""
from __future__ import annotations

import numpy as np

from calib.estimators import compliance, ruler, transmission
from calib.estimators.chain import synthetic_cpa
from calib.uncertainty import coverage_fraction, gum_covariance, jacobian
from calib.units import ARCSEC, DEG, NM_PER_LBIN
from tests.fakes.cpa_session import from_synthetic

RUNS = 200


def _check(frac, names):
    bad = {n: f for n, f in zip(names, frac) if not 0.90 <= f <= 0.99}
    assert not bad, bad


def test_ruler_closed_form_coverage():
    s = ruler.simulate_sightings(1609.9, -1.489 * DEG, 1.358 * DEG, [((-300, 1200, 0.0), 0.0, 0.0)], [0, 930, 1860])
    x0 = np.r_[ruler.closed_form_readings(s), 1860.0, 930.0]
    sd = np.r_[[3 * ARCSEC] * 6, 0.05, 0.05]
    X = x0 + np.random.default_rng(100).standard_normal((RUNS, 8)) * sd
    est = ruler.closed_form(X)
    err = np.sqrt(np.diagonal(gum_covariance(jacobian(ruler.closed_form, X, sd * 0.1), np.diag(sd ** 2)), 0, -2, -1))
    _check(coverage_fraction(est, err, ruler.closed_form(x0)), ruler.CLOSED_NAMES)


def test_cpa_chain_coverage_ruler_points_axes_dh():
    s = synthetic_cpa(seed=1, n_points=4)
    X = from_synthetic(s).draw(np.random.default_rng(101), RUNS)     # readings by the oracle
    est = s.chain(X)
    sd = np.sqrt(np.diag(s.cov))
    J = jacobian(s.chain, X, 0.1 * sd)
    err = np.sqrt(np.diagonal(gum_covariance(J, s.cov), 0, -2, -1))
    _check(coverage_fraction(est, err, s.truth_dh()), s.chain.names()[0])


def test_transmission_error_coverage():
    rng = np.random.default_rng(102)
    th = np.radians(np.arange(-266, 266.1, 4.0))
    sig = 0.005 * DEG
    truth = np.array([1.8, 2 * np.pi / 1.8, 0.0, 0.047 * DEG, 0.0])
    y = 0.047 * DEG * np.sin(1.8 * th) + sig * rng.standard_normal((RUNS, th.size))
    W = np.eye(th.size)
    p0 = transmission._gn(np.array([1.8, 0.0, 0.047 * DEG, 0.0]), th, y[0], 1, W)
    p = transmission._gn(p0, th, y, 1, W)
    est = transmission._outputs(p, 1)
    err = np.empty_like(est)
    for i in range(RUNS):                          # first-order errors from each run's own fit (cheap: 4x4)
        J = transmission._model_jac(p[i], th, 1)
        G = transmission._jac_outputs(p[i], 1)
        err[i] = np.sqrt(np.diag(G @ (sig ** 2 * np.linalg.inv(J.T @ J)) @ G.T))
    _check(coverage_fraction(est, err, truth)[[0, 1, 3, 4]], ["omega", "period", "amplitude", "phase"])


def test_joint_compliance_coverage():
    rng = np.random.default_rng(103)
    K1, K2, Tb = 2.275e5 * NM_PER_LBIN, 1.698e5 * NM_PER_LBIN, 45 * NM_PER_LBIN
    T = compliance.torque_Nm(np.linspace(0, 2.2 * Tb / 0.5, 15), 500.0, 0.0)
    T = np.r_[T, T[::-1]]
    u = np.r_[np.zeros(15), np.ones(15)]
    sig = 1e-6
    y = np.minimum(T, Tb) / K1 + np.maximum(T - Tb, 0) / K2 + 2e-5 * u + sig * rng.standard_normal((RUNS, 30))
    p = compliance._fit(T, u, y, min_side=3)
    est = compliance._outputs(p)
    err = np.empty_like(est)
    for i in range(RUNS):
        J = compliance._model_jac(p[i], T, u)
        c1, c2 = p[i, 2], p[i, 3]
        G = np.zeros((5, 5))
        G[0, 2], G[1, 3], G[2, 4], G[3, 1], G[4, 0] = -1 / c1 ** 2, -1 / c2 ** 2, 1, 1, 1
        err[i] = np.sqrt(np.diag(G @ (sig ** 2 * np.linalg.inv(J.T @ J)) @ G.T))
    _check(coverage_fraction(est, err, [K1, K2, Tb, 2e-5, 0.0]), compliance.FIT_NAMES)
