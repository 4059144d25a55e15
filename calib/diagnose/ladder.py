"""The sim-to-real ladder: the model built up step by step, each step scored on held-out rows (issue 24, item 3).

Why: an owner wants to see where the gap lies and how far each kind of correction shrinks it -- as DLR reports
Agile Justin's calibration (frames only, + joint offsets, + full geometry, + elasticity, ...; mean, RMS and maximum
of the held-out error at each step) -- and what each accepted group is worth in the final model (leave one group
out: the final model without it, refitted).

Steps: the **located nominal** description (only where the robot stands and its tool points fitted: ``before``),
**+ joint offsets**, **+ full geometry** (the rest of the geometric set), then each **accepted effect** in the order
the diagnosis accepted it; the last step is the diagnosis's final model (``after``).  Each step's significance is the
nested F-test of the step against the one before on the fit rows (whitened residual sums of squares), and for an
effect also the selection's own corrected p-value.

Scored rows: the test rows of the data's split (every step refitted on the fit rows alone and scored once), or the
k-fold predictions of the fit rows.  The located nominal model, the geometric baseline and the effect steps are the
fits the diagnosis made (exact); the joint-offsets step and the leave-one-group-out models that no fit of the
diagnosis holds are one Gauss-Newton step from the final fit with the group held at its design values (the fits of a
calibration are nearly linear there; ``refit`` says which).
"""
from __future__ import annotations

import textwrap
from dataclasses import dataclass, field

import numpy as np

from calib.accuracy import error_stats, locate_free
from calib.distributions import f_sf
from calib.heldout import HeldOut, noise_scale, predicted_cov_mm2
from calib.identify import identify
from calib.model import MeasurementModel
from calib.names import effect_label, prose
from calib.pruning import LinearFit

from .data import DiagnosisData
from .gap import CVResult, cv_fit, geometric_free


@dataclass
class Scored:
    """One model scored: per-point held-out residuals, the fit on every fit row, how it was refitted."""

    name: str
    added: str
    model: MeasurementModel
    free: list[str]
    residual_mm: np.ndarray            # (n_scored, 3)
    rss: float                         # whitened residual sum of squares on the fit rows
    n_obs: int
    refit: str = "exact"
    selection_p: float | None = None
    accepted: bool = True

    def stats(self) -> dict:
        e = error_stats(np.linalg.norm(self.residual_mm, axis=1))
        return {f"test_{k}" if k != "n" else "n_test": v for k, v in e.items()}


@dataclass
class Ladder:
    steps: list[Scored]
    logo: list[tuple[Scored, Scored]]           # (the final model without a group, the final model)
    protocol: str
    heldout: HeldOut | None = None
    p_values: list[tuple[float | None, float | None]] = field(default_factory=list)   # (F, p) per step

    def as_json(self) -> list[dict]:
        out = []
        for s, (F, p) in zip(self.steps, self.p_values):
            out.append({"model": s.name, "added": s.added, "n_params": len(s.free), **s.stats(),
                        "f_statistic": F, "p_value": p, "selection_p_value": s.selection_p,
                        "significance": _words(p, s.selection_p), "accepted": s.accepted, "refit": s.refit})
        return out

    def logo_json(self) -> list[dict]:
        out = []
        for without, final in self.logo:
            a, b = without.stats(), final.stats()
            out.append({"without": without.added, "n_params": len(without.free), **a,
                        "loss_rms_mm": _diff(a["test_rms_mm"], b["test_rms_mm"]),
                        "loss_mean_mm": _diff(a["test_mean_mm"], b["test_mean_mm"]), "refit": without.refit})
        return out

    def lines(self, robot=None) -> list[str]:
        """The ladder and the leave-one-group-out table as terminal lines: a label longer than its column wraps at
        its words onto lines of its own below the numbers, so the columns stay aligned and nothing is cut.
        ``robot``: joints named as its description names them (before the wrapping, which counts their length)."""
        out = [f"   {'step':<{LABEL_WIDTH + 1}}{'params':>7}{'mean':>9}{'RMS':>9}{'max':>9}  significance"]
        for row in self.as_json():
            first, *rest = _wrapped(prose(row["model"], robot) if robot else row["model"], LABEL_WIDTH)
            out.append(f"   {first:<{LABEL_WIDTH + 1}}{row['n_params']:>7}{_f(row['test_mean_mm'])}"
                       f"{_f(row['test_rms_mm'])}{_f(row['test_max_mm'])}  {row['significance']}"
                       + ("" if row["accepted"] else " (not in the final model)"))
            out += [f"       {r}" for r in rest]
        if self.logo:
            out.append("   leave one group out (the final model without it, refitted): held-out RMS and what the "
                       "group is worth")
            for row in self.logo_json():
                label = "without " + row["without"]
                first, *rest = _wrapped(prose(label, robot) if robot else label, LABEL_WIDTH - 2)
                out.append(f"     {first:<{LABEL_WIDTH - 1}}{_f(row['test_rms_mm'])} mm RMS, "
                           f"{_f(row['test_mean_mm'])} mm mean: loss {row['loss_rms_mm']:+.4f} mm RMS")
                out += [f"         {r}" for r in rest]
        return out


#: characters of a step's label on the line of its numbers (longer labels wrap at their words)
LABEL_WIDTH = 45


def _wrapped(label: str, width: int) -> list[str]:
    """``label`` in lines of at most ``width`` characters, broken between words (the continuation lines are indented
    by the caller, so they are 4 characters shorter)."""
    first = textwrap.wrap(label, width, break_on_hyphens=False) or [""]
    if len(first) == 1:
        return first
    rest = textwrap.wrap(label[len(first[0]):].strip(), width - 4, break_on_hyphens=False)
    return [first[0]] + rest


def _f(v) -> str:
    return f"{v:>9.4f}" if v is not None else f"{'-':>9}"


def _diff(a, b):
    return None if a is None or b is None else float(a - b)


def _words(p: float | None, sel_p: float | None) -> str:
    if p is None:
        return "-"
    txt = f"nested F p = {p:.2g}" + (f", selection p = {sel_p:.2g}" if sel_p is not None else "")
    return txt + ("" if p < 0.01 else " (not significant at 0.01)")


# -- scoring ---------------------------------------------------------------------------------------------------------
@dataclass
class _Scorer:
    """Scores models on the held-out rows: ``test`` (the split's test rows) or the k-fold predictions of ``data``."""

    data: DiagnosisData
    test: DiagnosisData | None
    folds: list
    loss: str
    #: per fit (keyed by its identity), its model's whitened Jacobian of the free columns at the all-row fit: the
    #: leave-one-group-out steps linearise the same final fit once per group
    _jw: dict = field(default_factory=dict, repr=False)

    def of_cv(self, name: str, added: str, cv: CVResult, selection_p=None, accepted=True) -> Scored:
        """A fit the diagnosis made (exact): its k-fold residuals, or its all-row fit scored on the test rows."""
        m = cv.model
        res = cv.residual_mm if self.test is None else self._test_res(m, cv.all_fit.theta)
        return Scored(name, added, m, list(cv.all_fit.free), res, _rss(cv.all_fit), cv.all_fit.n_obs, "exact",
                      selection_p, accepted)

    def _test_res(self, model, theta) -> np.ndarray:
        t = self.test
        return t.points_mm - model.points(t.q_rad, t.ctx, np.asarray(theta)[: model.P])

    def exact(self, name: str, added: str, model: MeasurementModel, free: list[str], cur: CVResult) -> Scored:
        """Refit ``model`` with ``free`` from ``cur``'s fits (the rest at their design values): every fold and the
        fit rows (no split), or the fit rows alone (split)."""
        th_all = _start(model, free, cur.all_fit.theta)
        if self.test is None:
            cv = cv_fit(model, self.data, free, [(f.train, f.test) for f in cur.folds],
                        theta0=[_start(model, free, f.theta) for f in cur.folds], theta0_all=th_all, start=False,
                        loss=self.loss, report=False)
            return Scored(name, added, model, list(cv.all_fit.free), cv.residual_mm, _rss(cv.all_fit),
                          cv.all_fit.n_obs)
        idn = identify(model, self.data.observations(), free=free, theta0=th_all, outliers="off", start=False,
                       loss=self.loss, report=False)            # scored on the test rows and by its rss
        return Scored(name, added, model, list(idn.free), self._test_res(model, idn.theta), _rss(idn), idn.n_obs)

    def linear(self, name: str, added: str, cur: CVResult, hold: list[str], accepted=True) -> Scored:
        """``cur``'s model with ``hold`` at their design values, the rest refitted by one Gauss-Newton step from each
        of ``cur``'s fits (:class:`calib.pruning.LinearFit`)."""
        m, data = cur.model, self.data
        free = [n for n in cur.all_fit.free if n in m.index]
        idx = [m.index[n] for n in free]
        keep = np.array([n not in hold for n in free])
        Jw = self._whitened_jacobian(cur, idx)

        def lin(theta, fold=None):
            r = np.einsum("nij,nj->ni", data.whitening, data.points_mm - cur.points_mm(data, fold))
            return LinearFit(Jw, r, np.zeros((0, len(idx))), np.zeros(0), theta[idx], m.nominal[idx],
                             np.ones(len(idx), bool), True, data.whitening)

        every = np.arange(data.n)
        whole = lin(cur.all_fit.theta[: m.P])
        d, _ = whole.fit(every, keep)
        rw = whole.r - np.einsum("nkp,p->nk", whole.J, d)
        if self.test is None:
            res = np.full_like(data.points_mm, np.nan)
            for i, f in enumerate(cur.folds):
                lf = lin(f.theta, i)
                df, _ = lf.fit(f.train, keep)
                res[f.test] = lf.predict_mm(f.test, df)
        else:
            th = cur.all_fit.theta[: m.P].copy()
            th[idx] += d
            res = self._test_res(m, th)
        return Scored(name, added, m, [n for n, k in zip(free, keep) if k], res, float(np.sum(rw ** 2)),
                      3 * data.n, "linearised", accepted=accepted)


    def _whitened_jacobian(self, cur: CVResult, idx: list[int]) -> np.ndarray:
        """(N, 3, len(idx)) the whitened Jacobian of ``cur``'s model at its all-row fit, columns ``idx`` (computed
        once per fit and columns)."""
        fit, jw = self._jw.get(id(cur), (None, None))
        if fit is not cur or jw[0] != idx:
            m, data = cur.model, self.data
            ev = m.evaluate(data.q_rad, data.ctx, cur.all_fit.theta[: m.P], jacobian=True)
            jw = (list(idx), np.einsum("nij,njp->nip", data.whitening, ev.jacobian[:, :, idx]))
            self._jw[id(cur)] = (cur, jw)
        return jw[1]


def _start(model: MeasurementModel, free: list[str], theta: np.ndarray) -> np.ndarray:
    """Design values, with ``free`` taken from ``theta`` (a fit of the same or a larger model)."""
    th = model.nominal.copy()
    for n in free:
        if n in model.index and model.index[n] < len(theta):
            th[model.index[n]] = theta[model.index[n]]
    return th


def _rss(ident) -> float:
    return float(ident.reduced_chi2) * max(1, int(ident.n_obs) - len(ident.free))


def _nested(prev: Scored, cur: Scored) -> tuple[float | None, float | None]:
    """Nested F-test of ``cur`` against ``prev`` on the fit rows (None when it adds no parameter)."""
    dp = len(cur.free) - len(prev.free)
    dof = cur.n_obs - len(cur.free)
    if dp <= 0 or dof <= 0 or not cur.rss > 0:
        return None, None
    F = max(0.0, (prev.rss - cur.rss) / dp) / (cur.rss / dof)
    return float(F), float(f_sf(F, dp, dof))


# -- the ladder ------------------------------------------------------------------------------------------------------
def build(data: DiagnosisData, test: DiagnosisData | None, folds, level: str, geo: CVResult, sel,
          loss: str, protocol: str, unused_full: CVResult | None = None) -> Ladder:
    """The ladder of a finished diagnosis (see the module docstring).  ``geo``: the geometric baseline (its level
    ``level``), ``sel``: the selection (:class:`calib.diagnose.select.Selection`); ``unused_full``: the full geometric
    set when it was fitted and predicted worse than the offsets (a step shown, not in the final model)."""
    sc = _Scorer(data, test, folds, loss)
    model = geo.model
    loc = [n for n in locate_free(model) if n in geo.all_fit.free]
    steps = [sc.exact("located nominal", "base and tool points located", model, loc, geo)]
    if level == "full":
        full = sc.of_cv("+ full geometry", "the rest of the geometric set (lengths, twists, offsets d)", geo)
        offs = sc.linear("+ joint offsets", "joint zero offsets", geo,
                         [n for n in geometric_free(model, "full") if n not in geometric_free(model, "offsets")])
        steps += [offs, full]
    else:
        steps.append(sc.of_cv("+ joint offsets", "joint zero offsets", geo))
        if unused_full is not None:
            steps.append(sc.of_cv("+ full geometry", "the rest of the geometric set (predicts worse: not kept)",
                                  unused_full, accepted=False))
    base_effects = len(model.effects)
    final = sel.final
    n = 0
    groups = _groups(sel.findings)
    for group in groups:
        n += len(group)
        f = group[-1]
        name = "+ " + " + ".join(g.candidate.label for g in group)
        kind = f.candidate.kind + (" (found jointly)" if len(group) > 1 else "")
        cv = final if n == len(sel.findings) else f.fit
        if cv is not None and len(cv.model.effects) == base_effects + n:
            steps.append(sc.of_cv(name, kind, cv, f.p_value))
        else:       # the finding's own fit held one that backward elimination dropped: cut the final model
            steps.append(_cumulative(sc, final, base_effects + n, name, kind, f.p_value))
    lad = Ladder(steps, _logo(sc, level, final, steps, base_effects, groups), protocol)
    lad.p_values = _p_values(steps)
    lad.heldout = _heldout(sc, steps[0], [s for s in steps if s.accepted][-1], final, protocol)
    return lad


def _p_values(steps: list[Scored]) -> list[tuple[float | None, float | None]]:
    """Each step's nested F-test against the last step kept before it (a step not in the final model is tested
    against the one before it, and skipped by the next)."""
    out, kept = [(None, None)], steps[0]
    for s in steps[1:]:
        out.append(_nested(kept, s))
        if s.accepted:
            kept = s
    return out


def _groups(findings) -> list[list]:
    """Consecutive findings accepted together (a joint group shares its fit) as one step each."""
    out: list[list] = []
    for f in findings:
        if out and f.candidate.label in out[-1][-1].jointly:
            out[-1].append(f)
        else:
            out.append([f])
    return out


def _cumulative(sc: _Scorer, final: CVResult, n_effects: int, name: str, kind: str, p) -> Scored:
    """The final model cut to its first ``n_effects`` effects, refitted exactly from the final fits."""
    m = final.model
    model = MeasurementModel(m.robot, list(m.effects[:n_effects]))
    free = [n for n in final.all_fit.free if n in model.index]
    out = sc.exact(name, kind, model, free, final)
    out.selection_p = p
    return out


def _logo(sc: _Scorer, level: str, final: CVResult, steps: list[Scored], base_effects: int,
          groups: list[list]) -> list[tuple[Scored, Scored]]:
    """The final model without each group: joint offsets, the rest of the geometry, each accepted effect group
    (``groups``: the findings as the ladder groups them, in the order of the final model's effects)."""
    m = final.model
    kept = [s for s in steps if s.accepted]
    last = kept[-1]
    offsets = [n for n in geometric_free(m, "offsets") if n not in locate_free(m)]
    out = [(sc.linear("", "joint offsets", final, offsets), last)]
    if level == "full":
        rest = [n for n in geometric_free(m, "full") if n not in geometric_free(m, "offsets")]
        out.append((sc.linear("", "the rest of the geometry", final, rest), last))
    first = base_effects
    for i, group in enumerate(groups):
        effects = m.effects[first:first + len(group)]
        first += len(group)
        label = " + ".join(effect_label(m.robot, e) for e in effects)      # as the steps say them
        if i == len(groups) - 1:            # the final model without its last group: the step before
            out.append((_named(kept[-2], label), last))
            continue
        out.append((sc.linear("", label, final, [q for e in effects for q in e.qualified_names()]), last))
    return out


def _named(s: Scored, added: str) -> Scored:
    return Scored(s.name, added, s.model, s.free, s.residual_mm, s.rss, s.n_obs, s.refit)


def _heldout(sc: _Scorer, before: Scored, after: Scored, final: CVResult, protocol: str) -> HeldOut:
    """Before/after and the predicted sigmas of the final model's held-out predictions (split: the fit on the fit
    rows; k-fold: the all-row covariance scaled by the share of rows a fold trains on)."""
    m, fit = final.model, final.all_fit
    d = sc.test if sc.test is not None else sc.data
    par = predicted_cov_mm2(m, fit, d.q_rad, d.ctx, np.zeros_like(d.cov_mm2))
    if sc.test is None:     # a fold's fit saw only its training rows: its parameters are that much less certain
        par = par * d.n / np.mean([len(f.train) for f in final.folds])
    cov = par + noise_scale(fit) * d.cov_mm2
    ok = np.isfinite(after.residual_mm).all(axis=1)
    return HeldOut(before.residual_mm[ok], after.residual_mm[ok], cov[ok], protocol)
