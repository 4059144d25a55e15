"""Joint axes: least-squares plane and circle (sections 4.3.1-4.3.2, App A.3)."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.axes import check_axis, fit_axis, fit_circle

C0 = np.array([400.0, 2500.0, 100.0])
N0 = np.array([0.1, 0.2, 1.0]) / np.linalg.norm([0.1, 0.2, 1.0])
R0 = 600.0


def _circle(deg):
    e1 = np.cross(N0, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(N0, e1)
    t = np.radians(np.asarray(deg, float))
    return C0 + R0 * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)


def _thesis_centre(P):
    """App A.3.1 circumcentre in the plane (X, Y) for three points."""
    (X1, Y1), (X2, Y2), (X3, Y3) = P[:, :2]
    Nr = (X2**2 - X1**2 + Y2**2 - Y1**2) * (Y3 - Y2) - (X3**2 - X2**2 + Y3**2 - Y2**2) * (Y2 - Y1)
    D = (X2 - X1) * (Y3 - Y2) - (X3 - X2) * (Y2 - Y1)
    return Nr / (2 * D)


def test_exact_circle_and_right_hand_normal():
    th = fit_circle(_circle(np.linspace(-60, 80, 8)))
    np.testing.assert_allclose(th, np.r_[C0, N0, R0], atol=1e-9)
    th_rev = fit_circle(_circle(np.linspace(80, -60, 8)))           # reversed sweep: negative rotation
    np.testing.assert_allclose(th_rev[3:6], -N0, atol=1e-12)


def test_three_points_reduce_to_the_thesis_circle():
    P = _circle([0.0, 50.0, 110.0]) * np.array([1, 1, 0]) + np.array([0, 0, 7.0])   # in a horizontal plane
    th = fit_circle(P)
    assert th[0] == pytest.approx(_thesis_centre(P), abs=1e-8)
    np.testing.assert_allclose(np.linalg.norm(P - th[:3], axis=1), th[6], atol=1e-8)


def test_batched_fit_equals_single_fits():
    rng = np.random.default_rng(0)
    P = _circle(np.linspace(-40, 40, 6)) + 0.1 * rng.standard_normal((5, 6, 3))
    batch = fit_circle(P)
    for i in range(5):
        np.testing.assert_allclose(batch[i], fit_circle(P[i]), atol=1e-7)


def test_three_ways_agree_with_anisotropic_correlated_points():
    rng = np.random.default_rng(1)
    P = _circle(np.linspace(-50, 70, 7))
    A = rng.standard_normal((21, 21)) * 0.02
    U = A @ A.T + np.diag(np.tile([0.05, 0.3, 0.05], 7) ** 2)
    res = fit_axis(P + rng.multivariate_normal(np.zeros(21), U).reshape(7, 3), U, n_mc=20000, rng=4)
    for e in res.estimates():
        assert e.agreement() < 0.10, e
    assert np.linalg.norm(res.value[3:6]) == pytest.approx(1.0)


def test_degenerate_sweeps_refused():
    U = np.eye(9) * 0.01
    with pytest.raises(EstimationError, match="axes: circle fit of j2: needs at least 3 target positions, got 2"):
        fit_axis(_circle([0, 30]), np.eye(6) * 0.01, joint="j2")
    with pytest.raises(EstimationError, match="collinear"):
        fit_axis(np.array([[0, 0, 0], [100, 0, 0], [200, 0, 0.0]]), U)
    with pytest.raises(EstimationError, match="distinct"):
        fit_axis(np.array([[0, 0, 0], [0, 0, 0], [200, 50, 0.0]]), U)
    with pytest.raises(EstimationError, match="(too short|collinear)"):
        fit_axis(_circle([0.0, 0.5, 1.0]), np.eye(9) * 1e-4)
    with pytest.raises(EstimationError, match="non-finite"):
        fit_axis(np.r_[_circle([0, 30]), [[np.nan, 0, 0]]], U)


BAD_SWEEPS = [(_circle([0, 30]), np.eye(6) * 0.01),
              (np.array([[0, 0, 0], [100, 0, 0], [200, 0, 0.0]]), np.eye(9) * 0.01),
              (np.array([[0, 0, 0], [0, 0, 0], [200, 50, 0.0]]), np.eye(9) * 0.01),
              (_circle([0.0, 0.5, 1.0]), np.eye(9) * 1e-4),
              (np.r_[_circle([0, 30]), [[np.nan, 0, 0]]], np.eye(9) * 0.01),
              (_circle([0, 40, 80, 120]), np.eye(9) * 0.01)]         # a covariance of the wrong size


@pytest.mark.parametrize("P, U", BAD_SWEEPS)
def test_check_axis_refuses_what_fit_axis_refuses(P, U):
    """The transmission run checks its A2 positions with check_axis instead of a whole fit_axis whose errors it
    discarded: the same refusal, word for word."""
    with pytest.raises(EstimationError) as full:
        fit_axis(P, U, n_mc=0, joint="j4")
    with pytest.raises(EstimationError) as checked:
        check_axis(P, U, joint="j4")
    assert str(checked.value) == str(full.value)


def test_check_axis_gives_fit_axis_circle():
    rng = np.random.default_rng(3)
    P = _circle(np.linspace(-60, 70, 9)) + rng.normal(0, 0.05, (9, 3))
    U = np.eye(27) * 0.05 ** 2
    theta = check_axis(P, U, joint="j6")
    assert np.array_equal(theta, fit_axis(P, U, n_mc=0, joint="j6").value)
    assert np.allclose(theta[:3], C0, atol=0.5) and np.allclose(theta[3:6], N0, atol=1e-3)
