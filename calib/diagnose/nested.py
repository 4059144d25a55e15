"""The k-fold held-out figure of a diagnosis without a split, nested (issue 24, item 1).

Why: without a ``split`` column the diagnosis scores its candidates on k-fold predictions of every row and keeps
the best; the same predictions then overstate how well the chosen model does on poses it has not seen (an effect
picked because it fits the noise of these folds lowers their figure).  Nested: in each outer fold every choice --
gross errors, the geometric set, the noise floor, the effects, the stopping rule -- is made on that fold's fit rows
alone (with inner folds of their own), the chosen model is fitted on them and predicts the fold's test rows once.
The figure pooled over the outer folds is the held-out figure; the findings reported stay those of the run on every
row.

Cost: each outer fold is a diagnosis of its own, so nesting multiplies the work by about k.  It is done up to
:data:`NESTED_MAX_POSES` poses (where a diagnosis takes a fraction of a second and the optimism of a choice is
largest); above, the figure is the plain k-fold one and the protocol says so (a ``split`` column gives a figure no
choice has seen at any size).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from calib.accuracy import grouped_folds, locate_free, make_folds
from calib.heldout import HeldOut, noise_scale, predicted_cov_mm2
from calib.identify import identify

from .data import DiagnosisData

#: most poses a diagnosis without a split nests its k-fold figure for (k diagnoses more: see the module docstring)
NESTED_MAX_POSES = 150
#: outer folds
OUTER_FOLDS = 5


def n_poses(data: DiagnosisData) -> int:
    return len(set(data.pose_id)) if data.pose_id else data.n


def outer_folds(data: DiagnosisData, k: int = OUTER_FOLDS) -> list[tuple[np.ndarray, np.ndarray]]:
    """Outer folds; the rows of one pose (several targets) are held out together."""
    if data.pose_id and len(set(data.pose_id)) < data.n:
        return grouped_folds(data.pose_id, k)
    return make_folds(data.n, k)


def nested_heldout(data: DiagnosisData, choose: Callable[[DiagnosisData], object],
                   k: int = OUTER_FOLDS) -> HeldOut:
    """Pool the outer folds' predictions.  ``choose(fit_rows)`` makes every choice on ``fit_rows`` and returns the
    chosen model's fit there (a :class:`calib.diagnose.gap.CVResult`: ``model`` and ``all_fit``)."""
    n = data.n
    before, after, cov = (np.full((n, 3), np.nan), np.full((n, 3), np.nan), np.full((n, 3, 3), np.nan))
    folds = outer_folds(data, k)
    for tr, te in folds:
        fit_rows, test = data.subset(tr), data.subset(te)
        final = choose(fit_rows)
        m, fit = final.model, final.all_fit
        after[te] = test.points_mm - m.points(test.q_rad, test.ctx, fit.theta[: m.P])
        cov[te] = predicted_cov_mm2(m, fit, test.q_rad, test.ctx, np.zeros_like(test.cov_mm2)) \
            + noise_scale(fit) * test.cov_mm2
        loc = identify(m, fit_rows.observations(), free=[q for q in locate_free(m) if q in fit.free],
                       theta0=m.nominal, outliers="off", start=True, report=False)
        before[te] = test.points_mm - m.points(test.q_rad, test.ctx, loc.theta[: m.P])
    return HeldOut(before, after, cov, f"nested {len(folds)}-fold cross-validation: in each fold every choice (gross "
                                       f"errors, geometric set, noise floor, effects) made on its fit rows alone")
