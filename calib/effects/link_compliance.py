"""Cantilever bending of link j (frame j-1 to frame j) under the load it carries at its end (section 4.6).

The segment is a cantilever with flexural rigidity EI loaded at its end by the weight of everything beyond it plus the
payload and the external tool force: tip deflection F L^3 / (3 EI) and tip slope F L^2 / (2 EI), carried rigidly to
the tool point.  A point-stage effect.
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, Loads, register_effect


@register_effect
class LinkCompliance(Effect):
    kind = "link_compliance"
    stage = "point"
    needs_loads = True
    param_names = ("compliance_per_nmm2",)      # 1 / EI
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "ei_nmm2": Field("number", required=True, positive=True)}

    def __init__(self, joint: int, ei_nmm2: float):
        super().__init__(joint, {"compliance_per_nmm2": 1.0 / ei_nmm2})

    @classmethod
    def zero(cls, joint=None):
        return cls(joint, 1e18)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["ei_nmm2"])

    def point_delta(self, fp, point, loads: Loads, values):
        j = self.joint                          # link j spans frame j-1 -> frame j
        start, end = fp.frame_t[:, j - 1], fp.frame_t[:, j]
        seg = end - start
        L = np.linalg.norm(seg, axis=-1)
        u = seg / np.where(L > 0, L, 1.0)[:, None]
        F = loads.tip_force_n[:, j - 1]
        Fperp = F - np.sum(F * u, -1)[:, None] * u
        # unit compliance response: deflection F L^3/3 and slope F L^2/2 (per unit 1/EI)
        defl = Fperp * (L ** 3 / 3.0)[:, None]
        slope_vec = np.cross(u, Fperp) * (L ** 2 / 2.0)[:, None]       # rotation vector (rad per unit 1/EI)
        unit = defl + np.cross(slope_vec, point - end)
        return unit * values[0], unit[..., None]
