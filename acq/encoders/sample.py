"""Encoder samples, the counts -> joint angle conversion, and wrap-around unwrapping.

Raw counts are always kept exactly as the tap sent them (``counts_wire``, signed 32-bit), next to the unwrapped
counts and the joint angles derived through the robot description: a wrong gear ratio or coupling constant must never
corrupt stored data, only a recomputable view of it (protocols.md §5.2).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calib.robot import Robot


@dataclass(frozen=True)
class EncoderSample:
    """One latched sample of the six motor encoders."""

    seq: int                          # unwrapped sample counter (wire: u16)
    t_device_us: int                  # unwrapped tap clock (wire: u32)
    counts_wire: tuple[int, ...]      # exactly as received, signed 32-bit
    counts: tuple[int, ...]           # unwrapped (continuous across the int32 wrap)
    t_mono: float                     # host receipt, time.monotonic()
    t_wall: float                     # host receipt, time.time()
    flags: int = 0
    pot_valid: int = 0
    joint_rad: np.ndarray | None = field(default=None, compare=False)


class JointConverter:
    """Encoder counts -> joint angles through gear ratios, counts per revolution and the coupling matrix.

    The map is linear, so it is taken once from :meth:`Robot.joint_from_counts` (applied to the identity) instead of
    solving per sample: same numbers, no second copy of the math.
    """

    def __init__(self, robot: Robot, offsets_counts: np.ndarray | None = None):
        self.robot = robot
        self.matrix = robot.joint_from_counts(np.eye(robot.n))          # row i: joints for one count on motor i
        self.offsets_counts = np.zeros(robot.n) if offsets_counts is None else np.asarray(offsets_counts, float)
        self._last: tuple = (None, None)        # (counts, matrix and offsets bytes), the joints they gave

    def joint_rad(self, counts) -> np.ndarray:
        """The joints of one sample's counts (a new array).  The last conversion is kept: a robot holding still sends
        the same counts in every sample of an encoder window (kept by the counts, the matrix and the offsets)."""
        key = (tuple(counts), self.matrix.tobytes(), self.offsets_counts.tobytes())
        if key != self._last[0]:
            self._last = (key, (np.asarray(counts, float) - self.offsets_counts) @ self.matrix)
        return self._last[1].copy()


class Unwrapper:
    """Continuous value from a wrapping counter of ``bits`` bits (signed or unsigned)."""

    def __init__(self, bits: int, signed: bool):
        self.mod = 1 << bits
        self.signed = signed
        self._last: int | None = None
        self._offset = 0

    def __call__(self, x: int) -> int:
        if self._last is not None:
            d = x - self._last
            if d > self.mod // 2:
                self._offset -= self.mod
            elif d < -self.mod // 2:
                self._offset += self.mod
        self._last = x
        return x + self._offset

    def reset(self) -> None:
        self._last, self._offset = None, 0


@dataclass
class TapStats:
    """Counters a session shows and stores: nothing lost silently."""

    frames: int = 0
    samples: int = 0
    lost_samples: int = 0             # sequence gaps
    incomplete_samples: int = 0       # a sample whose frames did not all arrive
    orphan_frames: int = 0            # data frame without its opening status frame
    bad_frames: int = 0               # undecodable frame, wrong length, bad CRC
    error_frames: int = 0             # CAN error frames seen
    bus_errors: int = 0               # interface exceptions (bus-off, ...)
    reconnects: int = 0
    last_error: str = ""
