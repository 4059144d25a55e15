"""Transmission error: joint angle from two targets (eq 4.4.1) and the harmonic fit (section 5.4.2)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.transmission import angle_errors, fit_transmission_error, measure_joint_angle
from calib.units import DEG


@pytest.mark.parametrize("amp_deg,omega,lo,hi", [(0.050, 0.9, -110, 170), (0.047, 1.8, -266, 266)])
def test_thesis_te_curves_recovered_with_estimated_fundamental(amp_deg, omega, lo, hi):
    # section 5.4.2: K_theta4 = 0.050 deg sin(0.9 theta4) (period 400 deg), K_theta6 = 0.047 deg sin(1.8 theta6)
    rng = np.random.default_rng(8)
    th = np.radians(np.arange(lo, hi + 0.1, 2.0))
    sig = 0.003 * DEG
    e = amp_deg * DEG * np.sin(omega * th) + 0.01 * DEG + sig * rng.standard_normal(th.size)
    res = fit_transmission_error(th, e, sigma_rad=sig, n_mc=2000, rng=1)
    assert res.extras["harmonics"] == 1
    for name, truth in (("omega", omega), ("amplitude1_rad", amp_deg * DEG), ("period_rad", 2 * np.pi / omega)):
        x = res[name]
        assert abs(x.value - truth) < 4 * x.error, (name, x)
        assert x.agreement() < 0.10, x
    assert np.degrees(res["period_rad"].value) == pytest.approx(360 / omega, rel=0.05)


def test_two_harmonics_chosen_by_the_data():
    rng = np.random.default_rng(2)
    th = np.radians(np.arange(-180, 180.1, 2.0))
    e = DEG * (0.05 * np.sin(1.8 * th) + 0.02 * np.sin(3.6 * th + 0.5)) + 0.002 * DEG * rng.standard_normal(th.size)
    res = fit_transmission_error(th, e, sigma_rad=0.002 * DEG, n_mc=0)
    assert res.extras["harmonics"] == 2
    assert res["amplitude2_rad"].value == pytest.approx(0.02 * DEG, rel=0.1)


def test_joint_angle_from_two_targets():
    n = np.array([0.0, 0.1, 1.0])
    n /= np.linalg.norm(n)
    e1 = np.cross(n, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    ang = 0.3
    A1r, A2r = np.array([400.0, 2500, 0]), np.array([400.0, 2500, 0]) + 300 * e1 + 40 * n
    A1 = A1r
    A2 = A1r + 300 * (np.cos(ang) * e1 + np.sin(ang) * e2) + 40 * n
    res = measure_joint_angle(A1r, A2r, A1, A2, n, np.eye(12) * 0.05 ** 2, n_mc=20000)
    assert res.value[0] == pytest.approx(ang, abs=1e-12)
    assert res["theta_m_rad"].agreement() < 0.10
    assert res.error[0] == pytest.approx(np.sqrt(4) * 0.05 / 300, rel=0.05)   # 4 independent in-plane errors / 300 mm


def test_bad_te_input():
    th = np.radians(np.arange(0, 100, 2.0))
    with pytest.raises(EstimationError, match="transmission error: harmonic fit: no periodic error"):
        fit_transmission_error(th, 1e-6 * np.random.default_rng(0).standard_normal(th.size), sigma_rad=1e-6)
    with pytest.raises(EstimationError, match="too short"):
        fit_transmission_error(np.radians(np.linspace(0, 5, 20)), np.zeros(20))
    with pytest.raises(EstimationError, match="out of range"):
        fit_transmission_error(np.degrees(th) * 10, np.zeros(th.size))
    with pytest.raises(EstimationError, match="along the joint axis"):
        measure_joint_angle([0, 0, 0], [0, 0, 100], [0, 0, 0], [10, 0, 0], [0, 0, 1], np.eye(12))


def test_angle_errors_section_4_4():
    out = angle_errors([0.101, 0.2], [0.1, 0.2005], [0.1, 0.2])
    np.testing.assert_allclose(out["E_c_rad"], [0.001, -0.0005])
    np.testing.assert_allclose(out["E_a_rad"], [0.001, 0.0])
    with pytest.raises(EstimationError, match="joint angle errors"):
        angle_errors([0.1, 0.2], [0.1])


def _fit_or_refusal(th, e, sigma_rad, seed):
    """The fit, or None when it refuses because no periodic error stands above the noise (any other error fails)."""
    try:
        return fit_transmission_error(th, e, sigma_rad=sigma_rad, n_mc=200, rng=seed)
    except EstimationError as exc:
        assert "no periodic error is detectable above the measurement noise" in str(exc), exc
        return None


def test_fit_decides_by_the_error_size_and_monte_carlo_error_is_stable():
    """Short sweeps, noise 0.01 deg: no error is refused as undetectable; an error 5x the noise is found, its
    amplitude within 4 sigma of the truth; one half the noise is either refused the same way or found consistent with
    the truth (never a LinAlgError, never a confident wrong amplitude)."""
    th = np.radians(np.arange(-110, 110.1, 5.0))
    seen = set()
    for seed in range(30):
        rng = np.random.default_rng(seed)
        amp = rng.choice([0.0, 0.005, 0.05]) * DEG
        e = amp * np.sin(0.9 * th + rng.uniform(-3, 3)) + 0.01 * DEG * rng.standard_normal(th.size)
        res = _fit_or_refusal(th, e, 0.01 * DEG, seed)
        if amp == 0.0:
            assert res is None, (seed, res)
        elif amp == 0.05 * DEG:
            assert res is not None, seed
        if res is not None:
            a = res["amplitude1_rad"]
            assert abs(a.value - amp) < 4 * a.error, (seed, amp, a.value, a.error)
        seen.add((float(amp), res is None))
    assert {(0.0, True), (0.05 * DEG, False)} <= seen                 # both decisive cases were drawn
    th = np.radians(np.arange(-266, 266.1, 8.0))
    e = 0.047 * DEG * np.sin(1.8 * th) + 0.005 * DEG * np.random.default_rng(1).standard_normal(th.size)
    mc = [fit_transmission_error(th, e, sigma_rad=0.005 * DEG, n_mc=4000, rng=s)["amplitude1_rad"].error_mc
          for s in (1, 2)]
    assert mc[0] == pytest.approx(mc[1], rel=0.1)
