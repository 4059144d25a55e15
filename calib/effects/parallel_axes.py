"""The Hayati term a description lacks: for nominally parallel axes j and j+1 the DH offset d is ill-conditioned and
the real misalignment is a small rotation ``beta`` about frame j's y axis (Hayati, thesis §3.4).  When the robot
description models link j with DH (no ``beta``), this effect adds it: everything beyond frame j turns by ``beta``
about ``y_j`` through frame j's origin.  A point-stage effect; parameter in radians."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect


@register_effect
class ParallelAxes(Effect):
    kind = "parallel_axes"
    stage = "point"
    param_names = ("beta_rad",)
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "beta_deg": Field("number", required=True, min=-1, max=1)}

    def __init__(self, joint: int, beta_rad: float):
        super().__init__(joint, {"beta_rad": beta_rad})

    @classmethod
    def zero(cls, joint=None):
        return cls(joint, 0.0)

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], np.radians(c["beta_deg"]))

    def point_delta(self, fp, point, loads, values):
        j = self.joint
        y = fp.frame_R[:, j, :, 1]
        unit = np.cross(y, point - fp.frame_t[:, j])
        return unit * values[0], unit[..., None]
