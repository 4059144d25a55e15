"""Point coordinates from two sightings (thesis eq 4.3.1, App A.2, B.3), with their joint covariance.

``X = L tan(b) / (tan(a) + tan(b))``, ``Y = X tan(a)``, ``Z = sqrt(X^2 + Y^2) tan(phi)`` with ``a = alpha' - gamma1``,
``b = beta' - gamma2`` (sine form used: finite at 90 deg).  Every point shares L, gamma1, gamma2, so the points of one
session are *correlated*; :func:`points_from_readings` returns the full ``3N x 3N`` covariance, which the axis and DH
fits need to be honest about (a scale error in L moves every circle centre the same way).

First-order expressions (App B.3, re-derived where printed wrong): ``dX/dL = X/L``,
``dX/da = -X (1 + tan^2 a) / (tan a + tan b)``, ``dX/db = L tan a (1 + tan^2 b) / (tan a + tan b)^2`` (the printed
B.3 drops the square), ``dY = tan a dX + X (1 + tan^2 a) da``, ``dZ = tan(phi) (X dX + Y dY) / rho + rho (1 + tan^2
phi) dphi``, and ``da = d alpha' - d gamma1``, ``db = d beta' - d gamma2``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, NamedTuple

import numpy as np

from ..theodolite import Station, face_mean, intersect, thesis_xyz
from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, angles_in_range, at_least, finite

PROC = "points"


def point_xyz(x: np.ndarray) -> np.ndarray:
    """Vectorised eq 4.3.1: ``x (..., 6) = [alpha', beta', phi, L, gamma1, gamma2]`` -> ``(..., 3)`` mm."""
    x = np.asarray(x, float)
    ap, bp, ph, L, g1, g2 = np.moveaxis(x, -1, 0)
    return thesis_xyz(ap - g1, bp - g2, ph, L)


def point_first_order(x: np.ndarray) -> np.ndarray:
    """App B.3 Jacobian ``d(X, Y, Z)/d(alpha', beta', phi, L, gamma1, gamma2)``, shape ``(..., 3, 6)``."""
    x = np.asarray(x, float)
    ap, bp, ph, L, g1, g2 = np.moveaxis(x, -1, 0)
    a, b = ap - g1, bp - g2
    ta, tb = np.tan(a), np.tan(b)
    X, Y, Z = np.moveaxis(point_xyz(x), -1, 0)
    rho = np.hypot(X, Y)
    dX_dL = X / L
    dX_da = -X * (1 + ta ** 2) / (ta + tb)
    dX_db = L * ta * (1 + tb ** 2) / (ta + tb) ** 2
    z = np.zeros_like(X)
    # derivatives w.r.t. (a, b, phi, L)
    dX = np.stack([dX_da, dX_db, z, dX_dL], -1)
    dY = ta[..., None] * dX + np.stack([X * (1 + ta ** 2), z, z, z], -1)
    dZ = (np.tan(ph) / rho)[..., None] * (X[..., None] * dX + Y[..., None] * dY) \
        + np.stack([z, z, rho * (1 + np.tan(ph) ** 2), z], -1)
    Jabp = np.stack([dX, dY, dZ], -2)                       # (..., 3, 4) w.r.t. (a, b, phi, L)
    # chain to (alpha', beta', phi, L, gamma1, gamma2): a = alpha' - gamma1, b = beta' - gamma2
    C = np.zeros((4, 6))
    C[0, 0], C[0, 4] = 1, -1
    C[1, 1], C[1, 5] = 1, -1
    C[2, 2] = 1
    C[3, 3] = 1
    return Jabp @ C


def _check(ap, bp, ph, theo):
    step = "eq 4.3.1"
    angles_in_range(PROC, step, alpha_prime=ap, beta_prime=bp, phi=ph)
    finite(PROC, step, theodolite_parameters=theo)
    if np.any(np.abs(ph) >= np.pi / 2 - 1e-6):
        raise EstimationError(PROC, step, "an elevation phi is at or beyond +-90 deg (point straight above A)")
    L, g1, g2 = theo
    if L <= 0:
        raise EstimationError(PROC, step, f"baseline L must be positive (got {L} mm)")
    a, b = ap - g1, bp - g2
    bad = (a <= 1e-6) | (b <= 1e-6) | (a + b >= np.pi - 1e-6)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise EstimationError(PROC, step, f"sightings of point {i} do not intersect in front of both stations "
                              f"(alpha {np.degrees(a[i]):.4f} deg, beta {np.degrees(b[i]):.4f} deg)")


def points_from_readings(alpha_p_rad, beta_p_rad, phi_rad, theo_value, theo_cov, sigma_reading_rad: float,
                         n_mc: int = 20_000, rng=0) -> EstimateSet:
    """Coordinates of N points (eq 4.3.1) with their joint ``3N x 3N`` covariance three ways.

    ``theo_value = [L_mm, gamma1_rad, gamma2_rad]`` and ``theo_cov`` (3x3) from the ruler pre-calibration;
    ``sigma_reading_rad`` the 1-sigma noise of each reading.  Output names ``P{i}.X_mm`` ...
    """
    ap, bp, ph = (np.atleast_1d(np.asarray(v, float)).ravel() for v in (alpha_p_rad, beta_p_rad, phi_rad))
    if not (ap.size == bp.size == ph.size):
        raise EstimationError(PROC, "eq 4.3.1", f"alpha', beta', phi must have one reading per point "
                              f"(got {ap.size}, {bp.size}, {ph.size})")
    at_least(PROC, "eq 4.3.1", "point", ap.size, 1)
    theo = np.asarray(theo_value, float).ravel()
    _check(ap, bp, ph, theo)
    N = ap.size
    x = np.concatenate([np.stack([ap, bp, ph], -1).ravel(), theo])
    U = np.zeros((3 * N + 3, 3 * N + 3))
    U[:3 * N, :3 * N] = np.eye(3 * N) * sigma_reading_rad ** 2
    U[3 * N:, 3 * N:] = np.asarray(theo_cov, float)
    f = lambda z: points_vectorised(z, N)
    J1 = points_jacobian_first_order(x, N)
    names = [f"P{i}.{c}_mm" for i in range(N) for c in "XYZ"]
    return propagate(f, x, U, names, ["mm"] * 3 * N, n_mc=n_mc, rng=rng, first_order_cov=J1 @ U @ J1.T,
                     jac=None)


def points_vectorised(z: np.ndarray, N: int) -> np.ndarray:
    """``z (..., 3N + 3) = [alpha'_0, beta'_0, phi_0, ..., L, gamma1, gamma2]`` -> ``(..., 3N)`` coordinates."""
    z = np.asarray(z, float)
    rd = z[..., :3 * N].reshape(z.shape[:-1] + (N, 3))
    th = np.broadcast_to(z[..., None, 3 * N:], z.shape[:-1] + (N, 3))
    return point_xyz(np.concatenate([rd, th], -1)).reshape(z.shape[:-1] + (3 * N,))


def points_jacobian_first_order(x: np.ndarray, N: int) -> np.ndarray:
    """Analytic (App B.3) Jacobian of all N points w.r.t. readings and (L, gamma1, gamma2): ``(3N, 3N + 3)``."""
    rd = x[:3 * N].reshape(N, 3)
    th = np.broadcast_to(x[3 * N:], (N, 3))
    Jp = point_first_order(np.concatenate([rd, th], -1))        # (N, 3, 6)
    J = np.zeros((3 * N, 3 * N + 3))
    for i in range(N):
        J[3 * i:3 * i + 3, 3 * i:3 * i + 3] = Jp[i, :, :3]
        J[3 * i:3 * i + 3, 3 * N:] = Jp[i, :, 3:]
    return J


# -- targets from raw sightings, with the stations' own uncertainty ---------------------------------------------
@dataclass
class StationFit:
    """Stations built from fitted parameters (the ruler's L, gamma1, gamma2, hB) and those parameters' covariance.

    Why: every point is intersected with the *same* fitted stations, so an error in L or a gamma moves every point
    of a session together.  A point's covariance must carry that term (else its coverage falls to 77-88 %), and a fit
    over several points (a circle, a joint angle) must see the correlation it creates.
    """

    names: list[str]
    value: np.ndarray
    cov: np.ndarray
    build: Callable[[np.ndarray], dict[str, Station]]

    @property
    def stations(self) -> dict[str, Station]:
        return self.build(self.value)

    @staticmethod
    def exact(stations: dict[str, Station]) -> "StationFit":
        """Stations taken as exact (no ruler fit): no station term."""
        return StationFit([], np.zeros(0), np.zeros((0, 0)), lambda _v: stations)


class TargetPoint(NamedTuple):
    """One intersected target: point, covariance (reading noise + stations), miss distance, and
    ``d_station (3, P)`` = d point / d station parameters (for covariances across points)."""

    point_mm: np.ndarray
    cov_mm2: np.ndarray
    miss_mm: float
    d_station: np.ndarray
    cov_reading_mm2: np.ndarray


def locate_targets(readings: list[dict], fit: StationFit, min_stations: int = 2) -> dict[str, TargetPoint]:
    """Target name -> :class:`TargetPoint` from raw readings ``{"station", "target", "face", "hz_rad", "v_rad"}``.

    Each station's readings of a target (faces, repeats) are reduced to one face-I mean, whose noise is the
    station's reading sigma over sqrt(count); the point is the least-squares intersection (:func:`intersect`) and
    its sensitivity to the station parameters is taken by central differences (re-intersecting with perturbed
    stations), so the covariance is ``U_read + D U_station D^T``.  Targets sighted from fewer than two stations are
    left out.
    """
    base = fit.stations
    by: dict[tuple, list] = {}
    for r in readings:
        by.setdefault((r["station"], r["target"]), []).append(r)
    groups: dict[tuple, list] = {}
    for tg in sorted({r["target"] for r in readings}):
        names, obs = [], []
        for nm in base:
            rs = by.get((nm, tg))
            if rs:
                names.append(nm)
                obs.append((*face_mean([r["hz_rad"] for r in rs], [r["v_rad"] for r in rs],
                                       [r["face"] for r in rs]), len(rs)))
        if len(names) >= min_stations:
            groups.setdefault((tuple(names), tuple(o[2] for o in obs)), []).append((tg, obs))
    out = {}
    for (names, counts), items in groups.items():
        rd = [(np.array([obs[s][0] for _, obs in items]), np.array([obs[s][1] for _, obs in items]))
              for s in range(len(names))]

        def solve(stations, rd=rd, names=names, counts=counts):
            # each station's sigma shrinks with the readings averaged (faces, repeats)
            sts = [replace(stations[n], sigma_hz_rad=stations[n].sigma_hz_rad / np.sqrt(c),
                           sigma_v_rad=stations[n].sigma_v_rad / np.sqrt(c)) for n, c in zip(names, counts)]
            return intersect(sts, rd)

        x = solve(base)
        D = _station_sensitivity(solve, fit, x.point_mm)
        for i, (tg, _) in enumerate(items):
            Di = D[i]
            out[tg] = TargetPoint(x.point_mm[i], x.cov_mm2[i] + Di @ fit.cov @ Di.T, float(x.miss_mm[i]), Di,
                                  x.cov_mm2[i])
    return out


def _station_sensitivity(solve, fit: StationFit, p0: np.ndarray) -> np.ndarray:
    """d point / d station parameter ``(N, 3, P)`` by central differences of the whole intersection."""
    P = len(fit.names)
    D = np.zeros(p0.shape[:1] + (3, P))
    sd = np.sqrt(np.clip(np.diag(fit.cov), 0, None))
    for k in range(P):
        h = np.zeros(P)
        h[k] = max(0.1 * sd[k], 1e-9 * max(abs(fit.value[k]), 1.0))
        pp = solve(fit.build(fit.value + h)).point_mm
        pm = solve(fit.build(fit.value - h)).point_mm
        D[:, :, k] = (pp - pm) / (2 * h[k])
    return D


def points_covariance(points: list[TargetPoint], fit: StationFit) -> np.ndarray:
    """Joint ``(3N, 3N)`` covariance of several located targets: independent reading noise per point plus the
    stations' common term (the correlation a shared L or gamma puts between every pair of points)."""
    N = len(points)
    U = np.zeros((3 * N, 3 * N))
    for i, t in enumerate(points):
        U[3 * i:3 * i + 3, 3 * i:3 * i + 3] = t.cov_reading_mm2
    if fit.cov.size:
        D = np.concatenate([t.d_station for t in points], 0)
        U += D @ fit.cov @ D.T
    return U
