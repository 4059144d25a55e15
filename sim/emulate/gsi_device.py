"""Emulated Leica theodolite speaking GSI Online and streaming GSI-8/16 blocks (protocols.md §2).

Own parsing and formatting (not the driver's gsi_codec): commands framed on CR/LF; ``a``/``b``/``c`` -> ``?``;
``GET/M|I/WIxx[/WIyy..]`` -> the words (GSI-16 lines start with ``*``); ``SET/<p>/<v>`` -> ``?``;
``CONF/<p>`` -> ``pppp/vvvv``; ``PUT/...`` -> ``?``; anything else -> ``@W427``.  With ``stream_hz`` > 0 it also
sends a measurement block (WI 11, 21, 22, 31) on that schedule, like an operator pressing REC.
"""
from __future__ import annotations

import math
import re
import time
from typing import Callable

from calib.errors import RobocalError

from sim.emulate.device import DeviceBase
from sim.emulate.world import World, check_station

_GET = re.compile(rb"GET/([MI])((?:/WI\d{2,3})+)\Z")
_SET = re.compile(rb"SET/(\d{1,4})/(\d{1,6})\Z")
_CONF = re.compile(rb"CONF/(\d{1,4})\Z")
#: fastest block stream the emulator offers (a GSI-16 block is ~100 bytes: 20 blocks/s fill 19200 baud)
MAX_STREAM_HZ = 100.0
_UNIT = {"gon": ("2", 200.0 / math.pi, 5), "deg": ("3", 180.0 / math.pi, 5), "dms": ("4", None, 5)}


class GsiDevice(DeviceBase):
    label = "gsi"

    def __init__(self, world: World, station: str = "B", *, gsi16: bool = True, angle_unit: str = "gon",
                 stream_hz: float = 0.0, serial_no: int = 640054, instrument_type: str = "TC1100",
                 clock: Callable[[], float] = time.monotonic):
        super().__init__(clock)
        if angle_unit not in _UNIT:
            raise RobocalError(f"emulator gsi: angle unit {angle_unit!r} is not one of {', '.join(_UNIT)}")
        if not 0.0 <= stream_hz <= MAX_STREAM_HZ:          # also refuses NaN
            raise RobocalError(f"emulator gsi: stream rate {stream_hz!r} Hz is not 0 (off) .. {MAX_STREAM_HZ:g}")
        check_station(world, station, "gsi")
        self.world = world
        self.station = station
        self.gsi16 = gsi16
        self.angle_unit = angle_unit
        self.stream_hz = stream_hz
        self.serial_no = serial_no
        self.instrument_type = instrument_type
        self.face = 1
        self.block_no = 0
        self.params: dict[int, int] = {}
        self.requests: list[bytes] = []
        self._next_block: float | None = None
        self.tick_period_s = min(0.05, 1.0 / stream_hz) if stream_hz > 0 else None

    # -- words ------------------------------------------------------------------------------------------------------
    def _word(self, wi: int, info: str, data: str, sign: str = "+") -> str:
        width = 16 if self.gsi16 else 8
        return f"{wi:02d}.{info}{sign}{data.rjust(width, '0')[-width:]} "

    def _angle_word(self, wi: int, rad: float) -> str:
        code, scale, dec = _UNIT[self.angle_unit]
        if scale is None:                          # DDD.MMSSs
            tenths = int(round(math.degrees(rad) * 36000))
            d, rem = divmod(tenths, 36000)
            m, rem = divmod(rem, 600)
            val = d * 100000 + m * 1000 + rem
        else:
            val = int(round(rad * scale * 10 ** dec))
        return self._word(wi, "10" + code, str(val))   # compensator on (1), measured (0), unit

    def _words_for(self, wi: int, hz_v: tuple[float, float]) -> str | None:
        if wi == 21:
            return self._angle_word(21, hz_v[0])
        if wi == 22:
            return self._angle_word(22, hz_v[1])
        if wi == 31:
            fn = getattr(self.world, "slope_distance_m", None)
            if fn is None:
                return None
            return self._word(31, ".00", str(int(round(fn(self.station) * 1000))))
        if wi == 12:
            return self._word(12, "...", str(self.serial_no))
        if wi == 13:
            return self._word(13, "...", self.instrument_type)
        if wi == 11:
            return f"11{self.block_no % 10000:04d}+{str(self.block_no).rjust(16 if self.gsi16 else 8, '0')} "
        return None

    def _line(self, words: list[str], strip_last_blank: bool) -> bytes:
        text = "".join(words)
        if strip_last_blank:
            text = text[:-1]
        return (("*" if self.gsi16 else "") + text).encode("ascii") + b"\r\n"

    # -- commands ---------------------------------------------------------------------------------------------------
    def on_line(self, line: bytes) -> None:
        if not line:
            return
        self.requests.append(line)
        if line in (b"a", b"b", b"c"):
            self.emit(b"?\r\n")
            return
        m = _GET.match(line)
        if m:
            wis = [int(x) for x in re.findall(rb"\d+", m.group(2))]
            hz_v = self.world.sight(self.station, self.face)
            words = [self._words_for(wi, hz_v) for wi in wis]
            if any(w is None for w in words):
                self.emit(b"@W427\r\n")
                return
            self.emit(self._line(words, strip_last_blank=True))
            return
        m = _SET.match(line)
        if m:
            p, v = int(m.group(1)), int(m.group(2))
            if p == 137:
                if v not in (0, 1):
                    self.emit(b"@W427\r\n")
                    return
                self.gsi16 = v == 1
            self.params[p] = v
            self.emit(b"?\r\n")
            return
        m = _CONF.match(line)
        if m:
            p = int(m.group(1))
            v = (1 if self.gsi16 else 0) if p == 137 else self.params.get(p, 0)
            self.emit(f"{p:04d}/{v:04d}\r\n".encode("ascii"))
            return
        if line.startswith(b"PUT/"):
            self.emit(b"?\r\n")
            return
        self.emit(b"@W427\r\n")

    def tick(self, now: float | None = None) -> None:
        if self.stream_hz <= 0:
            return
        now = self.clock() if now is None else now
        with self.lock:
            if self._next_block is None:
                self._next_block = now
            if now < self._next_block:
                return
            self._next_block = max(self._next_block + 1.0 / self.stream_hz, now - 1.0)
            self.block_no += 1
            hz_v = self.world.sight(self.station, self.face)
            words = [self._words_for(wi, hz_v) for wi in (11, 21, 22, 31)]
            self.emit(self._line([w for w in words if w is not None], strip_last_blank=False))
