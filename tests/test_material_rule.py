"""The material rule of the diagnosis (issue 24): a step is material at a tenth of the baseline's excess gap, or of the
gap still open when it is confident and its held-out gain significant (calib.diagnose.findings.material_reason);
the held-out test is a paired t-test over the held-out poses, checked here against scipy.stats on residuals made
up for it."""
from types import SimpleNamespace

import numpy as np
from scipy import stats

from calib.diagnose.findings import MATERIAL_SHARE, heldout_gain_p, material_reason


def _fit(res: np.ndarray) -> SimpleNamespace:
    return SimpleNamespace(residual_mm=res, tested=np.isfinite(res).all(axis=1))


def test_heldout_gain_is_a_paired_test_over_the_poses():
    """Two targets a pose, an anisotropic instrument (sigma 0.05 / 0.1 / 0.2 mm), one pose not held out: the
    p-value is scipy's one-sided paired t-test of the per-pose whitened squared residuals."""
    rng = np.random.default_rng(4)
    n_pose, sig = 40, np.array([0.05, 0.1, 0.2])
    cur = rng.normal(0, 1, (2 * n_pose, 3)) * sig * 1.3
    new = cur * 0.9 + rng.normal(0, 1, cur.shape) * sig * 0.2
    cur[:2] = new[:2] = np.nan                           # pose p0: no fold held it out
    data = SimpleNamespace(whitening=np.broadcast_to(np.diag(1 / sig), (2 * n_pose, 3, 3)),
                           pose_id=[f"p{i // 2}" for i in range(2 * n_pose)])
    per_pose = [np.sum(((r / sig) ** 2)[2:].reshape(n_pose - 1, 2, 3), axis=(1, 2)) for r in (cur, new)]
    want = stats.ttest_rel(per_pose[0], per_pose[1], alternative="greater").pvalue
    got = heldout_gain_p(data, _fit(cur), _fit(new))
    assert 0 < want < 0.5
    np.testing.assert_allclose(got, want, rtol=1e-9)
    assert heldout_gain_p(data, _fit(new), _fit(cur)) == 1.0          # worse on the held-out poses: no gain


def test_the_open_gap_admits_only_confident_significant_steps():
    """Baseline excess 2.3 mm, gap still open 0.4 mm, a step of 0.1 mm (4 % of the one, 25 % of the other)."""
    base, open_, gain = 2.3, 0.4, 0.1
    assert material_reason(MATERIAL_SHARE * base, base, open_, False, 1.0, 0.01) == ""   # the baseline's share
    assert material_reason(gain, base, open_, True, 1e-9, 0.01) == ""
    assert "doubtful" in material_reason(gain, base, open_, False, 1e-9, 0.01)
    assert "not significant" in material_reason(gain, base, open_, True, 0.02, 0.01)
    assert "gap still open" in material_reason(0.03, base, open_, True, 1e-9, 0.01)
