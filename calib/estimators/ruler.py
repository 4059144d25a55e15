"""Theodolite pre-calibration with a ruler (thesis section 4.2, App A.1, B.1-B.2): L, gamma1, gamma2.

Three marks C, D, E on a ruler (CD = r1, DE = r2, CE = R) are sighted from both theodolites.  Reading conventions
(the ones :mod:`calib.theodolite` fixes): ``alpha' = -Hz_A`` and ``beta' = Hz_B`` (wrapped), the interior angles being
``alpha = alpha' - gamma1`` (counter-clockwise at A from the baseline A->B) and ``beta = beta' - gamma2`` (clockwise at
B from B->A).  With C the mark nearest A's side, alpha' decreases and beta' increases from C to E, so the subtended
angles are ``alpha1 = a'_C - a'_D``, ``alpha2 = a'_D - a'_E`` (eq 4.2.4) and ``beta1 = b'_D - b'_C``,
``beta2 = b'_E - b'_D`` -- the thesis's eq 4.2.4 writes ``beta1 = beta1' - beta2'``, which is negative in this
convention (its B circle must count the other way).

Closed form (A.1, re-derived): in triangle ACE the angle at C is ``theta1`` with
``tan theta1 = sin(a1+a2) / (r1 sin a2 / (r2 sin a1) - cos(a1+a2))`` -- the printed eq 4.2.2/A.1.3 has
``r1 sin a1 / (r2 sin a2)``, which does not follow from its own A.1.1-A.1.2 (sine rule in ACD and ADE); the angle at E
is ``phi1 = 180 - a1 - a2 - theta1`` and ``AC = R sin phi1 / sin(a1+a2)`` (eq 4.2.3).  Same at B.  Placing C at the
origin of a ruler frame with E on +x, ``L = |A - B|`` (eq 4.2.1) and the offsets follow from the bearing of a mark
seen from each station: ``gamma1 = a'_C - angle(BAC)``, ``gamma2 = b'_D - angle(ABD)`` (the thesis's A.1.6-A.1.7 with
their sign slips removed: the thesis defines alpha = alpha' - gamma1, so gamma1 = alpha' - alpha).

Least-squares form (:func:`ruler_lsq`): every sighting (several ruler placements, both faces, horizontal and vertical
angles) enters one weighted fit of L, gamma1, gamma2, B's height, and per placement the ruler pose; with both faces
the collimation and index errors of each instrument are fitted too.  Its covariance is ``(J^T W J)^-1`` plus the
ruler-length uncertainty propagated through the fit.

Units: mm and radians.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..angles import wrap_angle
from ..theodolite import observe_params, thesis_point, thesis_stations
from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, angles_in_range, at_least, finite
from ._lsq import gauss_newton

PROC = "ruler"
CLOSED_NAMES = ["L_mm", "gamma1_rad", "gamma2_rad"]
CLOSED_UNITS = ["mm", "rad", "rad"]




def _arg(w):
    return np.arctan2(w[..., 1], w[..., 0])


def _cross(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


# -- closed form -----------------------------------------------------------------------------------------------
def closed_form(x: np.ndarray) -> np.ndarray:
    """Vectorised closed form: ``x (..., 8) = [a'_C, a'_D, a'_E, b'_C, b'_D, b'_E, R, r1]`` -> ``(..., 3)``
    ``[L_mm, gamma1_rad, gamma2_rad]``.  NaN where the marks do not form triangles (use :func:`ruler_closed_form`
    for checked input)."""
    x = np.asarray(x, float)
    aC, aD, aE, bC, bD, bE, R, r1 = np.moveaxis(x, -1, 0)
    r2 = R - r1
    a1, a2 = wrap_angle(aC - aD), wrap_angle(aD - aE)
    b1, b2 = wrap_angle(bD - bC), wrap_angle(bE - bD)
    A, B = a1 + a2, b1 + b2
    th1 = np.arctan2(np.sin(A), r1 * np.sin(a2) / (r2 * np.sin(a1)) - np.cos(A))
    th2 = np.arctan2(np.sin(B), r1 * np.sin(b2) / (r2 * np.sin(b1)) - np.cos(B))
    AC = R * np.sin(np.pi - A - th1) / np.sin(A)
    BC = R * np.sin(np.pi - B - th2) / np.sin(B)
    pa = np.stack([AC * np.cos(th1), -AC * np.sin(th1)], -1)      # A in the ruler frame (C origin, E on +x)
    pb = np.stack([BC * np.cos(th2), -BC * np.sin(th2)], -1)
    pd = np.stack([r1, np.zeros_like(r1)], -1)
    L = np.linalg.norm(pa - pb, axis=-1)
    ang_A = _arg(-pa) - _arg(pb - pa)                               # ccw at A from A->B to A->C
    ang_B = _arg(pa - pb) - _arg(pd - pb)                           # cw at B from B->A to B->D
    return np.stack([L, wrap_angle(aC - wrap_angle(ang_A)), wrap_angle(bD - wrap_angle(ang_B))], -1)


def closed_form_first_order(x: np.ndarray) -> np.ndarray:
    """Analytic first-order Jacobian ``d[L, gamma1, gamma2]/d x`` (3, 8) of :func:`closed_form`.

    This follows the structure of the thesis's App B.1-B.2 (L through theta1, theta2, phi1, phi2, AC, BC; the gammas
    through the triangle ABC / ABD) but with the partial derivatives re-derived: several printed ones are wrong
    (e.g. ``d theta1/d alpha1 = -2 cos^2 theta1 / s1`` cannot hold -- the correct one is
    ``cos^2 theta1 (cos A k - 1 + sin A k cot a1 ... ) / s1^2``, below -- and B.2's epsilons drop the dependence of
    ``theta2 - theta1`` on the angles).  Each step is a small explicit Jacobian; their product is the total.
    """
    x = np.asarray(x, float)
    aC, aD, aE, bC, bD, bE, R, r1 = x
    r2 = R - r1
    a1, a2, b1, b2 = wrap_angle(aC - aD), wrap_angle(aD - aE), wrap_angle(bD - bC), wrap_angle(bE - bD)
    # step 0: intermediate variables v = [a1, a2, b1, b2, R, r1] from the inputs
    M0 = np.zeros((6, 8))
    M0[0, [0, 1]] = [1, -1]
    M0[1, [1, 2]] = [1, -1]
    M0[2, [3, 4]] = [-1, 1]
    M0[3, [4, 5]] = [-1, 1]
    M0[4, 6] = 1
    M0[5, 7] = 1

    def station(s1, s2):
        """theta (angle at C), AC and their gradients w.r.t. (s1, s2, R, r1)."""
        S = s1 + s2
        k = r1 * np.sin(s2) / (r2 * np.sin(s1))
        den = k - np.cos(S)
        th = np.arctan2(np.sin(S), den)
        c2 = np.cos(th) ** 2
        # t = sin S / den; dt/dS (k fixed) = (cos S den - sin^2 S)/den^2 = (k cos S - 1)/den^2; dt/dk = -sin S/den^2
        dt_dS = (k * np.cos(S) - 1) / den ** 2
        dt_dk = -np.sin(S) / den ** 2
        dk = np.array([-k / np.tan(s1), k / np.tan(s2), -k / r2, k / r1 + k / r2])   # d k/d(s1, s2, R, r1)
        dth = c2 * (dt_dS * np.array([1, 1, 0, 0]) + dt_dk * dk)
        phi = np.pi - S - th
        AC = R * np.sin(phi) / np.sin(S)
        dphi = -np.array([1, 1, 0, 0]) - dth
        dAC = (R * np.cos(phi) / np.sin(S)) * dphi \
            - (R * np.sin(phi) * np.cos(S) / np.sin(S) ** 2) * np.array([1, 1, 0, 0]) \
            + np.sin(phi) / np.sin(S) * np.array([0, 0, 1, 0])
        pos = np.array([AC * np.cos(th), -AC * np.sin(th)])
        dpos = np.outer([np.cos(th), -np.sin(th)], dAC) + AC * np.outer([-np.sin(th), -np.cos(th)], dth)
        return pos, dpos

    pa, dpa4 = station(a1, a2)
    pb, dpb4 = station(b1, b2)
    # embed the (s1, s2, R, r1) gradients into v = [a1, a2, b1, b2, R, r1]
    dpa = np.zeros((2, 6))
    dpa[:, [0, 1, 4, 5]] = dpa4
    dpb = np.zeros((2, 6))
    dpb[:, [2, 3, 4, 5]] = dpb4
    pd = np.array([r1, 0.0])
    dpd = np.zeros((2, 6))
    dpd[0, 5] = 1.0
    d = pa - pb
    L = np.linalg.norm(d)
    dL = d @ (dpa - dpb) / L

    def darg(w, dw):
        return (w[0] * dw[1] - w[1] * dw[0]) / (w @ w)

    dangA = darg(-pa, -dpa) - darg(pb - pa, dpb - dpa)
    dangB = darg(pa - pb, dpa - dpb) - darg(pd - pb, dpd - dpb)
    Jv = np.stack([dL, -dangA, -dangB])            # (3, 6) w.r.t. v
    J = Jv @ M0
    J[1, 0] += 1.0                                 # gamma1 = a'_C - angle
    J[2, 4] += 1.0                                 # gamma2 = b'_D - angle
    return J


def thesis_linear_sum(x: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """The thesis's error figure (eqs 5.2.2, B.1.4): the sum of the first-order terms ``sum |dF/dx_i| dx_i`` for
    resolutions ``delta (8,)`` (3 arc seconds for each reading, the ruler's marking accuracy for R, r1) -- a worst-case
    bound, not a standard deviation."""
    return np.abs(closed_form_first_order(x)) @ np.asarray(delta, float)


def _check_closed(x):
    x = np.asarray(x, float)
    if x.shape != (8,):
        raise EstimationError(PROC, "closed form", f"needs 6 azimuth readings and R, r1 (8 values), got {x.size}")
    angles_in_range(PROC, "closed form", readings=x[:6])
    finite(PROC, "closed form", R=x[6], r1=x[7])
    R, r1 = x[6], x[7]
    if not (0 < r1 < R):
        raise EstimationError(PROC, "closed form", f"ruler marks must satisfy 0 < r1 < R (got r1 {r1}, R {R} mm)")
    a1, a2 = wrap_angle(x[0] - x[1]), wrap_angle(x[1] - x[2])
    b1, b2 = wrap_angle(x[4] - x[3]), wrap_angle(x[5] - x[4])
    for nm, v in (("alpha1 (C-D at A)", a1), ("alpha2 (D-E at A)", a2), ("beta1 (C-D at B)", b1),
                  ("beta2 (D-E at B)", b2)):
        if not (1e-5 < v < np.pi - 1e-5):
            raise EstimationError(PROC, "closed form", f"subtended angle {nm} = {np.degrees(v):.5f} deg: marks "
                                  "coincide, are out of order (C must be the mark nearest A) or are collinear "
                                  "with the station")


def ruler_closed_form(readings_rad, R_mm: float, r1_mm: float, sigma_reading_rad: float, sigma_R_mm: float = 0.0,
                      sigma_r1_mm: float = 0.0, n_mc: int = 20_000, rng=0) -> EstimateSet:
    """L, gamma1, gamma2 from one ruler placement by the thesis's closed form, with errors three ways.

    ``readings_rad = [a'_C, a'_D, a'_E, b'_C, b'_D, b'_E]`` (see the module docstring for the convention),
    ``sigma_reading_rad`` the 1-sigma reading noise (3 arc seconds for the Sokkisha TM-20C), ruler length
    uncertainties ``sigma_R_mm``, ``sigma_r1_mm`` (independent).
    """
    x = np.concatenate([np.asarray(readings_rad, float).ravel(), [R_mm, r1_mm]])
    _check_closed(x)
    cov = np.diag([sigma_reading_rad ** 2] * 6 + [sigma_R_mm ** 2, sigma_r1_mm ** 2])
    J1 = closed_form_first_order(x)
    res = propagate(closed_form, x, cov, CLOSED_NAMES, CLOSED_UNITS, n_mc=n_mc, rng=rng,
                    first_order_cov=J1 @ cov @ J1.T)
    res.extras["jacobian_first_order"] = J1
    return res


# -- least squares over every sighting ------------------------------------------------------------------------
@dataclass
class RulerSightings:
    """Raw sightings of ruler marks: one row per (placement, mark, station, face).

    ``hz_rad``, ``v_rad`` are the instrument readings (Hz clockwise, V zenith, see :mod:`calib.theodolite`);
    ``station`` 0 = A, 1 = B; ``mark`` indexes ``marks_mm`` (distance of the mark from C along the ruler).
    """

    placement: np.ndarray
    mark: np.ndarray
    station: np.ndarray
    face: np.ndarray
    hz_rad: np.ndarray
    v_rad: np.ndarray

    def __post_init__(self):
        for k in ("placement", "mark", "station", "face"):
            setattr(self, k, np.asarray(getattr(self, k), int).ravel())
        self.hz_rad = np.asarray(self.hz_rad, float).ravel()
        self.v_rad = np.asarray(self.v_rad, float).ravel()

    @property
    def n(self) -> int:
        return self.hz_rad.size


class _RulerModel:
    """Forward model of every reading from the parameter vector; vectorised over leading dimensions."""

    def __init__(self, s: RulerSightings, n_marks: int, faces_both: bool, fixed: np.ndarray | None = None):
        self.s = s
        #: (2, 9) parameters of stations A, B (Station.PARAMS) not fitted here: tilts and trunnion tilt
        self.fixed = np.zeros((2, 9)) if fixed is None else np.asarray(fixed, float)
        self.nplace = int(s.placement.max()) + 1
        self.instr = faces_both
        self.n_global = 4 + (4 if faces_both else 0)
        self.P = self.n_global + 5 * self.nplace
        self.n_marks = n_marks
        names = ["L_mm", "gamma1_rad", "gamma2_rad", "hB_mm"]
        if faces_both:
            names += ["collimA_rad", "collimB_rad", "indexA_rad", "indexB_rad"]
        for k in range(self.nplace):
            names += [f"p{k}.x_mm", f"p{k}.y_mm", f"p{k}.z_mm", f"p{k}.azimuth_rad", f"p{k}.tilt_rad"]
        self.names = names
        self.steps = np.array([1e-4 if n.endswith("_mm") else 1e-8 for n in names])

    def readings(self, p: np.ndarray, marks: np.ndarray) -> np.ndarray:
        """Predicted [Hz..., V...] (..., 2n) for parameters p (..., P) and mark distances (..., n_marks)."""
        s = self.s
        pl = p[..., self.n_global:].reshape(p.shape[:-1] + (self.nplace, 5))
        dist = marks[..., s.mark] if marks.ndim > 1 else marks[s.mark]
        hz, v = self._observe([p[..., i, None] for i in range(self.n_global)], pl[..., s.placement, :], dist,
                              s.station, s.face)
        return np.concatenate([hz, v], -1)

    def _observe(self, glob: list, pl: np.ndarray, dist: np.ndarray, station: np.ndarray, face: np.ndarray):
        """(Hz, V) of sightings from their global parameters ``glob`` (each broadcast against the sightings),
        placement poses ``pl (..., 5)``, mark distances, stations and faces: every reading by the same element-wise
        operations, whichever sightings and parameter vectors are asked for together."""
        L, g1, g2, hB = glob[:4]
        if self.instr:
            cA, cB, kA, kB = glob[4:8]
        else:
            cA = cB = kA = kB = np.zeros_like(L)
        az, tl = pl[..., 3], pl[..., 4]
        u = np.stack([np.cos(tl) * np.cos(az), np.cos(tl) * np.sin(az), np.sin(tl)], -1)
        pt = pl[..., :3] + dist[..., None] * u
        isB = station == 1
        # the stations' parameters per sighting (Station.PARAMS order); levelling and trunnion are the set-up's
        par = np.broadcast_to(self.fixed[station], pt.shape[:-1] + (9,)).copy()
        par[..., 0] = np.where(isB, L, 0.0)
        par[..., 2] = np.where(isB, hB, 0.0)
        par[..., 3] = np.where(isB, np.pi + g2, -g1)
        par[..., 6] = np.where(isB, cB, cA)
        par[..., 8] = np.where(isB, kB, kA)
        return observe_params(par, pt, face)

    def residual(self, p, marks, obs):
        marks, obs = _align(marks, p), _align(obs, p)
        pred = self.readings(p, marks)
        n = self.s.n
        return np.concatenate([wrap_angle(obs[..., :n] - pred[..., :n]), obs[..., n:] - pred[..., n:]], -1)

    @cached_property
    def _touched(self) -> tuple[np.ndarray, np.ndarray]:
        """(parameter, sighting) pairs where the sighting's readings depend on the parameter: a station's
        parameters touch that station's sightings, a placement's pose that placement's.  Every other reading is
        computed from the very same floats whichever way the parameter is moved."""
        s = self.s
        of_station = [np.flatnonzero(s.station == k) for k in (0, 1)]
        rows = [of_station[1], of_station[0], of_station[1], of_station[1]]        # L, gamma1, gamma2, hB
        if self.instr:
            rows += [of_station[0], of_station[1], of_station[0], of_station[1]]    # collimation, index: A, B
        for k in range(self.nplace):
            rows += [np.flatnonzero(s.placement == k)] * 5
        cols = np.concatenate([np.full(r.size, j) for j, r in enumerate(rows)])
        return cols, np.concatenate(rows)

    def jacobian(self, p: np.ndarray, marks: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """:func:`calib.uncertainty.jacobian` of :meth:`residual` at one parameter vector ``p (P,)``, to the bit,
        evaluating only the readings a parameter touches (:attr:`_touched`: with both faces and three placements
        9 readings per sighting instead of 23); the others are exactly zero there too (a reading minus itself).
        Why: the session refits the stations after each ruler step, and the dense Jacobian was most of the fit."""
        cols, rows = self._touched
        h = np.broadcast_to(np.asarray(self.steps, float), p.shape)
        k = np.arange(cols.size)
        # the perturbed vectors as jacobian() forms them: x + h e_j and x - h e_j, the other entries +- 0.0
        xp = np.broadcast_to(p + 0.0, (cols.size, p.size)).copy()
        xm = np.broadcast_to(p - 0.0, (cols.size, p.size)).copy()
        xp[k, cols] = p[cols] + h[cols]
        xm[k, cols] = p[cols] - h[cols]
        x = np.concatenate([xp, xm])
        r2 = np.concatenate([rows, rows])
        s = self.s
        pl = x[:, self.n_global:].reshape(x.shape[0], self.nplace, 5)[np.arange(x.shape[0]), s.placement[r2]]
        hz, v = self._observe([x[:, i] for i in range(self.n_global)], pl, marks[s.mark[r2]], s.station[r2],
                              s.face[r2])
        n, m = s.n, cols.size
        dhz = wrap_angle(obs[r2] - hz)
        dv = obs[n + r2] - v
        two_h = 2 * h[cols]
        Jt = np.zeros((p.size, 2 * n))             # jacobian()'s (P, 2n) before its swap of the last two axes
        Jt[cols, rows] = (dhz[:m] - dhz[m:]) / two_h
        Jt[cols, n + rows] = (dv[:m] - dv[m:]) / two_h
        return np.swapaxes(Jt, -1, -2)


def _align(a: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Give a batched input the extra axes a batched parameter array has (inner Jacobian batches)."""
    a = np.asarray(a, float)
    if a.ndim > 1 and p.ndim > a.ndim:
        a = a.reshape(a.shape[:-1] + (1,) * (p.ndim - a.ndim) + a.shape[-1:])
    return a


def _initial_guess(model: _RulerModel, s: RulerSightings, marks: np.ndarray) -> np.ndarray:
    """Start from the closed form on placement 0 (face I, marks 0, mid, last) and the intersected ruler ends."""
    def read(pl, mk, st):
        sel = (s.placement == pl) & (s.mark == mk) & (s.station == st)
        if not np.any(sel):
            raise EstimationError(PROC, "least squares (start)", f"placement {pl}: mark {mk} not sighted from "
                                  f"station {'AB'[st]}")
        h, v, f = s.hz_rad[sel], s.v_rad[sel], s.face[sel]
        h = np.where(f == 2, h - np.pi, h)                    # face II -> face I direction
        v = np.where(f == 2, 2 * np.pi - v, v)
        hz = np.angle(np.mean(np.exp(1j * h)))
        return (wrap_angle(-hz) if st == 0 else wrap_angle(hz)), float(np.mean(v))

    mid = model.n_marks // 2
    last = model.n_marks - 1
    ra = [read(0, m, 0) for m in (0, mid, last)]
    rb = [read(0, m, 1) for m in (0, mid, last)]
    x = np.array([ra[0][0], ra[1][0], ra[2][0], rb[0][0], rb[1][0], rb[2][0], marks[last], marks[mid]])
    L, g1, g2 = closed_form(x)
    if not np.all(np.isfinite([L, g1, g2])):
        raise EstimationError(PROC, "least squares (start)", "the closed form on placement 0 failed: the marks do "
                              "not form a usable triangle with the stations")
    p = [L, g1, g2, 0.0] + ([0.0] * 4 if model.instr else [])
    for k in range(model.nplace):
        ends = []
        for m in (0, last):
            (al, va), (be, _) = read(k, m, 0), read(k, m, 1)
            ends.append(thesis_point(al, be, np.pi / 2 - va, L, g1, g2))
        e0, e1 = ends
        d = e1 - e0
        p += [*e0, np.arctan2(d[1], d[0]), np.arctan2(d[2], np.hypot(d[0], d[1]))]
    return np.array(p, float)


def ruler_lsq(sightings: RulerSightings, marks_mm, sigma_hz_rad: float, sigma_v_rad: float | None = None,
              marks_cov_mm2: np.ndarray | None = None, n_mc: int = 0, rng=0) -> EstimateSet:
    """Least-squares theodolite parameters from every ruler sighting, with the first-order covariance.

    ``marks_mm``: distance of each ruler mark from C (first 0).  ``marks_cov_mm2``: their covariance (default
    exact).  Returns an :class:`EstimateSet` over all fitted parameters (``L_mm``, ``gamma1_rad``, ``gamma2_rad``,
    ``hB_mm``, instrument errors when both faces were read, ruler poses).  ``cov_first_order`` is
    ``(J^T W J)^-1 + S U_marks S^T``; with ``n_mc > 0`` the fit is re-solved (batched) on Monte Carlo draws of the
    readings and marks, and the GUM covariance uses the numerical Jacobian of the whole fit.
    """
    s = sightings
    step = "least squares"
    marks = np.asarray(marks_mm, float).ravel()
    finite(PROC, step, marks_mm=marks)
    angles_in_range(PROC, step, limit_rad=2 * np.pi + 1e-9, hz_rad=s.hz_rad, v_rad=s.v_rad)
    if marks.size < 2 or marks[0] != 0.0 or np.any(np.diff(marks) <= 0):
        raise EstimationError(PROC, step, "marks_mm must start at 0 (mark C) and increase along the ruler")
    if np.any((s.mark < 0) | (s.mark >= marks.size)) or np.any((s.station < 0) | (s.station > 1)):
        raise EstimationError(PROC, step, "a sighting refers to an unknown mark or station")
    at_least(PROC, step, "marks on the ruler", marks.size, 3)
    both = bool(np.any(s.face == 2) and np.any(s.face == 1))
    model = _RulerModel(s, marks.size, both)
    at_least(PROC, step, "readings for the unknowns (add placements or faces)", 2 * s.n, model.P + 1)
    sv = sigma_hz_rad if sigma_v_rad is None else sigma_v_rad
    w = np.concatenate([np.full(s.n, sigma_hz_rad ** -2), np.full(s.n, sv ** -2)])
    obs = np.concatenate([s.hz_rad, s.v_rad])
    p0 = _initial_guess(model, s, marks)
    p, J, r, A = gauss_newton(lambda q: model.residual(q, marks, obs), p0, model.steps, w,
                              jac=lambda q: model.jacobian(q, marks, obs))
    try:
        Ainv = np.linalg.inv(A)
        if not np.all(np.isfinite(Ainv)) or np.linalg.cond(A) > 1e14:
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        raise EstimationError(PROC, step, "the sightings do not determine every unknown (rank deficient): "
                              "read the marks from both stations, and vertical angles for the ruler height")
    Um = np.zeros((marks.size, marks.size)) if marks_cov_mm2 is None else np.asarray(marks_cov_mm2, float)
    Jm = _jac_marks(model, p, marks, obs)
    S = -Ainv @ (J * w[:, None]).T @ Jm
    cov1 = Ainv + S @ Um @ S.T
    chi2 = float(np.sum(w * r * r))
    units = ["mm" if n.endswith("_mm") else "rad" for n in model.names]
    res = EstimateSet(model.names, p, units, cov_first_order=cov1)
    res.extras.update(chi2=chi2, dof=2 * s.n - model.P, residual=r)
    if n_mc:
        ncore = 2 * s.n + marks.size
        xin = np.concatenate([obs, marks])
        Ux = np.zeros((ncore, ncore))
        Ux[:2 * s.n, :2 * s.n] = np.diag(1.0 / w)
        Ux[2 * s.n:, 2 * s.n:] = Um

        def f(xb):
            o, mk = xb[..., :2 * s.n], xb[..., 2 * s.n:]
            start = np.broadcast_to(p, xb.shape[:-1] + (model.P,))
            q, *_ = gauss_newton(lambda qq: model.residual(qq, mk, o), start, model.steps, w, iterations=8)
            return q

        full = propagate(f, xin, Ux, model.names, units, n_mc=n_mc, rng=rng, first_order_cov=cov1, value=p)
        full.extras.update(res.extras)
        res = full
    return res


def _jac_marks(model, p, marks, obs):
    """Central differences of the residual in each mark's distance (step 1e-4 mm), every perturbed ruler in one
    batched evaluation: the same floats as one evaluation per ruler (the readings are element-wise)."""
    h = 1e-4
    eye = np.eye(marks.size)
    moved = np.concatenate([marks + h * eye, marks - h * eye])      # marks[i] +- h, the others +- 0.0
    y = model.residual(p, moved, obs)
    return np.ascontiguousarray(((y[:marks.size] - y[marks.size:]) / (2 * h)).T)


# -- synthetic sightings (tests, design of experiments) -------------------------------------------------------
def simulate_sightings(L_mm: float, gamma1_rad: float, gamma2_rad: float, placements, marks_mm, faces=(1,),
                       sigma_rad: float = 0.0, rng: np.random.Generator | None = None, hB_mm: float = 0.0,
                       collimation_rad=(0.0, 0.0), index_rad=(0.0, 0.0)) -> RulerSightings:
    """Readings of ruler marks for given placements ``[(C_xyz_mm, azimuth_rad, tilt_rad), ...]`` using the station
    model of :mod:`calib.theodolite` (so the estimator is checked against independent forward code)."""
    a, b = thesis_stations(L_mm, gamma1_rad, gamma2_rad, height_b_mm=hB_mm)
    a = replace(a, collimation_rad=collimation_rad[0], index_rad=index_rad[0])
    b = replace(b, collimation_rad=collimation_rad[1], index_rad=index_rad[1])
    marks = np.asarray(marks_mm, float)
    rows = {k: [] for k in ("placement", "mark", "station", "face", "hz_rad", "v_rad")}
    for k, (c, az, tl) in enumerate(placements):
        u = np.array([np.cos(tl) * np.cos(az), np.cos(tl) * np.sin(az), np.sin(tl)])
        pts = np.asarray(c, float) + marks[:, None] * u
        for st, stn in enumerate((a, b)):
            for f in faces:
                hz, v = stn.observe(pts, face=f)
                rows["placement"] += [k] * len(marks)
                rows["mark"] += list(range(len(marks)))
                rows["station"] += [st] * len(marks)
                rows["face"] += [f] * len(marks)
                rows["hz_rad"] += list(hz)
                rows["v_rad"] += list(v)
    s = RulerSightings(**rows)
    if sigma_rad and rng is not None:
        s.hz_rad = np.mod(s.hz_rad + sigma_rad * rng.standard_normal(s.n), 2 * np.pi)
        s.v_rad = s.v_rad + sigma_rad * rng.standard_normal(s.n)
    return s


def closed_form_readings(s: RulerSightings, placement: int = 0) -> np.ndarray:
    """The six face-I azimuths ``[a'_C, a'_D, a'_E, b'_C, b'_D, b'_E]`` of a three-mark placement."""
    out = []
    for st in (0, 1):
        for mk in (0, 1, 2):
            sel = (s.placement == placement) & (s.mark == mk) & (s.station == st) & (s.face == 1)
            if not np.any(sel):
                raise EstimationError(PROC, "closed form", f"mark {'CDE'[mk]} not sighted face I from "
                                      f"station {'AB'[st]} in placement {placement}")
            h = s.hz_rad[sel][0]
            out.append(wrap_angle(-h) if st == 0 else wrap_angle(h))
    return np.array(out)
