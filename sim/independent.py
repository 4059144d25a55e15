"""An independent data generator for the diagnosis's validation (issue 14): it shares no code with robocal's model.

Why: a validation whose truth comes from :class:`calib.model.MeasurementModel` can only show that the diagnosis
agrees with the model it is built on; a misunderstanding shared by both (a sign, a frame, a torque) would hide.  Here
the chain is written again as plain 4x4 products of the thesis's A-matrices, ``A_j = Rz(theta) Tz(d) Tx(a) Rx(alpha)
[Ry(beta)]`` (numbers read from the robot description: data, not code), and every effect has its own formula:

* transmission error ``s sin(nu q) + c cos(nu q)``; joint scale ``s q``; a quadratic joint error ``e q^2`` (outside
  the library); cross coupling ``sigma q_source``;
  backlash ``-b/2 * direction``;
* joint compliance ``tau / k`` with ``tau`` the gravity (and payload) torque about the joint axis from plain cross
  products of the link weights at their centres of mass;
* axis wobble (the counter-rotating once-per-turn tilt, and a twice-per-turn one the library does not have), the
  instrument moving (a step in time), the base rocking with the waist angle (outside the library), a tool sagging
  across its axis;
* point noise: Gaussian, or Student-t (3 degrees of freedom) with 1 % gross errors of 2-5 mm.

Nothing here imports :mod:`calib.model`, :mod:`calib.kinematics` or :mod:`calib.effects`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.robot import Robot

TOOL_MM = np.array([50.0, 20.0, 100.0])


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    M = np.zeros(t.shape + (4, 4))
    M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1] = c, -s, s, c
    M[..., 2, 2] = M[..., 3, 3] = 1.0
    return M


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _ry(b):
    c, s = np.cos(b), np.sin(b)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _trans(x=0.0, y=0.0, z=0.0):
    M = np.eye(4)
    M[:3, 3] = [x, y, z]
    return M


@dataclass
class Arm:
    """A serial arm with revolute joints in the thesis's terms (mm, rad, kg)."""

    a: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    offset: np.ndarray
    mass: np.ndarray
    com: np.ndarray                      # (n, 3) centre of mass of link j in frame j
    base: np.ndarray = field(default_factory=lambda: _trans(1500.0, 800.0, 200.0))
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.80665]))

    @classmethod
    def perturbed(cls, robot: Robot, rng: np.random.Generator) -> "Arm":
        """The description's arm with calibration-sized errors (the geometric fit's work)."""
        n = robot.n
        beta = np.where(robot.hayati, rng.normal(0, 0.02, n), 0.0) * np.pi / 180
        return cls(robot.a_mm + rng.normal(0, 0.3, n), robot.d_mm + rng.normal(0, 0.3, n),
                   robot.alpha_rad + rng.normal(0, 0.05 * np.pi / 180, n), beta,
                   rng.normal(0, 0.05 * np.pi / 180, n), np.asarray(robot.mass_kg, float),
                   np.asarray(robot.com_mm, float), gravity=np.asarray(robot.gravity_m_s2, float))

    @property
    def n(self) -> int:
        return len(self.a)

    def frames(self, theta: np.ndarray) -> list[np.ndarray]:
        """Frames 0..n (N, 4, 4) for joint angles (N, n): base A_1 ... A_j."""
        T = [np.broadcast_to(self.base, (len(theta), 4, 4))]
        for j in range(self.n):
            fixed = _trans(z=self.d[j]) @ _trans(x=self.a[j]) @ _rx(self.alpha[j]) @ _ry(self.beta[j])
            T.append(T[-1] @ _rz(theta[:, j] + self.offset[j]) @ fixed)
        return T

    def tool(self, T: list[np.ndarray]) -> np.ndarray:
        return T[-1][:, :3, :3] @ TOOL_MM + T[-1][:, :3, 3]

    def torques(self, theta: np.ndarray, payload_kg: np.ndarray) -> np.ndarray:
        """(N, n) torque of the weights (links and a payload at the tool) about each joint axis, N m."""
        T = self.frames(theta)
        g = self.base[:3, :3] @ self.gravity
        bodies = [(T[i + 1][:, :3, :3] @ self.com[i] + T[i + 1][:, :3, 3], np.full(len(theta), self.mass[i]), i)
                  for i in range(self.n)]
        bodies.append((self.tool(T), payload_kg, self.n))
        tau = np.zeros(theta.shape)
        for j in range(self.n):
            o, z = T[j][:, :3, 3], T[j][:, :3, 2]
            for r, m, link in bodies:
                if link >= j:
                    tau[:, j] += np.einsum("nc,nc->n", z, np.cross((r - o) * 1e-3, m[:, None] * g))
        return tau


@dataclass
class Conditions:
    q: np.ndarray                # (N, n) joint readings
    direction: np.ndarray        # (N, n) +-1
    payload_kg: np.ndarray       # (N,)
    temperature_c: np.ndarray    # (N,)
    time_s: np.ndarray           # (N,)


# -- effects: each returns the true joint angles (joint effects) or the displaced points (point effects) ----------------
def joint_error(kind: str, p: dict, arm: Arm, c: Conditions) -> np.ndarray:
    """(N, n) joint-angle change of a joint-level effect at unit magnitude (``p`` holds its structure)."""
    d = np.zeros(c.q.shape)
    j = p.get("joint", 1) - 1
    if kind == "transmission_error":
        d[:, j] = np.sin(p["order"] * c.q[:, j] + p["phase"])
    elif kind == "joint_scale":
        d[:, j] = c.q[:, j]
    elif kind == "joint_quadratic":
        d[:, j] = c.q[:, j] ** 2
    elif kind == "cross_coupling":
        d[:, j] = c.q[:, p["source"] - 1]
    elif kind == "backlash":
        d[:, j] = -0.5 * c.direction[:, j]
    elif kind == "joint_compliance":
        d[:, j] = arm.torques(c.q, c.payload_kg)[:, j]
    return d


JOINT_KINDS = ("transmission_error", "joint_scale", "joint_quadratic", "cross_coupling", "backlash",
               "joint_compliance")


def point_error(kind: str, p: dict, arm: Arm, c: Conditions, T: list[np.ndarray], pts: np.ndarray) -> np.ndarray:
    """(N, 3) displacement of a point-level effect at unit magnitude."""
    N = len(pts)
    if kind in ("axis_wobble", "axis_wobble2"):
        j = p["joint"] - 1
        phi = c.q[:, j] + arm.offset[j]
        k = 1.0 if kind == "axis_wobble" else 2.0
        w_local = np.stack([np.cos(k * phi + p["phase"]), -np.sin(k * phi + p["phase"]), np.zeros(N)], -1)
        w = np.einsum("nij,nj->ni", T[j][:, :3, :3], w_local)
        return np.cross(w, pts - T[j][:, :3, 3])
    if kind == "instrument_step":
        out = np.zeros((N, 3))
        out[c.time_s >= p["at_s"]] = p["direction"]
        return out
    if kind == "base_rock":
        out = np.zeros((N, 3))
        out[c.q[:, 0] > 0] = p["direction"]
        return out
    if kind == "tool_sag":
        g = arm.base[:3, :3] @ arm.gravity
        g = g / np.linalg.norm(g)
        z = T[-1][:, :3, 2]
        return g - np.einsum("nc,c->n", z, g)[:, None] * z
    raise ValueError(kind)


@dataclass
class Spec:
    """One effect in the truth: kind, structure, and size as a multiple of the noise floor."""
    kind: str
    params: dict
    level: float


def generate(robot: Robot, specs: list[Spec], n_poses: int, seed: int, sigma_mm: float = 0.05,
             heavy_tails: bool = False) -> tuple[Conditions, np.ndarray]:
    """Joint readings with their conditions and measured points (N, 3) carrying ``specs`` and the noise."""
    rng = np.random.default_rng(seed)
    arm = Arm.perturbed(robot, rng)
    lim = np.asarray(robot.limits_rad)
    lo, hi = lim[:, 0] + 0.1 * (lim[:, 1] - lim[:, 0]), lim[:, 1] - 0.1 * (lim[:, 1] - lim[:, 0])
    q = lo + (hi - lo) * rng.random((n_poses, robot.n))
    c = Conditions(q, rng.choice([-1.0, 1.0], q.shape), rng.choice([0.0, 2.0, 5.0], n_poses),
                   18.0 + 8.0 * rng.random(n_poses), np.arange(n_poses) * 60.0)
    floor = sigma_mm * np.sqrt(3.0)
    base_pts = arm.tool(arm.frames(q))
    dtheta = np.zeros(q.shape)
    for s in specs:                      # joint effects, each scaled so its own displacement RMS is level x floor
        if s.kind in JOINT_KINDS:
            unit = joint_error(s.kind, s.params, arm, c)
            probe = 1e-4 / max(1e-12, np.abs(unit).max())
            disp = arm.tool(arm.frames(q + probe * unit)) - base_pts
            dtheta += s.level * floor / (np.sqrt(np.mean(np.sum(disp ** 2, 1))) / probe) * unit
    T = arm.frames(q + dtheta)
    pts = arm.tool(T)
    for s in specs:                      # point effects on the final configuration (linear in their size)
        if s.kind not in JOINT_KINDS:
            unit = point_error(s.kind, s.params, arm, c, T, pts)
            pts = pts + s.level * floor / np.sqrt(np.mean(np.sum(unit ** 2, 1))) * unit
    if heavy_tails:
        noise = sigma_mm * rng.standard_t(3, (n_poses, 3)) / np.sqrt(3.0)
        gross = rng.random(n_poses) < 0.01
        noise[gross] += rng.uniform(2.0, 5.0, (int(gross.sum()), 1)) * rng.choice([-1, 1], (int(gross.sum()), 3))
    else:
        noise = rng.normal(0.0, sigma_mm, (n_poses, 3))
    return c, pts + noise
