"""What other parts of robocal read from a session database (the diagnosis, for one), without knowing the schema."""
from __future__ import annotations

from .exchange import pose_arrays


def diagnosis_arrays(path: str) -> dict:
    """The contract of :func:`calib.diagnose.data.session_observations`: the pose-set observations of a session
    (``q_rad``, ``points_mm``, ``cov_mm2``, ``procedure``, ``sighting_angle_deg``, ``raw_angles``)."""
    return pose_arrays(str(path))
