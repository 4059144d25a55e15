"""The pose set's errors beyond the identification's own covariance: what the stations' uncertainty and the
transmission-error run's order add, and the floor of the total.  Both terms re-solve the identification from its own
estimate with one input moved (a small step from a converged fit: no linear start and no outlier search) and read only
its estimate (``report=False``: no covariance, no search for the joint that would determine a held direction; the
held set and the estimate are the same)."""
from __future__ import annotations

import numpy as np

from calib.errors import RobocalError
from calib.identify import PointObservations, SharedStart, identify

from offline.reduction.pose_model import pose_model, sine_cosine

FLOOR_NOTE = ("error floored at the fit's own variance: the stations' and the transmission-error run's terms came "
              "out below it (numerical), never an error of 0")


def station_variance(model, obs, D, ident, priors, fit, problems: list[str] | None = None) -> np.ndarray:
    """What the stations' own uncertainty adds to each identified parameter's variance.

    Why: every pose point was intersected with the same ruler-fitted stations, so an error in L (a scale) or B's
    height moves all of them together and does not average down over the poses; the identification's covariance
    treats the points as independent.  Each station parameter is moved by its 1-sigma, the points follow through
    their sensitivities ``D`` (N, 3, K), and the identification is re-solved from its own estimate:
    ``G U_station G^T``.  The re-solves share their start (:class:`calib.identify.SharedStart`: the same parameters,
    joint readings and covariances, only the points moved) and the points' whitening.  A re-solve that fails, or a free parameter it leaves undefined, is said in ``problems``
    (the errors then leave that part of the stations' term out): never a silent zero."""
    out = np.zeros(len(ident.theta))
    if not fit.cov.size or any(d is None for d in D):
        return out
    free = np.zeros(len(ident.theta), bool)
    free[[ident.names.index(n) for n in ident.free]] = True
    said = problems if problems is not None else []
    Dk = np.array(D)                                          # (N, 3, K)
    G, shared = [], SharedStart()
    for k, sd in enumerate(np.sqrt(np.diag(fit.cov))):
        moved = PointObservations(obs.q_rad, obs.points_mm + Dk[:, :, k] * sd, cov_mm2=obs.cov_mm2, white=obs._white)
        try:
            g = identify(model, moved, free=list(ident.free), theta0=ident.theta, priors=priors, robust=False,
                         start=False, report=False, shared=shared)     # its estimate only: no covariance or words
        except RobocalError as exc:
            said.append(f"poses: the stations' uncertainty is left out of the errors (re-solve with station "
                        f"parameter {k} moved by 1 sigma failed: {exc})")
            return out
        with np.errstate(invalid="ignore"):
            gk = np.where(free, (g.theta - ident.theta) / sd, 0.0)    # held parameters (possibly at +-inf): 0
        bad = free & ~np.isfinite(gk)
        if bad.any():
            said.append(f"poses: the stations' uncertainty is left out of the errors of "
                        f"{', '.join(np.asarray(ident.names)[bad])} (station parameter {k}'s re-solve left them "
                        f"undefined)")
            gk[bad] = 0.0
        G.append(gk)
    G = np.stack(G, -1)
    return np.einsum("pk,kl,pl->p", G, fit.cov, G)


def floored_sigma(var: np.ndarray, fit_var: np.ndarray, prior_var: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Errors from the total variances ``var``, each floored at the fit's own variance -- ``fit_var`` (the
    identification's, reduced chi-square included) less the independent-prior terms ``prior_var`` that the
    transmission-error run's covariance replaces (the whole ``fit_var`` where that is not positive).  Why: the
    station and run terms added to it are positive semi-definite, so a total below the floor is rounding or a
    sensitivity gone wrong; a clip to 0 turned it into an error of 0, which the honesty check then skipped silently.
    Returns the errors and where the floor was hit (to be noted on the estimate)."""
    own = fit_var - prior_var
    floor = np.where(own > 0, own, fit_var)
    hit = ~(var >= floor)                       # NaN counts as hit
    return np.sqrt(np.where(hit, floor, var)), hit


def te_run_variance(robot, running: dict, specs: list[str], obs, ident, priors,
                    problems: list | None = None) -> tuple[np.ndarray, np.ndarray]:
    """What the transmission-error run's order, and the correlation of its coefficients, add to each identified
    parameter's variance.

    Why: the pose set's model holds a joint's transmission-error order at the run's estimate and takes the run's sine
    and cosine coefficients as independent priors.  But the order is known only to its error (joint 4's 0.9 to about
    5 % over a 270 deg run), a different order moves the coefficients the pose set finds, and the run's order,
    amplitude and phase are correlated.  So the run's whole covariance of (order, sine, cosine) goes through the fit:
    ``J U J^T`` with the sensitivity to the order from refits with the order moved by a tenth of its error either
    way, and to the prior values from the priors' gain ``C P`` -- in place of the independent-prior term
    ``C P C`` the identification's covariance holds.  Left out, the pose set's joint-4 coefficients scattered
    1.15 times their errors over 40 seeded demo runs.

    Returns what to add to each variance (``J U J^T`` less the prior term it replaces) and that prior term alone,
    both in the identification's scale (its covariance is inflated by the reduced chi-square, so the prior term it
    holds is ``scale g^2 sd^2``).  A refit that fails, or gives a non-finite sensitivity of a free parameter, leaves
    that joint at the independent-prior term, with a line in ``problems`` -- never a sensitivity of 0."""
    out, removed = np.zeros(len(ident.theta)), np.zeros(len(ident.theta))
    problems = [] if problems is None else problems
    free = np.isin(ident.names, list(ident.free))
    scale = max(1.0, float(ident.reduced_chi2))
    for j, res in sorted((running.get("transmission") or {}).items()):
        at = [i for i, t in enumerate(specs) if t.startswith(f"transmission_error:{j}:")]
        pri = [f"transmission_error.j{j}.{k}_rad" for k in ("s1", "c1")]
        if len(at) != 1 or not all(n in priors and n in ident.free for n in pri) or "omega" not in res.names:
            continue
        idx = [list(res.names).index(n) for n in ("omega", "amplitude1_rad", "phase1_rad")]
        G = np.eye(3)                                             # (order, s1, c1) from (order, A, phi)
        G[1:, 1:] = sine_cosine(*(float(res.value[i]) for i in idx[1:]))[1]
        U = G @ res.cov[np.ix_(idx, idx)] @ G.T
        order = float(specs[at[0]].rsplit(":", 1)[1])
        h = 0.1 * float(np.sqrt(U[0, 0]))
        moved, written = [], []
        for sgn in (1.0, -1.0):
            sp = list(specs)
            sp[at[0]] = f"transmission_error:{j}:{order + sgn * h:.8g}"
            written.append(float(sp[at[0]].rsplit(":", 1)[1]))     # the order the refit used, as written
            model, _, _ = pose_model(robot, running, [], sp)
            try:        # a small step from the converged fit, as in station_variance: no linear start or outlier search
                moved.append(identify(model, obs, free=list(ident.free), theta0=ident.theta, priors=priors,
                                      robust=False, start=False, report=False).theta)
            except RobocalError:
                break
        step = written[0] - written[-1]
        with np.errstate(invalid="ignore", divide="ignore"):
            dw = (moved[0] - moved[-1]) / step if len(moved) == 2 and step > 0 else np.full(len(ident.theta), np.nan)
        if not np.all(np.isfinite(dw[free])):
            problems.append(f"poses: the refit with joint {j}'s transmission-error order moved failed: its "
                            f"coefficients' errors keep the independent-prior term (the order's error is not "
                            f"propagated)")
            continue
        dw = np.where(free, dw, 0.0)                  # held parameters are not estimated: no sensitivity to carry
        gain = [ident.cov[:, ident.names.index(n)] / (priors[n][1] ** 2 * scale) for n in pri]
        J = np.stack([dw, *gain], -1)
        prior_term = scale * sum(g * g * priors[n][1] ** 2 for g, n in zip(gain, pri))
        out += np.einsum("pk,kl,pl->p", J, U, J) - prior_term
        removed += prior_term
    return out, removed
