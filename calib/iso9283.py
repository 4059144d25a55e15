"""ISO 9283 pose accuracy and repeatability: the five poses of the test cube and the two figures per pose.

ISO 9283:1998 (Manipulating industrial robots -- Performance criteria and related test methods), as commonly
summarised (the standard's own text rules; see ``shared/reference/real-robots.md`` section 4):

* the test cube lies in the working space; P1 is its centre, P2..P5 lie on the diagonals of one of its diagonal
  planes at 10 % of the diagonal's length from the corners (:func:`cube_points`);
* each pose is approached n times (30) from one direction;
* pose accuracy (7.2.1) ``AP = sqrt((x̄ - x_c)^2 + (ȳ - y_c)^2 + (z̄ - z_c)^2)``: the distance from the commanded
  position to the barycentre of the attained ones, with its components ``AP_x = x̄ - x_c`` ...;
* pose repeatability (7.2.2) ``RP = l̄ + 3 S_l``, ``l_j`` the distance of attempt j from the barycentre, ``l̄`` their
  mean and ``S_l = sqrt(sum (l_j - l̄)^2 / (n - 1))``.

Positions only: the theodolites measure points, not orientations (ISO's AP_a, AP_b, AP_c need a 6-D instrument).
Units: mm.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: ISO 9283's number of cycles per pose
CYCLES = 30
#: where P2..P5 sit on the diagonals: 10 % of the diagonal from each corner
CORNER_FRACTION = 0.10


@dataclass(frozen=True)
class PoseFigures:
    """AP and RP of one pose (mm), with the barycentre's offset from the command per axis."""

    pose: str
    n: int
    ap_mm: float
    apx_mm: float
    apy_mm: float
    apz_mm: float
    rp_mm: float
    mean_distance_mm: float          # l̄
    sd_distance_mm: float            # S_l

    def as_dict(self) -> dict:
        return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def pose_figures(pose: str, commanded_mm, attained_mm) -> PoseFigures:
    """ISO 9283 AP and RP of one pose from its commanded position (3,) and the attained ones (n, 3)."""
    c = np.asarray(commanded_mm, float)
    x = np.atleast_2d(np.asarray(attained_mm, float))
    n = len(x)
    if n < 2:
        raise ValueError(f"pose {pose}: repeatability needs at least two attempts, got {n}")
    bary = x.mean(axis=0)
    ap = bary - c
    dist = np.linalg.norm(x - bary, axis=1)
    lbar = float(dist.mean())
    sl = float(dist.std(ddof=1))
    return PoseFigures(pose, n, float(np.linalg.norm(ap)), float(ap[0]), float(ap[1]), float(ap[2]),
                       lbar + 3.0 * sl, lbar, sl)


def cube_points(centre_mm, side_mm: float) -> dict[str, np.ndarray]:
    """P1..P5 of an axis-aligned test cube: P1 the centre; P2..P5 on the diagonals of the diagonal plane through
    the edges (x, -y, -z) and (x, +y, +z), at :data:`CORNER_FRACTION` of the diagonal from its corners."""
    c = np.asarray(centre_mm, float)
    h = side_mm / 2.0
    corners = [np.array([-h, -h, -h]), np.array([h, -h, -h]), np.array([h, h, h]), np.array([-h, h, h])]
    keep = 1.0 - 2.0 * CORNER_FRACTION          # from the centre: the corner less 10 % of the full diagonal
    out = {"P1": c.copy()}
    for k, corner in enumerate(corners, start=2):
        out[f"P{k}"] = c + keep * corner
    return out


def summary(figures: list[PoseFigures]) -> dict:
    """The largest AP and RP over the poses: the figures a data sheet quotes."""
    return {"ap_max_mm": max(f.ap_mm for f in figures), "rp_max_mm": max(f.rp_mm for f in figures)}
