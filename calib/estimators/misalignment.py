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
from .dh import misalignments

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
