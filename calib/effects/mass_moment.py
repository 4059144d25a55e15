"""An identified lumped mass on a link: where the description gives no masses (a URDF without inertials) or lacks one
(an end effector, a payload, cables), its weight still loads every joint that carries the link.

The link (``joint`` J: the body of link J, fixed in frame J) gets a mass ``m`` (kg) whose first moment about the
frame's origin is ``m c`` (kg mm, frame J's axes).  The model adds it to the bodies every torque- and moment-driven
effect sees (:meth:`calib.model.MeasurementModel.loads`), so joint compliance, lateral compliance and anything else
that follows the loads feel it, with its derivative in the Jacobian.  A mass at the tool point is a mass moment on the
tool point's link (``m c`` = m times the point's coordinates in that frame).

Gravity's torque is linear in ``(m, m c)``, so the weight is represented exactly by four point masses fixed in frame
J: ``m - (s_x + s_y + s_z)`` at the origin and ``s_k = (m c)_k / L`` at ``L`` along axis k (L = 1 m): the same total
force and the same first moment, with no division by a mass that may be zero.  Without ``with_mass`` (0) the mass
is held at zero and only the moment is identified: a couple, for a body centred on the axis of the joints that
carry it.

Alone this effect moves nothing: a deflection is compliance x torque, so a mass moment and the compliances that see
it are determined only together with something that fixes the scale -- the description's other masses, a payload,
or a compliance known from a data sheet (a ``--prior``, from whose value identification starts).
"""
from __future__ import annotations

import numpy as np

from ..errors import RobocalError
from ..tomlspec import Field
from .base import Effect, PoseContext, register_effect

#: the lever of the point masses that carry the first moment (mm)
_LEVER_MM = 1000.0


@register_effect
class MassMoment(Effect):
    kind = "mass_moment"
    stage = "load"
    adds_bodies = True
    options = {"with_mass": int}
    positive_params = ("mass_kg",)
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "mass_kg": Field("number", default=0.0, min=0),
                       "mc_kgmm": Field("vector", default=[0.0, 0.0, 0.0], length=3)}

    def __init__(self, joint: int, mass_kg: float = 0.0, mc_kgmm=(0.0, 0.0, 0.0), with_mass: int = 1):
        if int(with_mass) not in (0, 1):
            raise ValueError(f"with_mass must be 0 or 1, got {with_mass}")
        self.with_mass = int(with_mass)
        mc = np.asarray(mc_kgmm, float)
        vals = {"mx_kgmm": mc[0], "my_kgmm": mc[1], "mz_kgmm": mc[2]}
        if self.with_mass:
            vals["mass_kg"] = mass_kg
        super().__init__(joint, vals)

    @property
    def param_names(self) -> tuple[str, ...]:
        return (("mass_kg",) if self.with_mass else ()) + ("mx_kgmm", "my_kgmm", "mz_kgmm")

    @classmethod
    def zero(cls, joint=None, with_mass: int = 1):
        return cls(joint, 0.0, (0.0, 0.0, 0.0), int(with_mass))

    @classmethod
    def from_table(cls, c):
        return cls(c["joint"], c["mass_kg"], c["mc_kgmm"], 1)

    def option_values(self):
        return {"with_mass": self.with_mass}

    def bodies(self, fp, values):
        v = np.asarray(values, float)
        m, mc = (v[0], v[1:]) if self.with_mass else (0.0, v)
        s = mc / _LEVER_MM                                                  # kg at 1 m along each axis
        R, t = fp.frame_R[:, self.joint], fp.frame_t[:, self.joint]        # (N, 3, 3), (N, 3)
        pos = np.concatenate([t[:, None, :], t[:, None, :] + _LEVER_MM * R.transpose(0, 2, 1)], axis=1)  # (N, 4, 3)
        mass = np.concatenate([[m - s.sum()], s])
        dmass = np.zeros((4, len(v)))
        k = self.with_mass
        if k:
            dmass[0, 0] = 1.0
        dmass[0, k:] = -1.0 / _LEVER_MM
        dmass[1:, k:] = np.eye(3) / _LEVER_MM
        return pos, mass, dmass, np.full(4, self.joint)


def check_scale(model, ctx: PoseContext, priors: dict, where: str) -> None:
    """A mass moment is seen only through the compliances that feel its weight (deflection = compliance x torque):
    something must fix their scale -- the description's masses, a payload or force in the data, or a prior on one of
    the compliances.  Without, the fit trades one against the other along a valley (a compliance held at zero and a
    mass of millions of kg fit alike): one line instead."""
    if not any(e.adds_bodies for e in model.effects):
        return
    known = bool(np.any(np.asarray(model.robot.mass_kg) > 0))
    forces = any(np.any(np.asarray(a) != 0) for a in (ctx.payload_kg, ctx.tool_force_n, ctx.joint_torque_nm,
                                                       ctx.point_force_n))
    felt = [q for e in model.effects if e.torque_driven or e.moment_driven for q in e.qualified_names()]
    if known or forces or any(q in priors for q in felt):
        return
    label = next(e.label for e in model.effects if e.adds_bodies)
    raise RobocalError(f"{where}: effect {label}: a mass is seen only through the compliances that feel its weight, "
                       f"and nothing fixes their scale (no masses in the robot description, no payload or force in "
                       f"the data, no --prior on a compliance): give one, e.g. --prior "
                       f"{felt[0] if felt else 'joint_compliance.jJ.compliance1_rad_per_nm'}=VALUE±SIGMA")
