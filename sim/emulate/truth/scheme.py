"""Section 4.3.1 of the thesis written out for the emulated truths: the misalignments of eqs 4.3.10-11, the
compensation of eqs 4.3.12-13 and the Puma lengths of eq 4.3.15, applied to the twin's exact axes.

Why not :mod:`calib.estimators`: a truth computed by the estimator it judges can only show that the estimator agrees
with itself (issue 25 item 4).  These are the thesis's definitions as plain vector algebra, one joint at a time, and
import nothing from the reduction; tests/test_truth_scheme.py holds them to the oracle's own copy
(tests/fakes/oracle/scheme.py) on axes of the independent chain.  Units: mm and rad; coordinates in R_f.
"""
from __future__ import annotations

import numpy as np

#: eq 4.3.15's lengths in the thesis's names (Fig 5.10's rows)
LENGTHS = ("a1_mm", "a2_mm", "d1_mm", "d2_mm", "d3_mm")


def tilt(z_design: np.ndarray, z_true: np.ndarray) -> np.ndarray:
    """Eq 4.3.10: the rotation vector (R_f components) that turns a design axis onto the true one -- about their
    common perpendicular, by the angle between them."""
    w = np.cross(z_design, z_true)
    s = float(np.linalg.norm(w))
    return np.zeros(3) if s == 0.0 else w * (np.arctan2(s, float(z_design @ z_true)) / s)


def misalignment_rows(z_true, z_design, x_frames) -> np.ndarray:
    """``(n, 6)`` per joint ``[dtheta_x, dtheta_y, dtheta_z, delta_alpha, delta_beta, delta_theta]``: the joint's
    tilt (eq 4.3.10), then the tilt relative to the previous joint's read along the design frame's x, y = z x x and z
    (eq 4.3.11, its two transverse parts apart)."""
    rows, before = [], np.zeros(3)
    for zt, zd, x in zip(np.asarray(z_true, float), np.asarray(z_design, float), np.asarray(x_frames, float)):
        zd, x = zd / np.linalg.norm(zd), x / np.linalg.norm(x)
        t = tilt(zd, zt / np.linalg.norm(zt))
        rel, before = t - before, t
        rows.append([*t, rel @ x, rel @ np.cross(zd, x), rel @ zd])
    return np.array(rows)


def in_joint_frame(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Eqs 4.3.12-13: a point given in R_f seen from S_fj, R_f turned back by the joint's tilt ``t`` to first order
    (``p - t x p``, the thesis's ``(I + Delta_j) p``)."""
    return p - np.cross(t, p)


def nearest_on_second(c1, n1, c2, n2) -> np.ndarray:
    """The point of the line (c2, n2) nearest the line (c1, n1): the wrist centre of eq 4.3.15 for axes 5 and 6."""
    b = float(n1 @ n2)
    w = c1 - c2
    return c2 + n2 * ((float(n2 @ w) - b * float(n1 @ w)) / (1.0 - b * b))


def puma_lengths(axes, z_design, x_frames, p_mm, L_p_mm: float, base_R) -> dict[str, float]:
    """Eq 4.3.15 on six axes ``[centre, direction]`` (6, 6) and the point P: the vertical pair (joint 1, the wrist
    centre, P) read in S_f1, the parallel shoulder-elbow-wrist axes (2, 3, 5) in S_f3 (eq 4.3.14), X, Y, Z along the
    robot base's axes ``base_R``."""
    A = np.asarray(axes, float)
    zt = A[:, 3:] / np.linalg.norm(A[:, 3:], axis=1, keepdims=True)
    tilts = misalignment_rows(zt, z_design, x_frames)[:, :3]
    Rb = np.asarray(base_R, float)

    def seen(p, joint):               # base axes, then turned back by that joint's tilt
        return in_joint_frame(Rb.T @ p, Rb.T @ tilts[joint - 1])

    c1, c2, c3, c5 = (seen(A[j - 1, :3], 1 if j == 1 else 3) for j in (1, 2, 3, 5))
    w = seen(nearest_on_second(A[4, :3], zt[4], A[5, :3], zt[5]), 1)
    p = seen(np.asarray(p_mm, float), 1)
    return {"a1_mm": float(np.hypot(c2[0] - c3[0], c2[2] - c3[2])), "a2_mm": float(w[0] - c1[0]),
            "d1_mm": float(w[1] - c1[1]), "d2_mm": float(np.hypot(c3[0] - c5[0], c3[2] - c5[2])),
            "d3_mm": float(np.hypot(p[0] - w[0], p[2] - w[2]) - L_p_mm)}
