"""Cantilever bending of link j under the loads it carries (section 4.6).

The link's body (:meth:`calib.kinematics.ChainPass.link_beam`: its length across joint j's axis, up to frame j) is a
cantilever with flexural rigidity EI clamped at frame j-1, loaded at its end by the weight of
everything beyond it plus the payload and the external tool force, and along its length by the forces at points fixed
on link j (hung masses; each acts at its projection on the segment).  A force P at a bends the beam at x by
P x^2 (3a - x) / (6 EI) (x <= a) or P a^2 (3x - a) / (6 EI) (x > a), with slope P x (2a - x) / (2 EI) or
P a^2 / (2 EI): at the tip, for a = L, F L^3 / (3 EI) and F L^2 / (2 EI).  A point beyond link j is carried rigidly
by the tip; a point on link j moves with the beam at its own projection; a point on an earlier link does not move.
A point-stage effect.
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, Loads, register_effect


def cantilever_shape(x_mm, a_mm):
    """``y * 6 EI / P``: the deflection shape (mm^3) at ``x`` for a unit load at ``a`` on a clamped cantilever."""
    x, a = np.asarray(x_mm, float), np.asarray(a_mm, float)
    return np.where(x <= a, x * x * (3 * a - x), a * a * (3 * x - a))


@register_effect
class LinkCompliance(Effect):
    kind = "link_compliance"
    driven_by = "load"
    stage = "point"
    needs_loads = True
    param_names = ("compliance_per_nmm2",)      # 1 / EI
    positive_params = param_names
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
        j = self.joint                          # link j: from joint j's axis to frame j
        where = fp.point_link                   # frame the point is fixed in (None: the tool, beyond frame n)
        if where is not None and where < j:
            return np.zeros_like(point), np.zeros(point.shape + (1,))
        start, end = fp.link_beam(j)
        seg = end - start
        L = np.linalg.norm(seg, axis=-1)
        u = seg / np.where(L > 0, L, 1.0)[:, None]
        # the loads: the tip force at L, then the point forces fixed on link j at their projections
        F, a = loads.tip_force_n[:, j - 1][:, None], L[:, None]
        if loads.point_link is not None and np.any(loads.point_link == j):
            on = loads.point_link == j
            proj = np.einsum("nkc,nc->nk", loads.point_at_mm[:, on] - start[:, None], u)
            F = np.concatenate([F, loads.point_force_n[:, on]], axis=1)
            a = np.concatenate([a, np.clip(proj, 0.0, L[:, None])], axis=1)
        Fperp = F - np.einsum("nkc,nc->nk", F, u)[..., None] * u[:, None]           # (N, K, 3)
        x = L if where is None or where > j else np.clip(np.einsum("nc,nc->n", point - start, u), 0.0, L)
        x = x[:, None]
        # unit compliance response (per unit 1/EI) at x: deflection and slope of the superposed cantilever loads
        defl = cantilever_shape(x, a) / 6.0
        slope = np.where(x <= a, x * (2 * a - x), a * a) / 2.0
        d_vec = np.einsum("nk,nkc->nc", defl, Fperp)
        rot = np.cross(u, np.einsum("nk,nkc->nc", slope, Fperp))                   # rotation vector at x
        unit = d_vec + np.cross(rot, point - (start + u * x))
        return unit * values[0], unit[..., None]

    def edge_parameters(self, values, sigmas, free):
        c = values["compliance_per_nmm2"]
        return {"compliance_per_nmm2": c, "compliance_sigma_per_nmm2": sigmas["compliance_per_nmm2"],
                "ei_nmm2": (1.0 / c) if c > 0 else None}
