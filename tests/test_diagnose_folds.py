"""The diagnosis's default folds: 5 whatever the number of poses (calib.diagnose.gap.DIAGNOSE_FOLDS), not
leave-one-out for small sets (which selects too many effects: see the docstring of calib.diagnose.gap); --folds N
with N poses is still leave-one-out; the targets of one pose are held out together."""
from __future__ import annotations

import numpy as np

from calib.diagnose.data import from_arrays
from calib.diagnose.gap import DIAGNOSE_FOLDS, data_folds
from calib.loading import load_robot


def _data(n: int):
    robot = load_robot()                                      # the thesis's Puma 560
    rng = np.random.default_rng(0)
    return from_arrays(robot, rng.uniform(-1.0, 1.0, (n, robot.n)), rng.normal(0.0, 500.0, (n, 3)), noise_mm=0.05)


def test_small_sets_get_five_folds_not_leave_one_out():
    for n in (12, 37, 400):
        folds = data_folds(_data(n))
        assert len(folds) == DIAGNOSE_FOLDS == 5
        assert sorted(np.concatenate([te for _, te in folds]).tolist()) == list(range(n))
        assert all(len(np.intersect1d(tr, te)) == 0 for tr, te in folds)


def test_asked_for_leave_one_out_is_leave_one_out():
    d = _data(37)
    folds = data_folds(d, 37)
    assert len(folds) == 37 and all(len(te) == 1 for _, te in folds)


def test_targets_of_one_pose_are_held_out_together():
    d = _data(40)
    d.pose_id = [f"p{i // 4}" for i in range(40)]           # ten poses of four targets
    folds = data_folds(d)
    assert len(folds) == 5
    for _, te in folds:
        assert {d.pose_id[i] for i in te}.isdisjoint({d.pose_id[i] for i in np.setdiff1d(np.arange(40), te)})


def test_kept_fold_points_are_the_models_points_on_every_row():
    # the selection and the ladder start every round from each fold's points on all rows, kept from the fits' own
    # evaluations instead of a pass per round: they must be what a pass of the model gives, row for row
    from calib.diagnose.gap import cv_fit, geometric_free
    from calib.model import MeasurementModel
    from sim.validate import Case, make_case_data

    data, _ = make_case_data(Case("transmission_error", 4, None, 3.0, seed=1, n_poses=40))
    model = MeasurementModel(data.robot)
    cv = cv_fit(model, data, geometric_free(model, "full"), data_folds(data))
    for i, f in enumerate(cv.folds):
        kept, fresh = cv.points_mm(data, i), model.points(data.q_rad, data.ctx, f.theta)
        assert np.array_equal(kept[f.train], fresh[f.train])          # the fit's own last evaluation
        # the test rows are the fold's prediction, evaluated on those rows alone: the same to rounding
        assert np.allclose(kept[f.test], fresh[f.test], rtol=0, atol=1e-9)
        assert np.array_equal(data.points_mm[f.test] - kept[f.test], cv.residual_mm[f.test])
    assert np.array_equal(cv.points_mm(data), model.points(data.q_rad, data.ctx, cv.all_fit.theta[: model.P]))
    # other rows than those fitted are evaluated, not taken from the fits
    other = data.subset(np.arange(10))
    assert np.array_equal(cv.points_mm(other, 0), model.points(other.q_rad, other.ctx, cv.folds[0].theta))


def test_folds_fitted_in_parallel_are_the_folds_fitted_one_after_the_other(monkeypatch):
    """The k fold fits and the whole-set fit run in threads (calib.threads.parallel_fits): each is the same
    computation, so every number must be bit for bit the serial one -- a fit that shared state with another (a
    cached evaluation, the model's caches) would show here.  ROBOCAL_PARALLEL_FITS=1 is the serial reference."""
    from calib import threads
    from calib.diagnose import gap
    from calib.diagnose.gap import cv_fit, geometric_free
    from calib.model import MeasurementModel
    from sim.validate import Case, make_case_data

    monkeypatch.setattr(gap, "PARALLEL_MIN_SIZE", 0)         # a small case, in threads all the same
    data, _ = make_case_data(Case("joint_compliance", 2, None, 3.0, seed=2, n_poses=60))
    model = MeasurementModel(data.robot)
    free = geometric_free(model, "full")
    runs = {}
    for n in ("1", "3"):
        monkeypatch.setenv(threads.FITS_ENV, n)
        assert threads.parallel_fits() == int(n)
        runs[n] = cv_fit(model, data, free, data_folds(data))
    a, b = runs["1"], runs["3"]
    assert np.array_equal(a.residual_mm, b.residual_mm) and a.chi2 == b.chi2
    assert np.array_equal(a.all_fit.theta, b.all_fit.theta) and np.array_equal(a.all_fit.sigma, b.all_fit.sigma)
    for fa, fb in zip(a.folds, b.folds):
        assert np.array_equal(fa.theta, fb.theta) and fa.free == fb.free and np.array_equal(fa.test, fb.test)


def test_parallel_fits_follow_the_variable_and_the_cores(monkeypatch):
    from calib import threads
    assert threads.parallel_fits({threads.FITS_ENV: "2"}) == 2
    assert threads.parallel_fits({threads.FITS_ENV: "zero"}) == 1            # nonsense: one at a time
    assert 1 <= threads.parallel_fits({}) <= threads.MAX_PARALLEL_FITS
