"""The rest of Chapter 4: the encoder-resolution run (Fig 5.14), E_a (section 4.4), eq 4.7.2's check of the
maker's coupling compensation, and d3 from P and L_p (eq 4.3.15) with its errors -- on data made independently."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.coupling import coupling_from_repeats, further_correction
from calib.estimators.dh import puma_thesis_dh
from calib.estimators.resolution import design_resolution_rad, encoder_resolution, encoder_resolution_fitted_axis
from calib.estimators.transmission import commanded_angle_errors
from tests.fakes import thesis_procedures as tp

DEG = np.pi / 180


#: the design resolution of a 1000-count encoder behind a 76.686:1 gear, written out (2 pi per motor turn): the
#: generators' truth, not the code under test
S_TRUE = 2 * np.pi / (1000 * 76.686)


def test_resolution_slope_and_refusal():
    S = design_resolution_rad(1000, 76.686)
    counts = np.arange(0, 10) * 200.0
    rng = np.random.default_rng(3)
    meas = tp.quantise(counts * S_TRUE * 1.001, 1e-7) + 2e-5 * rng.standard_normal(10)
    res = encoder_resolution(counts, meas, np.full(10, 2e-5 ** 2), S)
    assert abs(res["scale"].value - 1.001) < 4 * res["scale"].error
    assert abs(res["rad_per_count"].value - 1.001 * S_TRUE) < 4 * res["rad_per_count"].error
    with pytest.raises(EstimationError, match="resolution is not determined"):
        encoder_resolution(counts, 2e-5 * rng.standard_normal(10), np.full(10, 2e-5 ** 2), S)


def _tool_run(rng, span_deg, steps, sigma_mm=0.05):
    """A1 on a tilted axis 100 mm out, A2 at 500 mm radius 600 mm out (the demo's extended tool), turned by the
    counts at 1.002 x the design resolution, each point read with independent noise ``sigma_mm``."""
    S = design_resolution_rad(1000, 76.686)
    c, n = np.array([300.0, 2500.0, 200.0]), np.array([0.1, -0.05, 1.0]) / np.linalg.norm([0.1, -0.05, 1.0])
    e1 = np.cross(n, [1.0, 0, 0])
    e1 /= np.linalg.norm(e1)
    counts = np.round(np.linspace(0.0, np.radians(span_deg) / S, steps))
    th = counts * S_TRUE * 1.002
    A1 = tp.rotate(c + 100 * n, c, n, th) + sigma_mm * rng.standard_normal((steps, 3))
    A2 = tp.rotate(c + 600 * n + 500 * e1, c, n, th) + sigma_mm * rng.standard_normal((steps, 3))
    return counts, A1, A2, np.eye(6 * steps) * sigma_mm ** 2, S


def test_resolution_about_the_fitted_axis_carries_the_axis_error():
    """The run's axis is fitted from its own A2 positions; with A1->A2 as much along the axis as across it, a tilted
    axis moves every angle, so the slope's error must exceed what the angles about a known axis give -- and the
    stated error must cover the scatter over seeded runs (the angles-only error does not)."""
    z_full, z_angles = [], []
    for seed in range(40):
        counts, A1, A2, U, S = _tool_run(np.random.default_rng(seed), 60.0, 6)
        res = encoder_resolution_fitted_axis(counts, A1, A2, U, S)
        bare = encoder_resolution(counts, res.extras["angle_rad"], res.extras["angle_cov_rad2"], S)
        assert bare["scale"].value == pytest.approx(res["scale"].value, rel=1e-12)     # the same line
        z_full.append((res["scale"].value - 1.002) / res["scale"].error)
        z_angles.append((bare["scale"].value - 1.002) / bare["scale"].error)
    assert 0.5 < np.median(np.abs(z_full)) < 0.9 and np.mean(np.abs(z_full) < 2) >= 0.9
    assert np.median(np.abs(z_angles)) > 1.5                                  # the axis term is what matters here
    with pytest.raises(EstimationError, match="targets' covariance"):
        encoder_resolution_fitted_axis(counts, A1, A2, U[:-1, :-1], S)


def test_commanded_angle_error_carries_the_reference_pose():
    desired = np.radians([0.0, 10, 20, 30])
    C = np.diag(np.full(4, 1e-8))
    res = commanded_angle_errors(desired * 1.01, C, desired)
    assert res["E_a_slope"].value == pytest.approx(0.01, rel=1e-9)
    # E_a of pose 1 = (angle_1 - angle_0) - desired: both poses' noise
    assert res["E_a1_rad"].error == pytest.approx(np.sqrt(2e-8), rel=1e-6)
    with pytest.raises(EstimationError, match="E_a"):
        commanded_angle_errors(desired, C, np.zeros(4))


def test_eq_4_7_2_further_correction_is_measured_minus_controller():
    th = 10 * DEG
    runs = {"sigma56": ([th + 0.1804 * th] * 3, [th] * 3, [th] * 3)}
    res = coupling_from_repeats(runs, 1e-6)
    f = further_correction(res, {"sigma56": 0.1806})
    assert f["further56"].value == pytest.approx(-0.0002, abs=1e-9)
    assert f["further56"].error == pytest.approx(res["sigma56"].error)
    with pytest.raises(EstimationError, match="eq 4.7.2"):
        further_correction(res, {"sigma45": 0.0139})


def test_d3_from_P_and_Lp_with_errors():
    # eq 4.3.15: d3 = |(X, Z)_p - (X, Z)_c6| - L_p; B.6's d d3 / d L_p is -1 (printed -1/(2 d3))
    fig = {"X_c1": 474.9, "Y_c1": 2853.0, "X_c2": 474.9, "Z_c2": 184.9, "X_c3": 906.0, "Z_c3": 184.9,
           "X_c5": 906.0, "Z_c5": -247.2, "X_c6": 906.0, "Y_c6": 3007.5, "Z_c6": -247.2}
    ang = 0.3
    c = dict(fig, X_p=906.0 + 400.4 * np.cos(ang), Z_p=-247.2 + 400.4 * np.sin(ang), L_p=344.0)
    cov = np.diag([0.05 ** 2] * 13 + [0.1 ** 2])
    res = puma_thesis_dh(c, cov, n_mc=20000)
    assert res["d3_mm"].value == pytest.approx(56.4, abs=1e-9)
    assert res["d3_mm"].agreement() < 0.10
    assert res["d3_mm"].error > 0.1                                   # L_p's own error enters one to one
