"""Lateral elasticity: joint j tilts about the two axes perpendicular to its own under the bending moment it carries.

A joint carries, besides the torque about its axis, the moment of everything beyond it about the axis's other two
directions (the weight of a whole arm, or on a torso both arms and the head): bearings, gear housings and the link
structure give way to it.  The tilt is the rotation vector ``phi = D M_j`` with ``M_j`` the moment about the joint's
origin of all it carries (``Loads.joint_moment_nm``: gravity of the whole tree beyond, payload, tool and point forces)
and ``D = cx x x^T + cy y y^T`` with x, y the axes of the frame the joint's link starts from (its axis is that frame's
z; they are fixed in the body before the joint, the housing that bends).  Every point the joint moves (on a tree:
every branch below it, :meth:`calib.robot.Robot.frames_moved`) turns about the joint's pivot:
``delta = phi x (p - o_j)``.

The pivot is where the joint bends: a point on its axis, ``pivot_mm`` along it from the origin of the frame the
joint's link starts from (the option; 0 by default).  It matters: moving it along the axis changes both the moment
(by ``s z x F``) and the centre of the tilt, and a DH frame's origin can lie far from the physical joint (a yaw
joint on a column has its frame origin at the column's foot).  Give the pivot where the joint's bearing is (a
URDF's joint origin: ``d`` of that joint's origin along its axis from the frame, e.g. from ``robocal fk``).  First order in the undeflected pose: the moments are those of the joint readings, the
tilts of several joints add.  A point-stage effect, linear in its compliances (rad per N m, positive: a joint gives
way in the direction of the moment; a negative estimate absorbs another error and is said so by the identification).
"""
from __future__ import annotations

import numpy as np

from ..tomlspec import Field
from .base import Effect, ElementMotions, Loads, register_effect


@register_effect
class LateralCompliance(Effect):
    kind = "lateral_compliance"
    driven_by = "load"
    stage = "point"
    needs_loads = True
    moment_driven = True
    param_names = ("cx_rad_per_nm", "cy_rad_per_nm")
    positive_params = param_names
    options = {"pivot_mm": float}
    scenario_fields = {"joint": Field("int", required=True, min=1),
                       "stiffness_nm_per_rad": Field("number", required=True, positive=True),
                       "stiffness_y_nm_per_rad": Field("number", positive=True),
                       "pivot_mm": Field("number", default=0.0)}

    def __init__(self, joint: int, cx_rad_per_nm: float, cy_rad_per_nm: float | None = None, pivot_mm: float = 0.0):
        cy = cx_rad_per_nm if cy_rad_per_nm is None else cy_rad_per_nm
        if not np.isfinite(pivot_mm):
            raise ValueError(f"pivot_mm must be a finite number, got {pivot_mm}")
        self.pivot_mm = float(pivot_mm)
        super().__init__(joint, {"cx_rad_per_nm": cx_rad_per_nm, "cy_rad_per_nm": cy})

    @classmethod
    def zero(cls, joint=None, pivot_mm: float = 0.0):
        return cls(joint, 0.0, 0.0, pivot_mm)

    @classmethod
    def from_table(cls, c):
        ky = c["stiffness_y_nm_per_rad"] or c["stiffness_nm_per_rad"]
        return cls(c["joint"], 1.0 / c["stiffness_nm_per_rad"], 1.0 / ky, c["pivot_mm"])

    def option_values(self):
        return {"pivot_mm": self.pivot_mm}

    def moment_pivots_mm(self) -> list[float]:
        return [self.pivot_mm]

    # -- the pieces: the bending axes, the moment, the lever arm, which rows the joint moves -------------------------
    def _parts(self, fp, point, loads: Loads):
        j = self.joint - 1
        f = fp.parent_frame[j]
        R = fp.frame_R[:, f]                                        # (N, 3, 3): x, y bend, z the joint's axis
        axes = R[:, :, :2].transpose(0, 2, 1)                        # (N, 2, 3)
        r = point - self._pivot(fp, f)                               # (N, 3) mm, from the joint's pivot
        where = fp.point_frame if fp.point_link is None else fp.point_link
        moved = np.ones(len(point)) if loads.frames_moved is None else \
            np.broadcast_to(loads.frames_moved[j][where], (len(point),)).astype(float)
        return axes, loads.joint_moment_nm[:, j], r, moved, f

    def _pivot(self, fp, f: int) -> np.ndarray:
        """(N, 3) the pivot: on the joint's axis (z of frame f), ``pivot_mm`` from the frame's origin."""
        return fp.frame_t[:, f] + self.pivot_mm * fp.frame_R[:, f, :, 2]

    def point_delta(self, fp, point, loads: Loads, values):
        axes, M, r, moved, _ = self._parts(fp, point, loads)
        tilt = axes * np.einsum("nkc,nc->nk", axes, M)[..., None]             # (N, 2, 3): per unit compliance
        grad = np.cross(tilt, r[:, None, :]).transpose(0, 2, 1) * moved[:, None, None]   # (N, 3, 2)
        return grad @ np.asarray(values, float), grad

    def _compliance(self, axes, values) -> np.ndarray:
        """(N, 3, 3) D = cx x x^T + cy y y^T."""
        return np.einsum("nkc,k,nkd->ncd", axes, np.asarray(values, float), axes)

    def moment_gain(self, fp, point, loads: Loads, values):
        """d delta / d M = -[r]x D (delta = (D M) x r)."""
        axes, _, r, moved, _ = self._parts(fp, point, loads)
        D = self._compliance(axes, values)
        G = -np.cross(r[:, None, :], D.transpose(0, 2, 1)).transpose(0, 2, 1)  # column c: -(r x D[:, c])
        return (G * moved[:, None, None])[:, :, None, :]

    def geometry_jacobian(self, fp, point, loads: Loads, values, motions: ElementMotions):
        """A motion that moves the joint's frame (proximal) turns D and the lever arm with it: ``(a x phi -
        D (a x M)) x r + phi x (a x r)`` for a rotation about a, nothing for a translation; any other moves only the
        point: ``phi x dp``."""
        axes, M, r, moved, f = self._parts(fp, point, loads)
        D = self._compliance(axes, values)
        phi = np.einsum("ncd,nd->nc", D, M)                                        # (N, 3)
        a = motions.axis                                                            # (N, E, 3)
        turns = motions.moves[f] & motions.rotation                                 # (E,)
        dD_M = np.cross(a, phi[:, None, :]) - np.einsum("ncd,ned->nec", D, np.cross(a, M[:, None, :]))
        dD_M *= turns[None, :, None]
        # the lever arm r = p - o_j: the point's own motion less the origin's (a proximal motion moves both)
        d_origin = np.where(motions.rotation[None, :, None],
                            np.cross(a, self._pivot(fp, f)[:, None, :] - motions.origin_mm), a)
        d_origin *= motions.moves[f][None, :, None]
        dr = motions.point.transpose(0, 2, 1) - d_origin                           # (N, E, 3)
        out = np.cross(dD_M, r[:, None, :]) + np.cross(phi[:, None, :], dr)
        return out.transpose(0, 2, 1) * moved[:, None, None]

    def moment_term_size(self, loads: Loads, values) -> float:
        c = float(np.max(np.abs(values)))
        return c * float(np.max(np.linalg.norm(loads.joint_moment_nm[:, self.joint - 1], axis=-1), initial=0.0))

    def edge_parameters(self, values, sigmas, free):
        out = {}
        for k in ("cx_rad_per_nm", "cy_rad_per_nm"):
            if k in free:
                c = values[k]
                name = k.replace("_rad_per_nm", "")
                out[f"{name}_deg_per_nm"] = c * 180.0 / np.pi
                out[f"{name}_sigma_deg_per_nm"] = sigmas[k] * 180.0 / np.pi
                out[f"{name}_stiffness_nm_per_rad"] = (1.0 / c) if c > 0 else None
        return out
