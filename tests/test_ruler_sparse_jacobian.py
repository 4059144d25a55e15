"""The ruler fit's cheaper derivatives are the general code's, to the bit.

``_RulerModel.jacobian`` evaluates only the readings each parameter touches, ``_jac_marks`` every perturbed ruler in
one batch, and ``gauss_newton`` keeps the Jacobian while rejected steps leave the parameters alone: written for the
session's live refits; each must give the very floats of the dense central differences it replaces.
"""
from __future__ import annotations

import numpy as np
import pytest

from calib.estimators import ruler as R
from calib.estimators._lsq import gauss_newton
from calib.units import ARCSEC, DEG
from calib.uncertainty import jacobian

PLACEMENTS = [((-300, 1200, 0.0), 0.0, 0.0), ((-200, 1600, 150.0), 0.1, 0.05), ((100, 1000, -100.0), -0.15, 0.0)]
MARKS = np.array([0.0, 600.0, 1200.0, 1830.0, 1860.0])


def _problem(faces, n_place, seed):
    rng = np.random.default_rng(seed)
    s = R.simulate_sightings(1609.9, -1.489 * DEG, 1.358 * DEG, PLACEMENTS[:n_place], MARKS, faces=faces,
                             sigma_rad=3 * ARCSEC, rng=rng, hB_mm=0.7, collimation_rad=(4e-5, -2e-5),
                             index_rad=(1e-5, 3e-5))
    model = R._RulerModel(s, MARKS.size, len(faces) == 2)
    obs = np.concatenate([s.hz_rad, s.v_rad])
    p = R._initial_guess(model, s, MARKS) + rng.normal(0, 1e-3, model.P)      # away from any minimum
    return model, obs, p


def _same(a, b):
    assert a.shape == b.shape
    assert a.strides == b.strides                          # the normal equations' BLAS sees the same layout
    assert np.array_equal(a, b)
    assert np.array_equal(np.signbit(a), np.signbit(b))


@pytest.mark.parametrize("faces,n_place,seed", [((1, 2), 3, 1), ((1, 2), 2, 2), ((1,), 3, 3), ((1,), 2, 4)])
def test_sparse_jacobian_is_the_dense_one_to_the_bit(faces, n_place, seed):
    model, obs, p = _problem(faces, n_place, seed)
    dense = jacobian(lambda q: model.residual(q, MARKS, obs), p, model.steps)
    sparse = model.jacobian(p, MARKS, obs)
    _same(sparse, dense)
    assert np.count_nonzero(dense) < dense.size             # the structure it skips is really there


def test_marks_jacobian_is_one_evaluation_per_ruler_to_the_bit():
    model, obs, p = _problem((1, 2), 3, 5)
    h = 1e-4
    cols = []
    for i in range(MARKS.size):
        d = np.zeros_like(MARKS)
        d[i] = h
        cols.append((model.residual(p, MARKS + d, obs) - model.residual(p, MARKS - d, obs)) / (2 * h))
    _same(R._jac_marks(model, p, MARKS, obs), np.stack(cols, -1))


def test_gauss_newton_with_the_sparse_jacobian_gives_the_dense_fit():
    model, obs, p0 = _problem((1, 2), 3, 6)
    w = np.full(obs.size, (3 * ARCSEC) ** -2)
    f = lambda q: model.residual(q, MARKS, obs)              # noqa: E731
    dense = gauss_newton(f, p0, model.steps, w)
    sparse = gauss_newton(f, p0, model.steps, w, jac=lambda q: model.jacobian(q, MARKS, obs))
    for a, b in zip(dense, sparse):
        assert np.array_equal(a, b)


def test_kept_jacobian_is_the_one_recomputed():
    """A rejected step keeps p: the Jacobian gauss_newton keeps is the one it would compute again (every call of
    the Jacobian is at a new parameter vector, and the fit is that of a solver that recomputes it each step)."""
    model, obs, p0 = _problem((1, 2), 2, 7)
    w = np.full(obs.size, (3 * ARCSEC) ** -2)
    f = lambda q: model.residual(q, MARKS, obs)              # noqa: E731
    seen, calls = [], [0]

    def counting(q):
        calls[0] += 1
        seen.append(q.copy())
        return jacobian(f, q, model.steps)

    p, J, r, A = gauss_newton(f, p0, model.steps, w, jac=counting)
    assert all(not np.array_equal(a, b) for a, b in zip(seen, seen[1:]))
    _same(J, jacobian(f, p, model.steps))
    Jw = J * w[:, None]
    assert np.array_equal(A, Jw.T @ J)
    assert calls[0] < 31                                   # near the minimum most steps are rejected rounding
