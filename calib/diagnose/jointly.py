"""Effects found jointly: several joints' elasticities (or scale errors, backlashes...) accepted together.

Why: a real arm bends at every joint at once.  One by one, each joint's compliance explains a small share of the
gap and falls under the acceptance rule's material share, so the greedy selection stops with all of them left out
(DLR's ladder on Agile Justin: joint elasticity was the largest single group, as a group).  So when no single
candidate is accepted in a round, the candidates of one kind on different joints that each improve the linearised
held-out score are tried **together**: one nested F-test for the group (Bonferroni over the kinds tried), the
screen of its linearised held-out gain (the refit's material rule with a margin), one full refit in every fold, the material rule on the group's gain (:func:`calib.diagnose.findings.material_reason`, as
for one effect: a tenth of the baseline's excess, or of the gap still open when every member is 4 sigma from zero
and the group's held-out gain is significant), and the rule identify holds parameters by for each member (its value
2 sigma or more from zero, else it leaves the group and the group is refitted once).
Each member becomes a finding that names the others it was found with.
"""
from __future__ import annotations

import numpy as np

from calib.distributions import f_sf
from calib.pruning import SIGNIFICANT

from .findings import (DOUBTFUL_SPREAD, Finding, NearMiss, heldout_gain_p, material_reason, param_report, project,
                       refit, stability, stated_spread)

#: most members a group may have (the strongest by linearised score)
MAX_MEMBERS = 8


def joint_group(cx, cur, lin, ok, tests, chi2, n_tested: int, screen):
    """The best group of one kind that passes (a list of Findings and the new fit), or "" with nothing found.

    ``screen(columns, n_tests)``: the group's linearised held-out RMS (mm) and why it is not worth a refit ("" when
    it is), as single candidates are screened before theirs (:data:`calib.diagnose.select.LINEAR_SLACK`): a group's
    refit is one fit per fold with up to eight more effects, and most groups tried are not accepted (the nested
    TIAGo diagnosis refitted seven or eight groups in each of its six diagnoses and accepted none: 24 of 41 s)."""
    kinds = _groups(ok, chi2, cur.chi2)
    for kind, members in kinds.items():
        p, F = _group_test(lin, tests, ok, members)
        p = min(1.0, p * len(kinds))
        if p >= cx.alpha:
            continue
        cands = [ok[k][0] for k in members]
        predicted, why = screen([c for k in members for c in ok[k][1]], len(kinds))
        if why:
            cx.near.append(NearMiss(" + ".join(c.label for c in cands), predicted, p, why, cands[0].group))
            continue
        for _ in range(2):
            model, new = refit(cx.data, cur, cands, cx.geo_free, cx.loss)
            first = len(model.effects) - len(cands)
            spreads = [stated_spread(model, new, c, stability(model, new, c, first + i)[1], first + i)
                       for i, c in enumerate(cands)]
            keep = [c for c, s in zip(cands, spreads) if s <= 1.0 / SIGNIFICANT]
            if len(keep) == len(cands) or len(keep) < 2:
                break
            cands = keep
        else:
            keep = []           # a member still left after the refit: the last fit is not of these members
        gain = cur.rms_mm - new.rms_mm
        label = " + ".join(c.label for c in cands)
        why = "" if new.chi2 < cur.chi2 else "does not shrink the held-out gap"
        if not why and len(keep) >= 2 and len(keep) == len(cands):
            why = material_reason(gain, cx.excess_mm, cx.open_mm(cur), max(spreads) <= DOUBTFUL_SPREAD,
                                  min(1.0, heldout_gain_p(cx.data, cur, new) * len(kinds)), cx.alpha)
        if len(keep) < 2 or len(keep) != len(cands) or why:
            cx.near.append(NearMiss(label, new.rms_mm, p, f"together (a joint group) they shrink the held-out RMS by "
                                    f"{gain:.4f} mm, or a member is not significant", cands[0].group))
            continue
        out = []
        for i, c in enumerate(cands):
            spread, fold_sigma = stability(model, new, c, first + i)
            f = Finding(c, new.rms_mm, new.max_mm, p, F, float("nan"), new.chi2,
                        param_report(c, model, new, fold_sigma, first + i), n_tested, spread, [],
                        gain / cx.excess_mm if cx.excess_mm > 0 else float("nan"), new,
                        stated_spread=stated_spread(model, new, c, fold_sigma, first + i))
            f.jointly = [o.label for o in cands if o is not c]
            out.append(f)
        return out, new
    return ""


def _groups(ok, chi2: np.ndarray, cur_chi2: float) -> dict[str, list[int]]:
    """Per kind without an order grid, the best candidate per joint among those that improve the linearised score
    (two or more joints)."""
    best: dict[tuple, int] = {}
    for k, (c, _) in enumerate(ok):
        if c.order is not None or c.joint is None or not chi2[k] < cur_chi2:
            continue
        key = (c.kind, c.joint)
        if key not in best or chi2[k] < chi2[best[key]]:
            best[key] = k
    out: dict[str, list[int]] = {}
    for (kind, _), k in best.items():
        out.setdefault(kind, []).append(k)
    return {kind: sorted(ks, key=lambda k: chi2[k])[:MAX_MEMBERS] for kind, ks in out.items() if len(ks) >= 2}


def _group_test(lin, tests, ok, members: list[int]) -> tuple[float, float]:
    """Nested F-test of the members' columns together against the current model (whitened, all poses)."""
    if tests.r0 is None:
        return 1.0, 0.0
    cols = [c for k in members for c in ok[k][1]]
    B = project(lin.Qa, lin.Jw[:, cols])
    dc, *_ = np.linalg.lstsq(B, tests.r0, rcond=None)
    e = tests.r0 - B @ dc
    rss0, rss1 = float(tests.r0 @ tests.r0), float(e @ e)
    q = len(cols)
    dof = tests.dof - q
    if rss1 <= 0 or dof <= 0:
        return 1.0, 0.0
    F = max(0.0, (rss0 - rss1) / q) / (rss1 / dof)
    return float(f_sf(F, q, dof)), float(F)
