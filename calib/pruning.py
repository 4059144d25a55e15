"""Backward elimination of insignificant parameters, and its honest cross-validation, on the linearised fit.

Why linearised: the model selection (:mod:`calib.selection`) must compare "hold what is not significant" with the
other candidates by how well it predicts poses it has not seen.  Scoring the pruned model's own leave-one-out error
would be optimistic -- which parameters to hold was decided with the left-out pose in the data (on the TIAGo mocap
set the pruned model's leave-one-out error was 2.5 mm, its error on folds it never saw 3-7 mm).  The honest score
repeats the *decision* without each left-out pose; done with nonlinear refits that is hundreds of fits.  Around the
converged full fit a calibration problem is nearly linear (the linearised leave-one-out error matched refits to
0.2 % on that set), so the whole procedure runs on the fit's whitened Jacobian: every refit is a small least-squares
solve, every held parameter a fixed shift of the residual.

Conventions: ``x`` are the full fit's free parameters, ``ref`` their reference values (prior or design); holding
parameter ``h`` moves it by ``ref_h - x_h``; the residual of a pose changes by ``-J_i d``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: |estimate - reference| / sigma below which a parameter is held (the selection's rule, calib.selection)
SIGNIFICANT = 2.0


@dataclass
class LinearFit:
    """The full fit linearised: whitened Jacobian and residual per pose, the prior rows, the parameters."""

    J: np.ndarray                  # (N, k, p) whitened Jacobian of each pose's k observations
    r: np.ndarray                  # (N, k) whitened residual at the full fit
    Jp: np.ndarray                 # (m_p, p) prior rows
    rp: np.ndarray                 # (m_p,)
    x: np.ndarray                  # (p,) full-fit values
    ref: np.ndarray                # (p,) reference values
    movable: np.ndarray            # (p,) bool: may be held (the location never is)
    inflate_only: bool             # covariance scaled by max(1, reduced chi-square) (else by it always)
    white: np.ndarray              # (N, k, k) whitening of each pose (to go back to mm)

    def __post_init__(self):
        # the whole set's normal-equation pieces; a fold's are the sums over its poses' rows, one matrix product
        # (never a (N, p, p) stack of per-pose pieces: at 1000 poses and 85 parameters that was 58 MB summed per fold)
        N, k, p = self.J.shape
        self._Jf, self._rf = self.J.reshape(N * k, p), self.r.reshape(N * k)
        self._Gp, self._gp, self._bbp = self.Jp.T @ self.Jp, self.Jp.T @ self.rp, float(self.rp @ self.rp)
        self._G_all = self._Jf.T @ self._Jf + self._Gp
        self._g_all = self._Jf.T @ self._rf + self._gp
        self._bb_all = float(self._rf @ self._rf) + self._bbp

    @property
    def n(self) -> int:
        return len(self.r)

    def _rows(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """J^T J, J^T r and r^T r of the observations of ``poses`` (no priors)."""
        J, r = self.J[poses].reshape(-1, self.J.shape[2]), self.r[poses].ravel()
        return J.T @ J, J.T @ r, float(r @ r)

    def _sums(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """The normal matrix, right-hand side and b^T b of ``poses`` plus the priors (the whole set minus the few
        left out when that is cheaper: a leave-one-out fold)."""
        key = poses.tobytes()
        if getattr(self, "_key", None) == key:
            return self._last
        if 2 * len(poses) > self.n:
            out = np.ones(self.n, bool)
            out[poses] = False
            G, g, bb = self._rows(np.flatnonzero(out))
            G, g, bb = self._G_all - G, self._g_all - g, self._bb_all - bb
        else:
            G, g, bb = self._rows(poses)
            G, g, bb = G + self._Gp, g + self._gp, bb + self._bbp
        self._key, self._last = key, (G, g, bb)
        return G, g, bb

    def fit(self, poses: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Step ``d`` (p,) from the full fit for the free set on ``poses`` (the held parameters at their reference),
        and the free parameters' sigmas (scaled by the reduced chi-square as the fit scales them)."""
        G, g, bb = self._sums(poses)
        d = (self.ref - self.x) * ~free
        gs = g[free] - G[np.ix_(free, ~free)] @ d[~free]
        bb = bb - 2.0 * d @ g + d @ G @ d
        Gs = G[np.ix_(free, free)]
        sc = np.sqrt(np.where(np.diag(Gs) > 0, np.diag(Gs), 1.0))
        inv, rank = _inverse(Gs / np.outer(sc, sc))
        inv = inv / np.outer(sc, sc)
        coef = inv @ gs
        d = d.copy()
        d[free] = coef
        m = self.r.shape[1] * len(poses) + len(self.rp)
        red = max(0.0, bb - coef @ gs) / max(1, m - rank)
        scale = max(1.0, red) if self.inflate_only else red
        return d, np.sqrt(np.clip(np.diag(inv), 0.0, None) * scale)

    def eliminate(self, poses: np.ndarray) -> tuple[np.ndarray, dict[int, tuple[float, float]]]:
        """Backward elimination on ``poses``: hold the movable parameter nearest its reference in sigma, refit,
        until every free one is :data:`SIGNIFICANT` sigma or more away.  The free mask and, per held parameter,
        (estimate, sigma) where it was last free."""
        free = np.ones(len(self.x), bool)
        held: dict[int, tuple[float, float]] = {}
        while True:
            d, sd = self.fit(poses, free)
            est = self.x + d
            idx = np.flatnonzero(free)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(sd > 0, np.abs(est[idx] - self.ref[idx]) / sd, np.inf)
            t = np.where(self.movable[idx], t, np.inf)
            if not idx.size or t.min() >= SIGNIFICANT:
                return free, held
            j = int(idx[np.argmin(t)])
            held[j] = (float(est[j]), float(sd[np.argmin(t)]))
            free[j] = False

    def predict_mm(self, poses: np.ndarray, d: np.ndarray) -> np.ndarray:
        """(n, k) residuals in mm of ``poses`` after the step ``d``."""
        rw = self.r[poses] - np.einsum("nkp,p->nk", self.J[poses], d)
        return np.linalg.solve(self.white[poses], rw[..., None])[..., 0]

    def cv_rms_mm(self, folds: list[tuple[np.ndarray, np.ndarray]]) -> float:
        """RMS per-pose distance of the elimination procedure's predictions, the procedure repeated on each fold's
        training poses (the honest score of "hold what is not significant")."""
        out = np.zeros((self.n, self.r.shape[1]))
        for tr, te in folds:
            free, _ = self.eliminate(tr)
            d, _ = self.fit(tr, free)
            out[te] = self.predict_mm(te, d)
        return float(np.sqrt(np.mean(np.sum(out ** 2, axis=1))))


def _inverse(A: np.ndarray) -> tuple[np.ndarray, int]:
    """The inverse of a symmetric positive semi-definite (column-scaled) normal matrix over its determined
    directions, and their number.  Positive definite (the usual case: the full fit's parameters are determined): by
    its Cholesky factor, a tenth of the eigendecomposition's cost on the hundreds of refits an elimination makes;
    otherwise the pseudo-inverse over eigenvalues above 1e-20 of the largest."""
    # numpy's Cholesky, not LAPACK's dpotrf/dpotri through scipy.linalg: that import cost every diagnosis 0.3 s
    if A.size:
        try:
            L = np.linalg.cholesky(A)
        except np.linalg.LinAlgError:           # not positive definite: the eigendecomposition below
            pass
        else:
            Linv = np.linalg.solve(L, np.eye(len(A)))         # A^-1 = L^-T L^-1
            return Linv.T @ Linv, len(A)
    w, V = np.linalg.eigh(A)
    keep = w > 1e-20 * (w[-1] if w.size else 1.0)
    return (V[:, keep] / w[keep]) @ V[:, keep].T, int(keep.sum())


def linearise(problem, ident, ref: np.ndarray, movable: np.ndarray, per: int, white: np.ndarray) -> LinearFit:
    """:class:`LinearFit` of a converged identification: ``problem`` (:class:`calib.identify._Problem` on its rows,
    with its priors), ``ref``/``movable`` over ``ident.free``, ``per`` observations per pose, ``white`` (N, per, per)."""
    r, J = problem.residuals(ident.theta)
    kidx = [problem.names.index(n) for n in ident.free]
    Jk = J[:, kidx]
    N = problem.obs.n
    m = N * per
    # r = whitened (measured - predicted); J = d r / d theta (the problem's sign): a step d changes r by J d
    return LinearFit(-Jk[:m].reshape(N, per, -1), r[:m].reshape(N, per), -Jk[m:], r[m:],
                     ident.theta[kidx].copy(), np.asarray(ref, float), np.asarray(movable, bool),
                     getattr(ident, "error_scale", "inflate") != "residual", white)
