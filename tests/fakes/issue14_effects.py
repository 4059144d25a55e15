"""Independent formulas for the effects issue 14 adds, on the thesis generator's own frames (contract C7).

Imports nothing from ``calib``: each effect is written again from its physical description, one pose at a time.
"""
from __future__ import annotations

import numpy as np

from .oracle.chain import rotation_vector
from .thesis_puma import ThesisPuma


def joint_scale_point(arm: ThesisPuma, q: np.ndarray, joint: int, scale: float) -> np.ndarray:
    """The joint turns (1 + scale) times its reading."""
    th = q.copy()
    th[joint - 1] *= 1.0 + scale
    return arm.tool_point(th)


def axis_tilt_point(arm: ThesisPuma, q: np.ndarray, joint: int, c: float, s: float) -> np.ndarray:
    """Joint ``joint``'s axis tilted by the counter-rotating vector (c cos phi + s sin phi, -c sin phi + s cos phi, 0)
    of frame j-1, phi the joint angle; everything beyond turns about the axis point."""
    T = arm.frames(q)
    phi = q[joint - 1] + arm.theta_offset[joint - 1]
    w_local = np.array([c * np.cos(phi) + s * np.sin(phi), -c * np.sin(phi) + s * np.cos(phi), 0.0])
    R0, o = T[joint - 1][:3, :3], T[joint - 1][:3, 3]
    p = arm.tool_point(q)
    return o + rotation_vector(R0 @ w_local) @ (p - o)


def parallel_axes_point(arm: ThesisPuma, q: np.ndarray, joint: int, beta: float) -> np.ndarray:
    """Hayati's Rot(y, beta) after A_j, as the generator's chain has it."""
    saved = arm.beta.copy()
    arm.beta[joint - 1] += beta
    try:
        return arm.tool_point(q)
    finally:
        arm.beta = saved


def drift_point(arm: ThesisPuma, q: np.ndarray, shift_mm: np.ndarray) -> np.ndarray:
    """The base seen from the instrument moved by ``shift_mm``."""
    saved = arm.base.copy()
    arm.base[:3, 3] += shift_mm
    try:
        return arm.tool_point(q)
    finally:
        arm.base = saved


def tool_flex_point(arm: ThesisPuma, q: np.ndarray, sag_mm: float) -> np.ndarray:
    """The tool point sags along the part of gravity across the flange axis, ``sag_mm`` when horizontal."""
    T = arm.frames(q)
    g = T[0][:3, :3] @ arm.gravity_m_s2
    g = g / np.linalg.norm(g)
    z = T[6][:3, 2]
    return arm.tool_point(q) + sag_mm * (g - (g @ z) * z)
