"""A batched Gauss-Newton solver: many independent least-squares problems of the same shape at once.

Why batched: Monte Carlo propagation (GUM-S1) and the GUM's numerical Jacobian of an *implicit* estimator (a least-
squares fit) both need the fit re-solved for thousands of perturbed inputs.  Solving them as one ``(B, P)`` problem
keeps the Python loop to the handful of Gauss-Newton iterations.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..uncertainty import jacobian


def gauss_newton(residual: Callable[[np.ndarray], np.ndarray], p0: np.ndarray, steps: np.ndarray,
                 weights: np.ndarray | None = None, iterations: int = 30, tol: float = 1e-6,
                 jac: Callable[[np.ndarray], np.ndarray] | None = None):
    """Minimise ``sum w r(p)^2`` for a batch of parameter vectors ``p0 (..., P)``.

    ``residual(p (..., P)) -> (..., M)`` must be vectorised over leading dimensions; ``steps (P,)`` are the central-
    difference steps of the Jacobian (``jac(p)``, when given, must return that very central-difference Jacobian,
    computed more cheaply: the ruler's block-sparse one); iteration stops when every update is below ``tol * steps``.  Returns ``(p, J, r, normal)`` at the solution: the residual Jacobian
    ``(..., M, P)`` and the weighted normal matrix ``J^T W J (..., P, P)``.  Damped (Levenberg) when a step increases
    the cost, so a poor start on one member of the batch does not spoil the others.
    """
    p = np.array(p0, float)
    w = None if weights is None else np.asarray(weights, float)
    lam = np.full(p.shape[:-1], 1e-9)
    r = residual(p)

    def cost(rr):
        return np.sum(rr * rr if w is None else w * rr * rr, -1)

    c = cost(r)
    P = p.shape[-1]
    eye = np.eye(P)
    J = None                # the Jacobian and normal equations at the present p, None once p has moved
    if jac is None:
        def jac(q):
            return jacobian(residual, q, steps)
    for _ in range(iterations):
        if J is None:
            J = jac(p)
            Jw = J if w is None else J * w[..., :, None]
            A = np.swapaxes(Jw, -1, -2) @ J
            g = np.einsum("...mp,...m->...p", Jw, r)
            scale = np.sqrt(np.clip(np.diagonal(A, axis1=-2, axis2=-1), 1e-300, None))
            An = A / (scale[..., :, None] * scale[..., None, :])
        dp = -np.linalg.solve(An + lam[..., None, None] * eye, (g / scale)[..., None])[..., 0] / scale
        pn = p + dp
        rn = residual(pn)
        cn = cost(rn)
        better = np.isfinite(cn) & (cn <= c * (1 + 1e-12))
        if np.any(better):
            # a rejected step leaves p, r and so J, A, g as they were: only the damping changes (near the minimum
            # most steps are rejected rounding, and the Jacobian is nearly all of an iteration's cost)
            p = np.where(better[..., None], pn, p)
            r = np.where(better[..., None], rn, r)
            c = np.where(better, cn, c)
            J = None
        lam = np.where(better, lam * 0.1, lam * 10.0)
        lam = np.clip(lam, 1e-12, 1e8)
        if np.all(np.abs(dp) <= tol * steps):
            break
    if J is None:
        J = jac(p)
        Jw = J if w is None else J * w[..., :, None]
        A = np.swapaxes(Jw, -1, -2) @ J
    return p, J, r, A
