"""Wrist cross coupling (section 4.7): sigma_jk per coupled pair from the tapped counts, every repeat of a pair used
-- the scatter of the repeats (servo repeatability) pooled over the pairs, quantisation as the floor
(:func:`calib.estimators.coupling.coupling_from_repeats`) -- and eq 4.7.2's further correction against the factors
the controller compensates with (the description's)."""
from __future__ import annotations

import numpy as np

from calib.estimators.coupling import coupling_from_repeats, further_correction, quantisation_sigma
from calib.units import DEG

from offline.reduction.context import Reduction
from offline.reduction.registry import Stage

PHASES = ("start", "alone", "return", "with")


def reduce_coupling(ctx: Reduction, steps: list[dict]) -> None:
    if not steps:
        return
    robot = ctx.robot
    runs: dict[tuple, dict] = {}
    for st in steps:
        m = st["spec"]["meta"]
        if st.get("counts") is None or len(st["counts"]) == 0:
            continue
        runs.setdefault((m["j"], m["k"]), {}).setdefault(m.get("repeat", 0), {})[m["phase"]] = np.mean(st["counts"], 0)
    S = 2 * np.pi / (robot.counts_per_rev * robot.gear_ratio)           # joint rad per count, coupling ignored
    pairs, q = {}, 0.0
    for (j, k), reps in sorted(runs.items()):
        rows = [(ph["with"] - ph["return"], ph["alone"] - ph["start"], ph["with"], ph["return"]) for ph in reps.values()
                if all(p in ph for p in PHASES)]
        if not rows:
            continue
        th_with = np.array([w[k - 1] * S[k - 1] for w, _, _, _ in rows])            # S_k xi_k of eq 4.7.1
        th_alone = np.array([a[k - 1] * S[k - 1] for _, a, _, _ in rows])
        th_j = np.array([robot.joint_from_counts(w)[j - 1] - robot.joint_from_counts(r)[j - 1]
                         for _, _, w, r in rows])
        pairs[(j, k)] = (th_with, th_alone, th_j)
        q = max(q, quantisation_sigma(abs(S[k - 1])))
    ctx.figs["coupling"] = {}
    if not pairs:
        return
    res = coupling_from_repeats({f"sigma{j}{k}": v for (j, k), v in pairs.items()}, q * np.sqrt(2))
    # eq 4.7.2: what the controller compensates with (the description's factors) against what was measured
    further = further_correction(res, {f"sigma{j}{k}": float(robot.coupling[k - 1, j - 1]) for (j, k) in pairs})
    ctx.est.add_set("coupling.", further)
    for (j, k), (th_with, th_alone, th_j) in pairs.items():
        name = f"sigma{j}{k}"
        ctx.est.add_set("coupling.", res.subset([name]))
        ctx.figs["coupling"][f"{j}{k}"] = {"theta_j_deg": float(np.mean(th_j)) / DEG,
                                           "theta_k_alone_deg": float(np.mean(th_alone)) / DEG,
                                           "theta_k_with_deg": float(np.mean(th_with)) / DEG,
                                           "sigma": float(res[name].value), "repeats": int(th_j.size),
                                           "error_type": res.extras["type"]}


STAGE = Stage("coupling", reduce_coupling, procedures=("coupling",))
