"""What the diagnosis asks of identify to save work must not change the answer.

* ``outlier_report``: identify's outlier decision without the final fit: the same flagged (and rejected) poses as
  ``identify(...).outlier_report`` on the twin's measured points with three gross errors planted;
* ``report=False`` (a cross-validation fold's fit): the same estimate, free and held sets, reduced chi-square and
  RMS as the full identify, with a zero covariance and no explanation of the held directions;
* ``DiagnosisData.observations(rows)``: the rows' whitening sliced from the whole set's equals the one computed
  from their covariances.
"""
from __future__ import annotations

import numpy as np

from calib.diagnose.data import from_arrays
from calib.identify import PointObservations, identify, outlier_report, whitening
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
