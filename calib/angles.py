"""Angles and rigid motions, written once: the angle wrap and the least-squares rigid fit of one point set onto
another.  Rotation matrices from roll-pitch-yaw and back
(:func:`rot_zyx`, :func:`rpy_matrix`, :func:`rpy_from_matrix`), the one convention of the base, the description and the
URDF reader.
"""
from __future__ import annotations

import math

import numpy as np


def wrap_angle(a):
    """Angles wrapped to (-pi, pi] (radians; arrays keep their shape)."""
    return np.angle(np.exp(1j * np.asarray(a, float)))


def wrap_float(a: float) -> float:
    """:func:`wrap_angle` of one float, the same float (``atan2(sin, cos)``, which numpy's complex exponential and
    angle compute), without numpy's per-call cost: for code that wraps one reading at a time."""
    return math.atan2(math.sin(a), math.cos(a))


def circular_mean(a) -> float:
    """The mean direction of angles (rad): the angle of their mean unit vector, so readings either side of 0/2pi
    average to about 0, not to pi (a telescope's horizontal circle wraps there)."""
    return float(np.angle(np.mean(np.exp(1j * np.asarray(a, float)))))


def rigid_fit(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` with ``target ~ source @ R.T + t`` in the least-squares sense (N >= 3 points, (N, 3) each): the
    rotation by Kabsch's SVD of the centred points' cross-covariance, its last axis flipped when that gives a
    reflection (a proper rotation: what scipy's ``Rotation.align_vectors`` returns, checked against it in
    tests/test_angles.py); the translation from the centroids.  Plain numpy: scipy.spatial cost every fit 0.07-0.8 s
    of import for a 3x3 SVD."""
    source, target = np.asarray(source, float), np.asarray(target, float)
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    U, _, Vt = np.linalg.svd((target - ct).T @ (source - cs))
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    R = U @ np.diag([1.0, 1.0, d]) @ Vt
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
