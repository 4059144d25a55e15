"""Joint deflection under torque, two slopes and a loading/unloading dead zone (sections 4.5, 5.5.2).

The joint gives way in the direction of the torque acting on it, ``delta = f(tau)`` with ``f`` linear of slope 1/k1
up to the breakpoint torque and 1/k2 beyond; the loading and unloading branches are offset by the dead zone ``h``:
``delta -= h/2 * load_direction`` (+1 loading, -1 unloading, 0 unknown).  Parameterised by compliances (rad per N m)
so that the single-slope case is linear in its parameter.
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from ..units import DEG
from .base import Effect, register_effect


@register_effect
class JointCompliance(Effect):
    kind = "joint_compliance"
    own_joint_only = True
    driven_by = "load"
    needs_loads = True
    torque_driven = True
    param_names = ("compliance1_rad_per_nm", "compliance2_rad_per_nm", "breakpoint_nm", "deadzone_rad")
    positive_params = ("compliance1_rad_per_nm", "compliance2_rad_per_nm")
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "stiffness_nm_per_rad": Field("number", required=True, positive=True),
                       "stiffness2_nm_per_rad": Field("number", positive=True),
                       "breakpoint_nm": Field("number", positive=True),
                       "deadzone_deg": Field("number", default=0.0, min=0)}

    def __init__(self, joint: int, stiffness_nm_per_rad: float, stiffness2_nm_per_rad: float | None = None,
                 breakpoint_nm: float = np.inf, deadzone_rad: float = 0.0):
        k2 = stiffness_nm_per_rad if stiffness2_nm_per_rad is None else stiffness2_nm_per_rad
        super().__init__(joint, {"compliance1_rad_per_nm": 1.0 / stiffness_nm_per_rad,
                                 "compliance2_rad_per_nm": 1.0 / k2,
                                 "breakpoint_nm": breakpoint_nm, "deadzone_rad": deadzone_rad})

    @classmethod
    def zero(cls, joint=None):
        return cls(joint, 1e12)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["stiffness_nm_per_rad"], c["stiffness2_nm_per_rad"],
                   c["breakpoint_nm"] if c["breakpoint_nm"] else np.inf, c["deadzone_deg"] * DEG)

    def joint_delta(self, q, ctx, loads, values):
        c1, c2, tb, h = values
        j = self.joint - 1
        tau = loads.joint_torque_nm[:, j]
        a = np.abs(tau)
        below = a <= tb
        delta = np.zeros(q.shape)
        grad = np.zeros(q.shape + (4,))
        if below.all():
            # every pose on the first slope (no breakpoint, or below it): the general branch's first choices, the
            # same floats without the second slope's arithmetic (a one-pose evaluation pays per numpy call)
            d = c1 * tau
            grad[:, j, 0] = tau
        else:
            s = np.sign(tau)
            tb_f = tb if np.isfinite(tb) else 0.0
            d = np.where(below, c1 * tau, s * (c1 * tb_f + c2 * (a - tb_f)))
            grad[:, j, 0] = np.where(below, tau, s * tb_f)
            grad[:, j, 1] = np.where(below, 0.0, s * (a - tb_f))
            grad[:, j, 2] = np.where(below, 0.0, s * (c1 - c2))
        ld = ctx.load_direction[:, j]
        delta[:, j] = d - 0.5 * h * ld
        grad[:, j, 3] = -0.5 * ld
        return delta, grad

    def torque_gain(self, q, ctx, loads, values):
        """(N, n) d delta / d tau: the local compliance (the slope of the branch each pose is on)."""
        c1, c2, tb, _ = values
        g = np.zeros_like(q)
        g[:, self.joint - 1] = np.where(np.abs(loads.joint_torque_nm[:, self.joint - 1]) <= tb, c1, c2)
        return g

    def edge_parameters(self, values, sigmas, free):
        c = values["compliance1_rad_per_nm"]
        return {"compliance_deg_per_nm": c / DEG, "compliance_sigma_deg_per_nm": sigmas["compliance1_rad_per_nm"] / DEG,
                "stiffness_nm_per_rad": (1.0 / c) if c > 0 else None}
