"""The measurement noise as the data show it, against the noise the diagnosis was given.

Why: the floor every gap is measured against comes from the instruments' covariance or ``--noise-mm``.  A wrong value
moves the floor: too small and noise looks like an unexplained gap, too large and real effects hide below it.

* **Repeats** (rows with the same joint readings and the same target, e.g. a pose measured twice or a file with
  repeated poses) give a direct estimate: the pooled spread about each group's mean, per coordinate.
* Otherwise the **held-out residual** of the fitted model is an upper bound (it holds the noise plus whatever the
  model misses): it can refute a given noise that is too large, never one that is too small.

A disagreement by more than :data:`DISAGREE` either way (for an upper bound: the given noise above it) is a one-line
warning.  When the given noise is refuted as too large, the acceptance rule of the selection measures the gap against
a zero floor (stricter: every effect must remove a material share of the whole held-out RMS) instead of a floor the
data contradict; with repeats, the floor is rescaled to the estimate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import DiagnosisData

#: ratio between given and estimated noise above which the diagnosis warns
DISAGREE = 1.5


@dataclass
class NoiseEstimate:
    given_mm: float                 # per-coordinate 1-sigma in use (RMS over the poses' covariances)
    estimated_mm: float | None      # per-coordinate 1-sigma from the data (None: no repeats and no residual yet)
    how: str                        # "repeats (k groups, m rows)" or "held-out residual (upper bound)"
    upper_bound: bool

    @property
    def ratio(self) -> float:
        return self.given_mm / self.estimated_mm if self.estimated_mm else float("nan")

    @property
    def given_too_large(self) -> bool:
        return self.estimated_mm is not None and self.ratio > DISAGREE

    @property
    def given_too_small(self) -> bool:
        return not self.upper_bound and self.estimated_mm is not None and self.ratio < 1 / DISAGREE

    def warning(self, source: str) -> str:
        """One line, or "" when the given noise is consistent with the data."""
        if self.given_too_large:
            return (f"{source}: the given noise {self.given_mm:.4g} mm is {self.ratio:.1f}x the "
                    f"{'upper bound' if self.upper_bound else 'estimate'} {self.estimated_mm:.4g} mm from the "
                    f"{self.how}; the gap is judged against the data's noise")
        if self.given_too_small:
            return (f"{source}: the given noise {self.given_mm:.4g} mm is {1 / self.ratio:.1f}x smaller than the "
                    f"estimate {self.estimated_mm:.4g} mm from the {self.how}; the gap is judged against the data's "
                    f"noise")
        return ""

    def floor_scale(self) -> float:
        """Factor for the floor the selection judges against: 1 when consistent, the estimate's ratio with
        repeats, 0 when only an upper bound refutes the given noise (see the module docstring)."""
        if self.given_too_large and self.upper_bound:
            return 0.0
        if self.given_too_large or self.given_too_small:
            return 1.0 / self.ratio
        return 1.0

    def as_dict(self) -> dict:
        return {"given_mm": self.given_mm, "estimated_mm": self.estimated_mm, "from": self.how,
                "upper_bound": self.upper_bound}


def given_sigma_mm(data: DiagnosisData) -> float:
    """Per-coordinate 1-sigma of the covariances in use (RMS over poses and coordinates)."""
    return float(np.sqrt(np.mean(np.trace(data.cov_mm2, axis1=1, axis2=2)) / 3.0))


def repeat_groups(data: DiagnosisData) -> list[np.ndarray]:
    """Rows measured at the same joint readings (to 1e-7 rad) and the same target: groups of two or more."""
    key = [tuple(np.round(q, 7)) for q in data.q_rad]
    if "target" in data.labels:
        key = [k + (t,) for k, t in zip(key, data.labels["target"])]
    groups: dict = {}
    for i, k in enumerate(key):
        groups.setdefault(k, []).append(i)
    return [np.array(g) for g in groups.values() if len(g) >= 2]


def estimate(data: DiagnosisData, heldout_rms_mm: float | None = None) -> NoiseEstimate:
    """From repeats when there are any, else the held-out residual (3-D RMS) as an upper bound."""
    given = given_sigma_mm(data)
    groups = repeat_groups(data)
    if groups:
        ss = sum(float(np.sum((data.points_mm[g] - data.points_mm[g].mean(0)) ** 2)) for g in groups)
        dof = 3 * sum(len(g) - 1 for g in groups)
        rows = sum(len(g) for g in groups)
        return NoiseEstimate(given, float(np.sqrt(ss / dof)), f"repeats ({len(groups)} poses, {rows} rows)", False)
    if heldout_rms_mm is None:
        return NoiseEstimate(given, None, "", True)
    return NoiseEstimate(given, float(heldout_rms_mm / np.sqrt(3.0)), "held-out residual (upper bound)", True)
