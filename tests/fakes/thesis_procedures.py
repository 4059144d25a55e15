"""Independent data for the Chapter 4 estimators: the thesis's own formulas as plain numpy, nothing from ``calib``.

Why: an estimator tested on data made by its own model can only agree with itself.  Here every reading comes from the
thesis's geometry written out again -- the inverse of eq 4.3.1 (section 5.3.1: a point's interior angles at A and B
and A's elevation), Rodrigues rotations of a target about a joint axis, eq 4.4's two-target angle, eq 4.5.1's
``T = N L cos(theta_i)``, eq 4.7.1's coupled encoder counts, and a cantilever deflection obtained by integrating
``EI y'' = M`` numerically (not the closed form the estimator uses).

Reading conventions (those of the instruments): ``Hz`` clockwise seen from above, ``V`` zenith angle; station A at the
origin with its circle zero at yaw ``-gamma1``, B at ``(L, 0, hB)`` with its zero at yaw ``pi + gamma2``.  So
``Hz_A = -(alpha + gamma1)`` and ``Hz_B = beta + gamma2`` with the interior angles ``alpha = atan2(Y, X)`` at A and
``beta = atan2(Y, L - X)`` at B (the thesis's ``alpha' = alpha + gamma1``, ``beta' = beta + gamma2``).
"""
from __future__ import annotations

import numpy as np

from .oracle.beam import cantilever_deflection
from .oracle.chain import rotate_points as rotate
from .oracle.effects import quantise, transmission_truth, two_slope_deflection
from .oracle.stations import TWO_PI, face_two, station_angles


__all__ = ["ARCSEC", "cantilever_deflection", "puma_ready_axes", "quantise", "rotate", "ruler_rows", "sightings",
           "station_angles", "transmission_truth", "two_slope_deflection"]

ARCSEC = np.pi / (180 * 3600)


def sightings(P, names, L, g1, g2, hB, sigma, rng, faces=(1, 2), repeats=1, collimation=None, index=None):
    """Session-style reading rows ``{station, target, face, repeat, hz_rad, v_rad}`` of targets ``names`` at P, each
    reading with its own Gaussian noise ``sigma`` (rad); face II is ``Hz + 180 deg, 360 deg - V``.

    ``collimation`` / ``index`` (per station A, B; rad): an instrument out of adjustment, as the textbooks write it:
    the line of sight is off square to the trunnion axis by c, so Hz reads ``+ c / sin V`` on face I and ``- c / sin V``
    on face II; the vertical circle's zero is off by k, so V reads ``+ k`` on both faces."""
    hA, vA, hB_, vB = station_angles(P, L, g1, g2, hB)
    c = dict(zip("AB", collimation or (0.0, 0.0)))
    k_ = dict(zip("AB", index or (0.0, 0.0)))
    rows = []
    for i, nm in enumerate(names):
        for st, h, v in (("A", hA[i], vA[i]), ("B", hB_[i], vB[i])):
            for f in faces:
                for k in range(repeats):
                    cs = c[st] / np.sin(v)
                    hz, vv = (h + cs, v) if f == 1 else (h + np.pi - cs, TWO_PI - v)
                    rows.append({"station": st, "target": nm, "face": f, "repeat": k,
                                 "hz_rad": float(np.mod(hz + sigma * rng.standard_normal(), TWO_PI)),
                                 "v_rad": float(vv + k_[st] + sigma * rng.standard_normal())})
    return rows


def ruler_rows(L, g1, g2, hB, placements, marks, sigma, rng, faces=(1, 2)):
    """(placement, mark, station 0/1, face, hz, v) rows of ruler marks; ``placements = [(C_xyz, azimuth, tilt)]``."""
    rows = []
    for p, (c, az, tl) in enumerate(placements):
        u = np.array([np.cos(tl) * np.cos(az), np.cos(tl) * np.sin(az), np.sin(tl)])
        pts = np.asarray(c, float) + np.asarray(marks, float)[:, None] * u
        hA, vA, hB_, vB = station_angles(pts, L, g1, g2, hB)
        for m in range(len(marks)):
            for st, h, v in ((0, hA[m], vA[m]), (1, hB_[m], vB[m])):
                for f in faces:
                    hz, vv = (h, v) if f == 1 else face_two(h, v)
                    rows.append((p, m, st, f, np.mod(hz + sigma * rng.standard_normal(), TWO_PI),
                                 vv + sigma * rng.standard_normal()))
    return np.array(rows, float)


def puma_ready_axes(a1, a2, d1, d2, d3, L_p, base, tilt_axis, tilt):
    """A Puma at READY drawn from Fig 3.4's lengths with plain vectors: six axes (centre where a target's circle
    would be, unit direction) and the point P on joint 6's axis L_p beyond the flange; the whole arm placed at
    ``base`` and tilted rigidly by ``tilt`` (rad) about ``tilt_axis`` through the base.  Returns (axes (6, 6), P,
    design directions (6, 3))."""
    ex, ey, ez = np.eye(3)
    wrist = np.array([a2, d1, a1 + d2])
    centres = [np.array([0.0, 0.0, 300.0]), np.array([0.0, -250.0, 0.0]), np.array([0.0, -200.0, a1]),
               wrist + 120.0 * ez, wrist - 180.0 * ey, wrist + np.array([0.0, 0.0, d3 + 40.0])]
    dirs = [ez, ey, ey, ez, ey, ez]
    P = wrist + (d3 + L_p) * ez
    b = np.asarray(base, float)
    k = np.asarray(tilt_axis, float) / np.linalg.norm(tilt_axis)
    moved = rotate(np.array([c + b for c in centres] + [P + b]), b, k, np.full(7, tilt))
    turned = rotate(np.array(dirs), np.zeros(3), k, np.full(6, tilt))
    return np.hstack([moved[:6], turned]), moved[6], np.array(dirs)
