"""Joint compliance: eq 4.5.1 (division restored) and the two-slope loading/unloading fit (section 5.5.2)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.compliance import stiffness_single, to_lbin_per_rad, torque_Nm, two_slope_fit
from calib.units import DEG, LBIN_PER_NM, NM_PER_LBIN


def _series(K1_lbin, K2_lbin, Tb_lbin, rng, sigma=1e-6, offset=2e-5, n=15):
    K1, K2, Tb = (v * NM_PER_LBIN for v in (K1_lbin, K2_lbin, Tb_lbin))
    loads = np.linspace(0, 2.2 * Tb / 0.5, n)                       # newtons at 500 mm (section 5.5.2)
    T = torque_Nm(loads, 500.0, 0.0)
    T = np.r_[T, T[::-1]]
    unl = np.r_[np.zeros(n, bool), np.ones(n, bool)]
    th = np.minimum(T, Tb) / K1 + np.maximum(T - Tb, 0) / K2 + offset * unl
    return T, th + sigma * rng.standard_normal(T.size), unl


@pytest.mark.parametrize("K1,K2,Tb", [(1.156e5, 1.223e5, 100.0), (2.275e5, 1.698e5, 45.0)])
def test_thesis_stiffness_recovered_with_breakpoint_and_dead_zone(K1, K2, Tb):
    # section 5.5.2: K3 = 1.156e5 / 1.223e5 lb in/rad below / above 100 lb in; K4 = 2.275e5 / 1.698e5 about 45 lb in
    rng = np.random.default_rng(5)
    T, th, unl = _series(K1, K2, Tb, rng)
    res = two_slope_fit(T, th, unl, 1e-6, n_mc=3000, rng=1)
    for name, truth in (("K1_Nm_per_rad", K1 * NM_PER_LBIN), ("K2_Nm_per_rad", K2 * NM_PER_LBIN),
                        ("breakpoint_Nm", Tb * NM_PER_LBIN), ("offset_rad", 2e-5)):
        e = res[name]
        assert abs(e.value - truth) < 4 * e.error, (name, e)
        assert e.agreement() < 0.10, e
    assert to_lbin_per_rad(res["K1_Nm_per_rad"].value) == pytest.approx(K1, rel=0.02)
    assert res["K1_Nm_per_rad"].value * LBIN_PER_NM == pytest.approx(K1, rel=0.02)


def test_single_load_eq_4_5_1():
    res = stiffness_single(100.0, 500.0, 10 * DEG, 0.004, sigmas=(0.1, 0.5, 0.001, 2e-5), n_mc=20000)
    assert res.value[0] == pytest.approx(100 * 0.5 * np.cos(10 * DEG) / 0.004)
    assert res["K_Nm_per_rad"].agreement() < 0.10


def test_no_deflection_and_missing_series_refused():
    rng = np.random.default_rng(0)
    T, th, unl = _series(1.156e5, 1.223e5, 100.0, rng)
    with pytest.raises(EstimationError, match="joint compliance: two-slope fit: the loads produced no measurable"):
        two_slope_fit(T, np.zeros_like(th), unl, 1e-6)
    with pytest.raises(EstimationError, match="unloading"):
        two_slope_fit(T, th, np.zeros_like(unl), 1e-6)
    with pytest.raises(EstimationError, match="at least 6 distinct torques"):
        two_slope_fit(T[:3], th[:3], unl[:3], 1e-6)
    with pytest.raises(EstimationError, match="eq 4.5.1: the load produced no measurable deflection"):
        stiffness_single(100.0, 500.0, 0.0, 0.0)


def test_breakpoint_never_reported_at_a_bound_with_zero_error():
    rng = np.random.default_rng(4)
    K = 2.0e4
    T = np.r_[np.linspace(0, 40, 9), np.linspace(40, 0, 9)]
    u = np.r_[np.zeros(9), np.ones(9)].astype(bool)
    y = T / K + 1e-4 * u + 2e-5 * rng.standard_normal(18)          # one slope: no breakpoint to find
    res = two_slope_fit(T, y, u, 2e-5, n_mc=0)
    assert "breakpoint_Nm" not in res.names and "K2_Nm_per_rad" not in res.names
    assert "not determined" in res.extras["not_determined"]["breakpoint_Nm"]
    assert abs(res["K1_Nm_per_rad"].value - K) < 4 * res["K1_Nm_per_rad"].error
    assert all(e.error > 0 for e in res.estimates())
    with pytest.raises(EstimationError, match="not determined"):      # a load that twists nothing
        two_slope_fit(T, 1e-4 * u + 2e-5 * rng.standard_normal(18) + T * 1e-7, u, 2e-5, n_mc=0)
