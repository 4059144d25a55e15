"""Truths of the pose set's identification, in the fit's gauge: parameters the pose set cannot determine are held at
their design values and the free ones absorb their true deviations (the base yaw takes joint 1's zero offset, d3
takes d2 of the parallel pair ...).  Fitting the twin's own model, effects at their true values, to its noise-free
points at the session's joint readings, with the same parameters held, gives what a perfect estimator would return:
the truth the estimates are compared with (the twin's own value kept as ``truth_raw`` where they differ)."""
from __future__ import annotations

import numpy as np

from calib.errors import RobocalError
from calib.identify import PointObservations, identify

from sim.emulate.truth import Scoring, truth_of

GAUGE_NOTE = ("truth in the gauge of the held parameters (what perfect data would give with them at their design "
              "values)")


def gauge_truth(sc: Scoring, params: list[dict], q: np.ndarray) -> dict[str, float]:
    """The twin's geometry in the identification's gauge (see the module docstring)."""
    twin = sc.twin
    tm = twin.model
    th = np.array(twin.theta, float)
    value = {p["name"]: p["value"] for p in params}
    geo_free = [p["name"] for p in params if p["estimated"] and p["name"] in tm.kin.index]
    for n in tm.kin.names:
        if n not in geo_free and n in value:
            th[tm.index[n]] = value[n]
    pts, _ = twin.true_points(q)
    try:
        g = identify(tm, PointObservations(q, pts, sigma_mm=0.01), free=geo_free, theta0=th, robust=False)
    except RobocalError:
        return {}
    return {n: g.value(n) for n in g.free}


def held_away(sc: Scoring, params: list[dict]) -> dict[str, str]:
    """Estimated effect parameters whose effect has a parameter held away from the twin's value (a joint compliance
    fitted with one slope, its breakpoint held at infinity, where the twin has two slopes and a breakpoint): the free
    one absorbs the difference, so no truth in the fit's gauge is known for it -- name -> why, in words."""
    truth, geo = sc.truth, sc.twin.model.kin.index
    away: dict[str, list[str]] = {}
    for p in params:
        n = p["name"]
        if n not in geo and not p["estimated"] and n in truth and not np.isclose(truth[n], p["value"]):
            away.setdefault(n.rsplit(".", 1)[0], []).append(f"{n.rsplit('.', 1)[1]} held at {p['value']:.4g} "
                                                             f"(twin {truth[n]:.4g})")
    return {p["name"]: "no truth in the fit's gauge: its effect has " + ", ".join(away[p["name"].rsplit(".", 1)[0]])
            for p in params if p["estimated"] and p["name"] not in geo and p["name"].rsplit(".", 1)[0] in away}


@truth_of("poses")
def poses_truth(sc: Scoring, trace: dict) -> None:
    doc = sc.res.get("robot")
    if doc is None or "q_rad" not in trace:
        return
    params, truth = doc["parameters"], sc.truth
    gauge = gauge_truth(sc, params, np.asarray(trace["q_rad"], float))
    unknown = held_away(sc, params)
    for p in params:
        n, raw = p["name"], truth.get(p["name"])
        est = sc.estimate(f"ident.{n}")
        if not p["estimated"]:                      # held: its value is the design value by choice
            p["truth"], p["note"] = None, "held at its design value, not estimated: no truth to compare it with"
            if raw is not None:
                p["truth_raw"] = float(raw)
            if est is not None and raw is not None:
                sc.set(est["name"], raw)            # shown for information, never compared
            continue
        if n in unknown:
            p["truth"], p["note"] = None, unknown[n]
            if raw is not None:
                p["truth_raw"] = float(raw)
                sc.set(f"ident.{n}", None, raw=raw, note=unknown[n])
            continue
        tv = gauge.get(n, raw)
        p["truth"] = None if tv is None else float(tv)
        if tv is None:
            continue
        if raw is not None and est is not None and abs(tv - raw) > 0.1 * est["error"]:
            sc.set(est["name"], tv, raw=raw, note=GAUGE_NOTE)
        else:
            sc.set(f"ident.{n}", tv)
        if raw is not None and p["name"] in gauge and abs(tv - raw) > 0:
            p["truth_raw"], p["note"] = float(raw), GAUGE_NOTE
