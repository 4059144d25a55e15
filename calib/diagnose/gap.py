"""The gap: the geometric model fitted and scored on poses it was not fitted to.

Why held-out: a fit always explains its own poses better than the robot deserves (p parameters soak up p directions
of noise and unmodelled motion).  Scoring every pose by a fit that never saw it (k-fold) measures what a calibrated
model will do in use, and is what candidate effects are scored by.

Why 5-fold whatever the number of poses (:data:`DIAGNOSE_FOLDS`; ``--folds`` sets another k, ``--folds N`` with N
poses is leave-one-out): the folds choose effects, and leave-one-out chooses too many.  Its score is the fit's own
residual corrected by each pose's leverage, asymptotically Akaike's criterion, which keeps a term that fits noise or
stands in for another effect with a probability that does not vanish as poses are added (Shao, "Linear model
selection by cross-validation", JASA 1993: the held-out share must not shrink).  On the TIAGo training session
leave-one-out accepted, besides the wrist's play, plays on two other joints that no other session confirms, and on
its placebo (the next move's direction instead of the last) a joint compliance on the wrist standing in for the
gravity-held play the wrong directions leave in the data (2.5 sigma, its residual still ordered by the joint's
angle); with 5 folds neither (docs/diagnose-speed.md).  And 5 fits a candidate instead of one a pose.

Noise floor: the RMS 3-D error the instruments alone would give, ``sqrt(mean_i trace(cov_i))``, from each point's
covariance (theodolite intersection, ``sigma_*_mm`` columns) or ``--noise-mm``.  A held-out fit can not reach it
exactly: the parameters carry estimation noise too; :func:`heldout_floor_mm` gives that expected held-out floor.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from calib.effects.target_offset import TargetOffset
from calib.errors import RobocalError
from calib.identify import Identification, default_free, identify
from calib.model import MeasurementModel
from calib.threads import parallel_fits

from .data import DiagnosisData

from calib.accuracy import floor_mm, grouped_folds, make_folds

#: the diagnosis's folds unless told (see the module docstring: not leave-one-out for small sets)
DIAGNOSE_FOLDS = 5


def data_folds(data: DiagnosisData, k: int | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
    """The data's own split (one fold: fit rows train, test rows are held out) when it has one, else
    :func:`make_folds` with ``k`` folds (default :data:`DIAGNOSE_FOLDS`)."""
    if not data.split:
        k = k or DIAGNOSE_FOLDS
        if data.pose_id and len(set(data.pose_id)) < data.n:     # several targets per pose: held out together
            return grouped_folds(data.pose_id, k)
        return make_folds(data.n, k)
    s = np.asarray(data.split)
    fit, test = np.flatnonzero(s == "fit"), np.flatnonzero(s == "test")
    if len(test) == 0 or len(fit) == 0:
        raise RobocalError(f"{data.source}: the split column needs both fit and test rows "
                           f"({len(fit)} fit, {len(test)} test)")
    return [(fit, test)]


def check_folds(folds, n_params: int, source: str) -> None:
    """Every training set must hold at least as many observations as parameters: one line otherwise."""
    for i, (tr, _) in enumerate(folds):
        if 3 * len(tr) < n_params:
            raise RobocalError(f"{source}: held-out fold {i + 1} trains on {len(tr)} poses ({3 * len(tr)} "
                               f"observations) for {n_params} parameters; use fewer folds, --geometry offsets or "
                               f"more poses")


def geometric_free(model: MeasurementModel, level: str = "full") -> list[str]:
    """The geometric parameters to fit: ``full`` (identify's conventional set) or ``offsets`` (base, tool and the
    joint zero offsets only: for small data sets, as FIGAROH's ``joint_offset`` level).  Either way with the tool
    points of the data's extra targets (their offsets from the reference point), as identify fits them."""
    targets = [q for e in model.effects if isinstance(e, TargetOffset) for q in e.qualified_names()]
    if level == "full":
        names = default_free(model, effects=False)
    else:
        names = [n for n in model.kin.names if n.startswith(("base.", "tool."))]
        for j in range(model.robot.n):
            names.append(f"j{j + 1}.d_mm" if model.robot.prismatic[j] else f"j{j + 1}.theta_offset_rad")
    order = {n: i for i, n in enumerate(model.names)}
    return sorted(names + targets, key=order.get)


def auto_level(model: MeasurementModel, n_poses: int, n_folds: int, n_train: int | None = None) -> str:
    """``full`` unless a training fold (``n_train`` poses, default from k-fold) has fewer than three observations per
    full-set parameter."""
    if n_train is None:
        n_train = n_poses - int(np.ceil(n_poses / n_folds))
    return "full" if 3 * n_train >= 3 * len(geometric_free(model, "full")) else "offsets"


@dataclass
class FoldFit:
    train: np.ndarray
    test: np.ndarray
    theta: np.ndarray          # the model's parameter vector fitted on ``train``
    free: list[str]            # what the fit estimated (after the identifiability guard)
    #: (N, 3) the model's points at ``theta`` for every row: the fit rows from the fit's own last evaluation, the test
    #: rows as predicted (see :meth:`CVResult.points_mm`)
    points_mm: np.ndarray | None = field(default=None, repr=False, compare=False)


@dataclass
class CVResult:
    model: MeasurementModel
    folds: list[FoldFit]
    residual_mm: np.ndarray    # (N, 3) measured - predicted, each pose by the fold that did not see it
    chi2: float                # whitened held-out sum of squares
    all_fit: Identification    # the same model fitted on every pose (parameters, Jacobian point)
    #: the rows fitted (what :meth:`points_mm` checks it is asked about)
    data: DiagnosisData | None = field(default=None, repr=False, compare=False)

    @property
    def rms_mm(self) -> float:
        return rms_mm(self.residual_mm)

    def points_mm(self, data: DiagnosisData, fold: int | None = None) -> np.ndarray:
        """(N, 3) the model's points for every row of ``data`` at fold ``fold``'s fit (None: the all-row fit).

        Why kept: every round of the selection starts from each fold's residual on all rows, and the ladder's
        linearised steps from the same; the fits evaluated exactly these points last (a row's point does not depend
        on the other rows), so a pass of the model over every row per fold and round is saved.  Evaluated when
        ``data`` are not the rows fitted."""
        m = self.model
        if fold is None:
            th = self.all_fit.theta
            prob = self.all_fit.problem
            if data is self.data and prob is not None and prob.obs.n == data.n:
                return prob.last_points(th)
            return m.points(data.q_rad, data.ctx, th[: m.P])
        f = self.folds[fold]
        if data is self.data and f.points_mm is not None:
            return f.points_mm
        return m.points(data.q_rad, data.ctx, f.theta)

    @property
    def max_mm(self) -> float:
        return float(np.nanmax(np.linalg.norm(self.residual_mm, axis=1)))

    @property
    def tested(self) -> np.ndarray:
        """(N,) poses some fold held out (all of them, unless the data bring their own split)."""
        return np.isfinite(self.residual_mm).all(axis=1)


def rms_mm(res: np.ndarray) -> float:
    """RMS of the 3-D residual length (poses without a held-out residual, NaN, left out)."""
    return float(np.sqrt(np.nanmean(np.sum(np.asarray(res) ** 2, axis=-1))))


def noise_floor_mm(data: DiagnosisData) -> float:
    """RMS 3-D error the instruments alone explain (one formula: :func:`calib.accuracy.floor_mm`)."""
    return floor_mm(data.cov_mm2)


def whitened_chi2(data: DiagnosisData, res: np.ndarray, idx=None) -> float:
    W = data.whitening if idx is None else data.whitening[idx]
    return float(np.nansum(np.einsum("nij,nj->ni", W, res) ** 2))


#: rows x free parameters from which a cross-validation's fits run in threads: below it the fits' Python share
#: dominates and the threads only contend for the interpreter's lock (400 Puma poses x 30 parameters: 1.26 -> 1.67 s
#: whole process in threads; the elastic tree's 1000 rows x 100: 28.5 -> 23.6 s)
PARALLEL_MIN_SIZE = 40_000


def cv_fit(model: MeasurementModel, data: DiagnosisData, free: list[str], folds, theta0: list[np.ndarray] | None = None,
           theta0_all: np.ndarray | None = None, start: bool = True, loss: str = "linear",
           report: bool = True) -> CVResult:
    """Fit ``model`` on each fold's training poses with :func:`calib.identify.identify` and predict its test poses.

    ``theta0`` (one per fold) warm-starts refits after an effect was added; ``start`` runs identify's own start
    (rigid base fit and the linear step of Chapter 6) for the first, geometric fit.  ``loss``: the least-squares
    loss (as identify's ``--loss``), so the diagnosis fits exactly as identify does.  The folds' fits report nothing
    (identify's ``report=False``: they only predict); ``report=False`` asks the same of the all-pose fit (a ladder
    step, scored by its residual sum of squares).
    """
    check_folds(folds, len(free), data.source)
    res = np.full_like(data.points_mm, np.nan)

    def fold(i):
        tr, te = folds[i]
        obs = data.observations(tr)
        idn = identify(model, obs, free=free, theta0=None if theta0 is None else theta0[i], outliers="off",
                       start=start, loss=loss, report=False)       # a fold's fit only predicts its test rows
        th = idn.theta[: model.P]
        pts = np.empty_like(data.points_mm)
        pts[tr] = idn.problem.last_points(idn.theta)                # the fit's own last evaluation: no pass
        pts[te] = model.points(data.q_rad[te], data.ctx.subset(te), th)
        return FoldFit(tr, te, th, list(idn.free), pts)

    def whole():
        return identify(model, data.observations(), free=free, theta0=theta0_all, outliers="off", start=start,
                        loss=loss, report=report)

    workers = min(parallel_fits(), len(folds) + 1) if data.n * len(free) >= PARALLEL_MIN_SIZE else 1
    if workers > 1:             # independent fits: the same numbers in any order (calib.threads.parallel_fits)
        with ThreadPoolExecutor(workers) as pool:
            whole_fit = pool.submit(whole)
            fits = list(pool.map(fold, range(len(folds))))
            all_fit = whole_fit.result()
    else:
        fits = [fold(i) for i in range(len(folds))]
        all_fit = whole()
    for f in fits:
        res[f.test] = data.points_mm[f.test] - f.points_mm[f.test]
    return CVResult(model, fits, res, whitened_chi2(data, res), all_fit, data)


def heldout_floor_mm(cv: CVResult, data: DiagnosisData) -> float:
    """The held-out RMS a perfect model would show: instrument noise plus the prediction noise of the fitted
    parameters, ``sqrt(mean_i [trace(cov_i) + trace(J_i C J_i^T)])`` with C the fold fit's covariance from the
    instrument weights alone (not inflated by the misfit)."""
    model = cv.model
    ev = model.evaluate(data.q_rad, data.ctx, cv.all_fit.theta[: model.P], jacobian=True)
    W = data.whitening
    tot = np.trace(data.cov_mm2, axis1=1, axis2=2).copy()
    for f in cv.folds:
        idx = [model.index[n] for n in f.free]
        Jt = np.einsum("nij,njp->nip", W[f.train], ev.jacobian[f.train][:, :, idx]).reshape(-1, len(idx))
        C = np.linalg.pinv(Jt.T @ Jt)
        Jte = ev.jacobian[f.test][:, :, idx]
        tot[f.test] += np.einsum("nip,pq,niq->n", Jte, C, Jte)
    return float(np.sqrt(np.mean(tot)))
