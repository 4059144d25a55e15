"""The rigid fit of one point set onto another (calib.angles.rigid_fit), checked against scipy's own Kabsch
(``Rotation.align_vectors``) and against a known motion: the numpy SVD that replaced scipy's (whose import cost every
fit 0.07 s or more) must give the same proper rotation."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib.angles import rigid_fit


@pytest.mark.parametrize("seed", range(6))
def test_rigid_fit_matches_scipy_and_the_known_motion(seed):
    rng = np.random.default_rng(seed)
    src = rng.uniform(-500, 500, (20, 3))
    R_true = Rotation.random(random_state=seed).as_matrix()
    t_true = rng.uniform(-1000, 1000, 3)
    noise = 0.0 if seed % 2 else 0.05
    tgt = src @ R_true.T + t_true + rng.normal(0, noise, src.shape) if noise else src @ R_true.T + t_true
    R, t = rigid_fit(src, tgt)
    ref, _ = Rotation.align_vectors(tgt - tgt.mean(0), src - src.mean(0))
    assert np.allclose(R, ref.as_matrix(), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0) and np.allclose(R @ R.T, np.eye(3), atol=1e-12)
    if not noise:
        assert np.allclose(R, R_true, atol=1e-12) and np.allclose(t, t_true, atol=1e-9)


def test_rigid_fit_of_a_mirrored_set_is_still_a_rotation():
    """A reflection fits mirrored points best; the fit must stay a proper rotation, as scipy's does."""
    rng = np.random.default_rng(7)
    src = rng.uniform(-1, 1, (10, 3))
    tgt = src * np.array([1.0, 1.0, -1.0])
    R, _ = rigid_fit(src, tgt)
    ref, _ = Rotation.align_vectors(tgt - tgt.mean(0), src - src.mean(0))
    assert np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R, ref.as_matrix(), atol=1e-9)


def test_wrap_float_is_wrap_angles_float():
    """One float wrapped without numpy is the float wrap_angle gives, in (-pi, pi], over many turns either way."""
    from calib.angles import wrap_angle, wrap_float
    x = np.random.default_rng(0).uniform(-40.0, 40.0, 20000)
    got = np.array([wrap_float(float(a)) for a in x])
    np.testing.assert_array_equal(got, wrap_angle(x))
    assert np.all((got > -np.pi) & (got <= np.pi))
    np.testing.assert_allclose(np.cos(got), np.cos(x), atol=1e-12)


def test_circular_mean_averages_across_the_wrap_as_the_sum_of_unit_vectors_does():
    import math
    from calib.angles import circular_mean
    a = [2 * math.pi - 0.01, 0.03, 0.01]
    want = math.atan2(sum(math.sin(x) for x in a), sum(math.cos(x) for x in a))      # written out, not the function
    assert abs(circular_mean(a) - want) < 1e-15 and abs(want - 0.01) < 1e-4
    assert abs(circular_mean([math.pi / 2]) - math.pi / 2) < 1e-15
