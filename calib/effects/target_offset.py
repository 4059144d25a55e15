"""Several targets on the tip (laser-tracker reflectors, mocap markers): target k sits at the tool point plus an offset.

Not a running error but the geometry of extra tool points, written as a geometry-stage effect so that the one model
fits them jointly with the chain: rows measuring target ``k`` (``ctx.target == k``, see :class:`calib.targets.
TargetContext`) have the tool point moved by ``(dx_mm, dy_mm, dz_mm)`` in the flange frame n.  Target 0 is the tool
point itself; rows of a plain :class:`PoseContext` (no targets) are not moved.
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect


@register_effect
class TargetOffset(Effect):
    kind = "target_offset"
    stage = "geometry"
    has_joint = False
    param_names = ("dx_mm", "dy_mm", "dz_mm")
    options = {"target": int}
    text_required = 1
    scenario_fields = {"target": Field("int", required=True, min=1), "dx_mm": Field("number", default=0.0),
                       "dy_mm": Field("number", default=0.0), "dz_mm": Field("number", default=0.0)}

    def __init__(self, target: int, offset_mm=(0.0, 0.0, 0.0)):
        self.target = int(target)
        super().__init__(None, dict(zip(self.param_names, (float(v) for v in offset_mm))))

    @classmethod
    def zero(cls, joint=None, target: int = 1):
        return cls(target)

    @classmethod
    def from_table(cls, c):
        return cls(c["target"], (c["dx_mm"], c["dy_mm"], c["dz_mm"]))

    def option_values(self):
        return {"target": self.target}

    @property
    def label(self) -> str:
        return f"{self.kind}.t{self.target}"

    def geometry_delta(self, params, length_idx, ctx, values):
        """(N, P) change of the tool point's parameters (the last three) and its derivative (N, P, 3)."""
        N, P = ctx.n_poses, params.shape[-1]
        target = getattr(ctx, "target", None)
        rows = np.zeros(N, bool) if target is None else (np.asarray(target) == self.target)
        grad = np.zeros((N, P, 3))
        for i in range(3):
            grad[rows, P - 3 + i, i] = 1.0
        return grad @ np.asarray(values, float), grad
