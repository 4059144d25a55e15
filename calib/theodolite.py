"""Theodolite geometry: the angles a station reads for a point, and the point two or more sightings give back.

Station model (one per instrument), in the measurement frame R_f of the thesis (origin at theodolite A, X along the
baseline A -> B, Z up along A's vertical axis):

* position ``xyz_mm`` of the instrument's centre (intersection of the axes);
* ``yaw_rad``: world direction (counter-clockwise from +X) of the horizontal circle's zero;
* levelling ``tilt_x_rad``, ``tilt_y_rad``: the vertical axis tilted about the world X and Y axes;
* instrument errors: collimation ``collimation_rad`` (c), trunnion-axis tilt ``trunnion_rad`` (i) and vertical index
  error ``index_rad`` (k).

Readings are what a Leica instrument reports: ``Hz`` increasing clockwise seen from above, ``V`` the zenith angle
(0 up, pi/2 horizontal).  Face I:  ``Hz = Hz0 + c / sin V + i cot V``, ``V = V0 + k``; face II:
``Hz = Hz0 + pi - c / sin V - i cot V``, ``V = 2 pi - V0 + k``.

The thesis's own parameterisation (L, gamma1, gamma2; section 4.2 and eq 4.3.1) is the special case built by
:func:`thesis_stations`: A at the origin, B at (L, 0, 0), both levelled, with the interior angles
``alpha = alpha' - gamma1``, ``beta = beta' - gamma2`` and A's elevation ``phi``; :func:`thesis_readings` and
:func:`thesis_point` convert.  Targets lie on the +Y side of the baseline.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from .angles import wrap_angle, wrap_float
from .errors import GeometryError
from .units import ARCSEC

TWO_PI = 2 * np.pi




#: from this many angles on, an array of one repeated value (a batch of sightings from levelled stations: the ruler
#: fit's Jacobian evaluates 180,000 per demo) has its cosine and sine taken once
SAME_ANGLE_FROM = 64


def _cos_sin(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(cos a, sin a)``; a large array holding one value throughout (the same bits: -0.0 is not 0.0) gets them from
    its first element, broadcast -- the same ufunc on the same float, so the same floats (read-only views)."""
    if a.size >= SAME_ANGLE_FROM:
        flat = np.ascontiguousarray(a).reshape(-1)
        first = flat[:1]
        if (flat.view(np.int64) == first.view(np.int64)).all():
            return np.broadcast_to(np.cos(first), a.shape), np.broadcast_to(np.sin(first), a.shape)
    return np.cos(a), np.sin(a)


def station_rotation(yaw_rad, tilt_x_rad=0.0, tilt_y_rad=0.0) -> np.ndarray:
    """World <- instrument rotation ``Ry(tilt_y) Rx(tilt_x) Rz(yaw)``, batched over the angles' shapes -> (..., 3, 3).

    The one yaw convention: ``yaw`` is the world direction (counter-clockwise from +X) of the circle's zero."""
    yaw, tx, ty = np.broadcast_arrays(*(np.asarray(a, float) for a in (yaw_rad, tilt_x_rad, tilt_y_rad)))
    (cz, sz), (cx, sx), (cy, sy) = _cos_sin(yaw), _cos_sin(tx), _cos_sin(ty)
    # the product Ry Rx Rz written out, filled into one array (a stack of nine stacks cost more than the maths)
    R = np.empty(yaw.shape + (3, 3))
    sysx, cysx = sy * sx, cy * sx
    R[..., 0, 0] = cy * cz + sysx * sz
    R[..., 0, 1] = -cy * sz + sysx * cz
    R[..., 0, 2] = sy * cx
    R[..., 1, 0] = cx * sz
    R[..., 1, 1] = cx * cz
    R[..., 1, 2] = -sx
    R[..., 2, 0] = -sy * cz + cysx * sz
    R[..., 2, 1] = sy * sz + cysx * cz
    R[..., 2, 2] = cy * cx
    return R


def _readings_local(d, collimation_rad, trunnion_rad, index_rad, face):
    """(Hz, V) of instrument-frame vectors ``d (..., 3)``: the instrument errors and the face, see the module."""
    dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
    hz0 = np.arctan2(-dy, dx)
    v0 = np.arctan2(np.hypot(dx, dy), dz)
    sv = np.sin(v0)
    corr = collimation_rad / sv + trunnion_rad * np.cos(v0) / sv
    face2 = np.asarray(face) == 2
    hz = np.where(face2, hz0 + np.pi - corr, hz0 + corr)
    v = np.where(face2, TWO_PI - v0, v0) + index_rad
    return np.mod(hz, TWO_PI), v


def observe_params(params: np.ndarray, points_mm: np.ndarray, face=1):
    """:meth:`Station.observe` vectorised over the station parameters too: ``params (..., 9)`` in the order of
    :attr:`Station.PARAMS`, points ``(..., 3)``, face (...) -> ``(Hz, V)``.  Why: a fit of the stations (the ruler)
    needs the readings for a batch of parameter vectors, and must use the same instrument model as everything else."""
    p = np.asarray(params, float)
    R = station_rotation(p[..., 3], p[..., 4], p[..., 5])
    d = np.einsum("...i,...ij->...j", np.asarray(points_mm, float) - p[..., :3], R)
    return _readings_local(d, p[..., 6], p[..., 7], p[..., 8], face)


@dataclass(frozen=True)
class Station:
    """One theodolite: pose, levelling and instrument errors.  Units mm and rad."""

    name: str = "A"
    x_mm: float = 0.0
    y_mm: float = 0.0
    z_mm: float = 0.0
    yaw_rad: float = 0.0
    tilt_x_rad: float = 0.0
    tilt_y_rad: float = 0.0
    collimation_rad: float = 0.0
    trunnion_rad: float = 0.0
    index_rad: float = 0.0
    sigma_hz_rad: float = 3 * ARCSEC     #: 1-sigma reading noise, horizontal (Sokkisha TM-20C: read to 3")
    sigma_v_rad: float = 3 * ARCSEC

    PARAMS = ("x_mm", "y_mm", "z_mm", "yaw_rad", "tilt_x_rad", "tilt_y_rad", "collimation_rad", "trunnion_rad",
              "index_rad")

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x_mm, self.y_mm, self.z_mm])

    @cached_property
    def rotation(self) -> np.ndarray:
        """World <- instrument rotation: Ry(tilt_y) Rx(tilt_x) Rz(yaw) (the station is frozen: computed once; read-only
        so no caller can change the cached matrix)."""
        R = station_rotation(self.yaw_rad, self.tilt_x_rad, self.tilt_y_rad)
        R.flags.writeable = False
        return R

    @cached_property
    def _plain(self) -> tuple:
        """(name, position, rotation rows, c, i, k) in plain floats, for :func:`_refine_few`."""
        return (self.name, (self.x_mm, self.y_mm, self.z_mm), self.rotation.tolist(), self.collimation_rad,
                self.trunnion_rad, self.index_rad)

    def params(self) -> np.ndarray:
        return np.array([getattr(self, k) for k in self.PARAMS])

    def with_params(self, values) -> "Station":
        return replace(self, **{k: float(v) for k, v in zip(self.PARAMS, values)})

    # -- forward ---------------------------------------------------------------------------------------------
    def local(self, points_mm: np.ndarray) -> np.ndarray:
        """Points (N, 3) in the instrument frame."""
        return (np.asarray(points_mm, float) - self.position) @ self.rotation

    def observe(self, points_mm: np.ndarray, face: int | np.ndarray = 1, with_jacobian: bool = False):
        """Readings ``(Hz, V)`` in radians (Hz in [0, 2 pi)) of points (N, 3); optionally d(Hz, V)/d(point) (N, 2, 3).

        A point at the station's centre or straight above it has no horizontal direction: GeometryError.
        """
        if not with_jacobian and isinstance(points_mm, np.ndarray) and points_mm.shape == (1, 3) \
                and np.ndim(face) == 0:
            return self._observe_one(points_mm[0].tolist(), face == 2)
        d = self.local(points_mm)
        dx, dy, dz = d[..., 0], d[..., 1], d[..., 2]
        rho2 = dx * dx + dy * dy
        rho = np.sqrt(rho2)
        if np.any(rho < 1e-9):
            i = int(np.flatnonzero(rho < 1e-9)[0])
            raise GeometryError(f"station {self.name}: point {i} is at the station or on its vertical axis; "
                                f"no horizontal direction")
        hz, v = _readings_local(d, self.collimation_rad, self.trunnion_rad, self.index_rad, face)
        if not with_jacobian:
            return hz, v
        v0 = np.arctan2(rho, dz)
        sv = np.sin(v0)
        face2 = np.asarray(face) == 2
        r2 = rho2 + dz * dz
        # filled in place: np.stack per component cost more than the arithmetic on the one-point arrays of the
        # session's checks and the emulators (same values)
        dhz_dd = np.zeros(d.shape)
        dhz_dd[..., 0], dhz_dd[..., 1] = dy / rho2, -dx / rho2
        dv_dd = np.empty(d.shape)
        rr2 = rho * r2
        dv_dd[..., 0], dv_dd[..., 1], dv_dd[..., 2] = dz * dx / rr2, dz * dy / rr2, -rho / r2
        dcorr_dv = -(self.collimation_rad * np.cos(v0) + self.trunnion_rad) / (sv * sv)
        sgn = np.where(face2, -1.0, 1.0)
        dhz = dhz_dd + (sgn * dcorr_dv)[..., None] * dv_dd
        dv = np.where(face2[..., None], -dv_dd, dv_dd)
        Rt = self.rotation.T          # d(local)/d(point) = R^T
        J = np.empty(d.shape[:-1] + (2, 3))
        J[..., 0, :], J[..., 1, :] = dhz @ Rt, dv @ Rt
        return hz, v, J

    def _observe_one(self, p: list[float], face2: bool) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`observe` of one point (a (1, 3) array) in plain floats, the same operations in the same order (the
        emulated theodolites read one target at a time, and numpy's calls on one-point arrays cost more than their
        arithmetic): bit for bit the vectorised readings (a test holds them equal)."""
        _, pos, R, c, t, idx = self._plain
        e = (p[0] - pos[0], p[1] - pos[1], p[2] - pos[2])
        dx, dy, dz = (e[0] * R[0][j] + e[1] * R[1][j] + e[2] * R[2][j] for j in range(3))
        if math.sqrt(dx * dx + dy * dy) < 1e-9:
            raise GeometryError(f"station {self.name}: point 0 is at the station or on its vertical axis; "
                                f"no horizontal direction")
        hz0 = math.atan2(-dy, dx)
        v0 = math.atan2(float(np.hypot(dx, dy)), dz)        # numpy's hypot: math.hypot rounds differently
        sv = math.sin(v0)
        corr = c / sv + t * math.cos(v0) / sv
        hz = (hz0 + math.pi - corr if face2 else hz0 + corr) % TWO_PI
        return np.array([hz]), np.array([(TWO_PI - v0 if face2 else v0) + idx])

    def direction(self, hz_rad, v_rad, face: int | np.ndarray = 1) -> np.ndarray:
        """World unit vectors (N, 3) of sight lines from readings, with the instrument errors removed."""
        hz = np.asarray(hz_rad, float)
        v = np.asarray(v_rad, float) - self.index_rad
        face2 = np.asarray(face) == 2
        v0 = np.where(face2, TWO_PI - v, v)
        sv = np.sin(v0)
        corr = self.collimation_rad / sv + self.trunnion_rad * np.cos(v0) / sv
        hz0 = np.where(face2, hz - np.pi + corr, hz - corr)
        d = np.stack([np.sin(v0) * np.cos(hz0), -np.sin(v0) * np.sin(hz0), np.cos(v0)], -1)
        return d @ self.rotation.T


def face_mean(hz: np.ndarray, v: np.ndarray, face: np.ndarray) -> tuple[float, float]:
    """Face-I-equivalent mean of readings (face II reduced: Hz - 180 deg, 360 deg - V): removes c, i and k.

    Fewer than :data:`PLAIN_MEAN_BELOW` readings (a target read in both faces, or both faces twice: every session
    check and reduction asks for it) in plain floats, the same operations as numpy's below -- the same floats (a test
    holds them equal)."""
    if len(hz) < PLAIN_MEAN_BELOW:
        return _face_mean_few([float(x) for x in hz], [float(x) for x in v], [float(f) == 2 for f in face])
    hz, v, face = (np.asarray(a, float) for a in (hz, v, face))
    hz1 = np.where(face == 2, hz - np.pi, hz)
    v1 = np.where(face == 2, 2 * np.pi - v, v)
    ref = hz1[0]
    return float(np.mod(ref + np.mean(wrap_angle(hz1 - ref)), 2 * np.pi)), float(np.mean(v1))


#: numpy's mean adds fewer than 8 values one after the other (its pairwise summation starts at 8), so a plain
#: float sum in the same order is its very float below that
PLAIN_MEAN_BELOW = 8


def _face_mean_few(hz: list[float], v: list[float], face2: list[bool]) -> tuple[float, float]:
    """:func:`face_mean` of fewer than :data:`PLAIN_MEAN_BELOW` readings: the sum in order, divided by the count, as
    numpy's mean; the wrap is ``atan2(sin, cos)``, as :func:`calib.angles.wrap_angle`'s complex exponential."""
    hz1 = [h - math.pi if f else h for h, f in zip(hz, face2)]
    v1 = [2 * math.pi - x if f else x for x, f in zip(v, face2)]
    ref = hz1[0]
    d = [wrap_float(h - ref) for h in hz1]
    n = len(d)
    return (ref + sum(d[1:], d[0]) / n) % TWO_PI, sum(v1[1:], v1[0]) / n


@dataclass
class Intersection:
    """Points from sightings, with their 3x3 covariances and the geometry checks an operator needs."""

    point_mm: np.ndarray          # (N, 3)
    cov_mm2: np.ndarray           # (N, 3, 3)
    miss_mm: np.ndarray           # (N,) shortest distance between the first two sight lines
    angle_rad: np.ndarray         # (N,) intersection angle of the first two sight lines
    residual_rad: np.ndarray      # (N, 2k) reading residuals at the solution

    @property
    def sigma_mm(self) -> np.ndarray:
        return np.sqrt(np.diagonal(self.cov_mm2, axis1=-2, axis2=-1))


def closest_point(c1, u1, c2, u2, names=("A", "B"), min_angle_rad: float = 1e-4):
    """Midpoint of the common perpendicular of two sight lines (vectorised), its miss distance and the angle.

    Raises GeometryError for (nearly) parallel sight lines or a point behind a station.
    """
    w = c1 - c2
    b = np.sum(u1 * u2, -1)
    d = np.sum(u1 * w, -1)
    e = np.sum(u2 * w, -1)
    denom = 1.0 - b * b
    angle = np.arccos(np.clip(np.abs(b), 0.0, 1.0))
    bad = angle < min_angle_rad
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise GeometryError(f"sight lines from {names[0]} and {names[1]} are parallel for point {i} "
                            f"(intersection angle {np.degrees(angle[i]):.4f} deg); the point cannot be located")
    t1 = (b * e - d) / denom
    t2 = (e - b * d) / denom
    for t, nm in ((t1, names[0]), (t2, names[1])):
        if np.any(t <= 0):
            i = int(np.flatnonzero(t <= 0)[0])
            raise GeometryError(f"point {i} would lie behind station {nm} (range {t[i]:.1f} mm along its sight line)")
    p1 = c1 + t1[:, None] * u1
    p2 = c2 + t2[:, None] * u2
    return 0.5 * (p1 + p2), np.linalg.norm(p1 - p2, axis=-1), angle


#: :func:`intersect`'s default stopping rule: the largest step below this (mm), i.e. until the step is rounding.  The
#: reduction relies on it (its points are the fit's to the last bits).
STEP_TOL_MM = 1e-10


def intersect(stations: list[Station], readings: list[tuple], faces: list | None = None,
              iterations: int = 8, step_tol_mm: float = STEP_TOL_MM) -> Intersection:
    """Least-squares intersection of sightings of N points from k >= 2 stations.

    ``readings[s] = (hz_rad (N,), v_rad (N,))`` from station s.  Starts from the closest point of the first two sight
    lines and refines by Gauss-Newton on the readings weighted by each station's angular noise, so the covariance
    ``(J^T W J)^-1`` is the first-order covariance of the point from the reading noise.  The refinement stops once
    every point's step is below ``step_tol_mm`` (the default: rounding; a caller that only compares the point with
    millimetre limits may stop earlier, see :data:`STEP_TOL_MM`).
    """
    if len(stations) < 2:
        raise GeometryError("an intersection needs sightings from at least two stations")
    faces = faces or [1] * len(stations)
    hz = [np.atleast_1d(np.asarray(r[0], float)) for r in readings]
    vv = [np.atleast_1d(np.asarray(r[1], float)) for r in readings]
    if len(hz[0]) * len(stations) <= SMALL_SIGHTINGS:
        small = _intersect_few(stations, faces, hz, vv, iterations, step_tol_mm)
        if small is not None:
            return small
    dirs = [s.direction(h, v, f) for s, (h, v), f in zip(stations, zip(hz, vv), faces)]
    p, miss, angle = closest_point(stations[0].position, dirs[0], stations[1].position, dirs[1],
                                   (stations[0].name, stations[1].name))
    w = np.concatenate([[1 / s.sigma_hz_rad ** 2, 1 / s.sigma_v_rad ** 2] for s in stations])
    converged = False
    for _ in range(iterations):
        res, J = _residuals(stations, faces, hz, vv, p)
        JW = J * w[None, :, None]
        A = np.einsum("nki,nkj->nij", JW, J)
        g = np.einsum("nki,nk->ni", JW, res)
        step = np.linalg.solve(A, g[..., None])[..., 0]
        p = p + step
        if np.max(np.abs(step)) < step_tol_mm:
            converged = True
            break
    if converged:
        # a step below 1e-10 mm (the default tolerance) moves neither the residuals (< 1e-13 rad) nor J: the last
        # evaluation serves, less the step's first-order change of the residuals
        res = res - np.einsum("nki,ni->nk", J, step)
    else:
        res, J = _residuals(stations, faces, hz, vv, p)
        A = np.einsum("nki,nkj->nij", J * w[None, :, None], J)
    cov = np.linalg.inv(A)
    return Intersection(point_mm=p, cov_mm2=cov, miss_mm=miss, angle_rad=angle, residual_rad=-res)


#: at most this many sightings (points x stations) go through :func:`_intersect_few` (plain floats)
SMALL_SIGHTINGS = 12


def _intersect_few(stations, faces, hz, vv, iterations, step_tol_mm=STEP_TOL_MM) -> Intersection | None:
    """:func:`intersect` for a few points, in plain floats; None leaves it to the vectorised code (readings that are
    not finite, a singular normal matrix: its errors are the ones raised).

    Why: the session checks every step's one or two targets as it is recorded; on one-point arrays the numpy calls
    of :meth:`Station.direction`, :func:`closest_point` and :meth:`Station.observe` cost far more than their
    arithmetic.  The same model and derivatives, the same start (the closest point of the first two sight lines, with
    the same refusals), weights, iterations and stopping rule (every point steps until the largest step is below
    ``step_tol_mm``): equal to the vectorised code's to rounding (a test holds them together)."""
    n, k = len(hz[0]), len(stations)
    obs = [(s._plain, np.broadcast_to(np.asarray(f), (n,)).tolist(), h.tolist(), v.tolist(),
            1.0 / s.sigma_hz_rad ** 2, 1.0 / s.sigma_v_rad ** 2) for s, f, h, v in zip(stations, faces, hz, vv)]
    if not all(math.isfinite(x) for o in obs for x in o[2] + o[3]):
        return None
    try:
        pts, miss, angle = _closest_few(obs[0], obs[1], n)
        pts, res, A = _refine_few(obs, pts, iterations, step_tol_mm)
    except ZeroDivisionError:
        return None
    return Intersection(point_mm=np.array(pts), cov_mm2=np.linalg.inv(np.array(A)), miss_mm=np.array(miss),
                        angle_rad=np.array(angle), residual_rad=-np.array(res).reshape(n, 2 * k))


def _direction_one(plain, face2: bool, hz: float, v: float) -> list[float]:
    """:meth:`Station.direction` of one reading in plain floats."""
    _, _, R, c, t, idx = plain
    v = v - idx
    v0 = TWO_PI - v if face2 else v
    sv = math.sin(v0)
    corr = c / sv + t * math.cos(v0) / sv
    hz0 = hz - math.pi + corr if face2 else hz - corr
    d = (sv * math.cos(hz0), -sv * math.sin(hz0), math.cos(v0))
    return [d[0] * Ri[0] + d[1] * Ri[1] + d[2] * Ri[2] for Ri in R]


def _closest_few(o1, o2, n: int):
    """:func:`closest_point` of the first two stations' sight lines for ``n`` points in plain floats (the same
    refusals, in the same order): (points, miss distances, angles)."""
    (name1, c1, *_), (name2, c2, *_) = o1[0], o2[0]
    w = [a - b for a, b in zip(c1, c2)]
    lines = []
    for i in range(n):
        u1 = _direction_one(o1[0], o1[1][i] == 2, o1[2][i], o1[3][i])
        u2 = _direction_one(o2[0], o2[1][i] == 2, o2[2][i], o2[3][i])
        b = u1[0] * u2[0] + u1[1] * u2[1] + u1[2] * u2[2]
        lines.append((u1, u2, b, math.acos(min(max(abs(b), 0.0), 1.0))))
    for i, (_, _, _, angle) in enumerate(lines):
        if angle < 1e-4:
            raise GeometryError(f"sight lines from {name1} and {name2} are parallel for point {i} "
                                f"(intersection angle {math.degrees(angle):.4f} deg); the point cannot be located")
    ts = []
    for u1, u2, b, _ in lines:
        d = u1[0] * w[0] + u1[1] * w[1] + u1[2] * w[2]
        e = u2[0] * w[0] + u2[1] * w[1] + u2[2] * w[2]
        denom = 1.0 - b * b
        ts.append(((b * e - d) / denom, (e - b * d) / denom))
    for col, nm in ((0, name1), (1, name2)):
        for i, t in enumerate(ts):
            if t[col] <= 0:
                raise GeometryError(f"point {i} would lie behind station {nm} (range {t[col]:.1f} mm along its "
                                    f"sight line)")
    pts, miss = [], []
    for (u1, u2, _, _), (t1, t2) in zip(lines, ts):
        p1 = [c + t1 * u for c, u in zip(c1, u1)]
        p2 = [c + t2 * u for c, u in zip(c2, u2)]
        pts.append([0.5 * (a + b) for a, b in zip(p1, p2)])
        miss.append(math.sqrt(sum((a - b) ** 2 for a, b in zip(p1, p2))))
    return pts, miss, [line[3] for line in lines]


def _refine_few(obs, pts, iterations, step_tol_mm=STEP_TOL_MM):
    """The Gauss-Newton loop of :func:`intersect` in plain floats from the start points ``pts``: (points, residuals,
    normal matrices J^T W J) per point."""
    n = len(pts)
    converged = False
    for _ in range(iterations):
        rows = [_normal_equations(obs, i, pts[i]) for i in range(n)]
        steps = [_solve3(A, g) for _, _, A, g in rows]
        pts = [[x + dx for x, dx in zip(pt, st)] for pt, st in zip(pts, steps)]
        if max(abs(d) for st in steps for d in st) < step_tol_mm:
            converged = True
            break
    if converged:       # as the vectorised loop: the last residuals less the step's first-order change
        res = [[r - sum(jc * dc for jc, dc in zip(jr, st)) for r, jr in zip(rs, J)]
               for (rs, J, _, _), st in zip(rows, steps)]
    else:
        rows = [_normal_equations(obs, i, pts[i]) for i in range(n)]
        res = [rs for rs, _, _, _ in rows]
    return pts, res, [A for _, _, A, _ in rows]


def _normal_equations(obs, i, p):
    """Point ``i`` at ``p``: its residuals (2k,), Jacobian rows (2k, 3), J^T W J (3, 3) and J^T W r (3,)."""
    res, J = [], []
    A = [[0.0] * 3 for _ in range(3)]
    g = [0.0] * 3
    for (name, pos, R, c, t, idx), faces, hz, vv, w_hz, w_v in obs:
        ch, cv, jh, jv = _observe_one(name, pos, R, c, t, idx, faces[i] == 2, p, i)
        for r, row, w in ((wrap_float(hz[i] - ch), jh, w_hz), (vv[i] - cv, jv, w_v)):
            res.append(r)
            J.append(row)
            for a in range(3):
                wa = w * row[a]
                g[a] += wa * r
                for b in range(3):
                    A[a][b] += wa * row[b]
    return res, J, A, g


def _observe_one(name, pos, R, c, t, idx, face2, p, i):
    """:meth:`Station.observe` with its Jacobian for one point in plain floats: (Hz, V, dHz/dp, dV/dp)."""
    e = [p[0] - pos[0], p[1] - pos[1], p[2] - pos[2]]
    dx, dy, dz = (e[0] * R[0][j] + e[1] * R[1][j] + e[2] * R[2][j] for j in range(3))
    rho2 = dx * dx + dy * dy
    rho = math.sqrt(rho2)
    if rho < 1e-9:
        raise GeometryError(f"station {name}: point {i} is at the station or on its vertical axis; "
                            f"no horizontal direction")
    hz0 = math.atan2(-dy, dx)
    v0 = math.atan2(math.hypot(dx, dy), dz)
    sv, cv0 = math.sin(v0), math.cos(v0)
    corr = c / sv + t * cv0 / sv
    hz = (hz0 + math.pi - corr if face2 else hz0 + corr) % TWO_PI
    v = (TWO_PI - v0 if face2 else v0) + idx
    r2 = rho2 + dz * dz
    rr2 = rho * r2
    dv_dd = (dz * dx / rr2, dz * dy / rr2, -rho / r2)
    k = (-1.0 if face2 else 1.0) * (-(c * cv0 + t) / (sv * sv))
    dhz = (dy / rho2 + k * dv_dd[0], -dx / rho2 + k * dv_dd[1], k * dv_dd[2])
    dv = tuple(-x for x in dv_dd) if face2 else dv_dd
    return (hz, v, [dhz[0] * Ri[0] + dhz[1] * Ri[1] + dhz[2] * Ri[2] for Ri in R],
            [dv[0] * Ri[0] + dv[1] * Ri[1] + dv[2] * Ri[2] for Ri in R])


def _solve3(A, g):
    """``A x = g`` for a 3 x 3 ``A`` by Gaussian elimination with partial pivoting (ZeroDivisionError: singular)."""
    M = [list(A[r]) + [g[r]] for r in range(3)]
    for col in range(3):
        piv = max(range(col, 3), key=lambda r: abs(M[r][col]))
        M[col], M[piv] = M[piv], M[col]
        for r in range(col + 1, 3):
            f = M[r][col] / M[col][col]
            for c in range(col, 4):
                M[r][c] -= f * M[col][c]
    x = [0.0] * 3
    for r in (2, 1, 0):
        x[r] = (M[r][3] - sum(M[r][c] * x[c] for c in range(r + 1, 3))) / M[r][r]
    return x


def _residuals(stations, faces, hz, vv, p):
    """Observed minus computed readings (N, 2k) and d(computed)/d(point) (N, 2k, 3)."""
    rs, Js = [], []
    for s, f, h, v in zip(stations, faces, hz, vv):
        ch, cv, J = s.observe(p, f, with_jacobian=True)
        rs += [wrap_angle(h - ch), v - cv]
        Js.append(J)
    return np.stack(rs, -1), np.concatenate(Js, axis=-2)


# -- the thesis's parameterisation -----------------------------------------------------------------------------------
def thesis_stations(L_mm: float, gamma1_rad: float, gamma2_rad: float, sigma_rad: float = 3 * ARCSEC,
                    height_b_mm: float = 0.0) -> tuple[Station, Station]:
    """Stations A (origin) and B (L, 0, h) whose circle zeros give the thesis's offsets gamma1, gamma2.

    With clockwise circles, the thesis's interior-angle readings are ``alpha' = -Hz_A`` and ``beta' = Hz_B`` (mod 360
    deg); that holds when A's circle zero points at yaw -gamma1 and B's at pi + gamma2.
    """
    a = Station("A", 0.0, 0.0, 0.0, yaw_rad=-gamma1_rad, sigma_hz_rad=sigma_rad, sigma_v_rad=sigma_rad)
    b = Station("B", L_mm, 0.0, height_b_mm, yaw_rad=np.pi + gamma2_rad, sigma_hz_rad=sigma_rad,
                sigma_v_rad=sigma_rad)
    return a, b


def thesis_readings(a: Station, b: Station, points_mm: np.ndarray):
    """The thesis's raw readings alpha', beta' (circle readings at A, B) and phi (A's elevation), radians."""
    hz_a, v_a = a.observe(points_mm)
    hz_b, _ = b.observe(points_mm)
    return wrap_angle(-hz_a), wrap_angle(hz_b), np.pi / 2 - v_a


def thesis_point(alpha_p, beta_p, phi, L_mm, gamma1_rad, gamma2_rad) -> np.ndarray:
    """Eq 4.3.1: X = L tan(beta)/(tan(alpha) + tan(beta)), Y = X tan(alpha), Z = sqrt(X^2 + Y^2) tan(phi).

    ``alpha = alpha' - gamma1``, ``beta = beta' - gamma2``.  Raises GeometryError when the sight lines do not meet in
    front of both stations (parallel lines, or interior angles that do not form a triangle).
    """
    al = np.asarray(alpha_p, float) - gamma1_rad
    be = np.asarray(beta_p, float) - gamma2_rad
    s = np.sin(al + be)
    bad = (al <= 0) | (be <= 0) | (al + be >= np.pi) | (np.abs(s) < 1e-6)
    if np.any(bad):
        i = int(np.flatnonzero(np.atleast_1d(bad))[0])
        a_i, b_i = np.degrees(np.atleast_1d(al)[i]), np.degrees(np.atleast_1d(be)[i])
        raise GeometryError(f"sightings of point {i} do not intersect in front of both stations "
                            f"(alpha {a_i:.4f} deg, beta {b_i:.4f} deg)")
    return thesis_xyz(al, be, phi, L_mm)


def thesis_xyz(alpha_rad, beta_rad, phi_rad, L_mm) -> np.ndarray:
    """Eq 4.3.1 itself, unchecked and vectorised (the one copy): interior angles alpha, beta, A's elevation phi and
    the baseline L -> ``(..., 3)`` mm.  The sine form: identical to ``L tan b / (tan a + tan b)``, finite at 90 deg."""
    al, be = np.asarray(alpha_rad, float), np.asarray(beta_rad, float)
    s = np.sin(al + be)
    X = L_mm * np.sin(be) * np.cos(al) / s
    Y = L_mm * np.sin(be) * np.sin(al) / s
    Z = np.hypot(X, Y) * np.tan(phi_rad)
    return np.stack([X, Y, Z], -1)
