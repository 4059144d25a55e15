"""Angles and rigid motions, written once: the angle wrap and the least-squares rigid fit of one point set onto
another.  Rotation matrices from roll-pitch-yaw and back
(:func:`rot_zyx`, :func:`rpy_matrix`, :func:`rpy_from_matrix`), the one convention of the base, the description and the
URDF reader.
"""
from __future__ import annotations

import numpy as np


def wrap_angle(a):
    """Angles wrapped to (-pi, pi] (radians; arrays keep their shape)."""
    return np.angle(np.exp(1j * np.asarray(a, float)))


def rigid_fit(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` with ``target ~ source @ R.T + t`` in the least-squares sense (N >= 3 points, (N, 3) each): the
    rotation by the Kabsch SVD (a proper rotation: a reflection is turned into the nearest rotation, as scipy's
    ``Rotation.align_vectors`` does), the translation from the centroids.  Plain numpy: importing
    ``scipy.spatial`` for it cost every fit 0.3-0.8 s of start-up (a third of ``robocal demo``'s reprocessing)."""
    source, target = np.asarray(source, float), np.asarray(target, float)
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    H = (source - cs).T @ (target - ct)                 # sum of s_i t_i^T over the centred points
    U, _, Vt = np.linalg.svd(H)
    d = 1.0 if np.linalg.det(Vt.T @ U.T) >= 0 else -1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, ct - R @ cs


def rot_zyx(yaw, pitch, roll) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll) (..., 3, 3) for scalar or per-pose angles (the base's and the description's
    roll-pitch-yaw; the kinematics' base transform uses it too)."""
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    R = np.empty(np.shape(yaw) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sp, cp * sr, cp * cr
    return R


def rpy_matrix(rpy) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll) from (roll, pitch, yaw): the inverse of :func:`rpy_from_matrix` (plain numpy: a
    description loads without importing scipy, which costs a command half a second of start-up)."""
    roll, pitch, yaw = (float(v) for v in rpy)
    return rot_zyx(yaw, pitch, roll)


def rpy_from_matrix(R: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) with R = Rz(yaw) Ry(pitch) Rx(roll), the base convention of :mod:`calib.kinematics`."""
    pitch = -np.arcsin(np.clip(R[2, 0], -1.0, 1.0))
    return np.array([np.arctan2(R[2, 1], R[2, 2]), pitch, np.arctan2(R[1, 0], R[0, 0])])
