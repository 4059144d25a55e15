"""Misalignment table and compensation scheme (eqs 4.3.10-4.3.13), against rotations made independently."""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import EstimationError
from calib.estimators.misalignment import compensate, compensation_matrix, misalignment_table
from tests.fakes import thesis_procedures as tp


def test_compensation_undoes_a_small_rotation_of_the_frame():
    rng = np.random.default_rng(0)
    d = np.array([0.004, -0.007, 0.011])                       # R_f turned by d onto the joint frame
    P = rng.uniform(-2000, 2000, (5, 3))
    ang = np.linalg.norm(d)
    turned = tp.rotate(P, np.zeros(3), d / ang, np.full(5, -ang))   # the same points seen from the turned frame
    np.testing.assert_allclose(compensate(P, d), turned, atol=2000 * ang ** 2)
    assert compensation_matrix(np.zeros(3)) == pytest.approx(np.eye(3))


def test_table_recovers_a_known_tilt_with_honest_errors():
    zd = np.array([[0, 0, 1.0], [0, 1.0, 0], [0, 1.0, 0]])
    x = np.array([[1.0, 0, 0], [1.0, 0, 0], [0, 0, 1.0]])
    tilt = 0.01
    zm = np.array([[0, 0, 1.0], [0, np.cos(tilt), np.sin(tilt)], [0, np.cos(tilt), np.sin(tilt)]])
    U = np.eye(9) * 1e-4 ** 2
    res = misalignment_table(zm, U, zd, x, n_mc=20000)
    assert res["j2.delta_alpha_rad"].value == pytest.approx(tilt, rel=1e-6)
    assert res["j3.delta_alpha_rad"].value == pytest.approx(0.0, abs=1e-9)      # j3 follows j2: no relative tilt
    for e in res.estimates():
        assert e.agreement() < 0.10, e
    assert "j1.dtheta_z_rad" not in res.names                  # a turn about the design axis is not an estimate
    with pytest.raises(EstimationError, match="misalignment table"):
        misalignment_table(zm, np.eye(6), zd, x)
