"""Uncompensated wrist coupling: a share sigma of joint ``source``'s reading appears in joint ``joint``,
``delta_joint = sigma * q_source``."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, JointNumber, register_effect


@register_effect
class CrossCoupling(Effect):
    kind = "cross_coupling"
    own_joint_only = True
    driven_by = "source_angle"
    param_names = ("sigma",)
    options = {"source": JointNumber}
    text_required = 1
    scenario_fields = {"joint": Field("int", required=True, min=1), "source": Field("int", required=True, min=1),
                       "sigma": Field("number", required=True, min=-1, max=1)}

    def __init__(self, joint: int, source: int, sigma: float):
        self.source = int(source)
        super().__init__(joint, {"sigma": sigma})

    @classmethod
    def zero(cls, joint=None, source: int = 0):
        return cls(joint, source, 0.0)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["source"], c["sigma"])

    def option_values(self):
        return {"source": self.source}

    @property
    def label(self) -> str:
        return f"{self.kind}.j{self.source}j{self.joint}"

    def joint_delta(self, q, ctx, loads, values):
        delta = np.zeros(q.shape)
        grad = np.zeros(q.shape + (1,))
        grad[:, self.joint - 1, 0] = q[:, self.source - 1]
        delta[:, self.joint - 1] = values[0] * q[:, self.source - 1]
        return delta, grad

    def finding_label(self) -> str:
        return f"{self.kind} j{self.source}->j{self.joint}"

    def edge_parameters(self, values, sigmas, free):
        return {"source_joint": self.source, "sigma": values["sigma"], "sigma_sigma": sigmas["sigma"]}
