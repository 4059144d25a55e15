"""The generic propagation machinery against the GUM's own example H.2 and simple closed forms."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calib.uncertainty import (EstimateSet, UncertaintyError, coverage_fraction, jacobian, propagate,
                               sample_inputs)

H2 = Path(__file__).resolve().parents[2] / "shared" / "data" / "gum-h2-suncal" / "test_GUMH2.csv"
if not H2.exists():
    H2 = Path("/work/shared/data/gum-h2-suncal/test_GUMH2.csv")


def _h2_model(x):
    """GUM H.2: R = V/I cos(phi), X = V/I sin(phi), Z = V/I (I in A)."""
    V, I, ph = x[..., 0], x[..., 1], x[..., 2]
    Z = V / I
    return np.stack([Z * np.cos(ph), Z * np.sin(ph), Z], -1)


def _h2_inputs():
    data = np.genfromtxt(H2, delimiter=",", skip_header=1)
    data[:, 1] /= 1000.0                                   # mA -> A
    n = len(data)
    x = data.mean(0)
    cov = np.cov(data, rowvar=False) / n                   # covariance of the means (GUM H.2.3, eq 17)
    return x, cov


def test_gum_h2_law_of_propagation_and_monte_carlo():
    # GUM (JCGM 100:2008) Annex H.2, Table H.4: R = 127.732 ohm u 0.071, X = 219.847 u 0.295, Z = 254.260 u 0.236,
    # correlations r(R,X) = -0.588, r(R,Z) = -0.485, r(X,Z) = 0.993.
    x, cov = _h2_inputs()
    res = propagate(_h2_model, x, cov, ["R", "X", "Z"], ["ohm"] * 3, n_mc=200_000, rng=1)
    np.testing.assert_allclose(res.value, [127.732, 219.847, 254.260], atol=0.001)
    np.testing.assert_allclose(np.sqrt(np.diag(res.cov_gum)), [0.071, 0.295, 0.236], atol=0.001)
    np.testing.assert_allclose(np.sqrt(np.diag(res.cov_mc)), [0.071, 0.295, 0.236], atol=0.002)
    r = res.correlation()
    np.testing.assert_allclose([r[0, 1], r[0, 2], r[1, 2]], [-0.588, -0.485, 0.993], atol=0.002)


def test_gum_h2_second_approach_matches():
    # GUM H.2.4 (approach 2): compute R, X, Z per set and take mean and experimental std of the mean: same answer.
    data = np.genfromtxt(H2, delimiter=",", skip_header=1)
    data[:, 1] /= 1000.0
    y = _h2_model(data)
    np.testing.assert_allclose(y.std(0, ddof=1) / np.sqrt(len(y)), [0.071, 0.295, 0.236], atol=0.001)


def test_jacobian_batched_matches_analytic():
    x = np.array([[1.0, 2.0], [0.5, -1.0]])
    f = lambda z: np.stack([z[..., 0] * z[..., 1], np.sin(z[..., 0])], -1)
    J = jacobian(f, x)
    assert J.shape == (2, 2, 2)
    np.testing.assert_allclose(J[1], [[-1.0, 0.5], [np.cos(0.5), 0.0]], rtol=1e-6)


def test_semidefinite_inputs_and_nonlinear_mc_differs():
    # an exactly known input (zero variance) is fine; a strongly nonlinear model shows MC != GUM (the check can fail)
    cov = np.diag([0.0, 0.25])
    draws = sample_inputs(np.array([1.0, 0.0]), cov, 1000, np.random.default_rng(0))
    assert np.all(draws[:, 0] == 1.0)
    res = propagate(lambda z: np.stack([z[..., 1] ** 2 + z[..., 0]], -1), np.array([1.0, 0.0]), cov, ["y"], ["-"],
                    n_mc=20000)
    assert res["y"].error_gum == pytest.approx(0.0, abs=1e-6)
    assert res["y"].error_mc > 0.3          # chi-square spread: linearisation is blind to it
    assert res["y"].agreement() > 1.0


def test_bad_covariance_and_nonfinite_estimate_refused():
    with pytest.raises(UncertaintyError):
        sample_inputs(np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]), 10, np.random.default_rng(0))
    with pytest.raises(UncertaintyError, match="not finite"), np.errstate(invalid="ignore"):
        propagate(lambda z: np.log(z - 2.0), np.array([1.0]), np.eye(1), ["y"], ["-"], n_mc=0)


def test_estimate_json_and_coverage_helper():
    es = EstimateSet(["a"], np.array([1.0]), ["mm"], cov_gum=np.array([[0.04]]), cov_mc=np.array([[0.0441]]))
    d = es["a"].as_dict()
    assert d["name"] == "a" and d["unit"] == "mm" and d["error"] == pytest.approx(0.2)
    assert d["error_mc"] == pytest.approx(0.21)
    assert coverage_fraction(np.array([[0.0], [3.0]]), np.array([[1.0], [1.0]]), np.array([0.0]))[0] == 0.5
