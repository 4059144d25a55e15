"""A finding, a near miss, and the refit and measures that judge a candidate effect (held-out gain, the spread of
its parameters over the folds, its stated error).

Shared by the greedy selection (:mod:`calib.diagnose.select`), the joint groups (:mod:`calib.diagnose.jointly`) and
the stand-in rules (:mod:`calib.diagnose.standins`): in a module of their own so that none imports another's
private helpers and the selection and the joint groups do not import each other.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.distributions import f_sf
from calib.model import MeasurementModel

from .candidate import Candidate
from .data import DiagnosisData
from .gap import CVResult, cv_fit

#: an accepted effect must shrink the held-out RMS by this share of the excess gap (:func:`material_reason`: of the
#: baseline's excess over the floor, or, for a confident step whose held-out gain is significant, of the gap still
#: open)
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


def heldout_gain_p(data: DiagnosisData, cur: CVResult, new: CVResult) -> float:
    """One-sided p-value that ``new`` predicts the held-out poses no better than ``cur`` (uncorrected).

    Per pose (its targets together: they were held out together), the drop of the whitened held-out squared
    residual from ``cur`` to ``new``; the mean drop against its own scatter over the poses, a paired t-test (t^2 is
    F(1, n - 1)).  Both fits saw the same training rows in every fold, so the drops are paired; the poses are
    independent.  Only held-out rows enter: no fit row can make the step look better than it predicts.
    """
    return paired_gain_p(data, cur.tested & new.tested, cur.residual_mm, new.residual_mm)


def paired_gain_p(data: DiagnosisData, tested: np.ndarray, before_mm: np.ndarray, after_mm: np.ndarray) -> float:
    """:func:`heldout_gain_p` on held-out residuals (N, 3) given as arrays (``tested``: the rows that have one):
    also a linearised prediction's, to screen a step before its refit."""
    t = tested
    if not np.any(t):
        return 1.0
    W = data.whitening[t]
    d = np.sum(np.einsum("nij,nj->ni", W, before_mm[t]) ** 2, axis=1) - \
        np.sum(np.einsum("nij,nj->ni", W, after_mm[t]) ** 2, axis=1)
    if data.pose_id:
        _, inv = np.unique(np.asarray(data.pose_id)[t], return_inverse=True)
        d = np.bincount(inv, weights=d)
    n = len(d)
    mean = float(d.mean())
    if n < 3 or mean <= 0:
        return 1.0
    s = float(d.std(ddof=1))
    if s == 0:
        return 0.0
    return 0.5 * float(f_sf((mean / (s / np.sqrt(n))) ** 2, 1, n - 1))


def material_reason(gain_mm: float, baseline_excess_mm: float, open_excess_mm: float, confident: bool,
                    heldout_p: float, alpha: float) -> str:
    """"" when a step's held-out gain is material, else why not (a phrase after "it").

    A step must remove a material share of the gap: :data:`MATERIAL_SHARE` of the **baseline's** excess over the
    floor, or of the excess **still open** (the current model's held-out RMS minus the floor) when the step is
    confident and predicts better beyond chance:

    * **Why the open gap.**  A fixed share of the baseline's gap makes the order of discovery decide: on the
      elastic tree, torso_2's lateral compliance comes first and its joint compliance then removes 22 % of what is
      left but less than 10 % of the baseline's gap, so it was refused although the residual followed its angle
      (p ~ 1e-57) and the model stopped at 1.8x the floor.  What a step should be judged against is what is still
      unexplained: the same share of it.
    * **Why only confident steps** (``confident``: no alias, not at the edge of its order grid, its value 4 sigma or
      more from zero).  A stand-in for an effect the library lacks shows itself by exactly these signs, and near the
      floor the open gap is small, so a tenth of it would let stand-ins in one after another (measuring groups'
      gains against the open gap alone let doubtful groups of cross couplings and backlashes in: 2 more wrong names
      in 87 cases).  A doubtful step keeps the baseline's share: to be named at all it must matter to the whole
      gap, and it is then flagged doubtful.
    * **Why a held-out test** (``heldout_p``: :func:`heldout_gain_p`, corrected by the caller, below ``alpha``).
      The nested F-test says the effect is there on the fit rows; a tenth of a small open gap can be won by chance
      on the folds, so the held-out gain must be significant too -- a paired test on the held-out poses, the rows
      the step's choice is scored on.  It guards the looser share; the baseline's share needs no test of its own
      (the rule as it was, unchanged).
    """
    if gain_mm >= MATERIAL_SHARE * baseline_excess_mm:
        return ""
    base = (f"shrinks the held-out RMS by {gain_mm:.4f} mm only, less than {100 * MATERIAL_SHARE:.0f} % of "
            f"the excess gap ({baseline_excess_mm:.4f} mm)")
    if gain_mm < MATERIAL_SHARE * open_excess_mm:
        return base + f" and of the gap still open ({open_excess_mm:.4f} mm)"
    if not confident:
        return base + " (a doubtful step is judged against the whole gap)"
    if not heldout_p < alpha:
        return base + f"; against the gap still open its held-out gain is not significant (p = {heldout_p:.3g})"
    return ""
