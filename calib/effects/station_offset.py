"""Several instrument set-ups (``station`` column) in one identification: station k sees the robot base moved.

Not a running error but the geometry of re-stationing, written as a geometry-stage effect so that rows measured from
different set-ups are fitted jointly with one chain: rows of station ``k`` (``ctx.station == k``, see
:class:`calib.targets.TargetContext`) have the base pose parameters (x, y, z, yaw, pitch, roll: the chain's first six
elements) changed by this effect's six values.  Station 0 is the reference (the chain's own ``base.*``); rows of a
plain :class:`PoseContext` are not moved.
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, register_effect

BASE_PARAMS = ("dx_mm", "dy_mm", "dz_mm", "dyaw_rad", "dpitch_rad", "droll_rad")


@register_effect
class StationOffset(Effect):
    kind = "station_offset"
    stage = "geometry"
    has_joint = False
    param_names = BASE_PARAMS
    options = {"station": int}
    text_required = 1
    scenario_fields = {"station": Field("int", required=True, min=1),
                       **{p: Field("number", default=0.0) for p in BASE_PARAMS}}

    def __init__(self, station: int, values=(0.0,) * 6):
        self.station = int(station)
        super().__init__(None, dict(zip(self.param_names, (float(v) for v in values))))

    @classmethod
    def zero(cls, joint=None, station: int = 1):
        return cls(station)

    @classmethod
    def from_table(cls, c):
        return cls(c["station"], [c[p] for p in BASE_PARAMS])

    def option_values(self):
        return {"station": self.station}

    @property
    def label(self) -> str:
        return f"{self.kind}.s{self.station}"

    def geometry_delta(self, params, length_idx, ctx, values):
        """(N, P) change of the base parameters (the first six) and its derivative (N, P, 6)."""
        N, P = ctx.n_poses, params.shape[-1]
        station = getattr(ctx, "station", None)
        rows = np.zeros(N, bool) if station is None else (np.asarray(station) == self.station)
        grad = np.zeros((N, P, 6))
        for i in range(6):
            grad[rows, i, i] = 1.0
        return grad @ np.asarray(values, float), grad
