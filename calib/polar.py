"""Polar instruments (laser tracker, total station): a raw reading (Hz, V, distance) as a point with its covariance.

Convention (the theodolite's, :mod:`calib.theodolite`): in the instrument frame (z up along its vertical axis), ``Hz``
increases clockwise seen from above from the instrument's x axis, ``V`` is the zenith angle (0 up, 90 deg horizontal),
the distance is the slope distance to the target:

    x = d sin V cos Hz,   y = -d sin V sin Hz,   z = d cos V

Noise model: independent angle noise ``sigma_angle_rad`` on Hz and V and distance noise
``sigma_dist_mm + ppm * 1e-6 * d``; propagated through the Jacobian of the map above (first order, exact enough for
angle noise of arc seconds), so each row enters the identification with the covariance its own geometry gives: tight
along the line of sight for a tracker's interferometer, wide across it at long range.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import RobocalError
from .units import ARCSEC


@dataclass(frozen=True)
class PolarNoise:
    """1-sigma noise of a polar instrument's reading."""

    sigma_angle_rad: float = 1.0 * ARCSEC
    sigma_dist_mm: float = 0.01
    ppm: float = 1.0

    @classmethod
    def from_text(cls, text: str) -> "PolarNoise":
        """``ANGLE_ARCSEC,DIST_MM[,PPM]`` as given on the command line."""
        try:
            vals = [float(v) for v in text.split(",")]
        except ValueError:
            vals = []
        if len(vals) not in (2, 3) or not all(np.isfinite(vals)) or vals[0] <= 0 or vals[1] <= 0 or \
                (len(vals) == 3 and vals[2] < 0):
            raise RobocalError(f"--polar-noise {text!r}: expected ANGLE_ARCSEC,DIST_MM[,PPM] (positive numbers)")
        return cls(vals[0] * ARCSEC, vals[1], vals[2] if len(vals) == 3 else 0.0)


def polar_points(polar: np.ndarray, noise: PolarNoise) -> tuple[np.ndarray, np.ndarray]:
    """Points (N, 3) in the instrument frame and their covariance (N, 3, 3) from readings (N, 3): Hz, V (rad), d (mm)."""
    hz, v, d = polar[:, 0], polar[:, 1], polar[:, 2]
    sh, ch, sv, cv = np.sin(hz), np.cos(hz), np.sin(v), np.cos(v)
    p = np.stack([d * sv * ch, -d * sv * sh, d * cv], axis=1)
    J = np.empty((len(polar), 3, 3))                     # d point / d (hz, v, d)
    J[:, :, 0] = np.stack([-d * sv * sh, -d * sv * ch, np.zeros_like(d)], axis=1)
    J[:, :, 1] = np.stack([d * cv * ch, -d * cv * sh, -d * sv], axis=1)
    J[:, :, 2] = np.stack([sv * ch, -sv * sh, cv], axis=1)
    sd = noise.sigma_dist_mm + noise.ppm * 1e-6 * d
    S = np.zeros((len(polar), 3, 3))
    S[:, 0, 0] = S[:, 1, 1] = noise.sigma_angle_rad ** 2
    S[:, 2, 2] = sd ** 2
    return p, np.einsum("nij,njk,nlk->nil", J, S, J)
