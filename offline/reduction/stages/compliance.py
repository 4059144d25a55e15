"""Joint compliance (section 4.5): the deflection (angle of A1 -> A2 about the joint's axis) against the torque
about that axis, the torque from the geometry at each step's pose with its recorded loads
(:mod:`offline.reduction.torques`), loading then unloading: the two-slope fit
(:func:`calib.estimators.compliance.two_slope_fit`).  A joint about which the loads produce no torque (its axis along
gravity, a lever along the axis) gets no number: "not determined" and why.  The joints are fitted base first, and
what the ones already fitted turn about the next one's axis under its loads is taken out of its deflections
(:func:`offline.reduction.torques.compliance_deflection`).  Gives the fits by joint."""
from __future__ import annotations

import numpy as np

from calib.errors import RobocalError
from calib.estimators.compliance import two_slope_fit
from calib.units import DEG

from offline.reduction.context import Reduction
from offline.reduction.joints import angles_about, by_joint
from offline.reduction.registry import Stage
from offline.reduction.torques import compliance_deflection, series_loads, swept_geometry, torque_covariance

REPORTED = ("K1_Nm_per_rad", "K2_Nm_per_rad", "breakpoint_Nm", "offset_rad")
#: torque range (N m) below which the loads did not turn the joint
MIN_TORQUE_RANGE_NM = 0.05


def reduce_compliance(ctx: Reduction, steps: list[dict]) -> dict | None:
    if not steps:
        return None
    model, theta, sig_geo = swept_geometry(ctx)
    ctx.figs["compliance"] = {}
    ctx.trace["compliance"] = {}
    fits = {}
    for j, sts in sorted(by_joint(steps).items()):
        per_step = series_loads(sts, ctx, model, theta)
        T = np.array([p.torque_nm[j - 1] for p in per_step])
        axis = per_step[0].axes[j - 1]      # the joint's axis at the loading pose (not the swept one's pose)
        applied = np.ptp(T)
        if not np.isfinite(applied) or applied < MIN_TORQUE_RANGE_NM:
            ctx.said(f"compliance: joint {j}: not determined: the loads change the torque about joint {j} by "
                     f"{applied:.3g} N m at the loading pose (its axis is along gravity or the lever along the axis): "
                     f"hang them where they turn the joint")
            continue
        sign = 1.0 if T[np.argmax(np.abs(T))] >= 0 else -1.0        # the fit's branches are for positive torques
        defl, sig, dcov = angles_about(sts, ctx.points, axis)
        # the joints measured before it deflect too under these loads: their turn about this axis taken out
        others, ocov = compliance_deflection(per_step, fits, j, skip=j)
        defl, dcov = defl - others, dcov + ocov
        unload = np.array([s["spec"]["meta"]["phase"] == "unload" for s in sts])
        try:
            res = two_slope_fit(sign * T, sign * defl, unload, dcov, n_mc=ctx.n_mc,
                                sigma_torque_Nm=torque_covariance(per_step, j, sig_geo))
        except RobocalError as exc:                 # e.g. "not determined": the other joints still count
            ctx.said(f"compliance: joint {j}: {exc}")
            continue
        K = res["K1_Nm_per_rad"]
        if not (np.isfinite(K.value) and np.isfinite(K.error) and K.value > 0 and K.error < K.value):
            ctx.said(f"compliance: joint {j}: not determined: K1 = {K.value:.4g} +- {K.error:.2g} N m/rad (torque "
                     f"range {applied:.3g} N m, deflection sigma {np.nanmean(sig):.2g} rad)")
            continue
        single = bool(res.extras.get("single_slope"))
        span = sorted(abs(t) for t in res.extras.get("torque_range_Nm", (0.0, 0.0)))
        for e in res.estimates():
            if e.name not in REPORTED:
                continue
            extra = {}
            if single and e.name == "K1_Nm_per_rad":
                extra = {"single_slope": True,
                         "note": f"one slope over every load ({span[0]:.3g} .. {span[1]:.3g} N m): the breakpoint is "
                                 f"not determined, so K2 and the breakpoint are not reported; hang more, smaller "
                                 f"loads on each side of it to tell two slopes apart"}
            ctx.est.add(f"compliance.j{j}.{e.name}", e.value, e.error, e.unit, **extra)
        ctx.trace["compliance"][j] = {"torque_nm": T, "sign": sign, "unloading": unload, "single_slope": single,
                                      "cov_rad2": np.asarray(res.extras.get("cov_rad2", dcov))}
        fits[j] = res
        ctx.figs["compliance"][j] = {"torque_nm": T.tolist(), "deflection_deg": (defl / DEG).tolist(),
                                     "unloading": unload.tolist(), "fit": {k: float(res[k].value) for k in res.names}}
    return fits


STAGE = Stage("compliance", reduce_compliance, procedures=("compliance",), needs=("axes",), gives="compliance",
              progress=0.45)
