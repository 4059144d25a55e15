"""Stand-ins for play: a joint scale, a harmonic or a compliance on a joint that only imitates its backlash (issue 27).

Play moves a joint by +-b/2 with the side it rests on; where the side follows the joint's angle (gravity turns over
with the arm) or its torque, a scale, a transmission error or a compliance on the same joint fits part of that step
and may be accepted first.  Such a finding is not a finding of its own: it is reported as an alias of the play.

* A play on the same joint was accepted too: the stand-in is refitted out of the final model (every fold, warm
  start), and dropped -- named among the play's aliases -- when the held-out RMS without it is less than the
  material share of the excess gap worse (the acceptance rule's own threshold).
* No play was accepted and the stand-in is the last finding: the play candidates on its joint (plain and
  gravity-loaded) are screened by the all-pose fit with the stand-in's columns replaced by theirs, the best few
  refitted in every fold; when the best explains the held-out gap as well as the stand-in (not worse by more than
  half the material share), it replaces it and the stand-in becomes its alias.  (A stand-in followed by other
  findings is left as it is: replacing it would mean refitting every later step.)

And the simpler play first: a gravity-loaded play found last is replaced by the plain play of its joint unless it
is significantly better (:func:`_simplify`).  The gravity variant's preload and tool mass are picked from a grid by
the held-out score, and the best of many grid points beats the plain play by the choice alone near the floor.
"""
from __future__ import annotations

import numpy as np

from calib.distributions import f_sf
from calib.model import MeasurementModel

from .candidate import Candidate
from .data import DiagnosisData
from .gap import CVResult, cv_fit
from .findings import MATERIAL_SHARE, Finding, param_report, stability, stated_spread
from .select import Selection

#: kinds that can imitate play on their joint
STAND_INS = ("joint_scale", "transmission_error", "joint_compliance")
#: the play kinds
PLAY = ("backlash", "backlash_gravity")
#: play candidates refitted in every fold when a stand-in is the last finding
REFIT_PLAYS = 2
#: level of the test a gravity-loaded play must pass against the plain play of its joint
SIMPLER_ALPHA = 0.01


def _refit_with(data: DiagnosisData, cur: CVResult, effects, loss: str) -> CVResult:
    """``cur``'s model with ``effects`` instead of its own (the geometric part and shared parameters warm)."""
    m = cur.model
    model = MeasurementModel(data.robot, list(effects))
    keep = {n: i for i, n in enumerate(m.names)}

    def carry(th):
        out = model.nominal.copy()
        for i, n in enumerate(model.names):
            if n in keep:
                out[i] = th[keep[n]]
        return out
    free = [n for n in cur.all_fit.free if n in model.index]
    free += [q for e in effects if e not in m.effects for q in e.qualified_names()]
    return cv_fit(model, data, list(dict.fromkeys(free)), [(f.train, f.test) for f in cur.folds],
                  theta0=[carry(f.theta) for f in cur.folds], theta0_all=carry(cur.all_fit.theta[: m.P]),
                  start=False, loss=loss)


def _index(model: MeasurementModel, f: Finding) -> int:
    return [i for i, e in enumerate(model.effects) if e.finding_label() == f.candidate.label][-1]


def resolve(data: DiagnosisData, sel: Selection, candidates: list[Candidate], floor_mm: float, base: CVResult,
            loss: str = "linear") -> None:
    """Apply the two rules of the module docstring to ``sel`` in place (``base``: the geometric fit the selection
    started from)."""
    excess = max(0.0, base.rms_mm - floor_mm)
    for f in list(sel.findings):
        c = f.candidate
        if c.kind not in STAND_INS or f not in sel.findings:
            continue
        play = next((b for b in sel.findings if b.candidate.kind in PLAY and b.candidate.joint == c.joint), None)
        if play is not None:
            _drop(data, sel, f, play, excess, loss)
        elif f is sel.findings[-1]:
            _swap(data, sel, f, [p for p in candidates if p.kind in PLAY and p.joint == c.joint], excess, loss,
                  _before_last(sel, base))
    last = sel.findings[-1] if sel.findings else None
    if last is not None and last.candidate.kind == "backlash_gravity" and \
            any(p.kind == "backlash" and p.joint == last.candidate.joint for p in candidates):
        grid = sum(p.kind == "backlash_gravity" and p.joint == last.candidate.joint for p in candidates)
        _simplify(data, sel, last, grid, excess, loss)


def _drop(data, sel: Selection, f: Finding, play: Finding, excess: float, loss: str) -> None:
    cur = sel.final
    i = _index(cur.model, f)
    new = _refit_with(data, cur, [e for k, e in enumerate(cur.model.effects) if k != i], loss)
    if new.rms_mm - cur.rms_mm < MATERIAL_SHARE * excess:
        sel.findings.remove(f)
        play.aliases.append(f"{f.candidate.label} (stands in for the play)")
        sel.final = new
        sel.findings[-1].fit = new
        sel.skipped.append(f"{f.candidate.label}: only stands in for the play {play.candidate.label} (without it "
                           f"the held-out RMS is {new.rms_mm:.4f} mm, with it {cur.rms_mm:.4f} mm)")


def _screen(data: DiagnosisData, without: CVResult, plays: list[Candidate]) -> list[Candidate]:
    """The play candidates ranked by the whitened all-pose residual they leave, each fitted with the current free
    columns projected out (one Jacobian for all)."""
    m = without.model
    big = MeasurementModel(data.robot, list(m.effects) + [p.make() for p in plays])
    theta = np.concatenate([without.all_fit.theta[: m.P], big.nominal[m.P:]])
    ev = big.evaluate(data.q_rad, data.ctx, theta, jacobian=True)
    W = data.whitening
    J = np.einsum("nij,njp->nip", W, ev.jacobian).reshape(3 * data.n, -1)
    r = np.einsum("nij,nj->ni", W, data.points_mm - ev.point_mm).ravel()
    Q, _ = np.linalg.qr(J[:, [big.index[n] for n in without.all_fit.free if n in big.index]])
    rp = r - Q @ (Q.T @ r)
    rss = []
    for k in range(len(plays)):
        s = big.effect_slices[len(m.effects) + k]
        col = J[:, s.start]
        col = col - Q @ (Q.T @ col)
        n2 = float(col @ col)
        rss.append(float(rp @ rp) - (float(col @ rp) ** 2 / n2 if n2 > 0 else 0.0))
    return [plays[k] for k in np.argsort(rss)]


def _swap(data, sel: Selection, f: Finding, plays: list[Candidate], excess: float, loss: str,
          before: CVResult | None) -> None:
    _replace(data, sel, f, plays, excess, loss, f"{f.candidate.label} (stands in for the play)", before=before)


def _before_last(sel: Selection, base: CVResult) -> CVResult:
    """The selection's fit before its last finding was accepted: the previous finding's, or the geometric fit."""
    return sel.findings[-2].fit if len(sel.findings) > 1 else base


def _same_fit(fit: CVResult | None, cur: CVResult, effects) -> bool:
    """Whether ``fit`` is already :func:`_refit_with` (cur, effects): the same effects, the same folds, and its kept
    free set the one that refit would ask for (then it is the same fit from another start, and one refit in every
    fold is saved)."""
    if fit is None or [e.label for e in fit.model.effects] != [e.label for e in effects]:
        return False
    if len(fit.folds) != len(cur.folds) or not all(np.array_equal(a.train, b.train) and np.array_equal(a.test, b.test)
                                                   for a, b in zip(fit.folds, cur.folds)):
        return False
    return set(fit.all_fit.free) == {n for n in cur.all_fit.free if n in fit.model.index}


def _simplify(data, sel: Selection, f: Finding, n_grid: int, excess: float, loss: str) -> None:
    """A gravity-loaded play that is not significantly better than the plain play of its joint: the plain one.
    The grid of preloads and tool masses (``n_grid`` points on the joint) picks its best point by the held-out score,
    which flatters it by the choice alone; so on all poses the gravity variant's whitened residual must beat the
    plain play's beyond chance, an F-test (one degree of freedom: the choice of sides) Bonferroni-corrected over the
    grid, at :data:`SIMPLER_ALPHA`."""
    plain = Candidate("backlash", f.candidate.joint, free=("width_rad",))
    grav = sel.final.all_fit

    def not_better(fit: CVResult) -> bool:
        m3 = 3 * data.n
        dof = max(1, m3 - len(grav.free))
        rss_g, rss_p = grav.reduced_chi2 * dof, fit.all_fit.reduced_chi2 * max(1, m3 - len(fit.all_fit.free))
        F = (rss_p - rss_g) / max(rss_g / dof, 1e-300)
        return F <= 0 or float(f_sf(F, 1, dof)) * max(1, n_grid) >= SIMPLER_ALPHA
    _replace(data, sel, f, [plain], excess, loss, f"{f.candidate.label} (not significantly better than the plain "
                                                  f"play)", accept=not_better)


def _replace(data, sel: Selection, f: Finding, plays: list[Candidate], excess: float, loss: str,
             alias: str, accept=None, before: CVResult | None = None) -> bool:
    """Replace the last finding ``f`` by the best of ``plays`` when it explains the held-out gap as well (not worse
    by more than half the material share; or when ``accept(fit)`` says so); ``alias`` names ``f`` among the new
    finding's aliases.  ``before``: the selection's fit without ``f``, used as it is when it is that model
    (:func:`_same_fit`)."""
    if not plays:
        return False
    cur = sel.final
    i = _index(cur.model, f)
    base_effects = [e for k, e in enumerate(cur.model.effects) if k != i]
    without = before if _same_fit(before, cur, base_effects) else _refit_with(data, cur, base_effects, loss)
    best = None
    for p in _screen(data, without, plays)[:REFIT_PLAYS]:
        fit = _refit_with(data, without, base_effects + [p.make()], loss)
        if best is None or fit.chi2 < best[1].chi2:
            best = (p, fit)
    p, fit = best
    if not (accept(fit) if accept is not None else fit.rms_mm <= cur.rms_mm + 0.5 * MATERIAL_SHARE * excess):
        return False
    model = fit.model
    spread, fold_sigma = stability(model, fit, p)
    m3 = 3 * data.n
    dof0, dof1 = max(1, m3 - len(without.all_fit.free)), max(1, m3 - len(fit.all_fit.free))
    rss0, rss1 = without.all_fit.reduced_chi2 * dof0, fit.all_fit.reduced_chi2 * dof1
    F = (rss0 - rss1) / max(rss1 / dof1, 1e-300)
    before = sel.findings[-2].rms_after_mm if len(sel.findings) > 1 else without.rms_mm
    new = Finding(p, fit.rms_mm, fit.max_mm, min(1.0, float(f_sf(max(F, 0.0), 1, dof1)) * len(plays)), float(F),
                  float(rss1 - rss0 + np.log(m3)), fit.chi2, param_report(p, model, fit, fold_sigma), len(plays),
                  spread, [alias] + list(f.aliases), (before - fit.rms_mm) / excess if excess > 0 else float("nan"),
                  fit, stated_spread=stated_spread(model, fit, p, fold_sigma))
    sel.findings[-1] = new
    sel.final = fit
    sel.skipped.append(f"{alias.split(' (')[0]}: replaced by {p.label} (held-out RMS {fit.rms_mm:.4f} mm with it, "
                       f"{cur.rms_mm:.4f} mm before)")
    return True
