"""Wrist cross coupling (section 4.7, 5.6.3)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.coupling import (check_compensation, coupling_factor, coupling_from_streams,
                                       quantisation_sigma)
from calib.units import DEG


def test_thesis_coupling_factors():
    q = quantisation_sigma(0.01 * DEG)
    # section 5.6.3: joint-6 encoder 11.711 deg with joint 5, 9.909 deg without, for 10 deg of joint 5 -> 0.1802
    s56 = coupling_factor(11.711 * DEG, 9.909 * DEG, 10.0 * DEG, q, name="sigma56", n_mc=20000)
    assert s56["sigma56"].value == pytest.approx(0.1802, abs=1e-4)
    assert abs(s56["sigma56"].value - 0.1806) < 0.001                  # manufacturer's value [33, 34]
    assert s56["sigma56"].agreement() < 0.10
    # 10.040 vs 9.909 deg for 10 deg of joint 4 -> sigma46 = 0.0131
    assert coupling_factor(10.040 * DEG, 9.909 * DEG, 10 * DEG, q, n_mc=0).value[0] == pytest.approx(0.0131, abs=1e-4)
    # sigma45: the printed readings (10.073 vs 9.934 deg) give 0.0139; the thesis prints Delta = 0.141 -> 0.0141
    s45 = coupling_factor(10.073 * DEG, 9.934 * DEG, 10 * DEG, q, n_mc=0).value[0]
    assert s45 == pytest.approx(0.0139, abs=1e-4)
    assert s45 != pytest.approx(0.0141, abs=1e-4)                     # the printed value is the slip


def test_streams_recover_coupling_and_errors_agree():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 2.0, 201)
    theta = 10 * DEG * t / 2.0                                         # both runs: commanded 0 -> 10 deg
    res_q = 0.002 * DEG
    alone = np.round((theta + 1e-4 * rng.standard_normal(t.size)) / res_q) * res_q
    with_ = np.round((theta + 0.1802 * theta + 1e-4 * rng.standard_normal(t.size)) / res_q) * res_q
    r = coupling_from_streams(t, with_, theta, t, alone, np.hypot(1e-4, quantisation_sigma(res_q)), n_mc=5000)
    e = r[r.names[0]]
    assert abs(e.value - 0.1802) < 4 * e.error
    assert e.agreement() < 0.10


def test_compensation_check_eq_4_7_2():
    tj = np.radians(np.linspace(0, 10, 11))
    tk = np.radians(np.linspace(0, 10, 11))
    enc = tk + 0.1802 * tj
    out = check_compensation(enc, tk, tj, 0.1806)                     # manufacturer's factor
    assert out["further_correction"] == pytest.approx(-0.0004, abs=1e-9)


def test_bad_coupling_input():
    with pytest.raises(EstimationError, match="coupling: eq 4.7.1: joint j was not moved"):
        coupling_factor(0.2, 0.1, 0.0, 1e-5)
    with pytest.raises(EstimationError, match="non-finite"):
        coupling_factor(np.nan, 0.1, 0.1, 1e-5)
    t = np.linspace(0, 1, 5)
    with pytest.raises(EstimationError, match="did not move"):
        coupling_from_streams(t, t, np.zeros(5), t, t, 1e-5)
