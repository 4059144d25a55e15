"""Link compliance by cantilever theory (section 4.6; printed eq 4.6.1 garbled)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.link_compliance import cantilever_shape, flexural_rigidity
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
