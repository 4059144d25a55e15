"""Play in a joint's drive: the link lags the motor by half the play in the direction of the last motion,
``delta = -b/2 * direction``."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from ..units import DEG
from .base import Effect, register_effect


@register_effect
class Backlash(Effect):
    kind = "backlash"
    own_joint_only = True
    driven_by = "direction"
    param_names = ("width_rad",)
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "width_deg": Field("number", required=True, min=0)}

    def __init__(self, joint: int, width_rad: float):
        super().__init__(joint, {"width_rad": width_rad})

    @classmethod
    def zero(cls, joint=None):
        return cls(joint, 0.0)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["width_deg"] * DEG)

    def joint_delta(self, q, ctx, loads, values):
        j = self.joint - 1
        delta = np.zeros_like(q)
        grad = np.zeros(q.shape + (1,))
        grad[:, j, 0] = -0.5 * ctx.direction[:, j]
        delta[:, j] = grad[:, j, 0] * values[0]
        return delta, grad

    def edge_parameters(self, values, sigmas, free):
        return {"width_deg": values["width_rad"] / DEG, "width_sigma_deg": sigmas["width_rad"] / DEG}
