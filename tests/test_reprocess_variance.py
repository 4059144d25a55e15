"""The pose set's error terms from the transmission-error run (``pose_errors.te_run_variance``) and the floor of the
total variance (``pose_errors.floored_sigma``): refits are stood in for by a linear response whose sensitivity to the
order is known, so the propagated term can be checked against it."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import offline.reduction.pose_errors as rp
from calib.errors import RobocalError
from calib.identify import PointObservations

NAMES = ["a_mm", "transmission_error.j4.s1_rad", "transmission_error.j4.c1_rad", "held_mm"]
FREE = NAMES[:3]
SENS = np.array([2.0, -1.0, 0.5, 0.0])        # d theta / d order of the stand-in refit


def _case(monkeypatch, omega_sd=1.234567891e-6, fail=None, red=4.0):
    C = np.diag([0.3, 0.02, 0.05, 0.0]) ** 2 * red
    C[0, 1] = C[1, 0] = 0.001 * red
    ident = SimpleNamespace(theta=np.array([1.0, 0.01, 0.02, 5.0]), names=NAMES, free=FREE, cov=C,
                            reduced_chi2=red)
    res = SimpleNamespace(names=["omega", "amplitude1_rad", "phase1_rad"], value=np.array([0.9, 0.02, 0.3]),
                          cov=np.diag([omega_sd, 0.01, 0.2]) ** 2)
    priors = {"transmission_error.j4.s1_rad": (0.01, 0.01), "transmission_error.j4.c1_rad": (0.02, 0.01)}
    specs = ["transmission_error:4:0.9"]
    monkeypatch.setattr(rp, "pose_model", lambda robot, running, problems, sp: (sp, None, None))

    def refit(model, obs, **kw):
        order = float(model[0].rsplit(":", 1)[1])
        theta = ident.theta + SENS * (order - 0.9)
        if fail == "nan":
            theta[0] = np.nan
        if fail == "raise":
            raise RobocalError("singular")
        return SimpleNamespace(theta=theta)

    monkeypatch.setattr(rp, "identify", refit)
    problems = []
    add, prior = rp.te_run_variance(None, {"transmission": {4: res}}, specs, None, ident, priors, problems)
    return ident, res, priors, add, prior, problems


def test_order_sensitivity_divides_by_the_orders_as_written(monkeypatch):
    """A step of 1.2e-7 written with 8 significant digits is 0.90000012, not 0.9 + 1.234567891e-7: dividing the
    refits' difference by 2h made the sensitivity 3 % wrong here."""
    ident, res, priors, add, prior, problems = _case(monkeypatch)
    assert not problems
    U_omega = res.cov[0, 0]
    gain = [ident.cov[:, NAMES.index(n)] / (priors[n][1] ** 2 * ident.reduced_chi2) for n in priors]
    A, phi = 0.02, 0.3
    G = np.array([[1, 0, 0], [0, np.cos(phi), -A * np.sin(phi)], [0, np.sin(phi), A * np.cos(phi)]])
    U = G @ res.cov @ G.T
    J = np.stack([np.where(np.isin(NAMES, FREE), SENS, 0.0), *gain], -1)
    expect_prior = ident.reduced_chi2 * sum(g * g * priors[n][1] ** 2 for g, n in zip(gain, priors))
    np.testing.assert_allclose(prior, expect_prior, rtol=1e-12)
    np.testing.assert_allclose(add, np.einsum("pk,kl,pl->p", J, U, J) - expect_prior, rtol=1e-9, atol=1e-18)
    assert U_omega > 0


def test_prior_term_is_taken_out_at_the_fits_scale(monkeypatch):
    """``ident.cov`` is inflated by the reduced chi-square: the prior term it holds, and the one taken out, is
    ``scale g^2 sd^2`` -- the unscaled term left a quarter of it in at a reduced chi-square of 4."""
    *_, prior1, _ = _case(monkeypatch, red=1.0)
    *_, prior4, _ = _case(monkeypatch, red=4.0)
    np.testing.assert_allclose(prior4, 4.0 * prior1, rtol=1e-12)


@pytest.mark.parametrize("fail", ["nan", "raise"])
def test_a_failed_refit_keeps_the_prior_term_and_says_so(monkeypatch, fail):
    *_, add, prior, problems = _case(monkeypatch, fail=fail)
    assert np.all(add == 0) and np.all(prior == 0)
    assert len(problems) == 1 and "joint 4" in problems[0] and "independent-prior" in problems[0]


def test_floor_at_the_fits_own_variance_never_zero():
    var = np.array([4.0, -1.0, 0.5, np.nan, 1.0])
    fit = np.array([3.0, 2.0, 1.0, 1.0, 1.0])
    prior = np.array([1.0, 1.0, 0.2, 0.0, 1.5])
    sigma, hit = rp.floored_sigma(var, fit, prior)
    np.testing.assert_allclose(sigma, np.sqrt([4.0, 1.0, 0.8, 1.0, 1.0]))
    assert hit.tolist() == [False, True, True, True, False]
    assert np.all(sigma > 0)


def _station_case(monkeypatch, resolve):
    """Two station parameters (sd 0.1 and 0.2) moving every point along x; the re-solve stood in for by ``resolve``."""
    ident = SimpleNamespace(theta=np.array([1.0, 0.01, 0.02, np.inf]), names=NAMES, free=FREE)
    fit = SimpleNamespace(cov=np.diag([0.1, 0.2]) ** 2)
    D = [np.array([[1.0, 1.0], [0.0, 0.0], [0.0, 0.0]])] * 4
    obs = PointObservations(np.zeros((4, 6)), np.zeros((4, 3)))
    monkeypatch.setattr(rp, "identify", resolve)
    problems: list[str] = []
    return rp.station_variance(None, obs, D, ident, {}, fit, problems), problems


def test_station_term_follows_the_resolves_and_a_failure_is_said_not_a_silent_zero(monkeypatch):
    """The term is sum_k (G_k sd_k)^2 with G_k a parameter's shift per unit of station parameter k: the stand-in
    re-solve moves ``a_mm`` by 3x the points' shift.  A failed re-solve or an undefined free parameter is a line in
    problems, never a silent zero."""
    def linear(model, obs, theta0, **kw):
        t = np.array(theta0, float)
        t[0] += 3.0 * obs.points_mm[0, 0]
        return SimpleNamespace(theta=t)
    var, problems = _station_case(monkeypatch, linear)
    assert var[0] == pytest.approx(9.0 * (0.1 ** 2 + 0.2 ** 2)) and np.all(var[1:] == 0) and not problems

    def failing(model, obs, **kw):
        raise RobocalError("singular")
    var, problems = _station_case(monkeypatch, failing)
    assert np.all(var == 0) and len(problems) == 1 and "left out" in problems[0] and "singular" in problems[0]

    def undefined(model, obs, theta0, **kw):
        t = np.array(theta0, float)
        t[1] = np.nan
        return SimpleNamespace(theta=t)
    var, problems = _station_case(monkeypatch, undefined)
    assert len(problems) == 2 and "transmission_error.j4.s1_rad" in problems[0]
