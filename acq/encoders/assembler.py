"""Pure sample assembly: decoded tap frames in, complete samples out, every loss counted.

Shared by the CAN and the serial tap (the serial frame carries a whole sample, the CAN tap four frames).  Sequence
gaps count lost samples; a status frame arriving before the previous sample's data completed counts an incomplete
sample (a lost data frame); data frames with no open sample are orphans (a lost status frame).  Incomplete samples are
never emitted.
"""
from __future__ import annotations

import time
from typing import Callable, Sequence

from .sample import EncoderSample, JointConverter, TapStats, Unwrapper

N_JOINTS = 6


class SampleAssembler:
    def __init__(self, converter: JointConverter | None = None, stats: TapStats | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.converter = converter
        self.stats = stats or TapStats()
        self.clock = clock
        self._seq = Unwrapper(16, signed=False)
        self._tus = Unwrapper(32, signed=False)
        self._cnt = [Unwrapper(32, signed=True) for _ in range(N_JOINTS)]
        self._last_counts: tuple = (None, None)     # (counts as sent, unwrapped) of the last sample
        self._last_seq: int | None = None
        self._open: list | None = None

    def reset(self) -> None:
        """After a reconnect: do not count the outage as a sequence gap (it is reported as a reconnect)."""
        self._last_seq = None
        self._open = None
        self._seq.reset()

    def status(self, seq: int, t_us: int, flags: int, pot_valid: int) -> None:
        """A TapStatus frame opens a sample."""
        if self._open is not None:
            self.stats.incomplete_samples += 1
        self._check_seq(seq)
        # [seq, t_us, flags, pot, counts by joint, joints still missing]
        self._open = [seq, t_us, flags, pot_valid, [None] * N_JOINTS, N_JOINTS]

    def data(self, first_joint: int, counts: Sequence[int]) -> EncoderSample | None:
        """A JointEnc frame: counts for joints first_joint, first_joint+1 (0-based); returns a completed sample."""
        o = self._open
        if o is None or o[4][first_joint] is not None:
            self.stats.orphan_frames += 1
            return None
        got = o[4]
        for k, c in enumerate(counts):
            if got[first_joint + k] is None:
                o[5] -= 1
            got[first_joint + k] = int(c)
        if o[5]:
            return None
        self._open = None
        return self._make(o[0], o[1], got, o[2], o[3])

    def whole(self, seq: int, t_us: int, counts: Sequence[int], flags: int = 0, pot_valid: int = 0) -> EncoderSample:
        """A frame carrying a complete sample (serial tap)."""
        self._check_seq(seq)
        return self._make(seq, t_us, list(counts), flags, pot_valid)

    def _check_seq(self, seq: int) -> None:
        u = self._seq(seq)
        if self._last_seq is not None:
            gap = u - self._last_seq - 1
            if gap > 0:
                self.stats.lost_samples += gap
        self._last_seq = u

    def _make(self, seq, t_us, counts, flags, pot) -> EncoderSample:
        wire = tuple(counts)
        if wire == self._last_counts[0]:        # a robot holding still: unwrapping the same counts changes nothing
            unwrapped = self._last_counts[1]
        else:
            unwrapped = tuple([w(c) for w, c in zip(self._cnt, wire)])
            self._last_counts = (wire, unwrapped)
        self.stats.samples += 1
        joint = self.converter.joint_rad(unwrapped) if self.converter is not None else None
        return EncoderSample(seq=self._last_seq, t_device_us=self._tus(t_us), counts_wire=wire,
                             counts=unwrapped, t_mono=self.clock(), t_wall=time.time(), flags=flags,
                             pot_valid=pot, joint_rad=joint)
