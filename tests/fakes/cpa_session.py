"""The raw inputs of the Chapter 4 common-normal chain (ruler, then one sweep per joint, laid out as
``calib.estimators.chain.CPAChain`` reads them), made by the tests' oracle from a parameter table by name.

Why: ``calib.estimators.chain.synthetic_cpa`` builds its sweeps with ``calib.kinematics`` and its readings with
``calib.theodolite``: a test of the DH estimator on those inputs checks the estimator against the model it shares
conventions with.  Here the same session is made again from plain 4x4 products (:mod:`.oracle.chain`) and plain
station trigonometry (:mod:`.oracle.stations`); the test takes only the layout and the parameter values from
``synthetic_cpa``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .oracle.chain import base_matrix, dh_frames, point_in
from .oracle.stations import thesis_angles


def frames(p: dict[str, float], n: int, q_rad: np.ndarray) -> list[np.ndarray]:
    """Frames 0..n of the chain whose parameters are ``p`` (robocal's names: base.*, j<k>.*)."""
    f = {fld: np.array([p[f"j{j}.{fld}"] for j in range(1, n + 1)])
         for fld in ("theta_offset_rad", "d_mm", "a_mm", "alpha_rad", "beta_rad")}
    base = base_matrix([p["base.x_mm"], p["base.y_mm"], p["base.z_mm"]], p["base.yaw_rad"], p["base.pitch_rad"],
                       p["base.roll_rad"])
    return dh_frames(base, np.asarray(q_rad, float) + f["theta_offset_rad"], f["d_mm"], f["a_mm"], f["alpha_rad"],
                     f["beta_rad"])


def _sweep(n: int, j: int, q0, n_points: int, span_deg: float) -> np.ndarray:
    """(n_points, n) joint angles: joint j swept over ``span_deg`` about ``q0``, the others held."""
    q = np.repeat(np.asarray(q0, float)[None], n_points, 0)
    q[:, j] += np.radians(np.linspace(-span_deg / 2, span_deg / 2, n_points))
    return q


def thesis_readings(points_mm, L_mm: float, gamma1: float, gamma2: float) -> np.ndarray:
    """(N, 3) the thesis's raw readings alpha' = alpha + gamma1, beta' = beta + gamma2 and phi (A's elevation)."""
    alpha, beta, phi_a, _ = thesis_angles(points_mm, L_mm)
    return np.stack([alpha + gamma1, beta + gamma2, phi_a], -1)


def cpa_inputs(p: dict[str, float], n: int, q0: np.ndarray, n_points: int, span_deg: float, L_mm: float,
               gammas: tuple[float, float], ruler: tuple[np.ndarray, float, float]) -> tuple[np.ndarray, list]:
    """Exact raw inputs and the sweeps' tool points: the ruler's three marks (C, C + r1 x, C + R x) read at A and at
    B, R and r1; then for each joint a sweep of ``n_points`` over ``span_deg`` about ``q0`` of the tool point
    (tool.*_mm in frame n), each point's alpha', beta', phi."""
    g1, g2 = gammas
    C, R, r1 = ruler
    marks = np.asarray(C, float) + np.array([[0, 0, 0], [r1, 0, 0], [R, 0, 0]])
    rd = thesis_readings(marks, L_mm, g1, g2)
    x = [*rd[:, 0], *rd[:, 1], R, r1]
    tool = [p["tool.x_mm"], p["tool.y_mm"], p["tool.z_mm"]]
    sweeps = []
    for j in range(n):
        pts = np.array([point_in(frames(p, n, q)[n], tool) for q in _sweep(n, j, q0, n_points, span_deg)])
        sweeps.append(pts)
        x += list(thesis_readings(pts, L_mm, g1, g2).ravel())
    return np.array(x, float), sweeps


@dataclass
class OracleCPA:
    """The oracle's copy of a ``synthetic_cpa`` session: exact inputs, sweep points and frames at the sweeps' centre."""

    x_true: np.ndarray
    sweep_points_mm: list[np.ndarray]
    frames: list[np.ndarray]
    sd: np.ndarray                  # the inputs' standard deviations

    def draw(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """Noisy raw inputs (one set, or ``(n, m)``)."""
        z = rng.standard_normal((1 if n is None else n, self.x_true.size)) * self.sd
        return self.x_true[None] + z if n is not None else self.x_true + z[0]


#: the ruler of ``synthetic_cpa``: C, R, r1 (mm)
RULER = (np.array([-300.0, 1200.0, 0.0]), 1860.0, 930.0)


def from_synthetic(s, span_deg: float = 90.0) -> OracleCPA:
    """The session ``s`` (a ``SyntheticCPA``) made again by the oracle from its true parameters and layout only."""
    p = {name: float(s.truth[i]) for name, i in s.kin.index.items()}
    n, q0 = s.robot.n, s.chain.q_rad
    x, sweeps = cpa_inputs(p, n, q0, s.chain.n_points[0], span_deg, s.L_mm, s.gamma_rad, RULER)
    return OracleCPA(x, sweeps, frames(p, n, q0), np.sqrt(np.diag(s.cov)))
