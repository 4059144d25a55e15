"""Greedy forward selection of unmodelled effects, scored on held-out poses, accepted only when it is honest.

Each round:

1. **Linearise** once: one model holding the accepted effects *and every remaining candidate* (at zero magnitude)
   is evaluated with its Jacobian at the current all-pose estimate.  Effects add, so each candidate's columns are
   exactly its own Jacobian; no effect math is repeated here, and the one Jacobian serves every candidate.
2. **Guard** (per candidate, all poses): a column that the data cannot drive (zero signal) is skipped; so is one
   whose signature the current model absorbs almost entirely (less than :data:`MIN_INDEPENDENT` of its whitened
   column norm left after projecting out the current columns); the best one also goes through
   :func:`calib.identifiability.analyse` (the guard identify uses).
3. **Score**: in every fold, one Gauss-Newton step on the training poses with the fold's current free parameters
   plus the candidate's (projected least squares, vectorised over candidates), then the whitened held-out sum of
   squares: the linearised score.  Candidates are ranked by it.
4. **Test**: nested F-test on all poses (whitened by the instrument covariance, as §9 of the anchors asks), with a
   Bonferroni correction for every candidate tried in the round (every order of the transmission-error grid counts).
   The same projected fits give each candidate's **aliases**: other candidates whose fitted signature is nearly the
   same (correlation above :data:`ALIAS_CORR`) and explains nearly as much (:data:`ALIAS_SHARE`).
5. **Refit and accept** the best few significant candidates (:data:`REFIT_BEST`), in rank order, fully with
   :func:`calib.identify.identify` in every fold (warm start) and on all poses.  A candidate is accepted only when
   its held-out gain is material (:func:`calib.diagnose.findings.material_reason`: :data:`MATERIAL_SHARE` of the
   baseline's excess over the floor, or of the excess still open for a confident candidate whose held-out gain is
   significant; the same for a second effect on the same joint or the next link) *and* its parameters are stable
   across the folds (jackknife relative spread below :data:`STABLE_MAX`).  Otherwise the next is tried; when none passes, selection
   stops and what is left is the unexplained gap, with the candidates that came closest.  A finding's parameters
   must also lie 2 sigma or more from zero (the rule identify holds parameters by).
6. **Jointly**: when no single candidate passes, the candidates of one kind on several joints are tried together
   (:mod:`calib.diagnose.jointly`): several joint elasticities at once.  A group is refitted only when its
   linearised held-out score (its columns together, as step 3) passes the screen single candidates pass before
   their refit (:func:`_group_screen`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from calib.distributions import f_sf
from calib.identifiability import analyse
from calib.model import MeasurementModel
from calib.pruning import SIGNIFICANT

from .candidate import Candidate
from .data import DiagnosisData
from .findings import (DOUBTFUL_SPREAD, MATERIAL_SHARE, STABLE_MAX, Finding, NearMiss, heldout_gain_p,
                       material_reason, paired_gain_p, param_report, project, refit, stability, stated_spread)
from .gap import CVResult, cv_fit, heldout_floor_mm
from .jointly import joint_group

#: a candidate must keep at least this share of its whitened signature once the current model's columns are
#: projected out (else the geometry absorbs it: the guard of §9, "O1/O4 not collapsing")
MIN_INDEPENDENT = 0.02
#: aliases: fitted signatures this correlated, explaining at least this share of the best one's reduction
ALIAS_CORR = 0.9
ALIAS_SHARE = 0.8
#: significant candidates refitted fully per round, in the order of their linearised score
REFIT_BEST = 3
#: candidates looked at per round, in the order of their linearised score
SCAN_BEST = 10
#: a candidate whose linearised held-out gain is below this share of the material gain is not refitted (the
#: one-step prediction from the current fit is close to the refit: the effects enter nearly linearly)
LINEAR_SLACK = 0.5
#: a joint group whose linearised held-out gain is not significant at this many times the level is not refitted
LINEAR_P_SLACK = 10.0


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
    near: list[NearMiss] = field(default_factory=list)


def _white_rows(W: np.ndarray, A: np.ndarray) -> np.ndarray:
    """(N,3,3) W and (N,3,...) A -> whitened rows (3N, ...)."""
    out = np.einsum("nij,nj...->ni...", W, A)
    return out.reshape((-1,) + A.shape[2:])


def _rows(idx: np.ndarray) -> np.ndarray:
    return (3 * np.asarray(idx)[:, None] + np.arange(3)).ravel()


@dataclass
class _Linear:
    """Step 1: the shared linearisation of one round."""
    big: MeasurementModel
    Jw: np.ndarray                  # (3N, P_big) whitened
    base_idx: list[int]             # the current model's free columns
    Qa: np.ndarray                  # orthonormal basis of them (all poses)
    cols: list[list[int]]           # per remaining candidate, its columns
    _blocks: dict = field(default_factory=dict, repr=False)

    def block(self, cols: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Columns ``cols`` of the whitened Jacobian (3N, len) and their product with the current model's basis
        ``Qa^T C``.  Gathered once per round and shared: the guard, the nested tests and the held-out scores each
        took their own copy of every candidate's columns (about 2000 columns of 3000 rows on the elastic tree) and
        the first two the same product."""
        key = tuple(cols)
        if key not in self._blocks:
            C = np.take(self.Jw, cols, axis=1)
            self._blocks[key] = (C, self.Qa.T @ C)
        return self._blocks[key]


def _linearise(data: DiagnosisData, cur: CVResult, remaining: list[Candidate]) -> _Linear:
    eff_cur = list(cur.model.effects)
    big = MeasurementModel(data.robot, eff_cur + [c.make() for c in remaining])
    theta = np.concatenate([cur.all_fit.theta[: cur.model.P], big.nominal[cur.model.P:]])
    ev = big.evaluate(data.q_rad, data.ctx, theta, jacobian=True)
    Jw = _white_rows(data.whitening, ev.jacobian)
    cols = []
    for i, c in enumerate(remaining):
        s = big.effect_slices[len(eff_cur) + i]
        names = big.effects[len(eff_cur) + i].param_names
        cols.append([s.start + names.index(p) for p in c.free])
    base_idx = [big.index[n] for n in cur.all_fit.free if n in big.index]
    Qa, _ = np.linalg.qr(Jw[:, base_idx])
    return _Linear(big, Jw, base_idx, Qa, cols)


def _guard(lin: _Linear, remaining: list[Candidate], note: Callable[[str], None]) -> list[tuple[Candidate, list[int]]]:
    """Step 2: candidates the data can drive and the current model does not absorb.

    A candidate's independent share is the smallest singular value of its column-normalised columns with the
    current model's projected out: the square root of the smallest eigenvalue of their projected Gram block
    (:func:`_diagonal_blocks`, all candidates at once).
    """
    C, QtC = lin.block([k for cols in lin.cols for k in cols])
    starts = np.cumsum([0] + [len(cols) for cols in lin.cols])[:-1]
    norm = np.linalg.norm(C, axis=0)
    indep = np.zeros(len(remaining))
    for first, Gk in _diagonal_blocks(C, QtC, starts):
        d = np.where(norm > 0, norm, 1.0)[first[:, None] + np.arange(Gk.shape[1])]
        low = np.linalg.eigvalsh(Gk / (d[:, :, None] * d[:, None, :]))[:, 0]
        indep[np.searchsorted(starts, first)] = np.sqrt(np.maximum(low, 0.0))
    ok = []
    for k, (c, cols) in enumerate(zip(remaining, lin.cols)):
        if np.any(norm[starts[k]: starts[k] + len(cols)] < 1e-6):
            note(f"{c.label}: no signal in these data (its driver does not vary over the poses)")
            continue
        if indep[k] < MIN_INDEPENDENT:
            if c.kind != "transmission_error":
                note(f"{c.label}: absorbed by the current model (only {100 * indep[k]:.1f} % of its signature is "
                     f"independent of it)")
            continue
        ok.append((c, cols))
    return ok


def _heldout_scores(data: DiagnosisData, cur: CVResult, lin: _Linear, ok,
                    rows_mm: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Step 3: linearised held-out chi-square and sum of squares (mm^2) per candidate, all folds.

    Per fold, each candidate's columns C_k are fitted to the training residual with the current model's columns B
    projected out (dc = argmin |P C_k dc - P r|, P = 1 - QQ^T, B = QR), the base follows (db = g0 - G dc), and the
    held-out poses are predicted.  All candidates at once: the small normal equations of every candidate come from
    the diagonals of C^T C and (Q^T C)^T (Q^T C) (:func:`_block_normal_equations`), and the predictions from one
    product -- a loop of one least-squares call per candidate and fold took most of the diagnosis's selection.
    ``rows_mm`` ((N, 3, candidates), optional) receives the predicted held-out residuals themselves.
    """
    W = data.whitening
    allcols = [k for _, cols in ok for k in cols]
    starts = np.cumsum([0] + [len(cols) for _, cols in ok])[:-1]
    chi2, sse = np.zeros(len(ok)), np.zeros(len(ok))
    Jw, big = lin.Jw, lin.big
    # the candidates' columns gathered once (shared with the nested tests): a fold copies its rows of them
    Cw = lin.block(allcols)[0]
    # the predictions in mm are the whitened ones unwhitened pose by pose (a second pass over every candidate's
    # columns in mm cost a fifth of the scores)
    unwhite = np.linalg.inv(W)
    for i, f in enumerate(cur.folds):
        tr, te = _rows(f.train), _rows(f.test)
        r3 = data.points_mm - cur.points_mm(data, i)
        r_w = _white_rows(W, r3[:, :, None])[:, 0]
        bidx = [big.index[n] for n in f.free if n in big.index]
        Q, R = np.linalg.qr(Jw[np.ix_(tr, bidx)])
        Ctr = Cw[tr]
        QtC, Qtr = Q.T @ Ctr, Q.T @ r_w[tr]
        rp = r_w[tr] - Q @ Qtr
        dc = _block_normal_equations(Ctr, QtC, Ctr.T @ rp, starts)        # (C P)^T P r = C^T P r
        # base update db = g0 - G dc; held-out prediction = h0 + H dc (whitened, then in mm pose by pose)
        G = np.linalg.solve(R, QtC)
        g0 = np.linalg.solve(R, Qtr)
        Jb = Jw[np.ix_(te, bidx)]
        H = Jb @ G
        H -= Cw[te]
        H *= dc
        pred = (r_w[te] - Jb @ g0)[:, None] + np.add.reduceat(H, starts, axis=1)
        chi2 += np.einsum("ij,ij->j", pred, pred)
        pred = np.matmul(unwhite[f.test], pred.reshape(len(f.test), 3, -1)).reshape(len(te), -1)
        sse += np.einsum("ij,ij->j", pred, pred)
        if rows_mm is not None:
            rows_mm.reshape(3 * data.n, -1)[te] = pred
    # a candidate absorbed on some fold's fit rows (NaN coefficients) improves nothing there: never ranked a winner
    return np.where(np.isfinite(chi2), chi2, np.inf), np.where(np.isfinite(sse), sse, np.inf)


def _diagonal_blocks(C: np.ndarray, QtC: np.ndarray, starts: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The candidates' projected Gram blocks ``C_k^T C_k - (Q^T C_k)^T (Q^T C_k)`` (candidate k: columns
    ``starts[k]:starts[k+1]``), grouped by block size: [(first columns (n,), blocks (n, size, size)), ...].

    Only the blocks on the diagonal of C^T C are needed, i.e. its first few diagonals: one pass over C each instead
    of the whole product (or a decomposition per candidate).
    """
    A = C.shape[1]
    sizes = np.diff(np.append(starts, A))
    if not len(sizes):
        return []
    diag = [np.einsum("ma,ma->a", C[:, : A - o], C[:, o:]) - np.einsum("ma,ma->a", QtC[:, : A - o], QtC[:, o:])
            for o in range(int(sizes.max()))]
    out = []
    for size in np.unique(sizes):
        first = starts[sizes == size]
        Gk = np.empty((len(first), size, size))
        for i in range(size):
            for j in range(size):
                Gk[:, i, j] = diag[abs(i - j)][first + min(i, j)]
        out.append((first, Gk))
    return out


def _block_normal_equations(C: np.ndarray, QtC: np.ndarray, rhs: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Each candidate's least-squares coefficients, candidates side by side (columns ``starts[k]:starts[k+1]``).

    Candidate k solves ``(C_k^T C_k - (Q^T C_k)^T (Q^T C_k)) dc_k = rhs_k``: the normal equations of its columns with
    the current model's projected out (:func:`_diagonal_blocks`), Jacobi-scaled and solved together per block size.
    The guard keeps only candidates with >= MIN_INDEPENDENT of their signature outside the current model, so the
    projected blocks are well conditioned (equal to a per-candidate ``lstsq`` to ~1e-14 relative on the diagnosis's
    data).
    """
    dc = np.zeros(C.shape[1])
    for first, Gk in _diagonal_blocks(C, QtC, starts):
        cols = first[:, None] + np.arange(Gk.shape[1])
        # on a fold's fit rows a candidate the guard passed on all rows can be absorbed: its projected diagonal rounds
        # to <= 0 and its coefficients come out NaN, which the caller scores as no improvement
        with np.errstate(invalid="ignore", divide="ignore"):
            d = np.sqrt(np.einsum("kii->ki", Gk))
            x = np.linalg.solve(Gk / (d[:, :, None] * d[:, None, :]), (rhs[cols] / d)[..., None])[..., 0]
            dc[cols] = x / d
    return dc


@dataclass
class _Tests:
    """Step 4: per candidate, the corrected p-value, F, delta BIC and the fitted whitened signature; ``r0`` the
    whitened residual the candidates were fitted to (current columns projected out) and ``dof`` its degrees of
    freedom before a candidate."""
    p: np.ndarray
    F: np.ndarray
    dbic: np.ndarray
    signature: list[np.ndarray]
    r0: np.ndarray | None = None
    dof: int = 0


def _nested_tests(data: DiagnosisData, cur: CVResult, lin: _Linear, ok) -> _Tests:
    """Step 4: each candidate fitted to the whole residual with the current model's columns projected out (all at
    once, :func:`_block_normal_equations`), its nested F-test (Bonferroni over the candidates) and delta BIC."""
    m = 3 * data.n
    r_all = _white_rows(data.whitening, (data.points_mm - cur.points_mm(data))[:, :, None])[:, 0]
    r0 = project(lin.Qa, r_all[:, None])[:, 0]
    rss0 = float(r0 @ r0)
    M = len(ok)
    C, QtC = lin.block([k for _, cols in ok for k in cols])
    starts = np.cumsum([0] + [len(cols) for _, cols in ok])[:-1]
    dc = _block_normal_equations(C, QtC, C.T @ r0, starts)
    fitted = np.zeros((m, 0))
    if M:
        P = lin.Qa @ QtC            # (C - Qa QtC) dc, in place: three temporaries of every candidate's columns
        np.subtract(C, P, out=P)
        P *= dc
        fitted = np.add.reduceat(P, starts, axis=1)
    e = r0[:, None] - fitted
    rss1 = np.einsum("ij,ij->j", e, e)
    q = np.diff(np.append(starts, C.shape[1]))
    dof = m - len(lin.base_idx) - q
    with np.errstate(divide="ignore", invalid="ignore"):
        F = np.where(rss1 > 0, ((rss0 - rss1) / q) / (rss1 / dof), np.inf)
    p = np.minimum(1.0, f_sf(F, q, dof) * M)
    dbic = rss1 - rss0 + q * np.log(m)             # whitened -2 log L difference + penalty (sigma known)
    return _Tests(p, F, dbic, list(fitted.T), r0, m - len(lin.base_idx))


def _adds_to(lin: _Linear, tests: _Tests, k: int, i: int, cols_k: list[int], cols_i: list[int]) -> float:
    """p-value (uncorrected) of the nested F-test: does candidate ``k`` explain significantly more of the residual
    than candidate ``i`` already does?  Large: the data cannot tell ``k`` from ``i``."""
    r0, t = tests.r0, tests.signature[i]
    rss_i = float((r0 - t) @ (r0 - t))
    both = project(lin.Qa, lin.Jw[:, cols_i + cols_k])
    dc, *_ = np.linalg.lstsq(both, r0, rcond=None)
    e = r0 - both @ dc
    rss_b = float(e @ e)
    q = len(cols_k)
    dof = tests.dof - len(cols_i) - q
    if rss_b <= 0 or dof <= 0:
        return 1.0
    return float(f_sf(max(0.0, (rss_i - rss_b) / q) / (rss_b / dof), q, dof))


def _aliases(k: int, ok, tests: _Tests, lin: _Linear, alpha: float) -> list[str]:
    """Other candidates (another group) that are genuinely interchangeable with candidate ``k`` on these data.

    Pre-selection: a fitted signature nearly the same as ``k``'s (correlation above :data:`ALIAS_CORR`) that
    explains at least :data:`ALIAS_SHARE` as much.  Decision: ``k`` adds nothing significant to a model that already
    holds the other one (nested F against the residual scatter, Bonferroni over the pre-selected ones, level
    ``alpha``).  A look-alike the data tell apart -- a weaker, partial version of the same signature that ``k``
    clearly beats -- is not an alias: only one the data cannot reject in ``k``'s favour is.
    """
    s = tests.signature[k]
    n2 = float(s @ s)
    if n2 <= 0:
        return []
    near = []
    for i, (c, _) in enumerate(ok):
        if i == k or c.group == ok[k][0].group:
            continue
        t = tests.signature[i]
        t2 = float(t @ t)
        if t2 >= ALIAS_SHARE * n2 and abs(float(s @ t)) / np.sqrt(n2 * t2) >= ALIAS_CORR:
            near.append((t2, i))
    out = [(t2, ok[i][0].label) for t2, i in near
           if tests.r0 is None or _adds_to(lin, tests, k, i, ok[k][1], ok[i][1]) * len(near) >= alpha]
    return [lab for _, lab in sorted(out, reverse=True)[:3]]


@dataclass
class _Context:
    """What the rounds share."""
    data: DiagnosisData
    geo_free: list[str]
    alpha: float
    floor_mm: float
    excess_mm: float                # baseline held-out RMS - floor
    loss: str
    notes: list[str] = field(default_factory=list)
    noted: set[str] = field(default_factory=set)
    near: list[NearMiss] = field(default_factory=list)

    def open_mm(self, cur: CVResult) -> float:
        """The excess still open: the current model's held-out RMS above the floor."""
        return max(0.0, cur.rms_mm - self.floor_mm)

    def note(self, text: str) -> None:
        if text not in self.noted:
            self.notes.append(text)
            self.noted.add(text)


def _immaterial(cx: _Context, cur: CVResult, predicted_gain: float, doubtful: Callable[[], bool]) -> bool:
    """The screen before a refit: the linearised held-out gain is below :data:`LINEAR_SLACK` of the least
    :func:`calib.diagnose.findings.material_reason` could accept -- the baseline's share, or the open gap's share for
    a candidate without the signs of a stand-in it can see before the refit (``doubtful()``: an alias, the edge of
    its order grid)."""
    if predicted_gain >= LINEAR_SLACK * MATERIAL_SHARE * cx.excess_mm:
        return False
    return predicted_gain < LINEAR_SLACK * MATERIAL_SHARE * cx.open_mm(cur) or doubtful()


def _group_screen(cx: _Context, cur: CVResult, lin: _Linear, cols: list[int], n_tests: int) -> tuple[float, str]:
    """A joint group's linearised held-out RMS (mm: its columns fitted together, :func:`_heldout_scores`) and why it
    is not refitted ("" to refit): no linearised gain, or one that the acceptance rule would refuse by a margin --
    under :data:`LINEAR_SLACK` of the baseline's material share and either under that of the open gap's or, for the
    open gap's share, not significant on the held-out poses at :data:`LINEAR_P_SLACK` times the level (the paired
    test of :func:`calib.diagnose.findings.heldout_gain_p` on the linearised prediction, Bonferroni over
    ``n_tests``).  Whether the group is confident shows only after the refit: the screen assumes it is."""
    rows = np.full((cx.data.n, 3, 1), np.nan)
    chi2, sse = _heldout_scores(cx.data, cur, lin, [(None, cols)], rows)
    predicted = float(np.sqrt(sse[0] / cx.data.n))
    gain = cur.rms_mm - predicted
    if not chi2[0] < cur.chi2:
        return predicted, "together (a joint group) they do not shrink the held-out gap (linearised)"
    if gain >= LINEAR_SLACK * MATERIAL_SHARE * cx.excess_mm:
        return predicted, ""
    why = (f"together (a joint group) they shrink the held-out RMS by {gain:.4f} mm only (linearised), less "
           f"than {100 * MATERIAL_SHARE:.0f} % of the excess gap ({cx.excess_mm:.4f} mm)")
    if gain < LINEAR_SLACK * MATERIAL_SHARE * cx.open_mm(cur):
        return predicted, why
    p = min(1.0, paired_gain_p(cx.data, cur.tested, cur.residual_mm, rows[:, :, 0]) * n_tests)
    if p >= LINEAR_P_SLACK * cx.alpha:
        return predicted, why + f" and not significant on the held-out poses (linearised p = {p:.2g})"
    return predicted, ""


def _try_accept(cx: _Context, cur: CVResult, lin: _Linear, ok, tests: _Tests, k: int,
                n_tested: int) -> tuple[Finding, CVResult] | str:
    """Refit candidate ``k`` and apply the acceptance rule; a Finding and the new fit, or why not."""
    cand = ok[k][0]
    model, new = refit(cx.data, cur, cand, cx.geo_free, cx.loss)
    gain = cur.rms_mm - new.rms_mm
    spread, fold_sigma = stability(model, new, cand)
    stated = stated_spread(model, new, cand, fold_sigma)
    aliases, edge = _aliases(k, ok, tests, lin, cx.alpha), _grid_edge(cand, ok)
    why = ""
    if new.chi2 >= cur.chi2:
        why = "does not shrink the held-out gap once refitted fully"
    else:
        confident = not aliases and not edge and stated <= DOUBTFUL_SPREAD
        why = material_reason(gain, cx.excess_mm, cx.open_mm(cur), confident,
                              min(1.0, heldout_gain_p(cx.data, cur, new) * n_tested), cx.alpha)
    if not why and spread > STABLE_MAX:
        why = f"its parameters are not stable across the folds (relative spread {spread:.2f})"
    if not why and stated > 1.0 / SIGNIFICANT:
        why = (f"not significant: its value is within {SIGNIFICANT:g} sigma of zero (stated error "
               f"{100 * stated:.0f} % of it), the rule identify holds parameters by")
    if why:
        cx.near.append(NearMiss(cand.label, new.rms_mm, float(tests.p[k]), why, cand.group))
        return why
    f = Finding(cand, new.rms_mm, new.max_mm, float(tests.p[k]), float(tests.F[k]), float(tests.dbic[k]), new.chi2,
                param_report(cand, model, new, fold_sigma), n_tested, spread, aliases,
                gain / cx.excess_mm if cx.excess_mm > 0 else float("nan"), new,
                stated_spread=stated)
    f.leftover = edge
    return f, new


def _grid_edge(cand: Candidate, ok) -> str:
    """A finding whose best order is the lowest or highest of its group's grid (transmission error, axis tilt) has
    not been resolved: the joint error follows the angle more slowly (a scale, a quadratic) or faster than every
    candidate tried, and the fitted sinusoid only stands in for it."""
    orders = sorted({c.order for c, _ in ok if c.group == cand.group and c.order is not None})
    if cand.order is None or len(orders) < 3 or orders[0] < cand.order < orders[-1]:
        return ""
    return (f"its best order ({cand.order:g}/rad) is the {'lowest' if cand.order == orders[0] else 'highest'} tried: "
            f"what follows joint {cand.joint}'s angle is slower or faster than every periodic candidate")


def _round(cx: _Context, cur: CVResult, remaining: list[Candidate], rounds: list[Round]):
    """One round: a (Finding, new fit) pair, or the reason to stop, plus candidates the guard held."""
    lin = _linearise(cx.data, cur, remaining)
    ok = _guard(lin, remaining, cx.note)
    if not ok:
        return "no identifiable candidate left", []
    chi2, sse = _heldout_scores(cx.data, cur, lin, ok)
    tests = _nested_tests(cx.data, cur, lin, ok)
    order = [int(k) for k in np.argsort(chi2)]
    rnd = Round(cur.rms_mm, [(ok[k][0].label, float(np.sqrt(sse[k] / cx.data.n)), float(tests.p[k]))
                             for k in order[:8]], None)
    rounds.append(rnd)
    held, tried, why = [], 0, ""
    for k in order[:SCAN_BEST]:
        if tried >= REFIT_BEST or chi2[k] >= cur.chi2:
            break
        cand = ok[k][0]
        if tests.p[k] >= cx.alpha:
            cx.near.append(NearMiss(cand.label, float(np.sqrt(sse[k] / cx.data.n)), float(tests.p[k]),
                                    f"not significant (corrected p = {tests.p[k]:.3g})", cand.group))
            why = why or f"best remaining candidate {cand.label} is not significant (corrected p = {tests.p[k]:.3g})"
            continue
        predicted = float(np.sqrt(sse[k] / cx.data.n))
        if _immaterial(cx, cur, cur.rms_mm - predicted,
                       lambda: bool(_aliases(k, ok, tests, lin, cx.alpha) or _grid_edge(cand, ok))):
            gain = cur.rms_mm - predicted
            cx.near.append(NearMiss(cand.label, predicted, float(tests.p[k]),
                                    f"shrinks the held-out RMS by {gain:.4f} mm only (linearised), less than "
                                    f"{100 * MATERIAL_SHARE:.0f} % of the excess gap ({cx.excess_mm:.4f} mm)",
                                    cand.group))
            why = why or f"best remaining candidate {cand.label} {cx.near[-1].reason}"
            continue
        ida = analyse(np.hstack([lin.Jw[:, lin.base_idx], lin.Jw[:, ok[k][1]]]),
                      [lin.big.names[i] for i in lin.base_idx] + [f"candidate.{p}" for p in cand.free])
        if any(n.startswith("candidate.") for n in ida.fixed):
            cx.note(f"{cand.label}: held by the identifiability guard ("
                    + "; ".join(c.words(cx.data.robot) for c in ida.unidentifiable) + ")")
            held.append(cand)
            continue
        tried += 1
        res = _try_accept(cx, cur, lin, ok, tests, k, len(ok))
        if isinstance(res, tuple):
            rnd.accepted = cand.label
            return res, held
        why = why or f"best remaining candidate {cand.label} {res}"
    res = joint_group(cx, cur, lin, ok, tests, chi2, len(ok),
                      lambda cols, n_tests: _group_screen(cx, cur, lin, cols, n_tests))
    if isinstance(res, tuple):
        rnd.accepted = " + ".join(f.candidate.label for f in res[0])
        return res, held
    return why or "no candidate shrinks the held-out gap", held


def forward_select(data: DiagnosisData, base: CVResult, geo_free: list[str], candidates: list[Candidate],
                   alpha: float = 0.01, max_effects: int = 8,
                   progress: Callable[[str, float], None] | None = None, floor_mm: float | None = None,
                   loss: str = "linear") -> Selection:
    """Greedy forward selection from the geometric fit ``base`` (see the module docstring).  ``floor_mm``: the
    held-out RMS a perfect model would reach (default: :func:`calib.diagnose.gap.heldout_floor_mm`)."""
    floor = heldout_floor_mm(base, data) if floor_mm is None else floor_mm
    cx = _Context(data, geo_free, alpha, floor, base.rms_mm - floor, loss)
    cur, findings, rounds = base, [], []
    stop = f"reached the limit of {max_effects} effects"
    while len(findings) < max_effects:
        if cx.excess_mm <= 0 or cur.rms_mm <= floor:
            stop = "the held-out gap is at the noise floor"
            break
        groups = {f.candidate.group for f in findings}
        remaining = [c for c in candidates if c.group not in groups]
        if not remaining:
            stop = "no candidate left"
            break
        if progress:
            progress(f"round {len(findings) + 1}", len(findings) / max(1, max_effects))
        res, held = _round(cx, cur, remaining, rounds)
        candidates = [c for c in candidates if c not in held]
        if isinstance(res, str):
            stop = res
            break
        findings += res[0] if isinstance(res[0], list) else [res[0]]
        cur = res[1]
    cur = _backward(cx, cur, findings)
    return Selection(findings, rounds, cur, cx.notes, stop, cx.near)


def _without(cx: _Context, cur: CVResult, drop: int) -> CVResult:
    """The final model without its effect ``drop``, refitted in every fold (warm start) and on all poses."""
    m = cur.model
    keep = np.ones(m.P, bool)
    keep[m.effect_slices[drop]] = False
    model = MeasurementModel(cx.data.robot, [e for i, e in enumerate(m.effects) if i != drop])
    prefix = m.effects[drop].label + "."
    free = [n for n in cur.all_fit.free if not n.startswith(prefix)]
    return cv_fit(model, cx.data, free, [(f.train, f.test) for f in cur.folds],
                  theta0=[f.theta[keep] for f in cur.folds], theta0_all=cur.all_fit.theta[keep], start=False,
                  loss=cx.loss)


def _linear_keep_cost(data: DiagnosisData, cur: CVResult) -> list[float]:
    """Per effect of the final model, the all-pose RMS (mm) its removal would add to first order: its contribution
    J_i theta_i with the other free columns refitted (projected out).  Only a cheap screen before the refit."""
    m = cur.model
    theta = cur.all_fit.theta[: m.P]
    J = m.evaluate(data.q_rad, data.ctx, theta, jacobian=True).jacobian.reshape(3 * data.n, -1)
    free = [m.index[n] for n in cur.all_fit.free if n in m.index]
    rms2 = cur.all_fit.residual_rms ** 2 if np.isfinite(cur.all_fit.residual_rms) else 0.0
    out = []
    for s in m.effect_slices:
        own = [k for k in free if s.start <= k < s.stop]
        others = [k for k in free if not s.start <= k < s.stop]
        Q, _ = np.linalg.qr(J[:, others])
        v = J[:, own] @ theta[own]
        e = v - Q @ (Q.T @ v)
        out.append(float(np.sqrt(rms2 + e @ e / data.n) - np.sqrt(rms2)))
    return out


def _backward(cx: _Context, cur: CVResult, findings: list[Finding]) -> CVResult:
    """A finding accepted early can be superseded by later ones (a joint-2 compliance standing in for a joint-3
    compliance and a joint-2 transmission error that are both there): each earlier finding is refitted out of the
    final model, and dropped when the held-out RMS without it is less than the material share of the baseline's
    excess gap worse *and* its removal is not significant (:func:`_significant_loss`) or it is doubtful (its
    amplitude within 4 sigma of zero, or an alias).  Greedy forward selection
    then backward elimination.

    Why the significance: on a tree many small elasticities together close a large gap, each less than a tenth of
    the baseline's (the elastic tree's lateral compliances, 0.1 mm each of 1.2 mm); the share alone dropped them
    again after they were found, though the fit rows and the folds both said they were needed."""
    changed = True
    while changed and len(findings) > 1:
        changed = False
        keep_cost = _linear_keep_cost(cx.data, cur)
        first = len(cur.model.effects) - len(findings)     # the findings are the model's last effects
        for i in range(len(findings) - 1):
            if keep_cost[first + i] >= 2 * MATERIAL_SHARE * cx.excess_mm:
                continue            # clearly needed: its linearised removal costs twice the material share
            new = _without(cx, cur, first + i)
            if new.rms_mm - cur.rms_mm < MATERIAL_SHARE * cx.excess_mm and (findings[i].doubtful or
                                                                            not _significant_loss(cx, cur, new, len(findings))):
                f = findings.pop(i)
                cx.near.append(NearMiss(f.candidate.label, new.rms_mm, f.p_value,
                                        f"superseded by the later findings: without it the held-out RMS is "
                                        f"{new.rms_mm:.4f} mm (with it {cur.rms_mm:.4f} mm)", f.candidate.group))
                cur = new
                findings[-1].fit = cur
                changed = True
                break
    return cur


def _significant_loss(cx: _Context, cur: CVResult, without: CVResult, n_tests: int = 1) -> bool:
    """Whether removing an effect both raises the held-out chi-square and is significant on the fit rows (nested
    F-test of the whitened residual sums of squares at ``alpha``, Bonferroni over the ``n_tests`` findings)."""
    if not without.chi2 > cur.chi2:
        return False
    a, b = cur.all_fit, without.all_fit
    q = len(a.free) - len(b.free)
    dof = int(a.n_obs) - len(a.free)
    if q <= 0 or dof <= 0:
        return False
    rss1 = float(a.reduced_chi2) * dof
    rss0 = float(b.reduced_chi2) * max(1, int(b.n_obs) - len(b.free))
    if not rss1 > 0:
        return False
    F = max(0.0, (rss0 - rss1) / q) / (rss1 / dof)
    return float(f_sf(F, q, dof)) * max(1, n_tests) < cx.alpha


def leftover_structure(data: DiagnosisData, final: CVResult, findings: list[Finding], alpha: float = 0.01,
                       material_mm: float = 0.0) -> None:
    """Mark findings whose own driver still orders the final held-out residual beyond what the noise explains: the
    effect then describes only part of what follows that driver (a step read as a sinusoid, a wobble of another
    order).

    Test: the instrument-whitened held-out residual, grouped by quartiles of the driver (the joint's angle, or time
    for a drift); per component a one-way analysis of variance whose error term is the larger of the scatter within
    the groups and the instrument noise (whitened: 1), so residual scatter from elsewhere cannot make a dependence
    look significant and a dependence smaller than the noise cannot either; Bonferroni over the three components and
    the findings.  And the dependence must be material: the RMS of the group means (mm) at least ``material_mm``."""
    t = final.tested
    if not findings or not np.any(t):
        return
    res_mm = final.residual_mm[t]
    res_w = np.einsum("nij,nj->ni", data.whitening[t], res_mm)
    n_tests = 3 * len(findings)
    for f in findings:
        c = f.candidate
        if c.joint is not None:
            x, what = data.q_rad[t, c.joint - 1], f"joint {c.joint}'s angle"
        elif c.kind == "instrument_drift":
            x, what = data.ctx.time_s[t], "time"
        else:
            continue
        edges = np.unique(np.quantile(x, [0, 0.25, 0.5, 0.75, 1]))
        if len(edges) < 3:
            continue
        keys = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
        groups = [keys == k for k in range(len(edges) - 1) if np.count_nonzero(keys == k) > 1]
        p, size = _group_dependence(res_w, res_mm, groups)
        p = min(1.0, p * n_tests)
        if p < alpha and size >= material_mm:
            f.leftover = "; ".join(filter(None, [f.leftover, f"the residual left still depends on {what} "
                                                 f"(p = {p:.2g}, {size:.4f} mm RMS between its quartiles)"]))


def _group_dependence(res_w: np.ndarray, res_mm: np.ndarray, groups: list[np.ndarray]) -> tuple[float, float]:
    """Smallest per-component ANOVA p-value of the whitened residual over ``groups`` (error term: the larger of the
    within-group scatter and the unit noise), and the RMS (mm, 3-D) of the group means about the overall mean."""
    g = len(groups)
    n = sum(int(np.count_nonzero(m)) for m in groups)
    if g < 2 or n <= g:
        return 1.0, 0.0
    p = 1.0
    for v in res_w.T:
        mu = v[np.concatenate([np.flatnonzero(m) for m in groups])].mean()
        between = sum(np.count_nonzero(m) * (v[m].mean() - mu) ** 2 for m in groups) / (g - 1)
        within = sum(float(np.sum((v[m] - v[m].mean()) ** 2)) for m in groups) / (n - g)
        F = between / max(within, 1.0)
        p = min(p, float(f_sf(F, g - 1, n - g)))
    mu_mm = res_mm.mean(0)
    size = np.sqrt(sum(np.count_nonzero(m) * np.sum((res_mm[m].mean(0) - mu_mm) ** 2) for m in groups) / n)
    return p, float(size)
