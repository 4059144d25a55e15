"""Link compliance (section 4.6): the flexural rigidity of a link from dial gauges touching it, masses hung on it.

Every reading is predicted by the model's physics (:class:`calib.model.MeasurementModel` with the link's bending,
:class:`calib.effects.LinkCompliance`, and its joints' compliance, :class:`calib.effects.JointCompliance`), at the
step's pose, with the hung masses as point forces (:mod:`calib.loads`) and each gauge as a point on the link read
along its axis: the design column of a compliance is what a unit of it moves the gauge, loaded minus unloaded.  So
only the load's component across the link bends it (a link off level is not biased), and a compliant joint is not
read as bending: the stiffness the joint-compliance run measured is taken out (with its error), and a joint it did
not measure is fitted alongside -- the gauges at several points separate a rigid turn from a bend.  The result
(:func:`calib.estimators.link_compliance.rigidity_from_design`): EI with its error when the gauges show bending,
else a 95 % one-sided lower bound -- the thesis's own finding on the Puma (section 5.7) stated as a result.
"""
from __future__ import annotations

import numpy as np

from calib.effects import JointCompliance, LinkCompliance
from calib.estimators.link_compliance import RigidityBound, rigidity_from_design
from calib.loads import hung_masses, point_force_context
from calib.model import MeasurementModel

from acq.session.setup import GAUGE_SIGMA_MM

from offline.reduction.context import Reduction
from offline.reduction.joints import reading_q
from offline.reduction.registry import Stage
from offline.reduction.torques import swept_geometry


def gauge_rows(ctx: Reduction, steps: list[dict], j: int, joints: list[int]):
    """Per gauge reading: the reading (mm), its design row (gauge motion per unit of link j's compliance, then of
    each of ``joints``' compliance), the gauge's position along the link (mm) and the load hung (N)."""
    effects = [LinkCompliance(j, 1e18)] + [JointCompliance(i, 1e12) for i in joints]
    model = MeasurementModel(ctx.robot, effects)
    geo_model, geo, _ = swept_geometry(ctx)
    theta = model.nominal.copy()
    theta[: model.n_geometric] = geo[: geo_model.n_geometric]
    cols = [model.index[f"link_compliance.j{j}.compliance_per_nmm2"]] + \
        [model.index[f"joint_compliance.j{i}.compliance1_rad_per_nm"] for i in joints]
    g = model.gravity_n_per_kg(theta)
    # the gauge's Jacobian unloaded, by pose, point and link: a series hangs its loads at one pose, so every step
    # after the first asks for the very evaluation again (the same arguments: the same floats)
    unloaded: dict[tuple, np.ndarray] = {}
    y, rows, x, P = [], [], [], []
    for st in steps:
        s = st["spec"]["setup"]                                   # in the step vocabulary since reading
        masses = hung_masses(s.get("loads", []))
        q = reading_q(st, ctx.robot)[None]
        loaded = model.context(1, **point_force_context(masses, g))
        for k, gauge in enumerate(s.get("gauges", [])):
            v = st["inputs"].get(f"{gauge['name']}_mm")
            if v is None:
                continue
            axis = np.asarray(gauge["axis"], float) / np.linalg.norm(gauge["axis"])
            point = np.asarray(gauge["point_mm"], float)
            link = int(gauge["link"])
            J = model.evaluate(q, loaded, theta, jacobian=True, tool_mm=point, link=link).jacobian[0]
            key = (q.tobytes(), point.tobytes(), link)
            if key not in unloaded:
                unloaded[key] = model.evaluate(q, model.context(1), theta, jacobian=True, tool_mm=point,
                                               link=link).jacobian[0]
            rows.append(axis @ (J - unloaded[key])[:, cols])
            y.append(float(v))
            x.append(float(s["gauges_x_mm"][k]) if "gauges_x_mm" in s else float("nan"))
            P.append(float(sum(m.mass_kg for m in masses) * np.linalg.norm(g)))
    return np.array(y), np.array(rows).reshape(len(y), len(cols)), x, P


def reduce_link(ctx: Reduction, steps: list[dict]) -> None:
    if not steps:
        return
    cfg = ctx.setup.link
    j = cfg.joint
    measured = {i: r for i, r in (ctx.outputs.get("compliance") or {}).items() if i <= j}
    joints = sorted(set(measured) | {j})
    y, X, x, P = gauge_rows(ctx, steps, j, joints)
    sigma = float(cfg.gauge_sigma_mm or GAUGE_SIGMA_MM)
    C = sigma ** 2 * np.eye(len(y))
    keep = [0]
    for c, i in enumerate(joints, 1):        # a measured joint's turn taken out, with its stiffness's error
        if i in measured:
            K, sK = measured[i]["K1_Nm_per_rad"].value, measured[i]["K1_Nm_per_rad"].error
            y = y - X[:, c] / K
            C = C + np.outer(X[:, c], X[:, c]) * (sK / K ** 2) ** 2
        elif np.any(np.abs(X[:, c]) > 0):
            keep.append(c)
    res = rigidity_from_design(X[:, keep], y, C, ("EI_Nmm2",),
                               second_moment_mm4=cfg.second_moment_mm4, n_mc=ctx.n_mc)
    ctx.figs["link"] = {"x_mm": x, "load_n": P, "deflection_mm": y.tolist(), "load_x_mm": [cfg.load_x_mm] * len(y)}
    prefix = f"link.j{j}."
    if isinstance(res, RigidityBound):
        ctx.est.add_bound(f"{prefix}EI_lower_bound_Nmm2", res.EI_lower_bound_Nmm2, "N mm^2", "lower", res.confidence,
                          detection_limit_Nmm2=res.detection_limit_Nmm2, compliance_per_Nmm2=res.compliance_per_Nmm2,
                          compliance_error_per_Nmm2=res.compliance_error_per_Nmm2,
                          largest_deflection_mm=res.largest_deflection_mm, sigma_mm=res.sigma_mm,
                          note=f"no significant bending (largest deflection {res.largest_deflection_mm:.2g} mm, gauge "
                               f"noise {sigma:.2g} mm): the link is at least this stiff at "
                               f"{100 * res.confidence:g} % confidence")
        ctx.figs["link"].update(EI_lower_bound_Nmm2=res.EI_lower_bound_Nmm2, confidence=res.confidence)
        return
    ctx.est.add_set(prefix, res, only=("EI_Nmm2",))
    ctx.figs["link"]["EI_Nmm2"] = float(res["EI_Nmm2"].value)


STAGE = Stage("link", reduce_link, procedures=("link_compliance",), needs=("axes", "compliance"),
              label="link compliance")
