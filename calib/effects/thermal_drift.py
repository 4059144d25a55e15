"""Thermal growth of every link length: a and d scale by ``1 + kappa (T - T_ref)`` (a geometry-stage effect)."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect


@register_effect
class ThermalDrift(Effect):
    kind = "thermal_drift"
    driven_by = "temperature"
    stage = "geometry"
    has_joint = False
    param_names = ("kappa_per_degc",)
    options = {"reference_degc": float}
    scenario_fields = {"kappa_per_degc": Field("number", required=True, min=0, max=1e-3),
                       "reference_degc": Field("number", default=20.0)}

    def __init__(self, kappa_per_degc: float, reference_c: float = 20.0):
        self.reference_c = float(reference_c)
        super().__init__(None, {"kappa_per_degc": kappa_per_degc})

    @classmethod
    def zero(cls, joint=None, reference_degc: float = 20.0):
        return cls(0.0, reference_degc)

    @classmethod
    def from_table(cls, c):
        return cls(c["kappa_per_degc"], c["reference_degc"])

    def option_values(self):
        return {"reference_degc": self.reference_c}

    def _scale(self, ctx, values):
        """(N,) the factor every length carries at each pose's temperature."""
        return 1.0 + values[0] * (ctx.temperature_c - self.reference_c)

    def geometry_delta(self, params, length_idx, ctx, values):
        """(N, P) parameter change and its derivative (N, P, 1)."""
        dT = ctx.temperature_c - self.reference_c
        grad = np.zeros((ctx.n_poses, params.shape[-1], 1))
        base = np.broadcast_to(params, (ctx.n_poses, params.shape[-1]))
        grad[:, length_idx, 0] = base[:, length_idx] * dT[:, None]
        return grad[..., 0] * values[0], grad

    def geometry_chain(self, J_geo, length_idx, ctx, values):
        """Lengths scale with (1 + kappa dT): their columns carry that factor."""
        out = J_geo.copy()
        out[:, :, length_idx] *= self._scale(ctx, values)[:, None, None]
        return out

    def edge_parameters(self, values, sigmas, free):
        return {"kappa_per_degc": values["kappa_per_degc"], "kappa_sigma_per_degc": sigmas["kappa_per_degc"],
                "reference_degc": self.reference_c}
