"""Joint misalignments and the compensation scheme (thesis section 4.3.1, eqs 4.3.10-4.3.13, Fig 5.10's rows).

**Misalignment table**: for each joint the small rotation ``(dtheta_x, dtheta_y, dtheta_z)`` (components in R_f) that
turns its design axis into the measured one, and between successive joints the twist and angle deviations
``delta alpha_j``, ``delta beta_j``, ``delta theta_j`` (:func:`calib.estimators.dh.misalignments`), with their errors propagated from
the measured axes' covariances (GUM; Monte Carlo on request).

**Compensation scheme** (eqs 4.3.12-4.3.13): coordinates known in R_f are expressed in S_fj, a frame at A with axes
parallel to joint j's frame, by the differential rotation ``(I + Delta_j)`` with

    Delta_j = [[0, -dz, dy], [dz, 0, -dx], [-dy, dx, 0]]

for the small angles ``(dx, dy, dz) = -(dtheta_xj, dtheta_yj, dtheta_zj)`` (R_f turned back onto the joint).  The
printed eq 4.3.12 repeats ``-dtheta_xj`` where the skew-symmetric matrix needs ``-dtheta_zj`` and writes ``Delta_j``
for ``I + Delta_j`` in 4.3.13; both fixed here.  Units: mm and rad.
"""
from __future__ import annotations

import numpy as np

from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, finite
from .dh import PUMA_NAMES, misalignments, puma_formulas

PROC = "misalignment"
ROW = ["dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "delta_alpha_rad", "delta_beta_rad", "delta_theta_rad"]


def compensation_matrix(dtheta_rad) -> np.ndarray:
    """Eq 4.3.12 (corrected): ``I + Delta`` for small rotations ``(..., 3)`` of R_f onto the joint frame."""
    d = -np.asarray(dtheta_rad, float)
    dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
    z = np.zeros_like(dx)
    D = np.stack([np.stack([z, -dz, dy], -1), np.stack([dz, z, -dx], -1), np.stack([-dy, dx, z], -1)], -2)
    return np.eye(3) + D


def compensate(points_mm, dtheta_rad) -> np.ndarray:
    """Eq 4.3.13: points ``(..., N, 3)`` in R_f expressed in S_fj (origin at A, axes parallel to joint j's frame)."""
    return np.einsum("...ij,...nj->...ni", compensation_matrix(dtheta_rad), np.asarray(points_mm, float))


def misalignment_table(normals: np.ndarray, normals_cov: np.ndarray, z_design: np.ndarray, x_frames: np.ndarray,
                       n_mc: int = 0, rng=0) -> EstimateSet:
    """Fig 5.10's misalignment rows with errors: measured axis directions ``normals (n, 3)`` (unit, R_f) with their
    covariance ``(3n, 3n)``, the design directions ``z_design (n, 3)`` and common normals ``x_frames (n, 3)`` of the
    design frames at the measurement pose.  Names ``j{k}.dtheta_x_rad`` ... ``j{k}.delta_theta_rad``; components
    that are identically zero (a turn about the design axis itself) are left out."""
    step = "misalignment table"
    N = np.asarray(normals, float)
    finite(PROC, step, normals=N, design=z_design, x_frames=x_frames)
    n = len(N)
    if N.shape != (n, 3) or np.shape(z_design) != (n, 3) or np.shape(x_frames) != (n, 3):
        raise EstimationError(PROC, step, "one measured axis, one design axis and one common normal per joint")
    U = np.asarray(normals_cov, float)
    if U.shape != (3 * n, 3 * n):
        raise EstimationError(PROC, step, f"the axes' covariance must be {3 * n}x{3 * n}, got {U.shape}")

    def f(z):
        return misalignments(z.reshape(z.shape[:-1] + (n, 3)), z_design, x_frames).reshape(z.shape[:-1] + (6 * n,))

    names = [f"j{k + 1}.{r}" for k in range(n) for r in ROW]
    res = propagate(f, N.ravel(), U, names, ["rad"] * 6 * n, n_mc=n_mc, rng=rng)
    # a turn about the design axis itself is no misalignment: those components are identically zero, not estimates
    return res.subset([nm for nm, e in zip(res.names, res.error) if e > 1e-12])


# -- the thesis's own route: compensated centres -> eq 4.3.15 --------------------------------------------------------
#: the joints whose frame S_fj each coordinate of eq 4.3.15 is expressed in: the vertical pair (joint 1, and joint 6
#: with the wrist and P) in S_f1, the parallel shoulder-elbow-wrist axes (2, 3, 5) in S_f3 -- eq 4.3.14's "the joints
#: j-1, j, j+1 expressed in S_fj"
_FRAME_OF = {1: 0, 6: 0, "P": 0, 2: 2, 3: 2, 5: 2}


def wrist_point(c5, n5, c6, n6) -> np.ndarray:
    """The point of joint 6's axis nearest joint 5's (the wrist centre, where the thesis's ``Z_c6`` is taken: the
    centre of joint 6's own circle lies at its target's height, where eq 4.3.15's d3 would be 0).  ``(..., 3)``."""
    w = np.asarray(c5, float) - np.asarray(c6, float)
    b = np.sum(n5 * n6, -1)
    if np.any(1.0 - b * b < 1e-6):          # within 0.06 deg: the nearest point is undefined (was NaN)
        raise EstimationError(PROC, "wrist centre", "axes 5 and 6 are parallel: their nearest point, the wrist "
                              "centre of eq 4.3.15, is undefined")
    t = (np.sum(n6 * w, -1) - b * np.sum(n5 * w, -1)) / (1.0 - b * b)
    return c6 + t[..., None] * n6


def compensated_puma_inputs(axes, z_design, x_frames, p_mm, L_p_mm: float, base_R=None) -> np.ndarray:
    """Eq 4.3.15's 14 inputs (:data:`calib.estimators.dh.PUMA_INPUTS`) from six fitted axes ``(..., 6, 6)`` =
    ``[centre_mm, unit direction]`` in R_f and the point P ``(..., 3)`` at ``L_p_mm`` beyond the flange: each
    coordinate in its joint's S_fj (eq 4.3.13 with that joint's measured misalignment, eqs 4.3.10-12).  ``base_R``
    (3x3): the robot base's design orientation in R_f -- the thesis's formulas read X, Y, Z along the base's axes (it
    assumes them parallel to R_f's); default identity."""
    A = np.asarray(axes, float)
    c, n = A[..., :3], A[..., 3:]
    delta = misalignments(n, z_design, x_frames)[..., :3]                # (..., 6, 3) measured tilt per joint
    Rb = np.eye(3) if base_R is None else np.asarray(base_R, float)
    w = wrist_point(c[..., 4, :], n[..., 4, :], c[..., 5, :], n[..., 5, :])
    pts = {1: c[..., 0, :], 2: c[..., 1, :], 3: c[..., 2, :], 5: c[..., 4, :], 6: w, "P": np.asarray(p_mm, float)}
    s = {}
    for key, p in pts.items():
        k = _FRAME_OF[key]
        s[key] = compensate((p @ Rb)[..., None, :], delta[..., k, :] @ Rb)[..., 0, :]
    X, Y, Z = 0, 1, 2
    cols = [s[1][..., X], s[1][..., Y], s[2][..., X], s[2][..., Z], s[3][..., X], s[3][..., Z], s[5][..., X],
            s[5][..., Z], s[6][..., X], s[6][..., Y], s[6][..., Z], s["P"][..., X], s["P"][..., Z],
            np.broadcast_to(float(L_p_mm), s[1][..., X].shape)]
    return np.stack(cols, -1)


def thesis_route(axes_value, axes_cov, z_design, x_frames, p_mm=None, p_cov=None, L_p_mm: float | None = None,
                 base_R=None, n_mc: int = 0, rng=0) -> EstimateSet:
    """a1, a2, d1, d2 (Puma naming, Fig 5.10) by the thesis's route -- the joint centres compensated into S_fj (eqs
    4.3.12-13), then eq 4.3.15 -- and d3 from the point P and L_p when P was sighted (``p_mm``, ``p_cov``,
    ``L_p_mm``).  Errors propagated from the axes' ``(36, 36)`` and P's ``(3, 3)`` covariances (GUM; Monte Carlo on
    request).  Why beside the sweeps' DH: it is the thesis's own reduction, so its numbers are the ones Fig 5.10
    prints; the general DH from successive axes does not assume the READY pose's parallel/perpendicular axes."""
    step = "compensation scheme (eqs 4.3.12-15)"
    V = np.asarray(axes_value, float).ravel()
    if V.size != 36:
        raise EstimationError(PROC, step, f"needs the six Puma axes (36 values), got {V.size}")
    with_p = p_mm is not None and L_p_mm is not None
    P = np.asarray(p_mm if with_p else [0.0, 0.0, 0.0], float)
    finite(PROC, step, axes=V, point_p=P)
    x = np.concatenate([V, P])
    U = np.zeros((39, 39))
    U[:36, :36] = np.asarray(axes_cov, float)
    if with_p:
        U[36:, 36:] = np.asarray(p_cov, float)
    k = 5 if with_p else 4
    Lp = float(L_p_mm) if with_p else 0.0

    def f(z):
        return puma_formulas(compensated_puma_inputs(z[..., :36].reshape(z.shape[:-1] + (6, 6)), z_design,
                                                     x_frames, z[..., 36:], Lp, base_R))[..., :k]

    return propagate(f, x, U, PUMA_NAMES[:k], ["mm"] * k, n_mc=n_mc, rng=rng)
