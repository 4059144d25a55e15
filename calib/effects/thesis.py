"""The running errors the thesis measured on its Puma 560, in robocal's conventions (defaults of the twin)."""
from __future__ import annotations

from ..units import DEG, NM_PER_LBIN
from .base import Effect
from .joint_compliance import JointCompliance
from .transmission_error import TransmissionError


def thesis_effects() -> list[Effect]:
    """The effects the thesis measured on its Puma 560 (sections 5.4.2, 5.5.2)."""
    return [
        TransmissionError(4, 0.9, [0.050 * DEG], []),
        TransmissionError(6, 1.8, [0.047 * DEG], []),
        JointCompliance(3, 1.156e5 * NM_PER_LBIN, 1.223e5 * NM_PER_LBIN, 100 * NM_PER_LBIN),
        JointCompliance(4, 2.275e5 * NM_PER_LBIN, 1.698e5 * NM_PER_LBIN, 45 * NM_PER_LBIN),
    ]


#: the running errors the thesis measured, as specs for identification
THESIS_RUNNING_ERRORS = ("transmission_error:4:0.9", "transmission_error:6:1.8", "joint_compliance:3",
                         "joint_compliance:4", "cross_coupling:6:5")
