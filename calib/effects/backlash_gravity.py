"""Play in a joint's drive as gravity loads it: the link rests against the side of the play its load torque pushes it
to, unless that torque is too small to overcome the drive's preload (friction, a preloaded gear), where the last
approach decides (issue 27).

``delta = +b/2 * sign(tau)`` where ``|tau| > preload``, else ``-b/2 * direction`` (the plain :mod:`backlash` term),
with ``tau`` the joint's load torque from the model's one gravity model (:meth:`calib.model.MeasurementModel.loads`:
every mass the joint carries, the payload and forces of the pose context) plus ``tool_mass_kg`` hung at the tool
point: the end-effector's lumped mass where the description gives none.  Sign convention: a positive torque turns the
link the positive way about its axis, so the link gives way along it (as :mod:`joint_compliance`).  A pose with
neither a torque above the preload nor a known direction (the first pose of a session) is at the middle of the play.

``preload_nm`` and ``tool_mass_kg`` only decide which side each pose rests on: the point moves in steps with them,
so they are structural settings (like a transmission error's order), searched on a grid by the diagnosis, and
``width_rad`` is the one parameter a least-squares fit estimates.  A preload above every pose's torque is the plain
backlash; a preload of zero is play held by gravity alone (no approach direction needed).
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from ..units import DEG
from .base import Effect, register_effect


@register_effect
class GravityBacklash(Effect):
    kind = "backlash_gravity"
    own_joint_only = True
    driven_by = "load"
    needs_loads = True
    param_names = ("width_rad",)
    options = {"preload_nm": float, "tool_mass_kg": float}
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "width_deg": Field("number", required=True, min=0),
                       "preload_nm": Field("number", default=0.0, min=0),
                       "tool_mass_kg": Field("number", default=0.0, min=0)}

    def __init__(self, joint: int, width_rad: float, preload_nm: float = 0.0, tool_mass_kg: float = 0.0):
        if not (preload_nm >= 0 and tool_mass_kg >= 0):
            raise ValueError(f"preload and tool mass must not be negative, got {preload_nm}, {tool_mass_kg}")
        super().__init__(joint, {"width_rad": width_rad})
        self.preload_nm = float(preload_nm)
        self.tool_mass_kg = float(tool_mass_kg)

    @classmethod
    def zero(cls, joint=None, preload_nm: float = 0.0, tool_mass_kg: float = 0.0):
        return cls(joint, 0.0, preload_nm, tool_mass_kg)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["width_deg"] * DEG, c["preload_nm"], c["tool_mass_kg"])

    def option_values(self):
        return {"preload_nm": self.preload_nm, "tool_mass_kg": self.tool_mass_kg}

    def finding_label(self) -> str:
        return (f"{self.kind} j{self.joint} (preload {self.preload_nm:.3g} N m, tool mass "
                f"{self.tool_mass_kg:.3g} kg)")

    def torque(self, loads) -> np.ndarray:
        """(N,) the joint's load torque with the lumped tool mass (N m)."""
        j = self.joint - 1
        tau = loads.joint_torque_nm[:, j]
        if self.tool_mass_kg and loads.tool_torque_per_kg is not None:
            tau = tau + self.tool_mass_kg * loads.tool_torque_per_kg[:, j]
        return tau

    def side(self, ctx, loads) -> np.ndarray:
        """(N,) +1 / -1: the side of the play the link rests on (0: unknown, the middle)."""
        tau = self.torque(loads)
        return np.where(np.abs(tau) > self.preload_nm, np.sign(tau), -ctx.direction[:, self.joint - 1])

    def joint_delta(self, q, ctx, loads, values):
        j = self.joint - 1
        delta = np.zeros_like(q)
        grad = np.zeros(q.shape + (1,))
        grad[:, j, 0] = 0.5 * self.side(ctx, loads)
        delta[:, j] = grad[:, j, 0] * values[0]
        return delta, grad

    def edge_parameters(self, values, sigmas, free):
        return {"width_deg": values["width_rad"] / DEG, "width_sigma_deg": sigmas["width_rad"] / DEG,
                "preload_nm": self.preload_nm, "tool_mass_kg": self.tool_mass_kg}
