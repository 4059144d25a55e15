"""Predictions of held-out points with their uncertainty, and how honest that uncertainty is (issue 24, item 6).

Why: the owner uses a calibrated model to send the robot to points it was not measured at; the model must say how
far off it may be there, and that statement must hold on real data.  Each predicted point carries the covariance

    ``Sigma_i = J_i C J_i^T + s V_i``

with ``J_i`` the point's Jacobian in the estimated parameters, ``C`` their covariance (from the fit, scaled as the fit
scaled it), ``V_i`` the point's measurement covariance and ``s`` the same scale (the reduced chi-square when the
errors are scaled by the residual, or when it exceeds 1): what the fit's own scatter says a new point will show on
top of the parameters' error.

Honesty: each coordinate's error divided by its predicted sigma is, for an honest model, a standard normal: the
median of |error|/sigma is 0.674 and 95.4 % lie within 2 sigma.  (Per coordinate, because the median of a 3-D
distance over its sigma has no such simple target; the convention is stated in the JSON.)
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np

from .accuracy import before_after_dict, grouped_folds, make_folds, point_errors_mm

#: the per-coordinate convention of :func:`honesty`
HONESTY_CONVENTION = ("each coordinate's held-out error over its predicted sigma (parameter covariance plus the "
                      "fit's noise); an honest model gives a median of 0.674 and 95.4 % within 2 sigma")


def noise_scale(ident) -> float:
    """The factor the fit applied to the given noise (see the module docstring)."""
    red = float(ident.reduced_chi2)
    return red if getattr(ident, "error_scale", "inflate") == "residual" else max(1.0, red)


def predicted_cov_mm2(model, ident, q_rad: np.ndarray, ctx, point_cov_mm2: np.ndarray) -> np.ndarray:
    """(N, 3, 3) covariance of the predicted points at ``q_rad`` (see the module docstring)."""
    ev = model.evaluate(q_rad, ctx, ident.theta[: model.P], jacobian=True)
    free = [n for n in ident.free if n in model.index]
    J = ev.jacobian[:, :, [model.index[n] for n in free]]
    ci = [ident.names.index(n) for n in free]
    C = ident.cov[np.ix_(ci, ci)]
    return np.einsum("nip,pq,njq->nij", J, C, J) + noise_scale(ident) * np.asarray(point_cov_mm2, float)


def honesty(res_mm: np.ndarray, cov_mm2: np.ndarray) -> dict:
    """``median_abs_z``, ``within_2sigma``, ``n_coordinates`` and the convention (:data:`HONESTY_CONVENTION`)."""
    res = np.asarray(res_mm, float).reshape(-1, 3)
    sd = np.sqrt(np.clip(np.einsum("nii->ni", np.asarray(cov_mm2, float).reshape(-1, 3, 3)), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(res / sd).ravel()
    z = z[np.isfinite(z)]
    if z.size == 0:
        return {"median_abs_z": None, "within_2sigma": None, "n_coordinates": 0, "convention": HONESTY_CONVENTION}
    return {"median_abs_z": float(np.median(z)), "within_2sigma": float(np.mean(z <= 2.0)),
            "n_coordinates": int(z.size), "median_sigma_mm": float(np.median(sd)),
            "convention": HONESTY_CONVENTION}


@dataclass
class HeldOut:
    """Held-out rows predicted by the located nominal model (``before``) and the calibrated one (``after``), with the
    calibrated prediction's covariance."""

    before_res_mm: np.ndarray          # (n, 3) measured - predicted
    after_res_mm: np.ndarray           # (n, 3)
    after_cov_mm2: np.ndarray          # (n, 3, 3)
    protocol: str
    before_deg: np.ndarray | None = None
    after_deg: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.after_res_mm)

    def as_dict(self) -> dict:
        """``before``, ``after`` (:func:`calib.accuracy.error_stats`), the protocol, the convention, and the
        ``uncertainty`` honesty of the calibrated predictions."""
        z = np.zeros(3)
        return {**before_after_dict(point_errors_mm(self.before_res_mm, z), point_errors_mm(self.after_res_mm, z),
                                    self.protocol, self.before_deg, self.after_deg),
                "uncertainty": honesty(self.after_res_mm, self.after_cov_mm2)}

    @staticmethod
    def pooled(parts: list["HeldOut"], protocol: str) -> "HeldOut":
        """Folds' predictions together (every row predicted once, by the fold that did not see it)."""
        cat = np.concatenate
        deg = all(p.after_deg is not None for p in parts) and bool(parts)
        return HeldOut(cat([p.before_res_mm for p in parts]), cat([p.after_res_mm for p in parts]),
                       cat([p.after_cov_mm2 for p in parts]), protocol,
                       cat([p.before_deg for p in parts]) if deg else None,
                       cat([p.after_deg for p in parts]) if deg else None)


def predict_heldout(model, before_theta: np.ndarray, after, q_rad: np.ndarray, ctx, points_mm: np.ndarray,
                    point_cov_mm2: np.ndarray, protocol: str) -> HeldOut:
    """Predict the held-out rows (``q_rad``, ``ctx``, measured ``points_mm`` with their covariance) with the located
    nominal parameters ``before_theta`` and the calibrated identification ``after``."""
    before = points_mm - model.points(q_rad, ctx, np.asarray(before_theta)[: model.P])
    res = points_mm - model.points(q_rad, ctx, after.theta[: model.P])
    return HeldOut(before, res, predicted_cov_mm2(model, after, q_rad, ctx, point_cov_mm2), protocol)


def crossval(model, obs, choose, k: int = 5, pose_id: list | None = None) -> HeldOut:
    """k-fold cross-validated predictions in which every choice is made again in each fold: ``choose(train_idx)``
    returns ``(before_theta, after_identification)`` fitted on those rows only (the model selection, the outlier
    decision and the noise scale included); ``choose(train_idx, test_idx)`` may also return the test rows'
    observations weighted by the fold's own noise decision; each row is predicted once, by the fold that did not
    see it.  Rows of
    one pose (several targets: ``pose_id``) are held out together."""
    groups = len(set(pose_id)) if pose_id else obs.n
    k = int(min(k, groups))
    folds = grouped_folds(list(pose_id), k) if pose_id and groups < obs.n else make_folds(obs.n, k)
    parts = []
    order = []
    for tr, te in folds:
        got = choose(tr, te) if _takes_test(choose) else choose(tr)
        before, after = got[:2]
        o = got[2] if len(got) > 2 else obs.subset(te)      # the test rows as the fold weighs them, when it says
        parts.append(predict_heldout(model, before, after, o.q_rad, o.ctx, o.points_mm, o.cov_mm2, ""))
        order.append(te)
    out = HeldOut.pooled(parts, f"{k}-fold cross-validation, every choice made again in each fold")
    inv = np.argsort(np.concatenate(order))          # back to the rows' order
    out.before_res_mm, out.after_res_mm, out.after_cov_mm2 = (out.before_res_mm[inv], out.after_res_mm[inv],
                                                              out.after_cov_mm2[inv])
    return out


def _takes_test(choose) -> bool:
    try:
        return len(inspect.signature(choose).parameters) >= 2
    except (TypeError, ValueError):
        return False

