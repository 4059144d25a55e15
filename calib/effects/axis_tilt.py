"""An axis that wobbles as it turns (bearing runout): joint j's axis tilts by a small rotation ``w`` that depends on
the joint's own angle, moving everything beyond the joint about the axis point (frame j-1's origin).

A once-per-turn tilt has two parts: one turning with the joint (a constant tilt of link j: geometry, absorbed by
alpha/beta and the offsets) and one turning against it, which no geometric parameter describes.  This effect is the
latter: in frame j-1, ``w = Rz(-phi) (c, s, 0)`` with ``phi`` the joint angle (read from the chain), i.e.
``w_x = c cos phi + s sin phi``, ``w_y = -c sin phi + s cos phi``.  A point-stage effect; parameters in radians.
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect


@register_effect
class AxisTilt(Effect):
    kind = "axis_tilt"
    driven_by = "joint_angle"
    stage = "point"
    param_names = ("c_rad", "s_rad")
    options = {"order": int}
    scenario_fields = {"joint": Field("int", required=True, min=1), "order": Field("int", default=1, min=1, max=6),
                       "c_deg": Field("number", default=0.0, min=-1, max=1),
                       "s_deg": Field("number", default=0.0, min=-1, max=1)}

    def __init__(self, joint: int, c_rad: float, s_rad: float, order: int = 1):
        if int(order) < 1:
            raise ValueError(f"order must be at least 1, got {order}")
        self.order = int(order)
        super().__init__(joint, {"c_rad": c_rad, "s_rad": s_rad})

    @classmethod
    def zero(cls, joint=None, order: int = 1):
        return cls(joint, 0.0, 0.0, int(order))

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], np.radians(c["c_deg"]), np.radians(c["s_deg"]), c["order"])

    def option_values(self):
        return {"order": self.order}

    @property
    def label(self) -> str:
        return f"{self.kind}.j{self.joint}" if self.order == 1 else f"{self.kind}.j{self.joint}o{self.order}"

    def point_delta(self, fp, point, loads, values):
        j = self.joint
        R0, R1 = fp.frame_R[:, j - 1], fp.frame_R[:, j]
        # the joint angle: frame j's x axis seen in frame j-1 (the twist alpha turns about that x, not the angle)
        x1 = np.einsum("nji,nj->ni", R0, R1[:, :, 0])
        phi = self.order * np.arctan2(x1[:, 1], x1[:, 0])
        c, s = np.cos(phi), np.sin(phi)
        zero = np.zeros_like(c)
        local = np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1)], -1)     # (N, 3, 2) d w / d (c, s)
        w_dirs = np.einsum("nij,njk->nik", R0, local)                                       # measurement frame
        arm = point - fp.frame_t[:, j - 1]
        grad = np.cross(w_dirs.transpose(0, 2, 1), arm[:, None, :]).transpose(0, 2, 1)      # (N, 3, 2)
        return np.einsum("nik,k->ni", grad, values), grad

    def finding_label(self) -> str:
        return f"{self.kind} j{self.joint}" + (f" (order {self.order:g}/turn)" if self.order != 1 else "")
