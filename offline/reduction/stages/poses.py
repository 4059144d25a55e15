"""The Chapter 6 pose set: the geometry and the session's running errors identified together
(:func:`calib.identify.identify`, model and priors from :mod:`offline.reduction.pose_model`), the errors completed with
the stations' and the transmission-error run's terms (:mod:`offline.reduction.pose_errors`), and the accuracy before
and after on held-out poses (:mod:`calib.accuracy`).  Gives the identified model document."""
from __future__ import annotations

import numpy as np

from calib.accuracy import before_after
from calib.compensate import model_document, unit_of
from calib.errors import RobocalError
from calib.identify import PointObservations, default_free, identify

from acq.session.imported import imported_context, imported_point, one_target_one_station

from offline.reduction.context import Reduction
from offline.reduction.joints import reading_q
from offline.reduction.pose_errors import FLOOR_NOTE, floored_sigma, station_variance, te_run_variance
from offline.reduction.pose_model import pose_model, running_error_specs
from offline.reduction.registry import Stage

#: fewer poses than this cannot identify a geometry with its running errors
MIN_POSES = 8


def accuracy(ctx: Reduction, model, obs, free, theta0, priors, warm=None) -> None:
    """Before/after accuracy on held-out poses into ``figs['accuracy']``; a pose set too small to split is said,
    not guessed.  ``warm``: the fit on every pose, where the fit on the fit poses starts."""
    try:
        acc = before_after(model, obs, free, theta0=theta0, priors=priors, warm=warm)
    except RobocalError as exc:
        ctx.said(f"poses: accuracy before/after not computed: {exc}")
        return
    ctx.figs["accuracy"] = {**acc.as_dict(), "test_index": acc.test_index.tolist(),
                            "before_err_mm": acc.before_err_mm.tolist(), "after_err_mm": acc.after_err_mm.tolist()}


def prepare_poses(ctx: Reduction, steps: list[dict]) -> None:
    """The poses' targets located (one batch for the procedure: :class:`offline.reduction.context.Located`) while
    the stage waits for the running errors' stages (see :mod:`offline.reduction.live`)."""
    sighted = [st for st in steps if st["readings"]]
    if sighted:
        ctx.points(sighted[0])


def reduce_poses(ctx: Reduction, steps: list[dict]) -> dict | None:
    if not steps:
        return None
    robot = ctx.robot
    q, P, S, D, used = [], [], [], [], []
    for st in steps:
        pt = ctx.points(st).get("P") if st["readings"] else None
        if pt is None:
            pt = imported_point(st)                               # an imported pose CSV: its own sigmas
        if pt is None:
            continue
        q.append(reading_q(st, robot))
        P.append(pt[0])
        S.append(pt[1])
        D.append(getattr(pt, "d_station", None))
        used.append(st)
    if len(q) < MIN_POSES:
        raise RobocalError(f"only {len(q)} poses with both sightings; identification needs more")
    one_target_one_station(used, "reprocess")
    running = {k: ctx.outputs.get(k) for k in ("transmission", "compliance")}
    specs = running_error_specs(ctx.setup, running, ctx.steps_of(("coupling",)))
    model, theta0, priors = pose_model(robot, running, ctx.problems, specs)
    q, P = np.array(q), np.array(P)
    obs = PointObservations(q, P, cov_mm2=np.array(S), ctx=imported_context(used, robot.n))
    # the dead zone needs loading and unloading, which a pose set has not: it stays out
    wanted = [n for n in default_free(model, effects=True) if not n.endswith("deadzone_rad")]
    ident = identify(model, obs, free=wanted, theta0=theta0, priors=priors)
    # the model document is the model and its identification alone (the errors below, with the stations' and the
    # run's terms, are the estimates'; the held-out accuracy does not change it): whoever waits for the model (ISO
    # 9283's compensated run) has it now, not after their eight re-solves
    doc = model_document(model, ident)
    ctx.gave("identified", doc)
    te_add, te_prior = te_run_variance(robot, running, specs, obs, ident, priors, ctx.problems)
    var = ident.sigma ** 2 + station_variance(model, obs, D, ident, priors, ctx.points.station_fit,
                                              ctx.problems) + te_add
    sigma, floored = floored_sigma(var, ident.sigma ** 2, te_prior)
    for n in ident.free:
        i = ident.names.index(n)
        ctx.est.add(f"ident.{n}", ident.theta[i], sigma[i], unit_of(n), **({"note": FLOOR_NOTE} if floored[i] else {}))
    for n in wanted:
        if n in ident.free:
            continue
        why = [c.words(robot) for c in ident.identifiability.unidentifiable + ident.identifiability.weak
               if n in c.coefficients][:1]
        ctx.est.add(f"ident.{n}", ident.value(n), 0.0, unit_of(n), held=True,
                    note="held at its design value, not estimated" + (f": {why[0]}" if why else "")
                         + "; its truth is not comparable with the value")
    pred = model.points(q, theta=ident.theta[:model.P])
    ctx.figs["poses"] = {"residual_mm": np.linalg.norm(P - pred, axis=1).tolist(),
                         "rms_mm": float(ident.residual_rms), "held": [n for n in wanted if n not in ident.free],
                         "points_mm": P.tolist(), "running_errors": list(specs)}
    ctx.trace["poses"] = {"q_rad": q}
    if ctx.held_out:
        accuracy(ctx, model, obs, ident.free, theta0, priors, ident.theta)
    return doc


PREPARE = prepare_poses
STAGE = Stage("poses", reduce_poses, procedures=("poses",), needs=("stations", "transmission", "compliance"),
              reads=("coupling",), gives="identified", progress=0.8)
