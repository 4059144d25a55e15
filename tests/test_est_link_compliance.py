"""Link compliance by cantilever theory (section 4.6; printed eq 4.6.1 garbled)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.link_compliance import RigidityBound, cantilever_shape, flexural_rigidity, link_rigidity
from tests.fakes import thesis_procedures as tp


def test_cantilever_shape_is_standard_beam_theory():
    a = 400.0
    assert cantilever_shape(a, a) / 6 == pytest.approx(a ** 3 / 3)             # tip: P a^3 / (3 EI)
    x = np.array([100.0, 250.0, 400.0, 650.0])                                 # against y'' = M / EI integrated
    assert cantilever_shape(x, a) / 6 == pytest.approx(tp.cantilever_deflection(x, a, 1.0, 1.0), rel=1e-5)
    x = np.linspace(0, 800, 9)
    y = cantilever_shape(x, a)
    assert np.allclose(np.diff(y[x >= a], 2), 0)                                # straight beyond the load


@pytest.mark.parametrize("joint", [False, True])
def test_EI_and_joint_stiffness_recovered(joint):
    rng = np.random.default_rng(0)
    EI, K = 2e9, 5e5                                                           # N mm^2 (2000 N m^2), N m/rad
    x = np.tile([100, 200, 300, 400.0], 3)
    a = np.full(12, 400.0)
    P = np.repeat([50, 100, 150.0], 4)
    # independent truth: EI y'' = M integrated numerically, plus the rigid turn of a compliant joint (P a / K)
    y = tp.cantilever_deflection(x, a, P, EI) + (x * P * a * 1e-3 / K if joint else 0)
    sig = 0.002
    res = flexural_rigidity(x, a, P, y + sig * rng.standard_normal(12), sig, include_joint=joint,
                            second_moment_mm4=1e4, n_mc=20000)
    e = res["EI_Nmm2"]
    assert abs(e.value - EI) < 4 * e.error
    assert e.agreement() < 0.10, e
    assert res["E_MPa"].value == pytest.approx(e.value / 1e4)
    if joint:
        assert abs(res["K_joint_Nm_per_rad"].value - K) < 4 * res["K_joint_Nm_per_rad"].error


def test_loads_without_deflection_refused():
    x = np.array([100, 200, 300.0])
    with pytest.raises(EstimationError, match="link compliance: cantilever fit: the loads produced no measurable"):
        flexural_rigidity(x, [300] * 3, [10] * 3, [0, 0, 0], 0.002)
    with pytest.raises(EstimationError, match="no load"):
        flexural_rigidity(x, [300] * 3, [0] * 3, [0.1, 0.2, 0.3], 0.002)
    with pytest.raises(EstimationError, match="2 or more positions"):
        flexural_rigidity([100] * 3, [300] * 3, [10, 20, 30], [0.1, 0.2, 0.3], 0.002, include_joint=True)


# -- a stiff link: a one-sided lower bound instead of "not determined" ----------------------------------------------
GAUGES = np.tile([150.0, 280.0, 400.0], 4)          # the demo's bench: three gauges, loads 0-150 N at 430 mm
LOAD_X = np.full(12, 430.0)
LOADS = np.repeat([0.0, 50.0, 100.0, 150.0], 3)
SIG = 0.001


def _limit_independent(confidence=0.95):
    """The detection limit from the independent beam (y'' = M / EI integrated numerically at EI = 1): the compliance
    is fitted from ``y = c s`` with ``s`` that beam's deflections, so ``sigma_c = SIG / |s|`` and the limit is
    ``1 / (z sigma_c)`` -- no reading involved."""
    from statistics import NormalDist
    s = tp.cantilever_deflection(GAUGES, LOAD_X, LOADS, 1.0)
    return np.linalg.norm(s) / (NormalDist().inv_cdf(confidence) * SIG)


def test_rigid_link_gives_a_lower_bound_below_the_truth_free_limit():
    limit = _limit_independent()
    for seed in range(60):
        y = SIG * np.random.default_rng(seed).standard_normal(12)           # a rigid link: gauge noise only
        b = link_rigidity(GAUGES, LOAD_X, LOADS, y, SIG)
        assert isinstance(b, RigidityBound), seed
        assert b.detection_limit_Nmm2 == pytest.approx(limit, rel=1e-3)
        assert 0 < b.EI_lower_bound_Nmm2 <= b.detection_limit_Nmm2 * (1 + 1e-12)
        assert b.EI_lower_bound_Nmm2 > 0.3 * limit                          # not uselessly conservative
        assert b.confidence == 0.95


def test_lower_bound_covers_a_barely_compliant_link_at_its_confidence():
    """A link the gauges barely see (true compliance 2.5 of the fit's errors, where clipping a negative fit no longer
    helps): the bound must hold the truth at or above it in 95 % of runs -- one-sided, not 97.5 % (a two-sided
    quantile) nor 100 % (a bound too loose to mean anything)."""
    from calib.estimators.link_compliance import rigidity_lower_bound
    limit = _limit_independent()
    EI = 1.645 * limit / 2.5                                                 # c = 2.5 sigma_c
    y0 = tp.cantilever_deflection(GAUGES, LOAD_X, LOADS, EI)
    held = [rigidity_lower_bound(GAUGES, LOAD_X, LOADS, y0 + SIG * np.random.default_rng(seed).standard_normal(12),
                                 SIG).EI_lower_bound_Nmm2 <= EI for seed in range(600)]
    assert 0.93 <= np.mean(held) <= 0.965, np.mean(held)


def test_compliant_link_gives_EI_with_an_honest_error():
    """The same bench with a link 20x more compliant than the limit: EI estimated, |EI - truth| / error with a median
    near 0.67 and about 95 % within 2 sigma over seeded runs."""
    EI = _limit_independent() / 20
    y0 = tp.cantilever_deflection(GAUGES, LOAD_X, LOADS, EI)
    z = []
    for seed in range(200):
        res = link_rigidity(GAUGES, LOAD_X, LOADS, y0 + SIG * np.random.default_rng(seed).standard_normal(12), SIG,
                            n_mc=0)
        assert not isinstance(res, RigidityBound), seed
        z.append(abs(res["EI_Nmm2"].value - EI) / res["EI_Nmm2"].error)
    assert 0.55 <= np.median(z) <= 0.85 and 0.90 <= np.mean(np.array(z) < 2) <= 0.99, (np.median(z), np.mean(z))


@pytest.mark.parametrize("sigma_mm", [0.0, -0.001, float("nan")])
def test_a_gauge_noise_that_is_not_positive_is_refused(sigma_mm):
    """0 would state EI with no error, a negative noise a nonsense interval, NaN a linear-algebra traceback."""
    x, a, P = np.array([300.0, 500.0, 700.0]), np.full(3, 800.0), np.full(3, 50.0)
    with pytest.raises(EstimationError, match="gauge.noise"):
        link_rigidity(x, a, P, np.array([0.01, 0.02, 0.03]), sigma_mm=sigma_mm)
