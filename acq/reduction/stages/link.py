"""Link compliance (section 4.6): the flexural rigidity of a link from dial gauges along it, loads hung on it
(:func:`calib.estimators.link_compliance.link_rigidity`): EI with its error when the gauges show bending, else a
95 % one-sided lower bound -- the thesis's own finding on the Puma (section 5.7: link compliance negligible against
joint compliance) stated as a result."""
from __future__ import annotations

from calib.estimators.link_compliance import RigidityBound, link_rigidity
from calib.units import G0_M_S2

from ..context import Reduction
from ..registry import Stage


def link_load_n(inputs: dict, spec_setup: dict) -> float:
    """The force hung at a link step (N): the mass the operator entered (``load_kg``, contract C3) times standard
    gravity; sessions recorded before that entered ``load_n``; else the planned load."""
    if inputs.get("load_kg") is not None:
        return float(inputs["load_kg"]) * G0_M_S2
    return float(inputs.get("load_n", spec_setup["load_n"]))


def reduce_link(ctx: Reduction, steps: list[dict]) -> None:
    if not steps:
        return
    cfg = ctx.setup["link"]
    x, a, P, y = [], [], [], []
    for st in steps:
        s = st["spec"]["setup"]
        for g, gx in enumerate(s["gauges_x_mm"]):
            v = st["inputs"].get(f"gauge{g + 1}_mm")
            if v is None:
                continue
            x.append(gx)
            a.append(s["load_x_mm"])
            P.append(link_load_n(st["inputs"], s))
            y.append(v)
    res = link_rigidity(x, a, P, y, sigma_mm=0.001, second_moment_mm4=cfg.get("second_moment_mm4"), n_mc=ctx.n_mc)
    ctx.figs["link"] = {"x_mm": x, "load_n": P, "deflection_mm": y, "load_x_mm": a}
    prefix = f"link.j{cfg['joint']}."
    if isinstance(res, RigidityBound):
        ctx.est.add_bound(f"{prefix}EI_lower_bound_Nmm2", res.EI_lower_bound_Nmm2, "N mm^2", "lower", res.confidence,
                          detection_limit_Nmm2=res.detection_limit_Nmm2, compliance_per_Nmm2=res.compliance_per_Nmm2,
                          compliance_error_per_Nmm2=res.compliance_error_per_Nmm2,
                          largest_deflection_mm=res.largest_deflection_mm, sigma_mm=res.sigma_mm,
                          note=f"no significant bending (largest deflection {res.largest_deflection_mm:.2g} mm, gauge "
                               f"noise {res.sigma_mm:.2g} mm): the link is at least this stiff at "
                               f"{100 * res.confidence:g} % confidence")
        ctx.figs["link"].update(EI_lower_bound_Nmm2=res.EI_lower_bound_Nmm2, confidence=res.confidence)
        return
    ctx.est.add_set(prefix, res, only=("EI_Nmm2",))
    ctx.figs["link"]["EI_Nmm2"] = float(res["EI_Nmm2"].value)


STAGE = Stage("link", reduce_link, procedures=("link_compliance",), label="link compliance")
