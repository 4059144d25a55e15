"""The whole Chapter 4 geometric chain as one vectorised function: ruler -> points -> axes -> DH.

Why one function: the estimation error of a DH parameter depends on every reading that led to it -- the ruler
sightings (through L, gamma1, gamma2, shared by every point) and the sweep sightings -- and on their correlations.
Writing the chain as ``f(raw readings (..., m)) -> DH (..., k)`` lets :func:`calib.uncertainty.propagate` give the
GUM and Monte Carlo errors of the final numbers directly, and the benchmark measure Monte Carlo draws per second.

Also here: :func:`synthetic_cpa`, a seeded synthetic session (a Puma with perturbed geometry in front of the two
theodolites, ruler sightings and one sweep per joint) built from :mod:`calib.kinematics` and
:mod:`calib.theodolite` -- independent forward code the estimators are tested against.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics import Kinematics
from ..robot import Robot
from ..loading import load_robot
from ..theodolite import thesis_readings, thesis_stations
from ..units import ARCSEC, DEG
from ..uncertainty import EstimateSet, propagate
from . import axes, dh, points, ruler


@dataclass
class CPAChain:
    """Layout of the raw inputs of one circle-point-analysis session and the vectorised chain over them.

    Inputs ``x = [a'_C, a'_D, a'_E, b'_C, b'_D, b'_E, R, r1, (alpha', beta', phi) per sweep point ...]``; sweeps
    are ``n_points[j]`` target positions of joint j in sweep order.  ``frame0_R``, ``frame0_t``, ``x_hint``,
    ``hayati``, ``d_nominal``, ``alpha_ref``, ``q_rad`` are as in :func:`calib.estimators.dh.dh_from_axes`.
    """

    n_points: tuple[int, ...]
    q_rad: np.ndarray
    frame0_R: np.ndarray
    frame0_t: np.ndarray
    x_hint: np.ndarray
    hayati: np.ndarray
    d_nominal: np.ndarray
    alpha_ref: np.ndarray

    @property
    def m(self) -> int:
        return 8 + 3 * sum(self.n_points)

    def names(self):
        return dh.link_names(len(self.n_points) - 1, self.hayati)

    def theodolite(self, x):
        return ruler.closed_form(x[..., :8])

    def axes(self, x):
        """(..., n_joints, 7) fitted circles [c, n, r] from the raw inputs."""
        x = np.asarray(x, float)
        theo = self.theodolite(x)
        pts, i = [], 8
        for N in self.n_points:
            rd = x[..., i:i + 3 * N].reshape(x.shape[:-1] + (N, 3))
            th = np.broadcast_to(theo[..., None, :], rd.shape)
            pts.append(points.point_xyz(np.concatenate([rd, th], -1)))
            i += 3 * N
        if len(set(self.n_points)) == 1:                 # one batched fit for every joint
            return axes.fit_circle(np.stack(pts, -3))
        return np.stack([axes.fit_circle(P) for P in pts], -2)

    def __call__(self, x):
        ax = self.axes(x)
        out = dh.dh_from_axes(ax[..., :3], ax[..., 3:6], self.q_rad, self.frame0_R, self.frame0_t, self.x_hint,
                              self.hayati, self.d_nominal, alpha_ref=self.alpha_ref)
        _, _, idx = self.names()
        return out.reshape(out.shape[:-2] + (-1,))[..., idx]

    def estimate(self, x, cov, n_mc: int = 2000, rng=0) -> EstimateSet:
        names, units, _ = self.names()
        return propagate(self, x, cov, names, units, n_mc=n_mc, rng=rng)


@dataclass
class SyntheticCPA:
    """A seeded synthetic session: truth, chain layout, exact inputs and their covariance."""

    robot: Robot
    kin: Kinematics
    truth: np.ndarray           # Kinematics parameter vector (true)
    nominal: np.ndarray         # nominal parameters with the same base pose
    chain: CPAChain
    x_true: np.ndarray          # exact raw inputs
    cov: np.ndarray             # their covariance
    L_mm: float
    gamma_rad: tuple[float, float]
    sweep_points_mm: list[np.ndarray]

    def truth_dh(self) -> np.ndarray:
        """True values of the chain's outputs, in the chain's order."""
        _, _, idx = self.chain.names()
        vals = []
        for j in range(len(self.chain.n_points) - 1):
            for f in dh.LINK_FIELDS:
                vals.append(self.truth[self.kin.index[f"j{j + 1}.{f}"]])
        return np.array(vals)[idx]

    def draw(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """Noisy raw inputs (one set, or ``(n, m)``)."""
        z = rng.standard_normal((1 if n is None else n, self.x_true.size)) * np.sqrt(np.diag(self.cov))
        x = self.x_true + z
        return x[0] if n is None else x


def synthetic_cpa(seed: int = 0, n_points: int = 8, span_deg: float = 90.0, sigma_rad: float = 3 * ARCSEC,
                  sigma_ruler_mm: float = 0.05, tool_mm=(150.0, 80.0, 120.0), perturb: bool = True) -> SyntheticCPA:
    """Puma 560 about 2.9 m in front of theodolites 1.61 m apart (the Fig 5.4 / 5.10 geometry), sweeps of
    ``span_deg`` about READY with ``n_points`` targets each; geometry perturbed by a seeded Generator."""
    rng = np.random.default_rng(seed)
    robot = load_robot()
    kin = Kinematics(robot)
    p = kin.params_with_tool(np.asarray(tool_mm, float))
    p[kin.index["base.x_mm"]], p[kin.index["base.y_mm"]], p[kin.index["base.z_mm"]] = 475.0, 2900.0, 0.0
    p[kin.index["base.yaw_rad"]] = 0.2
    truth = p.copy()
    if perturb:
        for j in range(1, robot.n + 1):
            for f, sc in (("theta_offset_rad", 0.003), ("a_mm", 0.5), ("alpha_rad", 0.003)):
                truth[kin.index[f"j{j}.{f}"]] += sc * rng.standard_normal()
            if robot.hayati[j - 1]:
                truth[kin.index[f"j{j}.beta_rad"]] += 0.002 * rng.standard_normal()
            else:
                truth[kin.index[f"j{j}.d_mm"]] += 0.5 * rng.standard_normal()
    q0 = np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0])
    ft = kin.forward(q0[None], truth)
    fn = kin.forward(q0[None], p)
    L, g1, g2 = 1609.9, -1.489 * DEG, 1.358 * DEG
    A, B = thesis_stations(L, g1, g2)
    R, r1 = 1860.0, 930.0
    C = np.array([-300.0, 1200.0, 0.0])
    marks = C + np.array([[0, 0, 0], [r1, 0, 0], [R, 0, 0]])
    ap, bp, _ = thesis_readings(A, B, marks)
    x = [*ap, *bp, R, r1]
    sig = [sigma_rad] * 6 + [sigma_ruler_mm, sigma_ruler_mm]
    sweeps = []
    for j in range(robot.n):
        q = np.repeat(q0[None], n_points, 0)
        q[:, j] += np.radians(np.linspace(-span_deg / 2, span_deg / 2, n_points))
        P = kin.points(q, truth)
        sweeps.append(P)
        a_, b_, f_ = thesis_readings(A, B, P)
        x += list(np.stack([a_, b_, f_], -1).ravel())
        sig += [sigma_rad] * (3 * n_points)
    chain = CPAChain(n_points=tuple([n_points] * robot.n), q_rad=q0, frame0_R=ft.frame_R[0, 0],
                     frame0_t=ft.frame_t[0, 0], x_hint=fn.frame_R[0, 1:-1, :, 0], hayati=robot.hayati[:-1],
                     d_nominal=robot.d_mm[:-1], alpha_ref=robot.alpha_rad[:-1])
    return SyntheticCPA(robot, kin, truth, p, chain, np.array(x, float), np.diag(np.square(sig)), L, (g1, g2),
                        sweeps)
