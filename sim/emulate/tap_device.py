"""Emulated encoder tap: the world's joint angles -> six latched motor-encoder counts, at a fixed rate.

CAN packing is written here from protocols.md §6.2 with :mod:`struct` (not with the driver's cantools codec), so the
receiver is checked against an independent writer; serial frames go through the driver's codec
(``acq.encoders.cobs_codec``: C-backed CRC and COBS, one formula), and the tests check that codec against the
independent writer in ``tests/fakes/serial_tap_codec.py``.

* CAN: TapStatus (0x103: seq u16, t_us u32, flags u8, pot_valid u8) opens a sample, then JointEnc12/34/56
  (0x100-0x102: two int32 little-endian each).
* Serial: ``COBS(payload ‖ CRC-16/CCITT-FALSE little-endian) ‖ 0x00`` with the 31-byte payload
  ``ver u8 | seq u16 | t_us u32 | j1..j6 i32``.

Counts are ``rint(robot.counts_from_joint(q))`` plus an optional offset (to exercise the int32 wrap), wrapped to
signed 32 bit as a real counter register would.
"""
from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from calib.errors import RobocalError
from calib.robot import Robot

from acq.encoders.cobs_codec import TapFrame, encode_frame
from sim.emulate.device import DeviceBase
from sim.emulate.world import World

STATUS_ID, DATA_IDS = 0x103, (0x100, 0x101, 0x102)
#: fastest sample rate the emulated tap offers (4 CAN frames a sample: ~2,000 samples/s fill a 1 Mbit/s bus)
MAX_RATE_HZ = 10_000.0
_STATUS = struct.Struct("<HIBB")
_PAIR = struct.Struct("<ii")


@dataclass(frozen=True)
class RawSample:
    seq: int              # u16 on the wire
    t_us: int             # u32 on the wire
    counts: tuple[int, ...]   # int32 (wrapped)
    flags: int = 0
    pot_valid: int = 0x3F


def wrap_i32(x: int) -> int:
    return ((int(x) + 2 ** 31) % 2 ** 32) - 2 ** 31


class TapModel:
    """Latches samples from the world on a schedule; the harness decides how they travel."""

    def __init__(self, world: World, robot: Robot, *, rate_hz: float = 500.0,
                 clock: Callable[[], float] = time.monotonic, count_offset: np.ndarray | int = 0, seq0: int = 0,
                 max_backlog_s: float = 0.25):
        if not 0.0 < rate_hz <= MAX_RATE_HZ:                 # also refuses NaN
            raise RobocalError(f"emulated tap: rate {rate_hz!r} samples/s is not in (0, {MAX_RATE_HZ:g}]")
        self.world = world
        self.robot = robot
        self.rate_hz = float(rate_hz)
        self.clock = clock
        self.count_offset = np.broadcast_to(np.asarray(count_offset, dtype=np.int64), (robot.n,)).copy()
        self.seq = seq0
        self.flags = 0
        self._t0: float | None = None
        self._made = 0
        self.max_backlog = max(1, int(self.rate_hz * max_backlog_s))
        self.skipped = 0
        self._last: tuple = (None, ())          # (readings and offsets, their counts): see _counts

    def latch(self, t_s: float | None = None) -> RawSample:
        """The sample the tap latches now, stamped ``t_s`` seconds (default the clock's now: a simulated clock's harness
        latches a window's samples at once and passes each one's scheduled time)."""
        t_s = self.clock() if t_s is None else t_s
        s = RawSample(self.seq & 0xFFFF, int(t_s * 1e6) & 0xFFFFFFFF, self._counts(), self.flags)
        self.seq += 1
        return s

    def _counts(self) -> tuple[int, ...]:
        """The wrapped counts of the joints' present readings; kept while the readings (and offsets) stay the same:
        an encoder window latches tens of samples of one pose, each the same conversion."""
        q = self.world.joint_angles_rad()
        key = (q.tobytes(), self.count_offset.tobytes())
        if key != self._last[0]:
            counts = np.rint(self.robot.counts_from_joint(q)).astype(np.int64) + self.count_offset
            self._last = (key, tuple(wrap_i32(c) for c in counts))
        return self._last[1]

    def due(self, now_s: float | None = None) -> int:
        """How many samples the schedule owes now (a stalled harness skips, like a tap overrunning its buffer)."""
        now_s = self.clock() if now_s is None else now_s
        if self._t0 is None:
            self._t0 = now_s
        owed = int((now_s - self._t0) * self.rate_hz) + 1 - self._made
        if owed > self.max_backlog:
            self.skipped += owed - self.max_backlog
            self._made += owed - self.max_backlog
            self.seq += owed - self.max_backlog          # the tap's counter runs on: the receiver sees the gap
            owed = self.max_backlog
        self._made += max(owed, 0)
        return max(owed, 0)


def can_frames(s: RawSample) -> list[tuple[int, bytes]]:
    """The four CAN frames of one sample, status first."""
    c = s.counts
    return [(STATUS_ID, _STATUS.pack(s.seq, s.t_us, s.flags, s.pot_valid)),
            (DATA_IDS[0], _PAIR.pack(c[0], c[1])), (DATA_IDS[1], _PAIR.pack(c[2], c[3])),
            (DATA_IDS[2], _PAIR.pack(c[4], c[5]))]


def serial_frame(s: RawSample, version: int = 1) -> bytes:
    """The sample as the serial tap sends it, framed by the driver's codec (the wire format is written once)."""
    return encode_frame(TapFrame(version, s.seq, s.t_us, s.counts))


class SerialTapDevice(DeviceBase):
    """The tap on a plain serial line: streams COBS frames; ignores input (it has no commands)."""

    label = "serialtap"

    def __init__(self, world: World, robot: Robot, *, rate_hz: float = 500.0,
                 clock: Callable[[], float] = time.monotonic, **model_kw):
        super().__init__(clock)
        self.model = TapModel(world, robot, rate_hz=rate_hz, clock=clock, **model_kw)
        self.tick_period_s = min(0.01, 1.0 / self.model.rate_hz)

    def feed(self, data: bytes) -> None:
        pass

    def tick(self, now: float | None = None) -> None:
        with self.lock:
            n = self.model.due(now)
            if n:
                self.emit(b"".join(serial_frame(self.model.latch()) for _ in range(n)))
