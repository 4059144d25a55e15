"""What the diagnosis asks of identify to save work must not change the answer.

* ``outlier_report``: identify's outlier decision without the final fit: the same flagged (and rejected) poses as
  ``identify(...).outlier_report`` on the twin's measured points with three gross errors planted;
* ``report=False`` (a cross-validation fold's fit): the same estimate, free and held sets, reduced chi-square and
  RMS as the full identify, with a zero covariance and no explanation of the held directions;
* ``shared=SharedStart()`` (re-solves with only the measured points moved): the very same floats as each re-solve
  alone, with one evaluation and analysis at the start for all of them; a re-solve from elsewhere neither uses nor
  spoils it;
* ``DiagnosisData.observations(rows)``: the rows' whitening sliced from the whole set's equals the one computed
  from their covariances.
"""
from __future__ import annotations

import numpy as np

from calib.diagnose.data import from_arrays
from calib.identify import PointObservations, SharedStart, identify, outlier_report, whitening
from calib.model import MeasurementModel

from tests.test_identify import geometric_twin, measure_points


def _planted():
    tw = geometric_twin(7)
    m, pts = measure_points(tw, tw.random_poses(100))
    p = pts.point_mm.copy()
    bad = [4, 41, 77]
    p[bad] += [3.0, -2.0, 4.0]
    return tw, m.q_read_rad, p, pts.cov_mm2, bad


def test_outlier_report_is_identifys_own_decision():
    tw, q, p, cov, bad = _planted()
    model = MeasurementModel(tw.robot)
    obs = PointObservations(q, p, cov)
    for mode in ("flag", "reject"):
        full = identify(model, obs, outliers=mode).outlier_report
        alone = outlier_report(model, obs, outliers=mode)
        assert alone.flagged == full.flagged == bad
        assert alone.rejected == full.rejected
        assert alone.as_dict() == full.as_dict()


def test_a_fit_that_only_predicts_is_the_same_fit():
    tw, q, p, cov, _ = _planted()
    model = MeasurementModel(tw.robot)
    obs = PointObservations(q, p, cov)
    full = identify(model, obs, outliers="off")
    lean = identify(model, obs, outliers="off", report=False)
    assert np.array_equal(full.theta, lean.theta)
    assert full.free == lean.free and full.fixed == lean.fixed
    assert full.reduced_chi2 == lean.reduced_chi2 and full.residual_rms == lean.residual_rms
    assert np.any(full.cov != 0) and not np.any(lean.cov) and lean.undetermined == []
    assert all(c.because_joint is None for c in lean.identifiability.unidentifiable)


def test_sliced_whitening_equals_the_rows_own():
    tw, q, p, cov, _ = _planted()
    rng = np.random.default_rng(0)
    A = rng.normal(0, 0.05, (len(q), 3, 3))
    cov = cov + np.einsum("nij,nkj->nik", A, A)          # full, different covariances per row
    data = from_arrays(tw.robot, q, p, cov_mm2=cov)
    rows = rng.permutation(len(q))[:37]
    obs = data.observations(rows)
    assert np.array_equal(obs._white, whitening(cov[rows]))
    assert np.array_equal(data.subset(rows).whitening, whitening(cov[rows]))
    assert np.array_equal(obs.subset(np.arange(5))._white, whitening(cov[rows[:5]]))


def test_resolves_sharing_their_start_are_the_same_fits(monkeypatch):
    tw, q, p, cov, _ = _planted()
    model = MeasurementModel(tw.robot)
    obs = PointObservations(q, p, cov)
    base = identify(model, obs, outliers="off")
    rng = np.random.default_rng(1)
    moves = [rng.normal(0, 0.02, p.shape) for _ in range(3)] + [np.outer(np.ones(len(p)), [0.05, 0.0, -0.03])]
    starts = [base.theta] * 3 + [base.theta + 1e-4 * (np.arange(len(base.theta)) % 3 == 0)]   # the last elsewhere

    def resolve(dp, theta0, shared=None, white=None):
        moved = PointObservations(q, p + dp, cov_mm2=cov, white=white)
        return identify(model, moved, free=list(base.free), theta0=theta0, robust=False, start=False,
                        report=False, shared=shared)

    calls = []
    evaluate = MeasurementModel.evaluate
    monkeypatch.setattr(MeasurementModel, "evaluate", lambda self, *a, **k: calls.append(1) or evaluate(self, *a, **k))
    alone = [resolve(dp, th) for dp, th in zip(moves, starts)]
    n_alone, shared = len(calls), SharedStart()
    together = [resolve(dp, th, shared, obs._white) for dp, th in zip(moves, starts)]
    for a, b in zip(alone, together, strict=True):
        assert np.array_equal(a.theta, b.theta)
        assert a.free == b.free and a.fixed == b.fixed
        assert a.reduced_chi2 == b.reduced_chi2 and a.residual_rms == b.residual_rms
    assert len(calls) - n_alone == n_alone - 2      # the second and third start from the first's evaluation
