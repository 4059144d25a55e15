"""The thesis's own reduction of the sweeps (eqs 4.3.12-15): the joint centres compensated into S_fj, then a1, a2,
d1, d2 -- and d3 from point P and L_p when P was sighted (:func:`calib.estimators.misalignment.thesis_route`).
The formulas are the thesis's Puma's: the stage applies only to a robot of that structure
(:attr:`calib.profile.RobotProfile.thesis_scheme`)."""
from __future__ import annotations

import numpy as np

from calib.estimators.misalignment import thesis_route

from acq.session.setup import point_p

from offline.reduction.context import Reduction
from offline.reduction.registry import Stage
from offline.reduction.stages.sweeps import SweptAxes


def point_p_mean(ctx: Reduction, p_steps: list[dict]):
    """Point P as the mean of its sightings with its covariance, and L_p (the step's, else the set-up's); all None
    when P was not sighted, or sighted without an L_p (said)."""
    if not p_steps:
        return None, None, None
    pts = [ctx.points(s)["P"] for s in p_steps]
    m = len(pts)
    W = np.kron(np.ones((1, m)), np.eye(3)) / m                          # mean of the repeats
    P, Pc = W @ np.concatenate([t[0] for t in pts]), W @ ctx.points.covariance(pts) @ W.T
    lp = p_steps[0]["spec"]["meta"].get("L_p_mm")
    if lp is None:                                   # an imported step: L_p from the set-up
        pp = point_p(ctx.setup)
        lp = None if pp is None else pp[2]
    if lp is None:
        ctx.said("compensation scheme: point P sighted but the set-up gives no L_p (point_p.L_p_mm): d3 not computed")
        return None, None, None
    return P, Pc, lp


def reduce_compensation(ctx: Reduction, steps: list[dict]) -> None:
    swept: SweptAxes | None = ctx.outputs.get("axes")
    if swept is None or len(swept.axes) < ctx.robot.n:
        return
    zd, xf = swept.design_frames()
    V, C = swept.stacked(range(1, 7))
    P, Pc, lp = point_p_mean(ctx, [st for st in steps if st["spec"]["meta"].get("point") == "P"])
    res = thesis_route(V, C, zd, xf, P, Pc, lp, swept.design.frame_R[0, 0], n_mc=ctx.n_mc)
    ctx.trace["compensation"] = {"L_p_mm": lp}
    ctx.est.add_set("comp.", res)
    ctx.figs["compensation"] = [{"name": nm, "value": float(res[nm].value), "error": float(res[nm].error),
                                 "truth": None} for nm in res.names]


STAGE = Stage("compensation", reduce_compensation, procedures=("sweep",), needs=("axes",),
              applies=lambda profile: profile.thesis_scheme, label="compensation scheme")
