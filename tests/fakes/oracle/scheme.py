"""Section 4.3.1 of the thesis as printed (with its two misprints mended): the misalignment of each joint axis (eqs
4.3.10-11), the compensation into S_fj (eqs 4.3.12-13) and the Puma's lengths from the compensated centres (eq
4.3.15).  One joint and one point at a time, with the matrices written out: the tests' truth for the Chapter 4
geometry, sharing no code with robocal's estimators or its emulated truths.

Misprints mended: eq 4.3.12 repeats ``-dtheta_x`` where its skew matrix needs ``-dtheta_z``, and eq 4.3.13 writes
``Delta_j`` for ``I + Delta_j``.  Units mm and rad; coordinates in R_f unless said.
"""
from __future__ import annotations

import math

import numpy as np


def axis_misalignment(z_design, z_measured) -> np.ndarray:
    """Eq 4.3.10: ``(dtheta_x, dtheta_y, dtheta_z)``, the rotation turning the design axis onto the measured one:
    its direction the unit normal of the plane of the two axes, its size the angle between them."""
    zd = np.asarray(z_design, float) / np.linalg.norm(z_design)
    zm = np.asarray(z_measured, float) / np.linalg.norm(z_measured)
    normal = np.array([zd[1] * zm[2] - zd[2] * zm[1], zd[2] * zm[0] - zd[0] * zm[2], zd[0] * zm[1] - zd[1] * zm[0]])
    sin_angle = math.sqrt(float(normal @ normal))
    if sin_angle == 0.0:
        return np.zeros(3)
    angle = math.atan2(sin_angle, float(zd @ zm))
    return normal / sin_angle * angle


def misalignment_table(z_design, z_measured, x_design) -> list[dict[str, float]]:
    """Fig 5.10's misalignment rows, one dict per joint: the joint's own ``dtheta_x/y/z`` (eq 4.3.10) and, from
    the difference of successive joints' rotations ``D_j``, ``delta_alpha = D_j . x_j``, ``delta_beta = D_j . y_j``,
    ``delta_theta = D_j . z_j`` with ``y_j = z_j x x_j`` of the design frame (eq 4.3.11, the two transverse parts
    kept apart); the first joint's difference is its own rotation."""
    rows = []
    previous = np.zeros(3)
    for zd, zm, xd in zip(z_design, z_measured, x_design):
        zd = np.asarray(zd, float) / np.linalg.norm(zd)
        xd = np.asarray(xd, float) / np.linalg.norm(xd)
        yd = np.cross(zd, xd)
        own = axis_misalignment(zd, zm)
        D = own - previous
        rows.append({"dtheta_x_rad": own[0], "dtheta_y_rad": own[1], "dtheta_z_rad": own[2],
                     "delta_alpha_rad": float(D @ xd), "delta_beta_rad": float(D @ yd),
                     "delta_theta_rad": float(D @ zd)})
        previous = own
    return rows


def eq_4_3_12(dtheta) -> np.ndarray:
    """``I + Delta_j`` for the joint's misalignment: R_f turned back onto the joint frame by the small angles
    ``(dx, dy, dz) = -(dtheta_x, dtheta_y, dtheta_z)``."""
    dx, dy, dz = -float(dtheta[0]), -float(dtheta[1]), -float(dtheta[2])
    return np.array([[1.0, -dz, dy],
                     [dz, 1.0, -dx],
                     [-dy, dx, 1.0]])


def eq_4_3_13(point, dtheta) -> np.ndarray:
    """A point of R_f expressed in S_fj (axes parallel to joint j's frame): ``(I + Delta_j) p``."""
    return eq_4_3_12(dtheta) @ np.asarray(point, float)


def wrist_centre(c5, n5, c6, n6) -> np.ndarray:
    """The point of joint 6's axis closest to joint 5's axis: minimise ``|c5 + s n5 - c6 - t n6|`` over s and t
    (the 2x2 normal equations, solved)."""
    c5, n5, c6, n6 = (np.asarray(v, float) for v in (c5, n5, c6, n6))
    M = np.array([[n5 @ n5, -(n5 @ n6)], [n5 @ n6, -(n6 @ n6)]])
    rhs = np.array([n5 @ (c6 - c5), n6 @ (c6 - c5)])
    _, t = np.linalg.solve(M, rhs)
    return c6 + t * n6


def eq_4_3_15(axes, z_design, x_design, p, L_p: float, base_R=np.eye(3)) -> dict[str, float]:
    """The Puma's lengths from six axes ``[(centre, direction)]`` at READY and the point P sighted ``L_p`` beyond the
    flange: each centre compensated into its S_fj (joints 1, 6 and P in S_f1; 2, 3 and 5 in S_f3: eq 4.3.14), X, Y,
    Z read along the robot base's axes (columns of ``base_R``), then
    ``a1 = |(X, Z)_c2 - (X, Z)_c3|``, ``a2 = X_c6 - X_c1``, ``d1 = Y_c6 - Y_c1``, ``d2 = |(X, Z)_c3 - (X, Z)_c5|``,
    ``d3 = |(X, Z)_p - (X, Z)_c6| - L_p``; c6 is the wrist centre (joint 6's axis where it meets joint 5's)."""
    Rb = np.asarray(base_R, float)
    centres = [np.asarray(c, float) for c, _ in axes]
    dirs = [np.asarray(n, float) / np.linalg.norm(n) for _, n in axes]
    table = misalignment_table(z_design, dirs, x_design)
    dtheta = [np.array([r["dtheta_x_rad"], r["dtheta_y_rad"], r["dtheta_z_rad"]]) for r in table]

    def in_S(point, joint):
        return eq_4_3_13(Rb.T @ point, Rb.T @ dtheta[joint - 1])

    X1, Y1, _ = in_S(centres[0], 1)
    X2, _, Z2 = in_S(centres[1], 3)
    X3, _, Z3 = in_S(centres[2], 3)
    X5, _, Z5 = in_S(centres[4], 3)
    X6, Y6, Z6 = in_S(wrist_centre(centres[4], dirs[4], centres[5], dirs[5]), 1)
    Xp, _, Zp = in_S(np.asarray(p, float), 1)
    return {"a1_mm": math.hypot(X2 - X3, Z2 - Z3), "a2_mm": X6 - X1, "d1_mm": Y6 - Y1,
            "d2_mm": math.hypot(X3 - X5, Z3 - Z5), "d3_mm": math.hypot(Xp - X6, Zp - Z6) - L_p}
