"""Plain 4x4 chains: elementary transforms, the DH/Hayati link matrix as printed, URDF origins, Rodrigues, joint
torques of forces at points and a Jacobian by differences.  Angles may be arrays (a leading shape of poses): every
transform broadcasts, so one formula serves a single pose and a vectorised benchmark alike."""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np


def rot(axis: int, angle) -> np.ndarray:
    """(..., 4, 4) rotation by ``angle`` about x (0), y (1) or z (2)."""
    angle = np.asarray(angle, float)
    c, s = np.cos(angle), np.sin(angle)
    T = np.broadcast_to(np.eye(4), angle.shape + (4, 4)).copy()
    i, k = [(1, 2), (2, 0), (0, 1)][axis]
    T[..., i, i], T[..., i, k], T[..., k, i], T[..., k, k] = c, -s, s, c
    return T


def rot_x(angle) -> np.ndarray:
    return rot(0, angle)


def rot_y(angle) -> np.ndarray:
    return rot(1, angle)


def rot_z(angle) -> np.ndarray:
    return rot(2, angle)


def trans(x, y, z) -> np.ndarray:
    """(..., 4, 4) translation."""
    t = np.stack(np.broadcast_arrays(*(np.asarray(v, float) for v in (x, y, z))), -1)
    T = np.broadcast_to(np.eye(4), t.shape[:-1] + (4, 4)).copy()
    T[..., :3, 3] = t
    return T


def hom(R=np.eye(3), t=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The 4x4 transform of rotation ``R`` (3, 3) and translation ``t``."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: ``Rz(yaw) Ry(pitch) Rx(roll)`` (3, 3)."""
    return (rot_z(yaw) @ rot_y(pitch) @ rot_x(roll))[:3, :3]


def axis_angle(axis, angle: float) -> np.ndarray:
    """Rodrigues: (3, 3) rotation by ``angle`` about the direction ``axis`` (any length)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def rotation_vector(w) -> np.ndarray:
    """(3, 3) rotation of the rotation vector ``w`` (direction the axis, length the angle)."""
    a = float(np.linalg.norm(w))
    return np.eye(3) if a == 0 else axis_angle(w, a)


def rotate_points(P, c, n, theta) -> np.ndarray:
    """Points P (..., 3) turned by theta (...) about the axis through c along n (Rodrigues on vectors)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    d = np.asarray(P, float) - c
    th = np.asarray(theta, float)[..., None]
    return c + d * np.cos(th) + np.cross(n, d) * np.sin(th) + n * (d @ n)[..., None] * (1 - np.cos(th))


def a_matrix(theta, d: float, a: float, alpha: float) -> np.ndarray:
    """(..., 4, 4) the A_j matrix of section 3.4 element by element as printed:
    ``Rot(z, theta) Trans(z, d) Trans(x, a) Rot(x, alpha)``."""
    return hayati_matrix(theta, d, a, alpha, 0.0)


def hayati_matrix(theta, d: float, a: float, alpha: float, beta: float) -> np.ndarray:
    """(..., 4, 4) ``A_j Rot(y, beta)``, Hayati's link for nearly parallel axes, multiplied out element by element
    (``beta = 0`` is section 3.4's A_j as printed; tests/test_oracle.py holds it to the product of its factors)."""
    theta = np.asarray(theta, float)
    ct, st, ca, sa, cb, sb = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta)
    A = np.zeros(theta.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2] = ct * cb - st * sa * sb, -st * ca, ct * sb + st * sa * cb
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2] = st * cb + ct * sa * sb, ct * ca, st * sb - ct * sa * cb
    A[..., 2, 0], A[..., 2, 1], A[..., 2, 2] = -ca * sb, sa, ca * cb
    A[..., 0, 3], A[..., 1, 3], A[..., 2, 3], A[..., 3, 3] = a * ct, a * st, d, 1.0
    return A


def base_matrix(xyz_mm=(0.0, 0.0, 0.0), yaw: float = 0.0, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """Measurement frame <- robot frame 0: translate, then turn about z (yaw), the new y (pitch), the new x (roll)."""
    return trans(*xyz_mm) @ rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def dh_frames(base: np.ndarray, theta, d, a, alpha, beta=None) -> list[np.ndarray]:
    """Frames 0..n (each (..., 4, 4)) of a DH chain with Hayati's ``Rot(y, beta)`` after each A_j:
    ``base A_1 Ry(beta_1) ... A_n Ry(beta_n)``; ``theta`` (..., n) the joint angles with their offsets added."""
    theta = np.asarray(theta, float)
    n = theta.shape[-1]
    beta = np.zeros(n) if beta is None else beta
    T = np.broadcast_to(base, theta.shape[:-1] + (4, 4))
    out = [T]
    for j in range(n):
        T = T @ hayati_matrix(theta[..., j], d[j], a[j], alpha[j], beta[j])
        out.append(T)
    return out


def point_in(T: np.ndarray, p) -> np.ndarray:
    """(..., 3) the point ``p`` (3,) given in frame(s) ``T`` (..., 4, 4), in the frame T is given in."""
    return T[..., :3, :3] @ np.asarray(p, float) + T[..., :3, 3]


def axis_torques(frames: Sequence[np.ndarray], loads: Iterable[tuple[np.ndarray, np.ndarray, int]]) -> np.ndarray:
    """(n,) torque (N m) about each joint axis of forces at points, one pose.

    ``frames`` 0..n (mm); joint j turns about the z axis of frame j-1 through its origin; ``loads`` are (point (3,) mm,
    force (3,) N, link) and joint j feels a force riding on link j or beyond: ``tau_j = z_{j-1} . (r - o_{j-1}) x F``.
    """
    n = len(frames) - 1
    tau = np.zeros(n)
    for r, F, link in loads:
        for j in range(min(link, n)):
            o, z = frames[j][:3, 3], frames[j][:3, 2]
            tau[j] += z @ np.cross((np.asarray(r, float) - o) * 1e-3, np.asarray(F, float))
    return tau


def numeric_jacobian(f: Callable[[np.ndarray], np.ndarray], x, step=1e-6) -> np.ndarray:
    """d f / d x by central differences, one column at a time: ``x`` (..., m) with ``step`` a number or (m,); ``f``
    maps x to an array of any shape; returns f's shape + (m,)."""
    x = np.asarray(x, float)
    steps = np.broadcast_to(np.asarray(step, float), x.shape[-1:])
    cols = []
    for i, h in enumerate(steps):
        e = np.zeros(x.shape[-1])
        e[i] = h
        cols.append((np.asarray(f(x + e), float) - np.asarray(f(x - e), float)) / (2 * h))
    return np.stack(cols, -1)
