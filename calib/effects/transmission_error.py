"""Gear transmission error of one joint as a harmonic series in its angle (section 4.4; K_theta fits of 5.4.2).

``delta = sum_h s_h sin(h nu q) + c_h cos(h nu q)``; ``nu`` is the fundamental order per radian of joint angle (the
thesis's K_theta4 = 0.050 deg sin(0.9 theta4) is nu = 0.9, s_1 = 0.050 deg).
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from ..units import DEG
from .base import Effect, register_effect


@register_effect
class TransmissionError(Effect):
    kind = "transmission_error"
    own_joint_only = True
    driven_by = "joint_angle"
    options = {"order": float, "harmonics": int}
    text_required = 1
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "order": Field("number", required=True, positive=True),
                       "sin_deg": Field("vector", default=[]), "cos_deg": Field("vector", default=[])}

    def __init__(self, joint: int, order: float, sin_rad, cos_rad):
        self.order = float(order)
        self.harmonics = max(len(sin_rad), len(cos_rad))
        s = list(sin_rad) + [0.0] * (self.harmonics - len(sin_rad))
        c = list(cos_rad) + [0.0] * (self.harmonics - len(cos_rad))
        vals = {}
        for h in range(self.harmonics):
            vals[f"s{h + 1}_rad"], vals[f"c{h + 1}_rad"] = s[h], c[h]
        self._names = tuple(vals)
        super().__init__(joint, vals)

    @classmethod
    def zero(cls, joint=None, order: float = 1.0, harmonics: int = 1):
        if not order > 0 or harmonics < 1:
            raise ValueError("order and harmonics must be positive")
        return cls(joint, order, [0.0] * harmonics, [0.0] * harmonics)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["order"], [v * DEG for v in c["sin_deg"]], [v * DEG for v in c["cos_deg"]])

    def option_values(self):
        return {"order": self.order, "harmonics": self.harmonics}

    @property
    def param_names(self):
        return self._names

    def basis(self, q):
        qj = q[:, self.joint - 1]
        B = np.empty((len(qj), 2 * self.harmonics))                # (N, K)
        for h in range(1, self.harmonics + 1):
            x = h * self.order * qj
            B[:, 2 * h - 2] = np.sin(x)
            B[:, 2 * h - 1] = np.cos(x)
        return B

    def joint_delta(self, q, ctx, loads, values):
        B = self.basis(q)
        delta = np.zeros(q.shape)
        delta[:, self.joint - 1] = B @ values
        grad = np.zeros(q.shape + (len(values),))
        grad[:, self.joint - 1, :] = B
        return delta, grad

    def finding_label(self) -> str:
        return f"{self.kind} j{self.joint} (order {self.order:g}/rad)"

    def edge_parameters(self, values, sigmas, free):
        s, c = values["s1_rad"], values["c1_rad"]
        return {"order_per_rad": float(self.order), "sin_deg": s / DEG, "cos_deg": c / DEG,
                "amplitude_deg": float(np.hypot(s, c)) / DEG,
                "sin_sigma_deg": sigmas["s1_rad"] / DEG, "cos_sigma_deg": sigmas["c1_rad"] / DEG}
