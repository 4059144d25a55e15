"""The diagnosis's view of the noise estimate (the estimator itself is :mod:`calib.noise`, shared with identify).

Why the diagnosis cares: the floor every gap is measured against comes from the instruments' covariance or
``--noise-mm``.  When the given noise is refuted as too large by the held-out residual alone (an upper bound), the
acceptance rule of the selection measures the gap against a zero floor (stricter: every effect must remove a material
share of the whole held-out RMS) instead of a floor the data contradict; with a model-free estimate (repeats, several
targets per pose, both faces) the floor is rescaled to the estimate.
"""
from __future__ import annotations

import numpy as np

from calib.noise import DISAGREE, NoiseEstimate, Sample, combine, model_free  # noqa: F401 (DISAGREE: re-export)
from calib import noise as _shared

from .data import DiagnosisData


def given_sigma_mm(data: DiagnosisData) -> float:
    """Per-coordinate 1-sigma of the covariances in use (RMS over poses and coordinates)."""
    return _shared.given_sigma_mm(data.cov_mm2)


def repeat_groups(data: DiagnosisData) -> list[np.ndarray]:
    """Rows measured at the same joint readings (to 1e-7 rad) and the same target: groups of two or more."""
    return _shared.repeat_groups(data.q_rad, data.labels.get("target"))


def sources(data: DiagnosisData) -> list[Sample]:
    """The model-free estimates the data allow (computed once per diagnosis: the both-faces one intersects)."""
    return model_free(data.q_rad, data.points_mm, data.cov_mm2, pose_id=data.pose_id or None,
                      target=data.labels.get("target"), sightings=data.sightings,
                      body=data.robot.tool_point_frames or None)


def estimate(data: DiagnosisData, heldout_rms_mm: float | None = None,
             found: list[Sample] | None = None) -> NoiseEstimate:
    """Model-free sources pooled when there are any, else the held-out residual (3-D RMS) as an upper bound."""
    found = sources(data) if found is None else found
    bound = None if heldout_rms_mm is None else float(heldout_rms_mm / np.sqrt(3.0))
    return combine(given_sigma_mm(data), found, bound)
