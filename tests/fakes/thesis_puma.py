"""An independent Puma 560 and theodolite pair, written for the tests from the thesis alone (contract C7).

Why it exists: a test whose truth comes from ``MeasurementModel`` can only show that the model agrees with itself.  This
module writes the thesis's formulas again, as plainly as possible and sharing no code with robocal (it imports nothing
from ``calib``), so that a misunderstanding in the model cannot hide in the test too:

* the A-matrices of section 3.4, element by element as printed (``A_j = Rot(z, theta) Trans(z, d) Trans(x, a)
  Rot(x, alpha)``), the link table of Fig 3.5 and the tool matrix ^6E (the tool point sits at (-Xt, -Yt, -Zt) in
  frame 6); the tool location is ``base A_1 ... A_6 ^6E``.  Two extensions the thesis names but does not print: a
  zero offset added to each joint reading, and Hayati's extra rotation ``Rot(y, beta)`` after ``A_j`` for the
  parallel axes 2 and 3;
* the stations of section 4.2 / eq 4.3.1: theodolite A at the origin, B at (L, 0, h) on the X axis, azimuths measured
  from the baseline after removing the offsets (alpha = alpha' - gamma1, beta = beta' - gamma2), phi the elevation;
  :func:`thesis_angles` is the inverse trigonometric analysis of section 5.3.1, :func:`point_from_angles` eq 4.3.1;
  :func:`leica_readings` turns the thesis's angles into what a clockwise-reading instrument shows (Hz, zenith V);
* running errors in the thesis's own terms: transmission error ``K_theta = s sin(order q)`` (section 5.4.2), joint
  compliance ``deflection = torque / K`` with the stiffness changing above a breakpoint torque (section 5.5.2), cross
  coupling ``sigma * q_source`` (section 4.7); gravity torques are plain cross products of each link's weight about
  each joint axis.

The formulas themselves are written once in tests/fakes/oracle (chain, stations, effects); this module is the thesis
Puma built from them.  Everything is a loop over poses and links of 4x4 products: slow, obvious, and the point.
Units mm, rad, N, kg.  Approximation shared with robocal's model on purpose (it is the thesis's small-deflection
view): the torques that deflect the joints are those of the configuration given by the readings.
"""
from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .oracle.chain import a_matrix, axis_torques, base_matrix, dh_frames, rot_y
from .oracle.effects import CrossCoupling, JointCompliance, TransmissionError
from .oracle.stations import leica_readings, point_from_angles, thesis_angles

__all__ = ["DEG", "FIG_3_5_ALPHA_DEG", "FIG_5_10_A_MM", "FIG_5_10_D_MM", "CrossCoupling", "JointCompliance",
           "ThesisPuma", "TransmissionError", "a_matrix", "base_matrix", "leica_readings", "point_from_angles",
           "rot_y", "six_e", "thesis_angles", "true_points"]

DEG = np.pi / 180.0
#: Fig 3.5 twist angles alpha_1..alpha_6 (deg)
FIG_3_5_ALPHA_DEG = (-90.0, 180.0, 90.0, -90.0, 90.0, 0.0)
#: Fig 5.10 "specified" link values, placed per Fig 3.5: a = (0, a1, a2, 0, 0, 0), d = (0, d1, 0, d2, 0, d3)
FIG_5_10_A_MM = (0.0, 432.0, -20.3, 0.0, 0.0, 0.0)
FIG_5_10_D_MM = (0.0, 149.1, 0.0, 432.0, 0.0, 57.1)


# -- chain (the products are tests/fakes/oracle/chain.py's) ---------------------------------------------------------
def six_e(xt: float, yt: float, zt: float) -> np.ndarray:
    """^6E of section 3.4 as printed: the tool at (-Xt, -Yt, -Zt) of frame 6, its axes reversed."""
    return np.array([[-1.0, 0, 0, -xt], [0, -1.0, 0, -yt], [0, 0, -1.0, -zt], [0, 0, 0, 1.0]])


@dataclass
class ThesisPuma:
    """A six-joint arm in the thesis's terms; angles in radians, lengths in mm."""

    alpha: np.ndarray = field(default_factory=lambda: np.array(FIG_3_5_ALPHA_DEG) * DEG)
    a_mm: np.ndarray = field(default_factory=lambda: np.array(FIG_5_10_A_MM))
    d_mm: np.ndarray = field(default_factory=lambda: np.array(FIG_5_10_D_MM))
    theta_offset: np.ndarray = field(default_factory=lambda: np.zeros(6))
    beta: np.ndarray = field(default_factory=lambda: np.zeros(6))
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    tool_xyz_t: tuple[float, float, float] = (0.0, 0.0, 0.0)     # Xt, Yt, Zt of ^6E
    mass_kg: np.ndarray = field(default_factory=lambda: np.zeros(6))
    com_mm: np.ndarray = field(default_factory=lambda: np.zeros((6, 3)))   # centre of mass of link j in frame j
    gravity_m_s2: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.80665]))   # in frame 0

    @classmethod
    def from_toml(cls, path: str | Path) -> "ThesisPuma":
        """Link table, masses and gravity read straight from a robot description file (plain tomllib)."""
        doc = tomllib.loads(Path(path).read_text(encoding="utf-8"))
        joints = doc["joint"]
        return cls(alpha=np.array([j["alpha_deg"] for j in joints]) * DEG,
                   a_mm=np.array([j["a_mm"] for j in joints], float),
                   d_mm=np.array([j["d_mm"] for j in joints], float),
                   mass_kg=np.array([j.get("mass_kg", 0.0) for j in joints], float),
                   com_mm=np.array([j.get("com_mm", [0.0, 0.0, 0.0]) for j in joints], float),
                   gravity_m_s2=np.array(doc["robot"]["gravity_m_s2"], float))

    def with_parameters(self, params: dict[str, float]) -> "ThesisPuma":
        """A copy with the link values, zero offsets and base given under robocal's names (``j2.a_mm``,
        ``j3.theta_offset_rad``, ``base.yaw_rad`` ...): a common vocabulary, not code; a name absent keeps this arm's
        value, and the base is ``base_matrix(xyz, yaw, pitch, roll)`` when any ``base.*`` is given."""
        arm = dataclasses.replace(self, alpha=self.alpha.copy(), a_mm=self.a_mm.copy(), d_mm=self.d_mm.copy(),
                                  theta_offset=self.theta_offset.copy(), beta=self.beta.copy())
        for j in range(6):
            for key, values in (("alpha_rad", arm.alpha), ("a_mm", arm.a_mm), ("d_mm", arm.d_mm),
                                ("theta_offset_rad", arm.theta_offset), ("beta_rad", arm.beta)):
                values[j] = params.get(f"j{j + 1}.{key}", values[j])
        if any(k.startswith("base.") for k in params):
            g = {k: params.get(f"base.{k}", 0.0) for k in ("x_mm", "y_mm", "z_mm", "yaw_rad", "pitch_rad", "roll_rad")}
            arm.base = base_matrix((g["x_mm"], g["y_mm"], g["z_mm"]), g["yaw_rad"], g["pitch_rad"], g["roll_rad"])
        return arm

    def frames(self, q: np.ndarray) -> list[np.ndarray]:
        """Frames 0..6 in the measurement frame for one pose of joint angles ``q`` (6,)."""
        return dh_frames(self.base, np.asarray(q, float) + self.theta_offset, self.d_mm, self.a_mm, self.alpha,
                         self.beta)

    def tool_point(self, q: np.ndarray) -> np.ndarray:
        """The tool point for one pose: base A_1 ... A_6 ^6E, its translation."""
        return (self.frames(q)[6] @ six_e(*self.tool_xyz_t))[:3, 3]

    def gravity_torques(self, q: np.ndarray, payload_kg: float = 0.0) -> np.ndarray:
        """Torque (N m) of the links' weights (and a payload at the tool point) about each joint axis, one pose.

        Joint j turns about the z axis of frame j-1 through its origin; every body beyond it pulls with m g at its
        centre of mass: tau_j = z_{j-1} . sum_i (r_i - o_{j-1}) x m_i g.
        """
        T = self.frames(q)
        g = T[0][:3, :3] @ self.gravity_m_s2
        loads = [(T[i + 1][:3, :3] @ self.com_mm[i] + T[i + 1][:3, 3], self.mass_kg[i] * g, i + 1) for i in range(6)]
        loads.append(((T[6] @ six_e(*self.tool_xyz_t))[:3, 3], payload_kg * g, 6))
        return axis_torques(T, loads)


# -- running errors (tests/fakes/oracle/effects.py) -------------------------------------------------------------------
def true_points(arm: ThesisPuma, q_rad: np.ndarray, effects=(), payload_kg=0.0) -> tuple[np.ndarray, np.ndarray]:
    """Tool points (N, 3) and true joint angles (N, 6) for joint readings (N, 6): reading + every running error."""
    q_rad = np.atleast_2d(q_rad)
    payload = np.broadcast_to(np.asarray(payload_kg, float), (len(q_rad),))
    pts, ths = [], []
    for q, m in zip(q_rad, payload):
        tau = arm.gravity_torques(q, m)
        th = q + sum((e.delta(q, tau) for e in effects), np.zeros(6))
        pts.append(arm.tool_point(th))
        ths.append(th)
    return np.array(pts), np.array(ths)
