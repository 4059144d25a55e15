"""Estimates that physics rules out: a compliance or a mass below zero.

A joint gives way in the direction of the load; a negative compliance makes it push back.  A fit that drives one
negative beyond its error is absorbing another error through the effect's signature (an unmodelled elasticity of a
neighbouring joint, a geometric error the load pattern happens to follow), and must say so instead of reporting a
stiffness; one negative within its error is simply not determined by the data.  Each effect names its positive
parameters (``Effect.positive_params``).
"""
from __future__ import annotations

from .compensate import unit_of

#: a negative estimate further than this many sigma below zero is a contradiction, not noise
SIGNIFICANT_SIGMA = 2.0


def sign_findings(model, ident) -> list[dict]:
    """Every estimated positive-by-physics parameter with a negative value: name, value, sigma, unit, and whether it
    is significantly negative (``absorbs``) or within its error of zero."""
    out = []
    for e in model.effects:
        for p, q in zip(e.param_names, e.qualified_names()):
            if p not in e.positive_params or q not in ident.free:
                continue
            v, s = ident.value(q), ident.std(q)
            if v < 0:
                out.append({"parameter": q, "value": v, "sigma": s, "unit": unit_of(q),
                            "absorbs": bool(v < -SIGNIFICANT_SIGMA * s)})
    return out


def sign_lines(findings: list[dict]) -> list[str]:
    """The findings in words, one line each."""
    lines = []
    for f in findings:
        head = f"{f['parameter']} = {f['value']:.4g} ± {f['sigma']:.2g} {f['unit']} is negative"
        if f["absorbs"]:
            lines.append(f"{head}, more than {SIGNIFICANT_SIGMA:g} sigma below zero: it is positive by physics, so "
                         f"this effect absorbs another error (an elasticity or geometry the model lacks); look for it "
                         f"(robocal diagnose) before trusting it")
        else:
            lines.append(f"{head} but within {SIGNIFICANT_SIGMA:g} sigma of zero: these data do not determine it")
    return lines
