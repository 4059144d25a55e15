"""Leica GSI driver: GSI Online requests (``GET/M/WI21/WI22``) and the GSI-8/16 stream (blocks sent on REC).

Same reliability rules as GeoCOM: one request at a time, every call with a timeout, a garbled line raises
ProtocolError (never a reading), measurement requests are retried after a resync (a repeated measurement is
harmless), a lost port is reopened.  GSI has no transaction id: after a timeout the input is drained before the
retry so a late answer cannot be taken for the next one.
"""
from __future__ import annotations

import math
import time

from ..errors import DeviceError, DeviceTimeout, InstrumentError, LinkLost, ProtocolError
from ..link import SerialLink, SerialSettings
from . import gsi_codec as gsi
from .base import AngleReading, DeviceInfo, SerialInstrument

DRIVER_NAME = "gsi"
DEFAULT_BAUD = 19200
TWO_PI = math.tau
MAX_DISTANCE_M = 1.0e5


class GsiTheodolite(SerialInstrument):
    driver = DRIVER_NAME

    def __init__(self, link: SerialLink, *, name: str | None = None, attempts: int = 2, timeout_s: float = 5.0,
                 reconnect: bool = True):
        self.link = link
        self.name = name or link.name
        self.attempts = max(1, attempts)
        self.timeout_s = timeout_s
        self.reconnect_enabled = reconnect
        self.retries = 0

    @classmethod
    def open(cls, url: str, *, name: str | None = None, baudrate: int = DEFAULT_BAUD, parity: str = "N",
             bytesize: int = 8, handshake: bool = True, **options) -> "GsiTheodolite":
        link = SerialLink(url, name=name, settings=SerialSettings(baudrate=baudrate, parity=parity,
                                                                  bytesize=bytesize))
        return cls._open_on(link, handshake, name=name, **options)

    def connect(self) -> None:
        """``c`` (clear) must be answered ``?``: proves an instrument in GSI Online mode is there."""
        self.link.drain(0.02)
        self.request(b"c\r\n", "clear (c)", expect="ok")

    # -- request path ---------------------------------------------------------------------------------------------
    def request(self, frame: bytes, command: str, *, expect: str = "words", timeout_s: float | None = None,
                attempts: int | None = None) -> gsi.OnlineReply:
        tries = attempts or self.attempts
        last: DeviceError | None = None
        for attempt in range(tries):
            if attempt:
                self.retries += 1
            try:
                if not self.link.is_open:
                    if not self.reconnect_enabled:
                        raise LinkLost(self.name, command, "port is closed")
                    self.link.reopen()
                return self._call(frame, command, expect, timeout_s or self.timeout_s)
            except (DeviceTimeout, ProtocolError) as exc:
                last = exc
                self.link.drain(0.05)
            except LinkLost as exc:
                last = exc
                if not self.reconnect_enabled:
                    raise
        assert last is not None
        if tries > 1:
            raise type(last)(last.device, last.command, f"{last.cause} (after {tries} attempts)")
        raise last

    def _call(self, frame: bytes, command: str, expect: str, timeout_s: float) -> gsi.OnlineReply:
        self.link.write(frame, command)
        deadline = time.monotonic() + timeout_s
        while True:
            line = self.link.read_until(gsi.TERM, max(0.0, deadline - time.monotonic()), command)
            if line.strip():
                break
        try:
            rep = gsi.parse_online_reply(line)
        except gsi.GsiError as exc:
            raise ProtocolError(self.name, command, f"garbled reply: {exc}") from None
        if rep.kind in ("warning", "error"):
            what = gsi.ONLINE_CODES.get(rep.code, "see the GSI Online manual")
            tag = "W" if rep.kind == "warning" else "E"
            raise InstrumentError(self.name, command, f"instrument answered @{tag}{rep.code} ({what})", rep.code)
        if rep.kind != expect:
            raise ProtocolError(self.name, command, f"garbled reply: expected {expect}, got {line[:40]!r}")
        self._last_raw = line
        return rep

    # -- API --------------------------------------------------------------------------------------------------------
    def identify(self) -> DeviceInfo:
        serial_no = self._words([12], measure=False, command="GET/I/WI12")[12].text()
        inst = self._words([13], measure=False, command="GET/I/WI13")[13].text()
        return DeviceInfo(DRIVER_NAME, self.link.url, name=inst, serial=serial_no, protocol_version="GSI Online")

    def word_length(self) -> int:
        """8 or 16 (CONF/137)."""
        rep = self.request(gsi.conf_command(137), "CONF/137", expect="conf")
        return 16 if rep.value == 1 else 8

    def set_word_length(self, gsi16: bool) -> None:
        self.request(gsi.set_command(137, 1 if gsi16 else 0), "SET/137", expect="ok")

    def _words(self, wis: list[int], measure: bool, command: str) -> dict[int, gsi.Word]:
        rep = self.request(gsi.get_command(wis, measure), command)
        got = _known(rep.words)
        missing = [wi for wi in wis if wi not in got]
        if missing:
            raise ProtocolError(self.name, command, f"garbled reply: word(s) {missing} missing or unreadable")
        return got

    def angles(self) -> AngleReading:
        """Measure and return Hz and V (``GET/M/WI21/WI22``)."""
        cmd = "GET/M/WI21/WI22"
        words = self._words([21, 22], measure=True, command=cmd)
        t_mono, t_wall = time.monotonic(), time.time()
        try:
            hz, v = words[21].angle_rad(), words[22].angle_rad()
        except gsi.GsiError as exc:
            raise ProtocolError(self.name, cmd, f"garbled reply: {exc}") from None
        return _reading(self.name, cmd, hz, v, t_wall, t_mono, self._last_raw)

    def read_block(self, timeout_s: float = 5.0) -> AngleReading:
        """The next block an instrument streams (REC / ALL on the keyboard): Hz, V and, if present, distance."""
        cmd = "read GSI block"
        while True:
            line = self.link.read_until(gsi.TERM, timeout_s, cmd)
            if line.strip():
                break
        t_mono, t_wall = time.monotonic(), time.time()
        try:
            words = _known(gsi.parse_block(line))
            missing = [wi for wi in (21, 22) if wi not in words]
            if missing:
                raise gsi.GsiError(f"word(s) {missing} missing or unreadable")
            hz, v = words[21].angle_rad(), words[22].angle_rad()
            dist = words[31].length_m() if 31 in words else None
        except gsi.GsiError as exc:
            raise ProtocolError(self.name, cmd, f"garbled block: {exc}") from None
        return _reading(self.name, cmd, hz, v, t_wall, t_mono, line, slope_distance_m=dist)


def _known(words) -> dict[int, gsi.Word]:
    """Words by index; unknown words stay in the raw frame but never stand in for a value."""
    return {w.wi: w for w in words if w.known}


def _reading(device: str, cmd: str, hz: float, v: float, t_wall: float, t_mono: float, raw: bytes,
             **extra) -> AngleReading:
    for what, val in (("Hz", hz), ("V", v)):
        if not 0 <= val <= TWO_PI:                  # exactly 400.00000 gon is a valid reading (= 0)
            raise ProtocolError(device, cmd, f"implausible reply: {what} = {val!r} rad is outside 0..400 gon")
    dist = extra.get("slope_distance_m")
    if dist is not None and not 0 <= dist <= MAX_DISTANCE_M:
        raise ProtocolError(device, cmd, f"implausible reply: slope distance {dist!r} m is outside "
                                         f"0..{MAX_DISTANCE_M:g} m")
    hz, v = hz % TWO_PI, v % TWO_PI
    return AngleReading(device, cmd, hz, v, t_wall, t_mono, face=2 if v > TWO_PI / 2 else 1, raw=raw, **extra)


def open_driver(url: str, **options) -> GsiTheodolite:
    return GsiTheodolite.open(url, **options)
