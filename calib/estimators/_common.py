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
