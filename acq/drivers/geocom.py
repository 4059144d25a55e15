"""Leica GeoCOM ASCII driver (TPS1000/1100/1200, TM/TS class): one synchronous request/reply at a time.

Why it looks like this: the instrument is strictly synchronous and may lose requests if pipelined (protocols.md
§1.2), so a call writes one request and waits for the reply with *its* transaction id, discarding stale replies of
earlier timed-out calls.  After a timeout or a garbled reply the link is resynchronised (LF, drain) and only
idempotent RPCs are repeated (a repeated ChangeFace would turn the telescope back).  A lost port is reopened and
the handshake repeated.  Every failure is a :class:`~acq.errors.DeviceError` naming device, RPC and cause.

Every call that needs values goes through :meth:`GeoComTheodolite.get`: a warning code sent without values
(1283-1289 alone) is an :class:`~acq.errors.InstrumentError` naming the code, never an IndexError; a distance sent
with an angles-only code (1285, 1288, 1289) is never returned; a physical value outside its envelope (an angle
outside [0, 2 pi], a negative or absurd distance, an impossible temperature) is a ProtocolError, like a garbled reply.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Sequence

from ..errors import DeviceError, DeviceTimeout, InstrumentError, LinkLost, ProtocolError
from ..link import SerialLink, SerialSettings
from . import geocom_codec as gc
from .base import AngleReading, DeviceInfo, SerialInstrument
from .geocom_codes import ANGLES_ONLY, ReturnCode, describe

DRIVER_NAME = "geocom"
DEFAULT_BAUD = 19200
#: codes meaning "request refused, nothing done" (busy, request checksum bad): sending it again is safe
_REFUSED = {13, 1293, 3101}
#: plausibility envelopes of physical values: beyond them a reply is garbled, whatever its grammar says
MAX_DISTANCE_M = 1.0e5
TEMPERATURE_RANGE_C = (-80.0, 120.0)
_TAU_HI = math.tau + 1e-9


@dataclass(frozen=True)
class Result:
    """A completed call: the return code (OK, or a warning whose values are usable) and the typed values."""

    rc: ReturnCode
    values: tuple
    reply: gc.Reply
    t_wall: float
    t_mono: float

    @property
    def warnings(self) -> tuple[str, ...]:
        return () if self.rc.code == 0 else (f"{self.rc.code} GRC_{self.rc.name}: {self.rc.text}",)


class GeoComTheodolite(SerialInstrument):
    """A GeoCOM instrument behind an injected link (anything with SerialLink's write/read_until/drain/reopen)."""

    driver = DRIVER_NAME

    def __init__(self, link: SerialLink, *, name: str | None = None, checksum: bool = False, attempts: int = 2,
                 reconnect: bool = True, retry_delay_s: float = 0.05):
        self.link = link
        self.name = name or link.name
        self.checksum = checksum
        self.attempts = max(1, attempts)
        self.reconnect_enabled = reconnect
        self.retry_delay_s = retry_delay_s
        self.precision = 15
        self._trid = 0
        self.stale_replies = 0            # replies discarded for a wrong TrId (diagnostics)
        self.retries = 0

    # -- opening ----------------------------------------------------------------------------------------------------
    @classmethod
    def open(cls, url: str, *, name: str | None = None, baudrate: int = DEFAULT_BAUD, checksum: bool = False,
             handshake: bool = True, **options) -> "GeoComTheodolite":
        """Open ``url`` with :func:`serial.serial_for_url` (8N1) and run the connect handshake."""
        link = SerialLink(url, name=name, settings=SerialSettings(baudrate=baudrate))
        return cls._open_on(link, handshake, name=name, checksum=checksum, **options)

    def connect(self) -> None:
        """Clear the receiver buffer with a bare LF, ping (COM_NullProc) and sync the double precision."""
        self.link.write(b"\n", "connect")
        self.link.drain(0.02)
        self.request(0)
        self.precision = self.double_precision()

    def reconnect(self) -> None:
        """Reopen the port (after an unplug) and repeat the handshake."""
        self.link.reopen()
        self.link.write(b"\n", "reconnect")
        self.link.drain(0.02)
        self._call(gc.spec(0), (), None)

    # -- the one request path ---------------------------------------------------------------------------------------
    def request(self, rpc: int, params: Sequence[str] = (), *, timeout_s: float | None = None,
                attempts: int | None = None) -> Result:
        """Send one RPC (params pre-formatted with ``gc.fmt_*``) and return its result; raises DeviceError."""
        sp = gc.spec(rpc)
        tries = (attempts or self.attempts) if sp.idempotent else 1
        last: DeviceError | None = None
        attempt = 0
        while attempt < tries:
            if attempt:
                self.retries += 1
                time.sleep(self.retry_delay_s)
            attempt += 1
            try:
                if not self.link.is_open:
                    if not self.reconnect_enabled:
                        raise LinkLost(self.name, _cmd(sp), "port is closed")
                    self.reconnect()
                return self._call(sp, params, timeout_s)
            except InstrumentError as exc:
                if exc.code not in _REFUSED:
                    raise
                last = exc                      # refused, not executed: sending it again is safe for any RPC
                tries = max(tries, 2)
            except (DeviceTimeout, ProtocolError) as exc:
                last = exc
                self._resync()
            except LinkLost as exc:
                last = exc
                if not self.reconnect_enabled:
                    raise
        assert last is not None
        if attempt > 1:
            raise type(last)(*_reargs(last, f"{last.cause} (after {attempt} attempts)"))
        raise last

    def _call(self, sp: gc.RpcSpec, params: Sequence[str], timeout_s: float | None) -> Result:
        cmd = _cmd(sp)
        trid = self._trid
        self._trid = (self._trid + 1) % gc.MAX_TRID
        try:
            frame = gc.encode_request(sp.rpc, params, trid, self.checksum)
        except gc.CodecError as exc:
            raise ProtocolError(self.name, cmd, f"cannot encode request: {exc}") from None
        timeout = sp.timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout
        self.link.write(frame, cmd)
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DeviceTimeout(self.name, cmd, f"no reply with transaction id {trid} within {timeout:g} s")
            line = self.link.read_until(gc.TERM, remaining, cmd)
            t_mono, t_wall = time.monotonic(), time.time()
            line = line.strip(b"\r\n")
            if not line:
                continue
            try:
                rep = gc.decode_reply(line, self.checksum)
            except gc.CodecError as exc:
                raise ProtocolError(self.name, cmd, f"garbled reply: {exc}") from None
            if rep.trid != trid:
                self.stale_replies += 1
                continue
            break
        if rep.rc_com != 0:
            c = describe(rep.rc_com)
            raise InstrumentError(self.name, cmd, f"communication error {c.code} GRC_{c.name}: {c.text}", c.code)
        rc = describe(rep.rc)
        if not rc.usable:
            raise InstrumentError(self.name, cmd, f"instrument returned {rc.code} GRC_{rc.name}: {rc.text}", rc.code)
        if rc.code != 0 and not rep.fields:
            values: tuple = ()
        else:
            try:
                values = gc.decode_values(sp, rep.fields)
            except gc.CodecError as exc:
                raise ProtocolError(self.name, cmd, f"garbled reply: {exc}") from None
        return Result(rc, values, rep, t_wall, t_mono)

    def _resync(self) -> None:
        """After a timeout or garbage: LF clears the instrument's receive buffer; drop whatever is in ours."""
        try:
            self.link.write(b"\n", "resync")
            self.link.drain(0.05)
        except LinkLost:
            pass

    def get(self, rpc: int, params: Sequence[str] = (), **kw) -> Result:
        """A call whose values the caller needs: every value the RPC's reply has, or a DeviceError.

        A warning code (1283-1289 ...) may come without values; for a call that needs them that is an
        :class:`InstrumentError` naming the code, never an IndexError further down.
        """
        r = self.request(rpc, params, **kw)
        sp = gc.spec(rpc)
        if len(r.values) != len(sp.reply):
            raise InstrumentError(self.name, _cmd(sp), f"instrument returned {r.warnings[0]}, without values",
                                  r.rc.code)
        return r

    def _implausible(self, rpc: int, what: str) -> ProtocolError:
        return ProtocolError(self.name, _cmd(gc.spec(rpc)), f"implausible reply: {what}")

    # -- COM / CSV ----------------------------------------------------------------------------------------------------
    def null_proc(self) -> None:
        self.request(0)

    def double_precision(self) -> int:
        digits = self.get(108).values[0]
        if not 0 <= digits <= 15:
            raise self._implausible(108, f"double precision {digits} is not 0..15 digits")
        return int(digits)

    def set_double_precision(self, digits: int) -> None:
        self.request(107, [gc.fmt_long(digits)])
        self.precision = digits

    def identify(self) -> DeviceInfo:
        name = self.get(5004).values[0]
        serial_no = self.get(5003).values[0]
        geocom = self.get(110).values
        firmware = self.get(5034).values
        return DeviceInfo(DRIVER_NAME, self.link.url, name=str(name), serial=str(serial_no),
                          firmware=".".join(map(str, firmware)), protocol_version=".".join(map(str, geocom)))

    def internal_temperature_c(self) -> float:
        t = float(self.get(5011).values[0])
        if not TEMPERATURE_RANGE_C[0] <= t <= TEMPERATURE_RANGE_C[1]:
            raise self._implausible(5011, f"internal temperature {t:g} degC is outside "
                                          f"{TEMPERATURE_RANGE_C[0]:g}..{TEMPERATURE_RANGE_C[1]:g} degC")
        return t

    # -- TMC ----------------------------------------------------------------------------------------------------------
    def angles(self, inc: gc.IncPrg = gc.IncPrg.AUTO) -> AngleReading:
        """Hz, V (TMC_GetAngle5, RPC 2107), corrected with the inclination as ``inc`` says."""
        r = self.get(2107, [gc.fmt_long(inc)])
        hz, v = r.values
        return self._reading(r, 2107, hz, v)

    def angles_with_inclination(self, inc: gc.IncPrg = gc.IncPrg.AUTO) -> AngleReading:
        """Hz, V, accuracy, cross/length inclination and face (TMC_GetAngle1, RPC 2003)."""
        r = self.get(2003, [gc.fmt_long(inc)])
        hz, v, acc, t_ms, xinc, linc, _incacc, _inct, face = r.values
        if face not in (0, 1):
            raise self._implausible(2003, f"face {face} is not 0 or 1")
        if acc < 0:
            raise self._implausible(2003, f"angle accuracy {acc:g} rad is negative")
        for what, x in (("cross inclination", xinc), ("length inclination", linc)):
            if abs(x) > math.pi / 2:
                raise self._implausible(2003, f"{what} {x:g} rad is beyond +-pi/2")
        return self._reading(r, 2003, hz, v, face=face + 1, angle_accuracy_rad=acc,
                             incline_cross_rad=xinc, incline_length_rad=linc, t_device_ms=t_ms)

    def _reading(self, r: Result, rpc: int, hz: float, v: float, **extra) -> AngleReading:
        if not (-1e-9 <= hz <= _TAU_HI and -1e-9 <= v <= _TAU_HI):    # one test for the usual reading
            for what, val in (("Hz", hz), ("V", v)):
                if not -1e-9 <= val <= _TAU_HI:             # a reply rounded up to exactly 2 pi is still valid
                    raise self._implausible(rpc, f"{what} = {val!r} rad is outside [0, 2 pi]")
        dist = extra.get("slope_distance_m")
        if dist is not None and not 0 < dist <= MAX_DISTANCE_M:
            raise self._implausible(rpc, f"slope distance {dist!r} m is outside (0, {MAX_DISTANCE_M:g}] m")
        extra.setdefault("face", 2 if v % math.tau > math.pi else 1)
        return AngleReading(self.name, gc.spec(rpc).name, float(hz) % math.tau, float(v) % math.tau, r.t_wall,
                            r.t_mono, warnings=r.warnings, raw=r.reply.raw, **extra)

    def incline_switch(self) -> bool:
        return bool(self.get(2007).values[0])

    def set_incline_switch(self, on: bool) -> None:
        self.request(2006, [gc.fmt_bool(on)])

    def do_measure(self, prog: gc.MeasPrg = gc.MeasPrg.DEF_DIST, inc: gc.IncPrg = gc.IncPrg.AUTO) -> None:
        self.request(2008, [gc.fmt_long(prog), gc.fmt_long(inc)])

    def simple_measurement(self, wait_ms: int = 5000, inc: gc.IncPrg = gc.IncPrg.AUTO) -> AngleReading:
        """Hz, V and slope distance (TMC_GetSimpleMea); ``slope_distance_m`` is None when only angles are valid."""
        r = self.get(2108, [gc.fmt_long(wait_ms), gc.fmt_long(inc)], timeout_s=wait_ms / 1000 + 5)
        hz, v, dist = r.values
        return self._reading(r, 2108, hz, v, slope_distance_m=_distance(r, dist))

    def face(self) -> int:
        """1 = face I, 2 = face II."""
        f = self.get(2026).values[0]
        if f not in (0, 1):
            raise self._implausible(2026, f"face {f} is not 0 or 1")
        return int(f) + 1

    # -- AUT / BAP (motorised instruments) ---------------------------------------------------------------------------
    def position(self, hz_rad: float, v_rad: float, pos_mode: gc.PosMode = gc.PosMode.NORMAL,
                 atr: gc.AtrMode = gc.AtrMode.POSITION) -> None:
        """Turn the telescope to Hz/V (AUT_MakePositioning); with ``atr=TARGET`` it then locks onto the prism."""
        self.request(9027, [gc.fmt_double(hz_rad), gc.fmt_double(v_rad), gc.fmt_long(pos_mode), gc.fmt_long(atr),
                            "0"])

    def change_face(self, pos_mode: gc.PosMode = gc.PosMode.NORMAL, atr: gc.AtrMode = gc.AtrMode.POSITION) -> None:
        self.request(9028, [gc.fmt_long(pos_mode), gc.fmt_long(atr), "0"])

    def measure_distance_angle(self, prog: gc.BapPrg = gc.BapPrg.DEF_DIST) -> AngleReading:
        """Hz, V and distance (BAP_MeasDistanceAngle); ``slope_distance_m`` is None when only angles are valid."""
        r = self.get(17017, [gc.fmt_long(prog)])
        hz, v, dist, _prog = r.values
        return self._reading(r, 17017, hz, v, slope_distance_m=_distance(r, dist))


def _distance(r: Result, dist: float) -> float | None:
    """The distance of a reply, or None when its return code says only the angles are valid."""
    return None if r.rc.code in ANGLES_ONLY else float(dist)


def _cmd(sp: gc.RpcSpec) -> str:
    return f"{sp.name} (RPC {sp.rpc})"


def _reargs(exc: DeviceError, cause: str) -> tuple:
    if isinstance(exc, InstrumentError):
        return exc.device, exc.command, cause, exc.code
    return exc.device, exc.command, cause


def open_driver(url: str, **options) -> GeoComTheodolite:
    return GeoComTheodolite.open(url, **options)
