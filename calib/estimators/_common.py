"""Shared pieces of the Chapter 4 estimators: the operator error and input checks.

Every check raises :class:`EstimationError` whose one-line message names the procedure (e.g. ``ruler``), the step
(e.g. ``closed form``) and what is wrong or missing, so a bad input never turns into a silent wrong number.
"""
from __future__ import annotations

import numpy as np

from ..errors import RobocalError


class EstimationError(RobocalError):
    """An estimator cannot produce a trustworthy number from the data it was given."""

    def __init__(self, procedure: str, step: str, problem: str):
        super().__init__(f"{procedure}: {step}: {problem}")
        self.procedure, self.step, self.problem = procedure, step, problem


def finite(procedure: str, step: str, **arrays) -> None:
    """Refuse NaN or infinite inputs, naming the first offending array and element."""
    for name, a in arrays.items():
        a = np.asarray(a, float)
        bad = ~np.isfinite(a)
        if np.any(bad):
            i = int(np.flatnonzero(bad.ravel())[0])
            raise EstimationError(procedure, step, f"{name} has a missing or non-finite value (element {i})")


def angles_in_range(procedure: str, step: str, limit_rad: float = 2 * np.pi, **arrays) -> None:
    """Refuse angles (radians) outside +-limit: usually degrees passed where radians are expected."""
    finite(procedure, step, **arrays)
    for name, a in arrays.items():
        a = np.asarray(a, float)
        if np.any(np.abs(a) > limit_rad):
            i = int(np.flatnonzero(np.abs(a.ravel()) > limit_rad)[0])
            raise EstimationError(procedure, step, f"{name} element {i} = {a.ravel()[i]:.6g} rad is out of range "
                                                   f"(|angle| <= {limit_rad:.4g} rad); were degrees passed?")


def at_least(procedure: str, step: str, what: str, have: int, need: int) -> None:
    if have < need:
        raise EstimationError(procedure, step, f"needs at least {need} {what}, got {have}")


def error_covariance(procedure: str, step: str, sigma, n: int) -> np.ndarray:
    """The (n, n) covariance of n errors from a scalar sigma, one sigma per error, or a full covariance.

    Why full: angles measured with the same fitted stations share those stations' errors, so their covariance has
    off-diagonal terms the fits must see.  Refuses a non-positive or non-finite sigma in one line."""
    s = np.asarray(sigma, float)
    C = s if s.ndim == 2 else np.diag(np.broadcast_to(s, (n,)) ** 2)
    if C.shape != (n, n) or not np.all(np.isfinite(C)) or np.any(np.diag(C) <= 0):
        raise EstimationError(procedure, step, f"the errors' sigma must be positive and finite, one per reading or an "
                                               f"{n}x{n} covariance")
    return 0.5 * (C + C.T)
