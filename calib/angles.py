"""Angles and rigid motions, written once: the angle wrap and the least-squares rigid fit of one point set onto
another.  (Rotation matrix to roll-pitch-yaw and back: :func:`calib.robot.rpy_from_matrix`, :func:`calib.robot.rot_zyx`.)
"""
from __future__ import annotations

import numpy as np


def wrap_angle(a):
    """Angles wrapped to (-pi, pi] (radians; arrays keep their shape)."""
    return np.angle(np.exp(1j * np.asarray(a, float)))


def rigid_fit(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` with ``target ~ source @ R.T + t`` in the least-squares sense (N >= 3 points, (N, 3) each): the
    rotation by scipy's :meth:`~scipy.spatial.transform.Rotation.align_vectors` (Kabsch, a proper rotation), the
    translation from the centroids."""
    from scipy.spatial.transform import Rotation     # 0.3-0.8 s to import (all of scipy.spatial): only when used
    source, target = np.asarray(source, float), np.asarray(target, float)
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    rot, _ = Rotation.align_vectors(target - ct, source - cs)
    R = rot.as_matrix()
    return R, ct - R @ cs
