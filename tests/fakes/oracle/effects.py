"""The thesis's running errors in its own terms, one formula each: what a joint's true angle is given its reading.

* transmission error ``K_theta = s sin(order q) + c cos(order q)`` (section 5.4.2);
* joint compliance, two slopes: stiffness k1 up to the breakpoint torque, k2 beyond (section 5.5.2), the same
  either way round, and the unloading branch parallel but offset by the dead zone;
* cross coupling ``sigma * q_source`` (section 4.7);
* an incremental encoder's whole counts;
* play in a drive: the link rests where its load torque pushes it when that torque beats the preload, where the
  motor left it otherwise.

The classes give a (n,) correction for one pose from its readings ``q`` and gravity torques ``tau``, so a generator
can sum any list of them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _at(n: int, joint: int, value: float) -> np.ndarray:
    out = np.zeros(n)
    out[joint - 1] = value
    return out


def transmission_truth(theta_enc, amplitude, omega, phase=0.0):
    """True joint angle minus encoder angle, section 5.4.2: ``amplitude sin(omega theta + phase)``."""
    return amplitude * np.sin(omega * np.asarray(theta_enc, float) + phase)


def two_slope(tau, k1: float, k2: float | None = None, breakpoint: float = np.inf):
    """Deflection (rad) of a joint under torque ``tau`` (N m): ``tau / k1`` up to the breakpoint, then ``1 / k2``
    more per N m; odd in tau."""
    k2 = k1 if k2 is None else k2
    t = np.abs(np.asarray(tau, float))
    return np.sign(tau) * (np.minimum(t, breakpoint) / k1 + np.maximum(t - breakpoint, 0.0) / k2)


def two_slope_deflection(T, K1, K2, Tb, offset, unloading):
    """Section 5.5.2's loading curve with a breakpoint, unloading parallel but offset by the dead zone."""
    return two_slope(T, K1, K2, Tb) + offset * np.asarray(unloading, float)


def quantise(angle_rad, rad_per_count):
    """An incremental encoder's reading: whole counts."""
    return np.round(np.asarray(angle_rad, float) / rad_per_count) * rad_per_count


def play_offset(width_rad: float, tau: float, preload_nm: float, approach: float) -> float:
    """Where a link with play ``width_rad`` sits about its mean: ``+width/2 sign(tau)`` when the load torque beats
    the preload, ``-width/2 * approach`` (the sign of its last move) otherwise."""
    side = np.sign(tau) if abs(tau) > preload_nm else -approach
    return 0.5 * width_rad * side


@dataclass
class TransmissionError:
    """K_theta = s sin(order q) + c cos(order q), added to joint ``joint``'s reading (section 5.4.2)."""

    joint: int
    order: float
    sin_rad: float
    cos_rad: float = 0.0

    def delta(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        qj = q[self.joint - 1]
        return _at(len(q), self.joint, self.sin_rad * np.sin(self.order * qj) + self.cos_rad * np.cos(self.order * qj))


@dataclass
class JointCompliance:
    """The joint gives way along its gravity torque, two slopes (section 5.5.2)."""

    joint: int
    k1_nm_per_rad: float
    k2_nm_per_rad: float | None = None
    breakpoint_nm: float = np.inf

    def deflection(self, tau: float) -> float:
        return float(two_slope(tau, self.k1_nm_per_rad, self.k2_nm_per_rad, self.breakpoint_nm))

    def delta(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return _at(len(q), self.joint, self.deflection(tau[self.joint - 1]))


@dataclass
class CrossCoupling:
    """A share ``sigma`` of joint ``source``'s reading appears in joint ``joint`` (section 4.7)."""

    joint: int
    source: int
    sigma: float

    def delta(self, q: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return _at(len(q), self.joint, self.sigma * q[self.source - 1])
