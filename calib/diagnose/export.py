"""The model a diagnosis hands on (``robocal diagnose --out MODEL.json``): the geometry and the findings that hold.

With ``--confirm`` sessions, a finding confirmed on none of them is an accident of the diagnosed data until shown
otherwise: it is left out and the rest refitted on every pose of DATA (the geometric set of the diagnosis and the
kept findings' parameters), so the exported model never carries an effect only one day supports.  Without
``--confirm`` every accepted finding is kept (the held-out test on DATA is the only evidence there is).
The model file is :func:`calib.compensate.save_model`'s (``robocal evaluate``, ``compensate`` read it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.identify import Identification, identify
from calib.model import MeasurementModel

from .gap import geometric_free


@dataclass
class Exported:
    model: MeasurementModel
    ident: Identification
    kept: list[str]                                      # finding labels in the model
    left_out: list[str] = field(default_factory=list)    # finding labels confirmed on no session

    def as_dict(self) -> dict:
        return {"findings": self.kept, "left_out": self.left_out,
                **({"reason": "confirmed on no --confirm session"} if self.left_out else {})}


def exported_model(diag, confirmed: list[bool] | None = None) -> Exported:
    """The final model of ``diag`` without the findings ``confirmed`` marks False, refitted on all of DATA when one
    is dropped (see the module docstring)."""
    findings = diag.selection.findings
    final = diag.selection.final
    confirmed = [True] * len(findings) if confirmed is None else list(confirmed)
    labels = [f.candidate.label for f in findings]
    if all(confirmed):
        return Exported(final.model, final.all_fit, labels)
    m = final.model
    drop = {lab for lab, ok in zip(labels, confirmed) if not ok}
    n_geo = len(diag.data.geometry_effects)          # the data's own geometry (target offsets) always stays
    keep_idx = [i for i, e in enumerate(m.effects) if i < n_geo or e.finding_label() not in drop]
    model = MeasurementModel(diag.data.robot, [m.effects[i] for i in keep_idx])
    theta = np.concatenate([final.all_fit.theta[: m.n_geometric]] +
                           [final.all_fit.theta[m.effect_slices[i]] for i in keep_idx])
    free = [n for n in final.all_fit.free if n in model.index]
    free = list(dict.fromkeys(geometric_free(model, diag.level) + free))
    ident = identify(model, diag.data.observations(), free=free, theta0=theta, outliers="off", start=False)
    return Exported(model, ident, [lab for lab, ok in zip(labels, confirmed) if ok],
                    [lab for lab, ok in zip(labels, confirmed) if not ok])
