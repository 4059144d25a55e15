"""The frames of a robot model at the joints' zero, from the one forward model (:class:`calib.kinematics.Kinematics`).

Why frames and not DH formulas: an exported description must reproduce what the model computes, whatever the
parametrisation (DH, Hayati, later trees); running the model's own forward pass and reading its frames is the one way
that cannot drift from it.  Frame ``k`` (0-based joint ``k``) of the chain carries joint ``k``'s axis as its z axis
(:func:`axis_frame`); the frame after it moves with joint ``k`` (:func:`moving_frame`).
"""
from __future__ import annotations

import numpy as np

from ..kinematics import Kinematics


def homogeneous(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def frames_at_zero(robot) -> np.ndarray:
    """(F, 4, 4) every frame of the chain at zero joint values, in the measurement frame (mm): frame 0 is the base
    after the robot's base transform."""
    kin = Kinematics(robot)
    fp = kin.forward(np.zeros((1, kin.n)))
    R, t = fp.frame_R[0], fp.frame_t[0]
    out = np.tile(np.eye(4), (len(R), 1, 1))
    out[:, :3, :3], out[:, :3, 3] = R, t
    return out


def axis_frame(kin_or_robot, k: int) -> int:
    """Index of the frame whose z axis is joint ``k``'s axis (0-based ``k``): the frame of the link joint ``k`` hangs
    from: the link's parent frame (``k`` on a serial chain; on a tree, where its branch leaves)."""
    parent = getattr(kin_or_robot, "parent_frame", None)
    return k if parent is None else int(parent[k])


def moving_frame(k: int) -> int:
    """Index of the frame that moves with joint ``k`` (0-based): the link after it."""
    return k + 1


def rotation_taking(v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The smallest rotation turning unit vector ``v`` onto unit vector ``u`` (Rodrigues about v x u)."""
    w = np.cross(v, u)
    s, c = float(np.linalg.norm(w)), float(np.dot(v, u))
    if s < 1e-15:
        if c > 0:
            return np.eye(3)
        raise ValueError("opposite axes: no unique smallest rotation")
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    return np.eye(3) + K + K @ K * ((1 - c) / s ** 2)


def rpy_of(R: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw (R = Rz(yaw) Ry(pitch) Rx(roll)), exact also at pitch +-90 deg (roll taken as 0)."""
    sp = -R[2, 0]
    if abs(sp) > 1 - 1e-12:
        pitch = np.copysign(np.pi / 2, sp)
        return np.array([0.0, pitch, np.arctan2(-R[0, 1], R[1, 1])])
    return np.array([np.arctan2(R[2, 1], R[2, 2]), np.arcsin(np.clip(sp, -1, 1)), np.arctan2(R[1, 0], R[0, 0])])
