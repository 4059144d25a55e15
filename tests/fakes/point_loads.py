"""Independent truth for forces at points on links: 4x4 homogeneous products of the description's link transforms
and plain cross products.  Imports nothing from calib.model, calib.kinematics or calib.effects (only the robot
description's numbers), so the model's loads and link points can be checked against it.  The products and the
torques are the oracle's (tests/fakes/oracle/chain.py)."""
from __future__ import annotations

import numpy as np

from .oracle.chain import axis_torques, base_matrix, dh_frames, point_in


def frames(robot, q_rad) -> list[np.ndarray]:
    """4x4 transforms of frames 0..n in the measurement frame for one pose: base = T(xyz) Rz Ry Rx, link j =
    Rz(q + offset) Tz(d) Tx(a) Rx(alpha) Ry(beta)."""
    roll, pitch, yaw = robot.base_rpy_rad
    base = base_matrix(robot.base_xyz_mm, yaw, pitch, roll)
    return dh_frames(base, np.asarray(q_rad, float) + robot.theta_offset_rad, robot.d_mm, robot.a_mm, robot.alpha_rad,
                     robot.beta_rad)


def point_in_frame(robot, q_rad, link: int, p_mm) -> np.ndarray:
    return point_in(frames(robot, q_rad)[link], p_mm)


def point_force_torques(robot, q_rad, link: int, p_mm, force_n) -> np.ndarray:
    """(n,) torque (N m) about each joint axis of one force at a point fixed in frame ``link``: joint j (axis z of
    frame j-1 through its origin) feels it when the point rides on link j or beyond."""
    Ts = frames(robot, q_rad)
    return axis_torques(Ts, [(point_in(Ts[link], p_mm), force_n, link)])
