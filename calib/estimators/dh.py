"""DH parameters from measured joint axes (circle point analysis), and the thesis's Puma formulas (eq 4.3.15, B.6).

General form (:func:`dh_from_axes`): with every joint axis measured at one pose ``q`` (all in R_f), walk the chain
``A_j = Rz(theta_j + offset_j) Tz(d_j) Tx(a_j) Rx(alpha_j) Ry(beta_j)`` (the convention of :mod:`calib.kinematics`):
the common normal between axis j and axis j+1 gives ``x_j``, the link length ``a_j`` (signed along ``x_j``), the
twist ``alpha_j``, the offset ``d_j`` (along axis j from the previous common normal) and ``theta_j`` (from ``x_{j-1}``
to ``x_j`` about axis j).  For a **Hayati** link (nominally parallel axes, e.g. Puma joints 2-3) the common normal is
ill-defined, so ``d_j`` is held at its nominal value, ``x_j`` is taken in the plane perpendicular to axis j through
that point, and the tilt of axis j+1 is split into ``alpha_j`` (about ``x_j``) and ``beta_j`` (about ``y_j``).  Signs
(axis direction, ``x_j`` when axes intersect, negative ``a_j``) follow nominal "hint" frames, so the result is in the
robot description's convention.  Vectorised over leading batch dimensions.

Thesis form (:func:`puma_thesis_dh`, eq 4.3.15 / B.6): with the Puma at READY and the compensation scheme applied,
``d1 = Y_c6 - Y_c1``, ``a2 = X_c6 - X_c1``, ``d2 = |(X, Z)_c3 - (X, Z)_c5|``, ``a1 = |(X, Z)_c2 - (X, Z)_c3|`` and
``d3 = |(X, Z)_p - (X, Z)_c6| - L_p``.  B.6's partials are right except ``d d3 / d L_p``, which is -1 (printed
``-1/(2 d3)``).
"""
from __future__ import annotations

import numpy as np

from ..angles import wrap_angle
from ..uncertainty import EstimateSet, propagate
from ._common import EstimationError, finite

PROC = "dh"


def _dot(a, b):
    return np.sum(a * b, -1)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def dh_from_axes(c: np.ndarray, z: np.ndarray, q_rad: np.ndarray, frame0_R: np.ndarray, frame0_t: np.ndarray,
                 x_hint: np.ndarray, hayati: np.ndarray, d_nominal: np.ndarray,
                 parallel_tol: float = 1e-3, alpha_ref: np.ndarray | None = None) -> np.ndarray:
    """Links 1..n-1 from n measured axes: points ``c (..., n, 3)`` and directions ``z (..., n, 3)``.

    ``frame0_R (3, 3)``, ``frame0_t (3,)``: robot frame 0 in R_f (its x axis fixes theta_1; its origin, projected on
    axis 1, fixes d_1); ``x_hint (n-1, 3)``: nominal ``x_j`` directions in R_f for the signs; ``hayati (n-1,)``,
    ``d_nominal (n-1,)`` per link.  Returns ``(..., n-1, 5)`` = ``[theta_offset_rad, d_mm, a_mm, alpha_rad,
    beta_rad]``; ``d`` of a Hayati link is the nominal one (not estimated) and ``beta`` of other links is 0.
    Non-Hayati links whose axes are parallel within ``parallel_tol`` rad give NaN (use :func:`check_axes`).
    ``alpha_ref (n-1,)`` (nominal twists) sets the branch: alpha is reported within +-pi of it, so a 180 deg twist
    does not jump between +pi and -pi from one Monte Carlo draw to the next.
    """
    c = np.asarray(c, float)
    z = _unit(np.asarray(z, float))
    n = z.shape[-2]
    zp = z[..., 0, :]
    # frame 0: origin projected onto axis 1, x made perpendicular to the measured axis 1
    t0 = np.asarray(frame0_t, float)
    O = c[..., 0, :] + _dot(t0 - c[..., 0, :], zp)[..., None] * zp
    x0 = np.asarray(frame0_R, float)[:, 0]
    xp = _unit(x0 - _dot(x0, zp)[..., None] * zp)
    out = []
    for k in range(n - 1):
        zn, cn = z[..., k + 1, :], c[..., k + 1, :]
        hint = np.asarray(x_hint[k], float)
        if hayati[k]:
            d = np.full(O.shape[:-1], float(d_nominal[k]))
            F = O + d[..., None] * zp
            s = _dot(F - cn, zp) / _dot(zn, zp)
            G = cn + s[..., None] * zn
            v = G - F
            x = _unit(v)
            sgn = np.where(_dot(x, hint) < 0, -1.0, 1.0)
            x = x * sgn[..., None]
            a = _dot(v, x)
            yv = np.cross(zp, x)
            beta = np.arcsin(np.clip(_dot(zn, x), -1, 1))
            alpha = np.arctan2(-_dot(zn, yv), _dot(zn, zp))
        else:
            w = np.cross(zp, zn)
            sw = np.linalg.norm(w, axis=-1)
            b = _dot(zp, zn)
            r = O - cn
            den = np.where(sw > parallel_tol, 1 - b * b, np.nan)
            t = (b * _dot(zn, r) - _dot(zp, r)) / den           # foot on axis k: O + t zp
            s = (_dot(zn, r) - b * _dot(zp, r)) / den           # foot on axis k+1: cn + s zn
            F = O + t[..., None] * zp
            G = cn + s[..., None] * zn
            v = G - F
            vn = np.linalg.norm(v, axis=-1, keepdims=True)
            x = np.where(vn > 1e-6, v / np.where(vn > 0, vn, 1), w / sw[..., None])
            sgn = np.where(_dot(x, hint) < 0, -1.0, 1.0)
            x = x * sgn[..., None]
            a = _dot(v, x)
            d = t
            yv = np.cross(zp, x)
            alpha = np.arctan2(-_dot(zn, yv), _dot(zn, zp))
            beta = np.zeros_like(a)
        if alpha_ref is not None:
            alpha = alpha_ref[k] + wrap_angle(alpha - alpha_ref[k])
        theta = np.arctan2(_dot(np.cross(xp, x), zp), _dot(xp, x))
        off = wrap_angle(theta - q_rad[k])
        out.append(np.stack([off, d, a, alpha, beta], -1))
        # next frame: x_j = R_F Rx(alpha) Ry(beta) e_x
        xj = np.cos(beta)[..., None] * x + (np.sin(alpha) * np.sin(beta))[..., None] * yv \
            - (np.cos(alpha) * np.sin(beta))[..., None] * zp
        O, xp, zp = G, xj, zn
    return np.stack(out, -2)


LINK_FIELDS = ("theta_offset_rad", "d_mm", "a_mm", "alpha_rad", "beta_rad")


def check_axes(z: np.ndarray, hayati, parallel_tol: float = 1e-3) -> None:
    """Refuse non-Hayati links whose measured axes are parallel (their common normal is undefined)."""
    z = _unit(np.asarray(z, float))
    finite(PROC, "common normals", axis_directions=z)
    for k in range(len(z) - 1):
        s = np.linalg.norm(np.cross(z[k], z[k + 1]))
        if not hayati[k] and s < parallel_tol:
            raise EstimationError(PROC, "common normals", f"axes {k + 1} and {k + 2} are parallel within "
                                  f"{np.degrees(np.arcsin(s)):.4f} deg: their common normal is undefined; mark link "
                                  f"{k + 1} as a Hayati link (beta instead of d)")


def link_names(n_links: int, hayati) -> tuple[list[str], list[str], list[int]]:
    """Reported names/units and the index into the flattened ``(n-1)*5`` vector (Hayati: beta instead of d)."""
    names, units, idx = [], [], []
    for k in range(n_links):
        for f, field in enumerate(LINK_FIELDS):
            if (field == "d_mm" and hayati[k]) or (field == "beta_rad" and not hayati[k]):
                continue
            names.append(f"j{k + 1}.{field}")
            units.append("mm" if field.endswith("_mm") else "rad")
            idx.append(5 * k + f)
    return names, units, idx


def dh_estimate(axes_value: np.ndarray, axes_cov: np.ndarray, q_rad, frame0_R, frame0_t, x_hint, hayati,
                d_nominal, alpha_ref=None, n_mc: int = 20_000, rng=0) -> EstimateSet:
    """DH parameters with errors from the stacked axes ``[c (3), n (3)]`` per joint (``(6n,)``) and their
    covariance (``(6n, 6n)``, e.g. block-diagonal from :func:`calib.estimators.axes.fit_axis`).  The thesis has no
    first-order expression for the common-normal construction (only for its Puma formulas, :func:`puma_thesis_dh`),
    so this reports the GUM and Monte Carlo ways."""
    v = np.asarray(axes_value, float)
    nj = v.size // 6
    zz = v.reshape(nj, 6)
    check_axes(zz[:, 3:], hayati)
    names, units, idx = link_names(nj - 1, hayati)

    def f(x):
        x = np.asarray(x, float)
        a = x.reshape(x.shape[:-1] + (nj, 6))
        out = dh_from_axes(a[..., :3], a[..., 3:], q_rad, frame0_R, frame0_t, x_hint, hayati, d_nominal,
                           alpha_ref=alpha_ref)
        return out.reshape(out.shape[:-2] + (-1,))[..., idx]

    return propagate(f, v, axes_cov, names, units, n_mc=n_mc, rng=rng)


# -- the thesis's Puma formulas ---------------------------------------------------------------------------------
PUMA_INPUTS = ["X_c1", "Y_c1", "X_c2", "Z_c2", "X_c3", "Z_c3", "X_c5", "Z_c5", "X_c6", "Y_c6", "Z_c6", "X_p", "Z_p",
               "L_p"]
PUMA_NAMES = ["a1_mm", "a2_mm", "d1_mm", "d2_mm", "d3_mm"]


def puma_formulas(x: np.ndarray) -> np.ndarray:
    """Eq 4.3.15, vectorised: ``x (..., 14)`` ordered as :data:`PUMA_INPUTS` -> ``(..., 5)`` [a1, a2, d1, d2, d3]."""
    x = np.asarray(x, float)
    Xc1, Yc1, Xc2, Zc2, Xc3, Zc3, Xc5, Zc5, Xc6, Yc6, Zc6, Xp, Zp, Lp = np.moveaxis(x, -1, 0)
    return np.stack([np.hypot(Xc2 - Xc3, Zc2 - Zc3), Xc6 - Xc1, Yc6 - Yc1, np.hypot(Xc3 - Xc5, Zc3 - Zc5),
                     np.hypot(Zp - Zc6, Xp - Xc6) - Lp], -1)


def puma_first_order(x: np.ndarray) -> np.ndarray:
    """App B.6 partial derivatives (5, 14), with ``d d3/d L_p = -1`` (printed -1/(2 d3))."""
    Xc1, Yc1, Xc2, Zc2, Xc3, Zc3, Xc5, Zc5, Xc6, Yc6, Zc6, Xp, Zp, Lp = x
    a1 = np.hypot(Xc2 - Xc3, Zc2 - Zc3)
    d2 = np.hypot(Xc3 - Xc5, Zc3 - Zc5)
    h = np.hypot(Zp - Zc6, Xp - Xc6)
    J = np.zeros((5, 14))
    J[0, [2, 3, 4, 5]] = [(Xc2 - Xc3) / a1, (Zc2 - Zc3) / a1, (Xc3 - Xc2) / a1, (Zc3 - Zc2) / a1]
    J[1, [0, 8]] = [-1, 1]
    J[2, [1, 9]] = [-1, 1]
    J[3, [4, 5, 6, 7]] = [(Xc3 - Xc5) / d2, (Zc3 - Zc5) / d2, (Xc5 - Xc3) / d2, (Zc5 - Zc3) / d2]
    J[4, [8, 10, 11, 12, 13]] = [-(Xp - Xc6) / h, -(Zp - Zc6) / h, (Xp - Xc6) / h, (Zp - Zc6) / h, -1]
    return J


def puma_thesis_dh(centres: dict, cov: np.ndarray | None = None, n_mc: int = 20_000, rng=0) -> EstimateSet:
    """a1, a2, d1, d2 -- and d3 when ``Z_c6``, ``X_p``, ``Z_p``, ``L_p`` are given -- by eq 4.3.15, errors three ways.

    ``centres``: ``{"X_c1": ..., "Y_c1": ..., ...}`` (mm) as printed in Fig 5.10 (where Z_c6 is 'undefined': d3 then
    cannot be computed); ``cov``: covariance (14x14) of the inputs in :data:`PUMA_INPUTS` order (default exact).
    """
    step = "Puma formulas (eq 4.3.15)"
    missing = [k for k in PUMA_INPUTS[:10] if k not in centres]
    if missing:
        raise EstimationError(PROC, step, "missing joint-centre coordinates: " + ", ".join(missing))
    with_d3 = all(k in centres for k in PUMA_INPUTS[10:])
    x = np.array([centres.get(k, 0.0) for k in PUMA_INPUTS], float)
    finite(PROC, step, centres=x)
    U = np.zeros((14, 14)) if cov is None else np.asarray(cov, float)
    J = puma_first_order(x)
    k = 5 if with_d3 else 4
    return propagate(lambda z: puma_formulas(z)[..., :k], x, U, PUMA_NAMES[:k], ["mm"] * k,
                     n_mc=n_mc if U.any() else 0, rng=rng, first_order_cov=(J @ U @ J.T)[:k, :k])


# -- misalignments (eqs 4.3.10-4.3.11) ------------------------------------------------------------------------
def misalignments(z_meas: np.ndarray, z_design: np.ndarray, x_frames: np.ndarray) -> np.ndarray:
    """Per joint j the small rotation ``(dtheta_x, dtheta_y, dtheta_z)`` (R_f components) turning the design axis
    into the measured one, and between successive joints the relative rotation ``D_j = delta_j - delta_{j-1}`` in
    the frame of link j (eqs 4.3.10-11): ``delta alpha_j = D_j . x_j`` (about the common normal ``x_frames[j]``, the
    twist deviation), ``delta beta_j = D_j . y_j`` and ``delta theta_j = D_j . z_j`` (``y_j = z_j x x_j``).  The
    printed 4.3.11 takes ``|D_j - (D_j . x_j) x_j|`` with a sign: that norm loses its sign when the remainder turns
    from y to z, so the two components are reported apart.  Returns ``(n, 6)``: ``[dtheta_x, dtheta_y, dtheta_z,
    delta_alpha, delta_beta, delta_theta]`` (rad); the first joint's relative terms are its own.
    """
    zm, zd = _unit(np.asarray(z_meas, float)), _unit(np.asarray(z_design, float))
    w = np.cross(zd, zm)
    s = np.linalg.norm(w, axis=-1, keepdims=True)
    ang = np.arctan2(s, _dot(zd, zm)[..., None])
    delta = np.where(s > 0, w / np.where(s > 0, s, 1) * ang, 0.0)
    D = delta - np.concatenate([np.zeros_like(delta[..., :1, :]), delta[..., :-1, :]], -2)
    x = _unit(np.asarray(x_frames, float))
    y = np.cross(zd, x)
    return np.concatenate([delta, _dot(D, x)[..., None], _dot(D, y)[..., None], _dot(D, zd)[..., None]], -1)
