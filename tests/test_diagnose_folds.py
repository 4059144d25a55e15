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
