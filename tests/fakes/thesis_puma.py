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

Everything is a loop over poses and links of 4x4 products: slow, obvious, and the point.  Units mm, rad, N, kg.
Approximation shared with robocal's model on purpose (it is the thesis's small-deflection view): the torques that
deflect the joints are those of the configuration given by the readings.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

DEG = np.pi / 180.0
#: Fig 3.5 twist angles alpha_1..alpha_6 (deg)
FIG_3_5_ALPHA_DEG = (-90.0, 180.0, 90.0, -90.0, 90.0, 0.0)
#: Fig 5.10 "specified" link values, placed per Fig 3.5: a = (0, a1, a2, 0, 0, 0), d = (0, d1, 0, d2, 0, d3)
FIG_5_10_A_MM = (0.0, 432.0, -20.3, 0.0, 0.0, 0.0)
FIG_5_10_D_MM = (0.0, 149.1, 0.0, 432.0, 0.0, 57.1)


# -- chain ------------------------------------------------------------------------------------------------------------
def a_matrix(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    """The A_j matrix of section 3.4 as printed."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def rot_y(beta: float) -> np.ndarray:
    c, s = np.cos(beta), np.sin(beta)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def six_e(xt: float, yt: float, zt: float) -> np.ndarray:
    """^6E of section 3.4 as printed: the tool at (-Xt, -Yt, -Zt) of frame 6, its axes reversed."""
    return np.array([[-1.0, 0, 0, -xt], [0, -1.0, 0, -yt], [0, 0, -1.0, -zt], [0, 0, 0, 1.0]])


def base_matrix(xyz_mm=(0.0, 0.0, 0.0), yaw: float = 0.0, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """Measurement frame <- robot frame 0: translate, then turn about z (yaw), the new y (pitch), the new x (roll)."""
    cz, sz, cy, sy, cx, sx = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1.0]])
    ry = np.array([[cy, 0, sy], [0, 1.0, 0], [-sy, 0, cy]])
    rx = np.array([[1.0, 0, 0], [0, cx, -sx], [0, sx, cx]])
    T = np.eye(4)
    T[:3, :3] = rz @ ry @ rx
    T[:3, 3] = xyz_mm
    return T


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

    def frames(self, q: np.ndarray) -> list[np.ndarray]:
        """Frames 0..6 in the measurement frame for one pose of joint angles ``q`` (6,)."""
        T = [self.base.copy()]
        for j in range(6):
            A = a_matrix(q[j] + self.theta_offset[j], self.d_mm[j], self.a_mm[j], self.alpha[j]) @ rot_y(self.beta[j])
            T.append(T[-1] @ A)
        return T

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
        bodies = [(T[i + 1][:3, :3] @ self.com_mm[i] + T[i + 1][:3, 3], self.mass_kg[i], i + 1) for i in range(6)]
        bodies.append(((T[6] @ six_e(*self.tool_xyz_t))[:3, 3], payload_kg, 7))
        tau = np.zeros(6)
        for j in range(6):
            o, z = T[j][:3, 3], T[j][:3, 2]
            for r, m, link in bodies:
                if link >= j + 1:
                    tau[j] += z @ np.cross((r - o) * 1e-3, m * g)
        return tau


# -- running errors ---------------------------------------------------------------------------------------------------
@dataclass
class TransmissionError:
    """K_theta = s sin(order q) + c cos(order q), added to joint ``joint``'s reading (section 5.4.2)."""

    joint: int
    order: float
    sin_rad: float
    cos_rad: float = 0.0

    def delta(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        out = np.zeros(6)
        out[self.joint - 1] = self.sin_rad * np.sin(self.order * q[self.joint - 1]) + \
            self.cos_rad * np.cos(self.order * q[self.joint - 1])
        return out


@dataclass
class JointCompliance:
    """The joint gives way along the torque: stiffness k1 up to the breakpoint torque, k2 beyond (section 5.5.2).

    Written as the deflection-torque curve through its corners, read off by linear interpolation.
    """

    joint: int
    k1_nm_per_rad: float
    k2_nm_per_rad: float | None = None
    breakpoint_nm: float = np.inf

    def deflection(self, tau: float) -> float:
        k2 = self.k1_nm_per_rad if self.k2_nm_per_rad is None else self.k2_nm_per_rad
        if not np.isfinite(self.breakpoint_nm):
            return tau / self.k1_nm_per_rad
        tb, far = self.breakpoint_nm, 2.0 * max(abs(tau), self.breakpoint_nm) + 1.0     # a corner beyond tau
        knee = tb / self.k1_nm_per_rad
        end = knee + (far - tb) / k2
        return float(np.interp(tau, [-far, -tb, 0.0, tb, far], [-end, -knee, 0.0, knee, end]))

    def delta(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        out = np.zeros(6)
        out[self.joint - 1] = self.deflection(tau[self.joint - 1])
        return out


@dataclass
class CrossCoupling:
    """A share ``sigma`` of joint ``source``'s reading appears in joint ``joint`` (section 4.7)."""

    joint: int
    source: int
    sigma: float

    def delta(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        out = np.zeros(6)
        out[self.joint - 1] = self.sigma * q[self.source - 1]
        return out


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


# -- theodolites (section 4.2, eq 4.3.1 and its inverse, section 5.3.1) ---------------------------------------------
def thesis_angles(points_mm: np.ndarray, L_mm: float, height_b_mm: float = 0.0):
    """Interior angles alpha (at A), beta (at B) from the baseline and the elevations phi_A, phi_B of points (N, 3)."""
    X, Y, Z = np.asarray(points_mm, float).T
    alpha = np.arctan2(Y, X)              # tan^-1(Y / X), in the right quadrant when the point is behind A or B
    beta = np.arctan2(Y, L_mm - X)
    phi_a = np.arctan(Z / np.sqrt(X ** 2 + Y ** 2))
    phi_b = np.arctan((Z - height_b_mm) / np.sqrt((L_mm - X) ** 2 + Y ** 2))
    return alpha, beta, phi_a, phi_b


def point_from_angles(alpha, beta, phi, L_mm: float) -> np.ndarray:
    """Eq 4.3.1 as printed: X = L tan b / (tan a + tan b), Y = L tan a tan b / (...), Z = L tan b tan phi /
    ((tan a + tan b) cos a)."""
    ta, tb = np.tan(alpha), np.tan(beta)
    X = L_mm * tb / (ta + tb)
    Y = L_mm * ta * tb / (ta + tb)
    Z = L_mm * tb * np.tan(phi) / ((ta + tb) * np.cos(alpha))
    return np.stack([X, Y, Z], -1)


def leica_readings(points_mm: np.ndarray, L_mm: float, gamma1: float, gamma2: float,
                   height_b_mm: float = 0.0) -> np.ndarray:
    """(N, 4) readings Hz_A, V_A, Hz_B, V_B of levelled, error-free instruments for points on the +Y side.

    The circles read clockwise; A's circle reads alpha' = alpha + gamma1 counter-clockwise from its zero, so
    Hz_A = -alpha'; B looks back along the baseline and reads beta' = beta + gamma2 clockwise, Hz_B = beta'.  V is
    the zenith angle, pi/2 - phi.
    """
    alpha, beta, phi_a, phi_b = thesis_angles(points_mm, L_mm, height_b_mm)
    two_pi = 2 * np.pi
    return np.stack([np.mod(-(alpha + gamma1), two_pi), np.pi / 2 - phi_a,
                     np.mod(beta + gamma2, two_pi), np.pi / 2 - phi_b], -1)
