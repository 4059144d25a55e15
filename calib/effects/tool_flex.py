"""A tool that bends under its own weight: the tool point moves along the part of gravity across the tool's axis
(flange z), ``delta = f (g - (g . z_n) z_n)`` with ``g`` the unit gravity direction, so the offset depends on the
tool's orientation to gravity; ``f`` (mm) is the sag with the tool horizontal.  Gravity is the robot description's
(``gravity_m_s2``, in frame 0), carried by the base (:meth:`calib.kinematics.ChainPass.gravity`): the same gravity
the loads of joint and link compliance use, so a wall- or ceiling-mounted robot sags the right way.  A point-stage
effect."""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect


@register_effect
class ToolFlex(Effect):
    kind = "tool_flex"
    stage = "point"
    has_joint = False
    param_names = ("sag_mm",)
    scenario_fields = {"sag_mm": Field("number", required=True, min=-10, max=10)}

    def __init__(self, sag_mm: float):
        super().__init__(None, {"sag_mm": sag_mm})

    @classmethod
    def zero(cls, joint=None):
        return cls(0.0)

    @classmethod
    def from_table(cls, c):
        return cls(c["sag_mm"])

    def point_delta(self, fp, point, loads, values):
        g = fp.gravity()
        g = g / np.linalg.norm(g, axis=-1, keepdims=True)    # down, in the measurement frame
        z = fp.frame_R[:, -1, :, 2]                      # tool axis (flange z)
        unit = g - np.sum(g * z, -1)[:, None] * z
        return unit * values[0], unit[..., None]
