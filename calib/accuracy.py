"""How accurate the robot was before calibration and is after, on poses the fit did not use.

Why held-out poses: a fit always looks good on the poses it was fitted to (it absorbs their noise); the robot's owner
wants to know how far the calibrated robot will be from where it is sent elsewhere.  The commercial reports (Spatial
Analyzer, RoboDK) and FIGAROH open with exactly these numbers.

* **before**: the nominal description, with only where the robot stands (base) and the tool point located on the
  fit poses -- the accuracy the robot had with its maker's description;
* **after**: the calibrated model (every parameter the identification estimated) fitted on the same fit poses;
* **floor**: what the instruments alone contribute to a position error (RMS of the 3-D point error from the points'
  covariances): an error near the floor means the model explains everything the instruments can see.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import RobocalError


@dataclass
class Accuracy:
    before_err_mm: np.ndarray          # (n_test,) position error of every test pose, nominal description
    after_err_mm: np.ndarray           # (n_test,) position error of every test pose, calibrated model
    floor_mm: float                    # RMS 3-D error the instruments alone explain
    test_index: np.ndarray             # which poses were held out

    @property
    def n_test(self) -> int:
        return int(len(self.after_err_mm))

    @staticmethod
    def _stats(err: np.ndarray) -> tuple[float, float, float]:
        return float(np.sqrt(np.mean(err ** 2))), float(np.percentile(err, 95)), float(np.max(err))

    def as_dict(self) -> dict:
        """The ``accuracy`` key of the results JSON."""
        b_rms, b_p95, b_max = self._stats(self.before_err_mm)
        a_rms, a_p95, a_max = self._stats(self.after_err_mm)
        return {"before_rms_mm": b_rms, "before_p95_mm": b_p95, "before_max_mm": b_max,
                "after_rms_mm": a_rms, "after_p95_mm": a_p95, "after_max_mm": a_max,
                "n_test": self.n_test, "floor_mm": float(self.floor_mm)}


def holdout(n_poses: int, share: float = 0.25, min_test: int = 4, min_fit: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A deterministic split: every k-th pose is a test pose, spread over the whole set (the order of a pose set
    follows the workspace, so a block at the end would test one corner only)."""
    if n_poses < min_fit + min_test:
        raise RobocalError(f"accuracy: {n_poses} poses cannot be split into {min_fit} to fit and {min_test} to test")
    k = max(2, int(round(1.0 / share)))
    test = np.arange(k - 1, n_poses, k)
    if len(test) < min_test:
        test = np.linspace(0, n_poses - 1, min_test).round().astype(int)
    fit = np.setdiff1d(np.arange(n_poses), test)
    return fit, test


def floor_mm(cov_mm2: np.ndarray) -> float:
    """RMS of the 3-D point error from the points' covariances (N, 3, 3)."""
    return float(np.sqrt(np.mean(np.trace(np.asarray(cov_mm2), axis1=1, axis2=2))))


def locate_free(model) -> list[str]:
    """Where the robot stands and its tool point: what 'before calibration' may still fit."""
    return [n for n in model.kin.names if n.startswith(("base.", "tool."))]


def before_after(model, obs, free: list[str], theta0: np.ndarray | None = None, priors: dict | None = None,
                 split: tuple[np.ndarray, np.ndarray] | None = None, identify_fn=None) -> Accuracy:
    """Fit the located nominal model and the calibrated model on the fit poses; errors on the test poses.

    ``model`` and ``obs`` (:class:`calib.identify.PointObservations`) as for :func:`calib.identify.identify`;
    ``free`` the calibrated model's free parameters, ``theta0``/``priors`` its start and priors.
    """
    from .identify import identify
    identify_fn = identify_fn or identify
    fit, test = split if split is not None else holdout(obs.n)
    o_fit, o_test = obs.subset(fit), obs.subset(test)
    nominal = model.nominal.copy()
    located = identify_fn(model, o_fit, free=locate_free(model), theta0=nominal)
    calibrated = identify_fn(model, o_fit, free=free, theta0=theta0 if theta0 is not None else nominal,
                             priors=priors or {})

    def errors(theta):
        pred = model.points(o_test.q_rad, ctx=o_test.ctx, theta=np.asarray(theta)[: model.P])
        return np.linalg.norm(o_test.points_mm - pred, axis=1)

    cov = o_test.cov_mm2 if getattr(o_test, "cov_mm2", None) is not None else np.zeros((o_test.n, 3, 3))
    return Accuracy(errors(located.theta), errors(calibrated.theta), floor_mm(cov), test)
