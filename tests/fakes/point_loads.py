"""Independent truth for forces at points on links: 4x4 homogeneous products of the description's link transforms
and plain cross products.  Imports nothing from calib.model, calib.kinematics or calib.effects (only the robot
description's numbers), so the model's loads and link points can be checked against it."""
from __future__ import annotations

import numpy as np


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    T = np.eye(4)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def _trans(x, y, z) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = x, y, z
    return T


def frames(robot, q_rad) -> list[np.ndarray]:
    """4x4 transforms of frames 0..n in the measurement frame for one pose: base = T(xyz) Rz Ry Rx, link j =
    Rz(q + offset) Tz(d) Tx(a) Rx(alpha) Ry(beta)."""
    roll, pitch, yaw = robot.base_rpy_rad
    T = _trans(*robot.base_xyz_mm) @ _rot(2, yaw) @ _rot(1, pitch) @ _rot(0, roll)
    out = [T]
    for j in range(robot.n):
        T = T @ _rot(2, q_rad[j] + robot.theta_offset_rad[j]) @ _trans(0, 0, robot.d_mm[j]) \
            @ _trans(robot.a_mm[j], 0, 0) @ _rot(0, robot.alpha_rad[j]) @ _rot(1, robot.beta_rad[j])
        out.append(T)
    return out


def point_in_frame(robot, q_rad, link: int, p_mm) -> np.ndarray:
    T = frames(robot, q_rad)[link]
    return (T @ np.r_[np.asarray(p_mm, float), 1.0])[:3]


def point_force_torques(robot, q_rad, link: int, p_mm, force_n) -> np.ndarray:
    """(n,) torque (N m) about each joint axis of one force at a point fixed in frame ``link``: joint j (axis z of
    frame j-1 through its origin) feels it when the point rides on link j or beyond."""
    Ts = frames(robot, q_rad)
    p = point_in_frame(robot, q_rad, link, p_mm) * 1e-3
    tau = np.zeros(robot.n)
    for j in range(1, robot.n + 1):
        if link >= j:
            z, o = Ts[j - 1][:3, 2], Ts[j - 1][:3, 3] * 1e-3
            tau[j - 1] = np.cross(p - o, np.asarray(force_n, float)) @ z
    return tau
