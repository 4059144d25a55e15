"""Non-geometric effects as composable terms of the one forward model, each with its own named parameters.

An effect acts at one of three stages of the model (see :mod:`calib.model`):

``joint``      adds to the joint angle: ``theta_true = q_reading + sum(delta)``  (transmission error, joint compliance,
               backlash, cross coupling);
``geometry``   changes the kinematic parameters pose by pose (thermal growth of the link lengths);
``point``      displaces the tool point in the measurement frame (link compliance: beam bending under load).

Every effect declares ``param_names`` (with units in the names) and returns its contribution *and* the derivative of
that contribution with respect to its own parameters, so identification, design of experiments and diagnosis get the
full Jacobian from the same code that the twin uses to make its truth.  Effects are registered by name in
:data:`EFFECTS`, the names the diagnosis reports (``transmission_error``, ``joint_compliance``, ``backlash``,
``cross_coupling``, ``link_compliance``, ``thermal_drift``).

Sign conventions (documented once, used everywhere):
* transmission error ``delta = sum_h s_h sin(h nu q) + c_h cos(h nu q)``; ``nu`` is the fundamental order per
  radian of joint angle (the thesis's K_theta4 = 0.050 deg sin(0.9 theta4) is nu = 0.9, s_1 = 0.050 deg);
* joint compliance: the joint gives way in the direction of the torque acting on it, ``delta = f(tau)`` with
  ``f`` linear of slope 1/k1 up to the breakpoint torque and 1/k2 beyond; the loading and unloading branches are
  offset by the dead zone ``h``: ``delta -= h/2 * load_direction`` (+1 loading, -1 unloading, 0 unknown);
* backlash: the link lags the motor by half the play in the direction of the last motion,
  ``delta = -b/2 * direction``;
* cross coupling: an uncompensated share of joint ``source``'s reading appears in joint ``joint``,
  ``delta_joint = sigma * q_source``;
* thermal growth: every a and d scales by ``1 + kappa (T - T_ref)``;
* link compliance: the segment from frame j-1 to frame j is a cantilever with flexural rigidity EI loaded at its end
  by the weight of everything beyond it plus the payload and the external tool force: tip deflection F L^3 / (3 EI)
  and tip slope F L^2 / (2 EI), carried rigidly to the tool point.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .units import DEG


@dataclass
class PoseContext:
    """What each of N poses was measured under, beyond its joint readings.  Arrays over poses; zeros by default."""

    n_poses: int
    n_joints: int = 6
    direction: np.ndarray | None = None        # (N, n) +1/-1: sign of each joint's last motion; 0 unknown
    load_direction: np.ndarray | None = None   # (N, n) +1 loading, -1 unloading, 0 unknown
    payload_kg: np.ndarray | None = None       # (N,) mass hanging at the tool point
    tool_force_n: np.ndarray | None = None     # (N, 3) external force at the tool point, measurement frame
    joint_torque_nm: np.ndarray | None = None  # (N, n) torque applied directly to joints (compliance loads)
    temperature_c: np.ndarray | None = None    # (N,)
    time_s: np.ndarray | None = None           # (N,)
    # forces at points fixed on links (hung masses: mass x the model's gravity), K of them per pose
    point_force_link: np.ndarray | None = None  # (K,) int: frame the point is fixed in (0 base, j = link j)
    point_force_mm: np.ndarray | None = None    # (N, K, 3) the point, in that frame
    point_force_n: np.ndarray | None = None     # (N, K, 3) the force, in the measurement frame

    def __post_init__(self):
        N, n = self.n_poses, self.n_joints
        for name, shape in (("direction", (N, n)), ("load_direction", (N, n)), ("payload_kg", (N,)),
                            ("tool_force_n", (N, 3)), ("joint_torque_nm", (N, n)), ("temperature_c", (N,)),
                            ("time_s", (N,))):
            v = getattr(self, name)
            default = 20.0 if name == "temperature_c" else 0.0
            v = np.full(shape, default) if v is None else np.broadcast_to(np.asarray(v, float), shape).copy()
            setattr(self, name, v)
        link = np.zeros(0, int) if self.point_force_link is None else np.asarray(self.point_force_link)
        if link.ndim != 1 or (link.size and (np.any(link != np.round(link)) or link.min() < 0 or link.max() > n)):
            raise ValueError(f"point_force_link must be frame indices 0..{n}, got {self.point_force_link!r}")
        self.point_force_link = link.astype(int)
        K = link.size
        for name in ("point_force_mm", "point_force_n"):
            v = getattr(self, name)
            v = np.zeros((N, K, 3)) if v is None else np.broadcast_to(np.asarray(v, float), (N, K, 3)).copy()
            setattr(self, name, v)

    def subset(self, idx) -> "PoseContext":
        pick = {k: getattr(self, k)[idx] for k in ("direction", "load_direction", "payload_kg", "tool_force_n",
                                                      "joint_torque_nm", "temperature_c", "time_s",
                                                      "point_force_mm", "point_force_n")}
        n_new = len(pick["payload_kg"])
        return PoseContext(n_new, self.n_joints, point_force_link=self.point_force_link, **pick)


@dataclass
class Loads:
    """Quantities some effects need, computed once per forward pass by the model."""

    joint_torque_nm: np.ndarray       # (N, n) torque about each joint axis (gravity + payload + tool force + applied)
    tip_force_n: np.ndarray           # (N, n, 3) force carried at the end of each link (frame j origin)
    dtau_dgeo: np.ndarray | None = None   # (N, n, P_geometric) d torque / d geometric parameter, when asked
    # the point forces of the pose context, placed: for effects that load a link along its length
    point_force_n: np.ndarray | None = None   # (N, K, 3) N, measurement frame
    point_at_mm: np.ndarray | None = None     # (N, K, 3) where each acts, measurement frame
    point_link: np.ndarray | None = None      # (K,) frame each point is fixed in


class Effect:
    """Base class.  Subclasses set ``kind``, ``stage`` and implement the stage's method."""

    kind: ClassVar[str] = ""
    stage: ClassVar[str] = "joint"

    def __init__(self, joint: int | None, values: dict[str, float]):
        self.joint = joint                       # 1-based joint the effect disturbs, or None
        self.values = np.array([values[k] for k in self.param_names], float)

    @property
    def label(self) -> str:
        return f"{self.kind}.j{self.joint}" if self.joint is not None else self.kind

    @property
    def param_names(self) -> tuple[str, ...]:
        raise NotImplementedError

    def qualified_names(self) -> list[str]:
        return [f"{self.label}.{p}" for p in self.param_names]

    def describe(self) -> str:
        parts = ", ".join(f"{k}={v:.6g}" for k, v in zip(self.param_names, self.values))
        return f"{self.label}({parts})"

    # joint stage: (N, n) delta and (N, n, K) derivative
    def joint_delta(self, q, ctx: PoseContext, loads: Loads | None, values):
        raise NotImplementedError


class TransmissionError(Effect):
    """Gear transmission error of one joint as a harmonic series in its angle (section 4.4; K_theta fits of 5.4.2)."""

    kind = "transmission_error"
    needs_loads = False

    def __init__(self, joint: int, order: float, sin_rad, cos_rad):
        self.order = float(order)
        self.harmonics = max(len(sin_rad), len(cos_rad))
        s = list(sin_rad) + [0.0] * (self.harmonics - len(sin_rad))
        c = list(cos_rad) + [0.0] * (self.harmonics - len(cos_rad))
        vals = {}
        for h in range(self.harmonics):
            vals[f"s{h + 1}_rad"], vals[f"c{h + 1}_rad"] = s[h], c[h]
        self._names = tuple(vals)
        super().__init__(joint, vals)

    @property
    def param_names(self):
        return self._names

    def basis(self, q):
        qj = q[:, self.joint - 1]
        cols = []
        for h in range(1, self.harmonics + 1):
            cols += [np.sin(h * self.order * qj), np.cos(h * self.order * qj)]
        return np.stack(cols, -1)                                 # (N, K)

    def joint_delta(self, q, ctx, loads, values):
        B = self.basis(q)
        delta = np.zeros_like(q)
        delta[:, self.joint - 1] = B @ values
        grad = np.zeros(q.shape + (len(values),))
        grad[:, self.joint - 1, :] = B
        return delta, grad


class JointCompliance(Effect):
    """Joint deflection under torque, two slopes and a loading/unloading dead zone (sections 4.5, 5.5.2).

    Parameterised by compliances (rad per N m) so that the single-slope case is linear in its parameter.
    """

    kind = "joint_compliance"
    needs_loads = True
    param_names = ("compliance1_rad_per_nm", "compliance2_rad_per_nm", "breakpoint_nm", "deadzone_rad")

    def __init__(self, joint: int, stiffness_nm_per_rad: float, stiffness2_nm_per_rad: float | None = None,
                 breakpoint_nm: float = np.inf, deadzone_rad: float = 0.0):
        k2 = stiffness_nm_per_rad if stiffness2_nm_per_rad is None else stiffness2_nm_per_rad
        super().__init__(joint, {"compliance1_rad_per_nm": 1.0 / stiffness_nm_per_rad,
                                 "compliance2_rad_per_nm": 1.0 / k2,
                                 "breakpoint_nm": breakpoint_nm, "deadzone_rad": deadzone_rad})

    def joint_delta(self, q, ctx, loads, values):
        c1, c2, tb, h = values
        j = self.joint - 1
        tau = loads.joint_torque_nm[:, j]
        a = np.abs(tau)
        s = np.sign(tau)
        below = a <= tb
        tb_f = tb if np.isfinite(tb) else 0.0
        d = np.where(below, c1 * tau, s * (c1 * tb_f + c2 * (a - tb_f)))
        ld = ctx.load_direction[:, j]
        d = d - 0.5 * h * ld
        delta = np.zeros_like(q)
        delta[:, j] = d
        grad = np.zeros(q.shape + (4,))
        grad[:, j, 0] = np.where(below, tau, s * tb_f)
        grad[:, j, 1] = np.where(below, 0.0, s * (a - tb_f))
        grad[:, j, 2] = np.where(below, 0.0, s * (c1 - c2))
        grad[:, j, 3] = -0.5 * ld
        return delta, grad

    def torque_gain(self, q, ctx, loads, values):
        """(N, n) d delta / d tau: the local compliance (the slope of the branch each pose is on)."""
        c1, c2, tb, _ = values
        g = np.zeros_like(q)
        g[:, self.joint - 1] = np.where(np.abs(loads.joint_torque_nm[:, self.joint - 1]) <= tb, c1, c2)
        return g


class Backlash(Effect):
    """Play in a joint's drive: the link lags the motor by half the play in the direction of the last motion."""

    kind = "backlash"
    needs_loads = False
    param_names = ("width_rad",)

    def __init__(self, joint: int, width_rad: float):
        super().__init__(joint, {"width_rad": width_rad})

    def joint_delta(self, q, ctx, loads, values):
        j = self.joint - 1
        delta = np.zeros_like(q)
        grad = np.zeros(q.shape + (1,))
        grad[:, j, 0] = -0.5 * ctx.direction[:, j]
        delta[:, j] = grad[:, j, 0] * values[0]
        return delta, grad


class CrossCoupling(Effect):
    """Uncompensated wrist coupling: a share sigma of joint ``source``'s reading appears in joint ``joint``."""

    kind = "cross_coupling"
    needs_loads = False
    param_names = ("sigma",)

    def __init__(self, joint: int, source: int, sigma: float):
        self.source = int(source)
        super().__init__(joint, {"sigma": sigma})

    @property
    def label(self) -> str:
        return f"{self.kind}.j{self.source}j{self.joint}"

    def joint_delta(self, q, ctx, loads, values):
        delta = np.zeros_like(q)
        grad = np.zeros(q.shape + (1,))
        grad[:, self.joint - 1, 0] = q[:, self.source - 1]
        delta[:, self.joint - 1] = values[0] * q[:, self.source - 1]
        return delta, grad


class ThermalDrift(Effect):
    """Thermal growth of every link length: a and d scale by ``1 + kappa (T - T_ref)``."""

    kind = "thermal_drift"
    stage = "geometry"
    needs_loads = False
    param_names = ("kappa_per_degc",)

    def __init__(self, kappa_per_degc: float, reference_c: float = 20.0):
        self.reference_c = float(reference_c)
        super().__init__(None, {"kappa_per_degc": kappa_per_degc})

    def geometry_delta(self, params, length_idx, ctx, values):
        """(N, P) parameter change and its derivative (N, P, 1)."""
        dT = ctx.temperature_c - self.reference_c
        grad = np.zeros((ctx.n_poses, params.shape[-1], 1))
        base = np.broadcast_to(params, (ctx.n_poses, params.shape[-1]))
        grad[:, length_idx, 0] = base[:, length_idx] * dT[:, None]
        return grad[..., 0] * values[0], grad


class LinkCompliance(Effect):
    """Cantilever bending of link j (frame j-1 to frame j) under the load it carries at its end (section 4.6)."""

    kind = "link_compliance"
    stage = "point"
    needs_loads = True
    param_names = ("compliance_per_nmm2",)      # 1 / EI

    def __init__(self, joint: int, ei_nmm2: float):
        super().__init__(joint, {"compliance_per_nmm2": 1.0 / ei_nmm2})

    def point_delta(self, fp, point, loads: Loads, values):
        j = self.joint                          # link j spans frame j-1 -> frame j
        start, end = fp.frame_t[:, j - 1], fp.frame_t[:, j]
        seg = end - start
        L = np.linalg.norm(seg, axis=-1)
        u = seg / np.where(L > 0, L, 1.0)[:, None]
        F = loads.tip_force_n[:, j - 1]
        Fperp = F - np.sum(F * u, -1)[:, None] * u
        # unit compliance response: deflection F L^3/3 and slope F L^2/2 (per unit 1/EI)
        defl = Fperp * (L ** 3 / 3.0)[:, None]
        slope_vec = np.cross(u, Fperp) * (L ** 2 / 2.0)[:, None]       # rotation vector (rad per unit 1/EI)
        unit = defl + np.cross(slope_vec, point - end)
        return unit * values[0], unit[..., None]


EFFECTS: dict[str, type[Effect]] = {cls.kind: cls for cls in
                                    (TransmissionError, JointCompliance, Backlash, CrossCoupling, ThermalDrift,
                                     LinkCompliance)}


def thesis_effects() -> list[Effect]:
    """The effects the thesis measured on its Puma 560, in robocal's conventions (defaults of the twin)."""
    from .units import NM_PER_LBIN
    return [
        TransmissionError(4, 0.9, [0.050 * DEG], []),
        TransmissionError(6, 1.8, [0.047 * DEG], []),
        JointCompliance(3, 1.156e5 * NM_PER_LBIN, 1.223e5 * NM_PER_LBIN, 100 * NM_PER_LBIN),
        JointCompliance(4, 2.275e5 * NM_PER_LBIN, 1.698e5 * NM_PER_LBIN, 45 * NM_PER_LBIN),
    ]


__all__ = ["PoseContext", "Loads", "Effect", "EFFECTS", "TransmissionError", "JointCompliance", "Backlash",
           "CrossCoupling", "ThermalDrift", "LinkCompliance", "thesis_effects"]


def effect_from_text(text: str, n_joints: int = 6) -> Effect:
    """An effect to identify, from a short spec (initial values zero or nominal):

    ``transmission_error:J:ORDER[:HARMONICS]``, ``joint_compliance:J``, ``backlash:J``, ``cross_coupling:J:SOURCE``,
    ``link_compliance:J``, ``thermal_drift``.
    """
    from .errors import RobocalError

    parts = text.split(":")
    kind, args = parts[0], parts[1:]
    need = {"transmission_error": (2, 3), "joint_compliance": (1, 1), "backlash": (1, 1), "cross_coupling": (2, 2),
            "link_compliance": (1, 1), "thermal_drift": (0, 0)}
    if kind not in need:
        raise RobocalError(f"effect {text!r}: unknown kind {kind!r} (known: {', '.join(need)})")
    lo, hi = need[kind]
    if not lo <= len(args) <= hi:
        raise RobocalError(f"effect {text!r}: {kind} takes {lo if lo == hi else f'{lo} to {hi}'} field(s) after "
                           f"the kind")
    try:
        nums = [float(a) for a in args]
    except ValueError:
        raise RobocalError(f"effect {text!r}: fields must be numbers") from None
    for k, v in enumerate(nums[:1] + (nums[1:2] if kind == "cross_coupling" else [])):
        if v != int(v) or not 1 <= v <= n_joints:
            raise RobocalError(f"effect {text!r}: joint must be 1..{n_joints}, got {v:g}")
    if kind == "transmission_error":
        h = int(nums[2]) if len(nums) > 2 else 1
        if nums[1] <= 0 or h < 1:
            raise RobocalError(f"effect {text!r}: order and harmonics must be positive")
        return TransmissionError(int(nums[0]), nums[1], [0.0] * h, [0.0] * h)
    if kind == "joint_compliance":
        return JointCompliance(int(nums[0]), 1e12)
    if kind == "backlash":
        return Backlash(int(nums[0]), 0.0)
    if kind == "cross_coupling":
        return CrossCoupling(int(nums[0]), int(nums[1]), 0.0)
    if kind == "link_compliance":
        return LinkCompliance(int(nums[0]), 1e18)
    return ThermalDrift(0.0)


#: the running errors the thesis measured, as specs for identification
THESIS_RUNNING_ERRORS = ("transmission_error:4:0.9", "transmission_error:6:1.8", "joint_compliance:3",
                         "joint_compliance:4", "cross_coupling:6:5")
