"""The emulated tap behind an SLCAN (Lawicel) serial adapter, for python-can's ``slcan`` interface over a pty.

Own parser of the ASCII protocol: commands end with CR; ``O``/``L`` open, ``C`` close, ``S0``-``S8``/``sXXYY``
bit rate, ``V`` version, ``N`` serial number, ``F`` status flags, ``Z0/Z1`` timestamps, ``t``/``T`` transmit;
success ``\\r``, failure ``\\a`` (BEL).  While open, the tap's frames go out as ``tIIILDD..\\r``.
"""
from __future__ import annotations

import re
import time
from typing import Callable

from calib.robot import Robot

from sim.emulate.device import DeviceBase
from sim.emulate.tap_device import TapModel, can_frames
from sim.emulate.world import World

_TX = re.compile(rb"t[0-7][0-9A-Fa-f]{2}[0-8](?:[0-9A-Fa-f]{2})*\Z|T[0-1][0-9A-Fa-f]{7}[0-8](?:[0-9A-Fa-f]{2})*\Z")


class SlcanTapDevice(DeviceBase):
    label = "slcan"

    def __init__(self, world: World, robot: Robot, *, rate_hz: float = 100.0,
                 clock: Callable[[], float] = time.monotonic, **model_kw):
        super().__init__(clock)
        self.model = TapModel(world, robot, rate_hz=rate_hz, clock=clock, **model_kw)
        self.tick_period_s = min(0.01, 1.0 / self.model.rate_hz)
        self.is_open = False
        self.bitrate_code: str | None = None
        self.received: list[bytes] = []          # frames the host transmitted

    def _lines(self) -> None:
        while True:
            i = self._inbuf.find(b"\r")
            if i < 0:
                if len(self._inbuf) > 1024:
                    self._inbuf.clear()
                return
            cmd = bytes(self._inbuf[:i]).strip(b"\n")
            del self._inbuf[:i + 1]
            self.emit(self._command(cmd))

    def _command(self, cmd: bytes) -> bytes:
        ok, bad = b"\r", b"\a"
        if not cmd:
            return ok
        c = cmd[:1]
        if c in (b"O", b"L") and len(cmd) == 1:
            if self.is_open:
                return bad
            self.is_open = True
            self.model._t0 = None
            self.model._made = 0
            return ok
        if c == b"C" and len(cmd) == 1:
            self.is_open = False
            return ok
        if c == b"S" and re.fullmatch(rb"S[0-8]", cmd):
            if self.is_open:
                return bad
            self.bitrate_code = cmd.decode()
            return ok
        if c == b"s" and re.fullmatch(rb"s[0-9A-Fa-f]{4}", cmd):
            return bad if self.is_open else ok
        if cmd == b"V":
            return b"V1013\r"
        if cmd == b"N":
            return b"NA123\r"
        if cmd == b"F":
            return b"F00\r"
        if re.fullmatch(rb"Z[01]", cmd):
            return ok
        if c in (b"t", b"T") and _TX.match(cmd):
            if not self.is_open:
                return bad
            self.received.append(cmd)
            return b"z\r" if c == b"t" else b"Z\r"
        return bad

    def tick(self, now: float | None = None) -> None:
        with self.lock:
            if not self.is_open:
                return
            n = self.model.due(now)
            if not n:
                return
            out = []
            for _ in range(n):
                for fid, data in can_frames(self.model.latch()):
                    out.append(f"t{fid:03X}{len(data)}{data.hex().upper()}\r".encode("ascii"))
            self.emit(b"".join(out))
