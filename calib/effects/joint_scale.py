"""Encoder or gear-ratio scale error of one joint: the joint turns ``(1 + s)`` times what its reading says,
``delta_j = s * q_j`` (a joint-stage effect; the constant part is the zero offset, so only the scale is new)."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect


@register_effect
class JointScale(Effect):
    kind = "joint_scale"
    own_joint_only = True
    driven_by = "joint_angle"
    param_names = ("scale",)
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "scale": Field("number", required=True, min=-0.1, max=0.1)}

    def __init__(self, joint: int, scale: float):
        super().__init__(joint, {"scale": scale})

    @classmethod
    def zero(cls, joint=None):
        return cls(joint, 0.0)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["scale"])

    def joint_delta(self, q, ctx, loads, values):
        j = self.joint - 1
        delta = np.zeros_like(q)
        grad = np.zeros(q.shape + (1,))
        grad[:, j, 0] = q[:, j]
        delta[:, j] = values[0] * q[:, j]
        return delta, grad
