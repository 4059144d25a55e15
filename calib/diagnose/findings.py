"""A finding, a near miss, and the refit and measures that judge a candidate effect (held-out gain, the spread of
its parameters over the folds, its stated error).

Shared by the greedy selection (:mod:`calib.diagnose.select`), the joint groups (:mod:`calib.diagnose.jointly`) and
the stand-in rules (:mod:`calib.diagnose.standins`): in a module of their own so that none imports another's
private helpers and the selection and the joint groups do not import each other.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.model import MeasurementModel

from .candidate import Candidate
from .data import DiagnosisData
from .gap import CVResult, cv_fit

#: an accepted effect must shrink the held-out RMS by this share of the baseline excess (baseline - floor)
MATERIAL_SHARE = 0.10
#: jackknife relative spread of the parameters across folds above which a candidate is not accepted
STABLE_MAX = 0.5
#: ... and above which an accepted finding is marked doubtful
DOUBTFUL_SPREAD = 0.25


@dataclass
class Finding:
    candidate: Candidate
    rms_after_mm: float
    max_after_mm: float
    p_value: float                  # Bonferroni-corrected
    f_statistic: float
    delta_bic: float                # BIC(with) - BIC(without), whitened, for reference
    heldout_chi2: float
    parameters: dict[str, float]
    n_tested: int
    stability: float = 0.0          # jackknife relative spread of the parameters across folds
    aliases: list[str] = field(default_factory=list)
    shrink_share: float = float("nan")   # share of the baseline excess this effect removed
    fit: CVResult | None = None     # the model with this and the earlier findings, fitted (for --confirm)
    leftover: str = ""              # structure the final residual still shows along this effect's own driver
    stated_spread: float = float("nan")  # the parameters' stated 1-sigma (Jacobian or folds, the larger) / value
    jointly: list[str] = field(default_factory=list)   # the other members of its joint group (calib.diagnose.jointly)

    @property
    def unstable(self) -> bool:
        """The parameters are not determined to better than :data:`DOUBTFUL_SPREAD` of their value by their own
        stated error (the larger of the Jacobian's and the folds' spread): the amplitude is within 4 sigma of 0."""
        spread = self.stated_spread if self.stated_spread == self.stated_spread else self.stability
        return spread > DOUBTFUL_SPREAD

    @property
    def doubtful(self) -> bool:
        return self.unstable or bool(self.aliases) or bool(self.leftover)


@dataclass
class NearMiss:
    """A candidate that was refitted or tested but not accepted, and why (the "closest candidates")."""
    label: str
    rms_mm: float                   # held-out RMS with it (refitted, or the linearised prediction)
    p_value: float
    reason: str
    group: tuple = ()               # the candidate's group (one per joint and kind)

    def as_dict(self) -> dict:
        return {"candidate": self.label, "rms_mm": self.rms_mm, "p_value": self.p_value, "reason": self.reason}


def project(Q: np.ndarray, A: np.ndarray) -> np.ndarray:
    """A with the span of the orthonormal columns Q projected out."""
    return A - Q @ (Q.T @ A)


def stability(model: MeasurementModel, cv: CVResult, cand: Candidate, e_i: int = -1) -> tuple[float, np.ndarray]:
    """Jackknife spread of an effect's estimated parameters over the folds (``e_i``: its index in the model, the
    newest by default): (relative spread, per-parameter sigma of the whole effect's parameters, zero for the ones not
    estimated)."""
    e_i = e_i % len(model.effects)
    s = model.effect_slices[e_i]
    names = model.effects[e_i].param_names
    idx = [s.start + names.index(p) for p in cand.free]
    vals = np.array([f.theta[idx] for f in cv.folds])
    k = len(vals)
    if k < 2:                   # the data's own split: one fit, no spread to measure
        return float("nan"), np.zeros(s.stop - s.start)
    se = np.sqrt((k - 1) / k * np.sum((vals - vals.mean(0)) ** 2, axis=0))
    ref = float(np.linalg.norm(cv.all_fit.theta[idx]))
    full = np.zeros(s.stop - s.start)
    full[[names.index(p) for p in cand.free]] = se
    return (float(np.linalg.norm(se)) / ref if ref > 0 else float("inf")), full


def stated_spread(model: MeasurementModel, cv: CVResult, cand: Candidate, fold_sigma: np.ndarray,
                   e_i: int = -1) -> float:
    """An effect's stated 1-sigma (the larger of the Jacobian's and the folds' spread, as reported) relative to its
    estimated value (norms over its estimated parameters); ``e_i`` as :func:`stability`."""
    e_i = e_i % len(model.effects)
    s = model.effect_slices[e_i]
    names = model.effects[e_i].param_names
    loc = [names.index(p) for p in cand.free]
    sig = np.maximum(cv.all_fit.sigma[s][loc], fold_sigma[loc])
    ref = float(np.linalg.norm(cv.all_fit.theta[s][loc]))
    return float(np.linalg.norm(sig)) / ref if ref > 0 else float("inf")


def param_report(cand: Candidate, model: MeasurementModel, cv: CVResult, fold_sigma: np.ndarray,
                  e_i: int = -1) -> dict:
    """Parameters in edge units; the 1-sigma is the larger of the Jacobian's and the folds' spread."""
    e_i = e_i % len(model.effects)
    s = model.effect_slices[e_i]
    names = model.effects[e_i].param_names
    theta = cv.all_fit.theta
    sig = np.maximum(cv.all_fit.sigma[s], fold_sigma)
    vals = {n: float(theta[s][k]) for k, n in enumerate(names)}
    sigs = {n: float(sig[k]) for k, n in enumerate(names)}
    return cand.parameters(vals, sigs)


def refit(data: DiagnosisData, cur: CVResult, cand: Candidate | list[Candidate], geo_free: list[str],
           loss: str) -> tuple[MeasurementModel, CVResult]:
    """Step 5: the current model plus ``cand`` (or several candidates together) fitted fully in every fold (warm
    start) and on all poses."""
    cands = cand if isinstance(cand, list) else [cand]
    new = [c.make() for c in cands]
    model = MeasurementModel(data.robot, list(cur.model.effects) + new)
    qual = [f"{e.label}.{p}" for e, c in zip(new, cands) for p in c.free]
    vals = np.concatenate([e.values for e in new])
    th0 = [np.concatenate([f.theta, vals]) for f in cur.folds]
    th0_all = np.concatenate([cur.all_fit.theta[: cur.model.P], vals])
    folds = [(f.train, f.test) for f in cur.folds]
    free_all = list(dict.fromkeys(geo_free + [n for n in cur.model.names[cur.model.n_geometric:]
                                              if n in cur.all_fit.free] + qual))
    return model, cv_fit(model, data, free_all, folds, theta0=th0, theta0_all=th0_all, start=False, loss=loss)
