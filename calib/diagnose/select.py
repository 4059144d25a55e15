"""Greedy forward selection of unmodelled effects, scored on held-out poses, with a nested F-test and a guard.

Each round:

1. **Linearise** once: one model holding the accepted effects *and every remaining candidate* (at zero magnitude)
   is evaluated with its Jacobian at the current all-pose estimate.  Effects add, so each candidate's columns are
   exactly its own Jacobian; no effect math is repeated here.
2. **Guard** (per candidate, all poses): a column that the data cannot drive (zero signal) is skipped; the augmented
   whitened Jacobian goes through :func:`calib.identifiability.analyse` (the same guard identify uses) and a
   candidate any of whose parameters it would hold is skipped; so is one whose signature the current model absorbs
   almost entirely (less than :data:`MIN_INDEPENDENT` of its whitened column norm left after projecting out the
   current columns).
3. **Score**: in every fold, one Gauss-Newton step on the training poses with the fold's current free parameters
   plus the candidate's (projected least squares, vectorised over candidates), then the whitened held-out sum of
   squares.  The best candidate is the one that shrinks the held-out gap most.
4. **Test**: nested F-test on all poses (whitened by the instrument covariance, as §9 of the anchors asks), with a
   Bonferroni correction for every candidate tried in the round (every order of the transmission-error grid counts).
   Accepted when the corrected p-value is below ``alpha`` *and* the held-out gap shrinks.
5. **Refit** the accepted set fully with :func:`calib.identify.identify` in every fold (warm start) and on all poses;
   the held-out RMS after it is the finding's ``rms_after_mm``.  Should the full refit not shrink the held-out gap
   (the linearisation misled), the effect is dropped and selection stops.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy import stats

from calib.identifiability import analyse
from calib.model import MeasurementModel

from .candidates import Candidate
from .data import DiagnosisData
from .gap import CVResult, cv_fit

#: a candidate must keep at least this share of its whitened signature once the current model's columns are
#: projected out (else the geometry absorbs it: the guard of §9, "O1/O4 not collapsing")
MIN_INDEPENDENT = 0.02


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


@dataclass
class Round:
    """What one round looked at: the best few candidates by held-out score (for the report)."""
    baseline_rms_mm: float
    ranking: list[tuple[str, float, float]]      # (label, predicted held-out RMS mm, corrected p)
    accepted: str | None


@dataclass
class Selection:
    findings: list[Finding]
    rounds: list[Round]
    final: CVResult
    skipped: list[str] = field(default_factory=list)   # guard notes
    stop_reason: str = ""


def _white_rows(W: np.ndarray, A: np.ndarray) -> np.ndarray:
    """(N,3,3) W and (N,3,...) A -> whitened rows (3N, ...)."""
    out = np.einsum("nij,nj...->ni...", W, A)
    return out.reshape((-1,) + A.shape[2:])


def _rows(idx: np.ndarray) -> np.ndarray:
    return (3 * np.asarray(idx)[:, None] + np.arange(3)).ravel()


def _project(Q: np.ndarray, A: np.ndarray) -> np.ndarray:
    return A - Q @ (Q.T @ A)


def _param_report(cand: Candidate, model: MeasurementModel, cv: CVResult) -> dict[str, float]:
    e_i = len(model.effects) - 1
    s = model.effect_slices[e_i]
    names = model.effects[e_i].param_names
    theta = cv.all_fit.theta
    sig = cv.all_fit.sigma
    vals = {n: float(theta[s][k]) for k, n in enumerate(names)}
    sigs = {n: float(sig[s][k]) for k, n in enumerate(names)}
    return cand.parameters(vals, sigs)


def forward_select(data: DiagnosisData, base: CVResult, geo_free: list[str], candidates: list[Candidate],
                   alpha: float = 0.01, max_effects: int = 6,
                   progress: Callable[[str, float], None] | None = None) -> Selection:
    """Greedy forward selection from the geometric fit ``base`` (see the module docstring)."""
    robot = data.robot
    W = data.whitening
    N = data.n
    m = 3 * N
    cur = base
    accepted: list[Candidate] = []
    findings: list[Finding] = []
    rounds: list[Round] = []
    notes: list[str] = []
    noted: set[str] = set()
    stop = "no candidate left"
    while len(accepted) < max_effects:
        groups = {c.group for c in accepted}
        remaining = [c for c in candidates if c.group not in groups]
        if not remaining:
            break
        if progress:
            progress(f"round {len(accepted) + 1}", len(accepted) / max_effects)
        eff_cur = list(cur.model.effects)
        big = MeasurementModel(robot, eff_cur + [c.make() for c in remaining])
        theta = np.concatenate([cur.all_fit.theta[: cur.model.P], big.nominal[cur.model.P:]])
        ev = big.evaluate(data.q_rad, data.ctx, theta, jacobian=True)
        Jw = _white_rows(W, ev.jacobian)                                   # (3N, P_big)
        Jmm = ev.jacobian.reshape(m, -1)
        ccols = []
        for i, c in enumerate(remaining):
            s = big.effect_slices[len(eff_cur) + i]
            names = big.effects[len(eff_cur) + i].param_names
            ccols.append([s.start + names.index(p) for p in c.free])
        # -- guard on all poses: signal, then independence from the current model (column-scaled)
        base_idx = [big.index[n] for n in cur.all_fit.free if n in big.index]
        Qa, _ = np.linalg.qr(Jw[:, base_idx])
        ok = []
        for c, cols in zip(remaining, ccols):
            C = Jw[:, cols]
            norm = np.linalg.norm(C, axis=0)
            if np.any(norm < 1e-6):
                key = f"{c.label}: no signal in these data (its driver does not vary over the poses)"
                if key not in noted:
                    notes.append(key)
                    noted.add(key)
                continue
            indep = float(np.linalg.svd(_project(Qa, C) / norm, compute_uv=False)[-1])
            if indep < MIN_INDEPENDENT:
                key = (f"{c.label}: absorbed by the current model (only {100 * indep:.1f} % of its signature "
                       f"is independent of it)")
                if c.kind != "transmission_error" and key not in noted:
                    notes.append(key)
                    noted.add(key)
                continue
            ok.append((c, cols))
        if not ok:
            stop = "no identifiable candidate left"
            break
        M = len(ok)
        allcols = [k for _, cols in ok for k in cols]
        pos, slices = 0, []
        for _, cols in ok:
            slices.append(slice(pos, pos + len(cols)))
            pos += len(cols)
        # -- held-out score: one projected Gauss-Newton step per fold, vectorised over candidates
        chi2 = np.zeros(M)
        sse = np.zeros(M)
        for f in cur.folds:
            tr, te = _rows(f.train), _rows(f.test)
            r3 = data.points_mm - cur.model.points(data.q_rad, data.ctx, f.theta)
            r_mm = r3.ravel()
            r_w = _white_rows(W, r3[:, :, None])[:, 0]
            bidx = [big.index[n] for n in f.free if n in big.index]
            Q, R = np.linalg.qr(Jw[tr][:, bidx])
            Ctr = Jw[tr][:, allcols]
            Cp = _project(Q, Ctr)
            rp = r_w[tr] - Q @ (Q.T @ r_w[tr])
            # base update db = g0 - G dc; held-out prediction = h0 + H dc (whitened and in mm)
            G = np.linalg.solve(R, Q.T @ Ctr)
            g0 = np.linalg.solve(R, Q.T @ r_w[tr])
            Hw = Jw[te][:, bidx] @ G - Jw[te][:, allcols]
            Hm = Jmm[te][:, bidx] @ G - Jmm[te][:, allcols]
            h0w = r_w[te] - Jw[te][:, bidx] @ g0
            h0m = r_mm[te] - Jmm[te][:, bidx] @ g0
            for k, sl in enumerate(slices):
                dc, *_ = np.linalg.lstsq(Cp[:, sl], rp, rcond=None)
                pw = h0w + Hw[:, sl] @ dc
                pm = h0m + Hm[:, sl] @ dc
                chi2[k] += pw @ pw
                sse[k] += pm @ pm
        order = np.argsort(chi2)
        best = int(order[0])
        # -- nested F-test on all poses for every candidate (reported for the top ones; decides for the best)
        r_all = _white_rows(W, (data.points_mm - cur.model.points(data.q_rad, data.ctx,
                                                                  cur.all_fit.theta[: cur.model.P]))[:, :, None])[:, 0]
        rss0_vec = _project(Qa, r_all[:, None])[:, 0]
        rss0 = float(rss0_vec @ rss0_vec)
        p_base = len(base_idx)

        def ftest(k: int) -> tuple[float, float, float]:
            cols = ok[k][1]
            Cp = _project(Qa, Jw[:, cols])
            dc, *_ = np.linalg.lstsq(Cp, rss0_vec, rcond=None)
            r1 = rss0_vec - Cp @ dc
            rss1 = float(r1 @ r1)
            q = len(cols)
            dof = m - p_base - q
            F = ((rss0 - rss1) / q) / (rss1 / dof) if rss1 > 0 else np.inf
            p = float(stats.f.sf(F, q, dof))
            dbic = rss1 - rss0 + q * np.log(m)       # whitened -2 log L difference + penalty (sigma known)
            return min(1.0, p * M), float(F), float(dbic)

        ranking = []
        for k in order[:8]:
            pk, _, _ = ftest(int(k))
            ranking.append((ok[int(k)][0].label, float(np.sqrt(sse[int(k)] / N)), pk))
        p_adj, F, dbic = ftest(best)
        cand = ok[best][0]
        ida = analyse(np.hstack([Jw[:, base_idx], Jw[:, ok[best][1]]]),
                      [big.names[i] for i in base_idx] + [f"candidate.{p}" for p in cand.free])
        if any(n.startswith("candidate.") for n in ida.fixed):
            notes.append(f"{cand.label}: held by the identifiability guard ("
                         + "; ".join(c.words() for c in ida.unidentifiable) + ")")
            candidates = [c for c in candidates if c is not cand]
            continue
        rnd = Round(cur.rms_mm, ranking, None)
        rounds.append(rnd)
        if not (p_adj < alpha and chi2[best] < cur.chi2):
            stop = (f"best remaining candidate {cand.label} is not significant (corrected p = {p_adj:.3g})"
                    if p_adj >= alpha else f"best remaining candidate {cand.label} does not shrink the held-out gap")
            break
        # -- full refit with the accepted effect
        new_eff = cand.make()
        model = MeasurementModel(robot, eff_cur + [new_eff])
        qual = [f"{new_eff.label}.{p}" for p in cand.free]
        th0 = [np.concatenate([f.theta, new_eff.values]) for f in cur.folds]
        th0_all = np.concatenate([cur.all_fit.theta[: cur.model.P], new_eff.values])
        folds = [(f.train, f.test) for f in cur.folds]
        free_all = list(dict.fromkeys(geo_free + [n for n in cur.model.names[cur.model.n_geometric:]
                                                  if n in cur.all_fit.free] + qual))
        new = cv_fit(model, data, free_all, folds, theta0=th0, theta0_all=th0_all, start=False)
        if new.chi2 >= cur.chi2:
            stop = f"{cand.label} did not shrink the held-out gap once refitted fully"
            break
        rnd.accepted = cand.label
        accepted.append(cand)
        findings.append(Finding(cand, new.rms_mm, new.max_mm, p_adj, F, dbic, new.chi2,
                                _param_report(cand, model, new), M))
        cur = new
    else:
        stop = f"reached the limit of {max_effects} effects"
    return Selection(findings, rounds, cur, notes, stop)
