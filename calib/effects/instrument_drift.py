"""The measurement frame moving during the session: the robot base seen from the instrument shifts by a ramp
``v (t - t_ref)`` (``step_s`` = 0) or by a step ``v [t >= step_s]`` (``step_s`` > 0), with ``v`` = (x, y, z) in mm
(per hour for a ramp).  A geometry-stage effect: it changes the base position pose by pose (the base translation
parameters come first in the parameter vector), so every point the robot carries moves alike."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect

#: positions of base.x_mm, base.y_mm, base.z_mm in the geometric parameter vector (calib.kinematics names them first)
BASE_XYZ = (0, 1, 2)


@register_effect
class InstrumentDrift(Effect):
    kind = "instrument_drift"
    driven_by = "time"
    stage = "geometry"
    has_joint = False
    param_names = ("x_mm", "y_mm", "z_mm")
    options = {"step_s": float, "reference_s": float}
    scenario_fields = {"x_mm": Field("number", default=0.0), "y_mm": Field("number", default=0.0),
                       "z_mm": Field("number", default=0.0), "step_s": Field("number", default=0.0, min=0),
                       "reference_s": Field("number", default=0.0)}

    def __init__(self, shift_mm, step_s: float = 0.0, reference_s: float = 0.0):
        self.step_s = float(step_s)
        self.reference_s = float(reference_s)
        super().__init__(None, dict(zip(self.param_names, np.asarray(shift_mm, float))))

    @classmethod
    def zero(cls, joint=None, step_s: float = 0.0, reference_s: float = 0.0):
        return cls([0.0, 0.0, 0.0], step_s, reference_s)

    @classmethod
    def from_table(cls, c):
        return cls([c["x_mm"], c["y_mm"], c["z_mm"]], c["step_s"], c["reference_s"])

    def option_values(self):
        return {"step_s": self.step_s, "reference_s": self.reference_s}

    @property
    def label(self) -> str:
        return f"{self.kind}.step{self.step_s:g}" if self.step_s > 0 else f"{self.kind}.ramp"

    def driver(self, ctx) -> np.ndarray:
        """(N,) the shift per unit of ``v`` at each pose: a step (0/1) or hours since the reference."""
        t = ctx.time_s
        if self.step_s > 0:
            return (t >= self.step_s).astype(float)
        return (t - self.reference_s) / 3600.0

    def geometry_delta(self, params, length_idx, ctx, values):
        P = params.shape[-1]
        grad = np.zeros((ctx.n_poses, P, 3))
        u = self.driver(ctx)
        for k, i in enumerate(BASE_XYZ):
            grad[:, i, k] = u
        return grad @ values, grad

    def finding_label(self) -> str:
        return f"{self.kind} step at {self.step_s:.0f} s" if self.step_s > 0 else f"{self.kind} ramp"
