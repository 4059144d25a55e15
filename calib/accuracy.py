"""How accurate the robot was before calibration and is after, on poses the fit did not use.

Why held-out poses: a fit always looks good on the poses it was fitted to (it absorbs their noise); the robot's owner
wants to know how far the calibrated robot will be from where it is sent elsewhere.  The commercial reports (Spatial
Analyzer, RoboDK) and FIGAROH open with exactly these numbers.

* **before**: the nominal description, with only where the robot stands (base) and the tool point located on the
  fit poses -- the accuracy the robot had with its maker's description;
* **after**: the calibrated model (every parameter the identification estimated) fitted on the same fit poses;
* **floor**: what the instruments alone contribute to a position error (RMS of the 3-D point error from the points'
  covariances): an error near the floor means the model explains everything the instruments can see.  One floor per
  pose set: taken over every pose of the set (not the held-out few), so that the accuracy and the diagnosis of the same
  poses state the same floor (:func:`calib.diagnose.gap.noise_floor_mm` is the same formula over the same points).

One convention everywhere (:data:`CONVENTION`): the error of a point is its 3-D Euclidean distance from where the
model puts it, and RMS, mean, 95th percentile and maximum are taken over those distances.  (The other convention in
use -- RMS over the flattened x, y, z coordinates -- is smaller by exactly sqrt(3) for isotropic errors; robocal never
uses it for accuracy.)  :func:`error_stats` computes these statistics for every command: identify, diagnose, evaluate,
the session report.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .effects.station_offset import StationOffset
from .effects.target_offset import TargetOffset
from .errors import RobocalError
from .identify import identify


#: how robocal measures a position error (stated in the JSON of every command that reports accuracy)
CONVENTION = "per-point 3-D Euclidean distance |measured - predicted| in mm; statistics over points"


def point_errors_mm(measured_mm: np.ndarray, predicted_mm: np.ndarray) -> np.ndarray:
    """(N,) per-point 3-D distances (the one convention, :data:`CONVENTION`)."""
    return np.linalg.norm(np.asarray(measured_mm, float) - np.asarray(predicted_mm, float), axis=-1)


def error_stats(err_mm: np.ndarray, err_deg: np.ndarray | None = None) -> dict:
    """``n``, ``mean_mm``, ``rms_mm``, ``p95_mm``, ``max_mm`` of per-point distances (``mean_deg``, ``max_deg`` of
    per-pose geodesic orientation errors when given): the one set of accuracy statistics every command reports.
    No rows: ``n`` 0 and the figures None."""
    e = np.asarray(err_mm, float).ravel()
    e = e[np.isfinite(e)]
    out: dict = {"n": int(e.size)}
    if e.size == 0:
        out.update(mean_mm=None, rms_mm=None, p95_mm=None, max_mm=None)
    else:
        out.update(mean_mm=float(e.mean()), rms_mm=float(np.sqrt(np.mean(e ** 2))),
                   p95_mm=float(np.percentile(e, 95)), max_mm=float(e.max()))
    if err_deg is not None:
        a = np.asarray(err_deg, float).ravel()
        a = a[np.isfinite(a)]
        out.update(mean_deg=float(a.mean()) if a.size else None, max_deg=float(a.max()) if a.size else None)
    return out


def before_after_dict(before_mm: np.ndarray, after_mm: np.ndarray, protocol: str,
                      before_deg: np.ndarray | None = None, after_deg: np.ndarray | None = None) -> dict:
    """The ``before`` and ``after`` JSON objects (:func:`error_stats`), the protocol that held the rows out and the
    distance convention."""
    return {"before": error_stats(before_mm, before_deg), "after": error_stats(after_mm, after_deg),
            "heldout_protocol": protocol, "error_convention": CONVENTION}


def before_after_line(doc: dict) -> str:
    """The terminal's first words on accuracy: ``before 4.12 mm mean (RMS 4.50, max 9.1) -> after ...``."""
    def one(s: dict) -> str:
        if not s.get("n"):
            return "-"
        deg = f", {s['mean_deg']:.3f} deg mean" if s.get("mean_deg") is not None else ""
        return f"{s['mean_mm']:.3f} mm mean (RMS {s['rms_mm']:.3f}, p95 {s['p95_mm']:.3f}, max {s['max_mm']:.3f}{deg})"
    return (f"accuracy on {doc['after']['n']} held-out points ({doc['heldout_protocol']}): before {one(doc['before'])}"
            f" -> after {one(doc['after'])}")


@dataclass
class Accuracy:
    before_err_mm: np.ndarray          # (n_test,) position error of every test pose, nominal description
    after_err_mm: np.ndarray           # (n_test,) position error of every test pose, calibrated model
    floor_mm: float                    # RMS 3-D error the instruments alone explain, over every pose of the set
    test_index: np.ndarray             # which poses were held out
    protocol: str = "every 4th pose held out"     # how (for the JSON and the terminal)

    @property
    def n_test(self) -> int:
        return int(len(self.after_err_mm))

    def as_dict(self) -> dict:
        """The ``accuracy`` key of the results JSON: ``before``/``after`` objects (:func:`error_stats`) and, as
        before, the flat ``before_rms_mm``... keys the session report reads."""
        b, a = error_stats(self.before_err_mm), error_stats(self.after_err_mm)
        return {"before_rms_mm": b["rms_mm"], "before_p95_mm": b["p95_mm"], "before_max_mm": b["max_mm"],
                "after_rms_mm": a["rms_mm"], "after_p95_mm": a["p95_mm"], "after_max_mm": a["max_mm"],
                "n_test": self.n_test, "floor_mm": float(self.floor_mm),
                **before_after_dict(self.before_err_mm, self.after_err_mm, self.protocol)}


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


#: below this many poses the diagnosis's held-out test is leave-one-out, above it k-fold
LOO_MAX_POSES = 40


def make_folds(n: int, k: int | None = None, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """(train, test) index pairs; every pose is tested exactly once.  ``k=None``: 5-fold, or leave-one-out up to
    :data:`LOO_MAX_POSES` poses."""
    if k is None:
        k = n if n <= LOO_MAX_POSES else 5
    k = int(min(max(k, 2), n))
    perm = np.random.default_rng(seed).permutation(n)
    parts = np.array_split(perm, k)
    return [(np.sort(np.concatenate(parts[:i] + parts[i + 1:])), np.sort(parts[i])) for i in range(k)]


def grouped_folds(pose_id: list[str], k: int | None = None, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`make_folds` over poses rather than rows: the rows of one pose (its targets) are held out together, so
    a pose is never predicted by a fit that saw the same configuration through another target."""
    _, group = np.unique(np.asarray(pose_id), return_inverse=True)
    return [(np.flatnonzero(np.isin(group, tr)), np.flatnonzero(np.isin(group, te)))
            for tr, te in make_folds(int(group.max()) + 1, k, seed)]


def floor_mm(cov_mm2: np.ndarray) -> float:
    """RMS of the 3-D point error from the points' covariances (N, 3, 3)."""
    return float(np.sqrt(np.mean(np.trace(np.asarray(cov_mm2), axis1=1, axis2=2))))


def locate_free(model) -> list[str]:
    """Where the robot stands and its tool point: what 'before calibration' may still fit -- the base, the tool
    point, the other targets' offsets from it and the other instrument set-ups (station offsets)."""
    names = [n for n in model.kin.names if n.startswith(("base.", "tool."))]
    for e in model.effects:
        if isinstance(e, (TargetOffset, StationOffset)):
            names += e.qualified_names()
    return names


def before_after(model, obs, free: list[str], theta0: np.ndarray | None = None, priors: dict | None = None,
                 split: tuple[np.ndarray, np.ndarray] | None = None, identify_fn=None,
                 warm: np.ndarray | None = None) -> Accuracy:
    """Fit the located nominal model and the calibrated model on the fit poses; errors on the test poses.

    ``model`` and ``obs`` (:class:`calib.identify.PointObservations`) as for :func:`calib.identify.identify`;
    ``free`` the calibrated model's free parameters, ``theta0``/``priors`` its start and priors; ``warm``: the
    calibrated model fitted on every pose, where the fit on the fit poses starts (a start point only: it converges
    to the fit poses' own minimum).  Neither fit flags gross errors: flagging reports them and changes no fit.
    Both fits only predict the test poses: ``report=False`` (no covariance, no words on held directions; the same
    estimate, :func:`calib.identify.identify`): 1-4 ms of the demo's 25-40.
    """
    identify_fn = identify_fn or identify
    fit, test = split if split is not None else holdout(obs.n)
    o_fit, o_test = obs.subset(fit), obs.subset(test)
    nominal = model.nominal.copy()
    located = identify_fn(model, o_fit, free=locate_free(model), theta0=nominal, outliers="off", report=False)
    more = {"warm": warm} if warm is not None else {}
    calibrated = identify_fn(model, o_fit, free=free, theta0=theta0 if theta0 is not None else nominal,
                             priors=priors or {}, outliers="off", report=False, **more)

    def errors(theta):
        pred = model.points(o_test.q_rad, ctx=o_test.ctx, theta=np.asarray(theta)[: model.P])
        return np.linalg.norm(o_test.points_mm - pred, axis=1)

    cov = obs.cov_mm2 if getattr(obs, "cov_mm2", None) is not None else np.zeros((obs.n, 3, 3))
    return Accuracy(errors(located.theta), errors(calibrated.theta), floor_mm(cov), test,
                    "the given split" if split is not None else "every 4th pose held out")
