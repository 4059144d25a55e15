"""Theodolite pre-calibration (thesis section 4.2, App A.1, B.1-B.2, Fig 5.4)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.ruler import (closed_form, closed_form_first_order, closed_form_readings, ruler_closed_form,
                                    ruler_lsq, simulate_sightings, thesis_linear_sum)
from calib.units import ARCSEC, DEG
from tests.fakes.oracle.chain import numeric_jacobian

L0, G1, G2 = 1609.9, -1.489 * DEG, 1.358 * DEG        # Fig 5.4 estimates


def _inputs(R=1860.0, Y=1200.0, X1=-300.0, r1=None):
    r1 = R / 2 if r1 is None else r1
    s = simulate_sightings(L0, G1, G2, [((X1, Y, 0.0), 0.0, 0.0)], [0.0, r1, R])
    return np.concatenate([closed_form_readings(s), [R, r1]])


def test_closed_form_recovers_truth_exactly():
    for R, Y, X1, r1 in ((1860, 1200, -300, 930), (1500, 2500, 200, 400), (1000, 900, -100, 700)):
        x = _inputs(R, Y, X1, r1)
        np.testing.assert_allclose(closed_form(x), [L0, G1, G2], atol=1e-9)


def test_first_order_expression_matches_numerical_jacobian():
    x = _inputs()
    Jn = numeric_jacobian(closed_form, x, np.r_[np.full(6, 1e-7), 1e-3, 1e-3])
    J = closed_form_first_order(x)
    np.testing.assert_allclose(J, Jn, rtol=1e-4, atol=1e-9 * np.abs(J).max())


def test_fig_5_4_estimation_errors_reproduced():
    # Fig 5.4 / section 5.2.2: R 1792-1860 mm, L ~ 1610 mm, 3" readings: dL ~ 0.3 mm, dgamma1 ~ 0.013 deg,
    # dgamma2 ~ 0.010 deg, all growing as R shrinks.  The thesis's figure is the linear sum of first-order terms
    # (eq B.1.4) -- reproduced here at Y = 1200 mm, X1 = -300 mm, ruler marks known to 0.05 mm.
    delta = np.r_[[3 * ARCSEC] * 6, 0.05, 0.05]
    e = np.array([thesis_linear_sum(_inputs(R), delta) for R in (1860.0, 1828.0, 1792.0)])
    dL, dg1, dg2 = e[0, 0], e[0, 1] / DEG, e[0, 2] / DEG
    assert 0.25 < dL < 0.35
    assert 0.011 < dg1 < 0.016
    assert 0.008 < dg2 < 0.013
    assert np.all(np.diff(e, axis=0) > 0)                  # errors grow as R decreases (Fig 5.4 trend)


def test_three_ways_agree_within_10_percent():
    x = _inputs()
    res = ruler_closed_form(x[:6], x[6], x[7], 3 * ARCSEC, 0.05, 0.05, n_mc=20000, rng=3)
    np.testing.assert_allclose(res.value, [L0, G1, G2], atol=1e-9)
    for e in res.estimates():
        assert e.agreement() < 0.10, e
    assert res["L_mm"].error == pytest.approx(0.13, abs=0.05)   # 1 sigma, smaller than the thesis's linear sum


def test_least_squares_all_sightings_both_faces():
    rng = np.random.default_rng(7)
    pl = [((-300, 1200, 0.0), 0.0, 0.0), ((-200, 1600, 150.0), 0.1, 0.05), ((100, 1000, -100.0), -0.15, 0.0)]
    marks = [0, 600, 1200, 1860]
    s = simulate_sightings(L0, G1, G2, pl, marks, faces=(1, 2), sigma_rad=3 * ARCSEC, rng=rng, hB_mm=12.0,
                           collimation_rad=(10 * ARCSEC, -5 * ARCSEC), index_rad=(4 * ARCSEC, 0.0))
    res = ruler_lsq(s, marks, 3 * ARCSEC, marks_cov_mm2=np.eye(4) * 0.05 ** 2, n_mc=200, rng=1)
    truth = {"L_mm": L0, "gamma1_rad": G1, "gamma2_rad": G2, "hB_mm": 12.0, "collimA_rad": 10 * ARCSEC}
    for k, v in truth.items():
        e = res[k]
        assert abs(e.value - v) < 4 * e.error, (k, e)
        assert abs(e.error_gum / e.error_first_order - 1) < 0.05
        assert abs(e.error_mc / e.error_first_order - 1) < 0.25     # 200 draws: ~10 % sampling error on a sigma
    assert 0.5 < res.extras["chi2"] / res.extras["dof"] < 2.0
    # every sighting beats one placement's closed form
    x = np.concatenate([closed_form_readings(s, 0), [1860.0, 600.0]])
    assert res["L_mm"].error < ruler_closed_form(x[:6], 1860.0, 600.0, 3 * ARCSEC, 0.05, 0.05, n_mc=0)["L_mm"].error


def test_bad_input_is_refused_with_a_clear_message():
    x = _inputs()
    with pytest.raises(EstimationError, match="ruler: closed form: .*coincide"):
        ruler_closed_form(np.r_[x[0], x[0], x[2:6]], x[6], x[7], 3 * ARCSEC)
    with pytest.raises(EstimationError, match="non-finite"):
        ruler_closed_form(np.r_[np.nan, x[1:6]], x[6], x[7], 3 * ARCSEC)
    with pytest.raises(EstimationError, match="degrees"):
        ruler_closed_form(np.degrees(x[:6]) + 400, x[6], x[7], 3 * ARCSEC)
    with pytest.raises(EstimationError, match="r1 < R"):
        ruler_closed_form(x[:6], 500.0, 900.0, 3 * ARCSEC)
    s = simulate_sightings(L0, G1, G2, [((-300, 1200, 0.0), 0.0, 0.0)], [0, 930, 1860])
    assert ruler_lsq(s, [0, 930, 1860], 3 * ARCSEC)["L_mm"].value == pytest.approx(L0, abs=1e-6)
    keep = s.station == 0
    from calib.estimators.ruler import RulerSightings
    s2 = RulerSightings(s.placement[keep], s.mark[keep], s.station[keep], s.face[keep], s.hz_rad[keep], s.v_rad[keep])
    with pytest.raises(EstimationError, match="ruler: least squares: needs at least"):
        ruler_lsq(s2, [0, 930, 1860], 3 * ARCSEC)
