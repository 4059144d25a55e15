"""Emulated Leica GeoCOM theodolite (TM30-like, motorised): answers byte for byte like protocols.md §1.

Own strict parsing (never the driver's codec, so a shared misunderstanding cannot hide): requests
``%R1Q,<rpc>[,<trid>[,<crc>]]:<params>`` framed on CR/LF; empty lines and bare LF ignored; ``c`` answered ``?``.
Replies echo the TrId (0 if none), carry a CRC-16/ARC iff the request did, format doubles with the current double
precision.  Every reply follows the reply grammar of protocols.md §1.3, return code included: a communication-layer
fault travels in ``<RC_COM>`` with RPC return code 0 (the shape GeoComPy synthesises for its own COM errors):
unknown RPC -> ``%R1P,3081,<trid>:0``; undecodable request -> ``%R1P,3080,0:0``; bad request CRC ->
``%R1P,3101,<trid>,<crc>:0``.  A parameter of the wrong count, type or range (a 4,301-digit integer, ``1e400``)
-> RC 2 (IVPARAM).  No request can make the device raise.

State: incline switch, face, telescope pointing after AUT_MakePositioning (otherwise the operator keeps it on the
target and the world's ``sight`` is read), distance measured by TMC_DoMeasure (cleared by TMC_CLEAR), double
precision.  Fault hooks: :meth:`script_rc` makes the next calls of an RPC return a chosen code (warning codes keep
their values, as real instruments do).
"""
from __future__ import annotations

import math
import re
import time
from collections import defaultdict, deque
from typing import Callable

import numpy as np

from sim.emulate.device import DeviceBase
from sim.emulate.world import World, check_station

TWO_PI = 2 * math.pi
_REQ = re.compile(rb"%R1Q,(\d{1,5})(?:,(\d{1,5})(?:,(\d{1,5}))?)?:(.*)\Z")
_NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\Z")
_INT = re.compile(r"[-+]?\d+\Z|0[xX][0-9a-fA-F]+\Z")
#: TMC codes that come *with* values (GeoComPy: "angles are measured, but no valid distance")
_WITH_VALUES = {1283, 1284, 1285, 1288, 1289}


def crc16_arc_bitwise(data: bytes) -> int:
    """CRC-16/ARC, bit by bit (independent of the driver's table version)."""
    crc = 0
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


class _BadParam(Exception):
    pass


def _num(s: str) -> float:
    if len(s) > 64 or not _NUM.match(s):
        raise _BadParam(s)
    x = float(s)
    if not math.isfinite(x):
        raise _BadParam(s)
    return x


def _int(s: str) -> int:
    """A 32-bit GeoCOM long (decimal or 0x hex); anything longer is a bad parameter, not a ValueError."""
    if len(s) > 11 or not _INT.match(s):
        raise _BadParam(s)
    n = int(s, 16) if s[:2].lower() == "0x" else int(s)
    if not -2 ** 31 <= n < 2 ** 32:
        raise _BadParam(s)
    return n


class GeoComDevice(DeviceBase):
    label = "geocom"

    def __init__(self, world: World, station: str = "A", *, instrument_name: str = "TM30 0.5",
                 serial_no: int = 3216936, geocom_version: tuple[int, int, int] = (3, 50, 0),
                 firmware: tuple[int, int, int] = (2, 20, 1), motorised: bool = True, seed: int = 0,
                 clock: Callable[[], float] = time.monotonic):
        super().__init__(clock)
        check_station(world, station, "geocom")
        self.world = world
        self.station = station
        self.instrument_name = instrument_name
        self.serial_no = serial_no
        self.geocom_version = geocom_version
        self.firmware = firmware
        self.motorised = motorised
        self.rng = np.random.default_rng(seed)
        self.precision = 15
        self.incline_on = True
        self.face = 1                                   # 1 = face I, 2 = face II
        self.pointing: tuple[float, float] | None = None
        self.distance_ready = False
        self.ang_switch = [True, True, True, True]
        self._script: dict[int, deque[tuple[int, bool]]] = defaultdict(deque)
        self.requests: list[bytes] = []                 # every request line seen (tests inspect it)
        self._handlers: dict[int, Callable[[list[str]], tuple[int, list[str]]]] = {
            0: self._null, 107: self._set_precision, 108: self._get_precision, 110: self._sw_version,
            111: self._switch_on, 112: self._null, 2003: self._angle1, 2006: self._set_incline,
            2007: self._get_incline, 2008: self._do_measure, 2014: self._get_ang_switch, 2016: self._set_ang_switch,
            2026: self._get_face, 2107: self._angle5, 2108: self._simple_mea, 2117: self._quick_dist,
            5003: self._instrument_no, 5004: self._instrument_name, 5008: self._date_time, 5011: self._int_temp,
            5034: self._fw_version, 9027: self._make_positioning, 9028: self._change_face, 17017: self._bap_meas,
        }

    # -- fault hooks --------------------------------------------------------------------------------------------------
    def script_rc(self, rpc: int, rc: int, times: int = 1, *, with_values: bool | None = None) -> None:
        """The next ``times`` calls of ``rpc`` return ``rc``; values are kept for the TMC warning codes unless
        ``with_values`` says otherwise (a real instrument may send a warning code alone)."""
        keep = rc in _WITH_VALUES if with_values is None else with_values
        self._script[rpc].extend([(rc, keep)] * times)

    # -- framing ------------------------------------------------------------------------------------------------------
    def on_line(self, line: bytes) -> None:
        if not line:
            return
        self.requests.append(line)
        if line == b"c":
            self.emit(b"?\r\n")
            return
        m = _REQ.match(line)
        if not m or not (line.isascii() and line.decode("ascii").isprintable()):      # bytes 0x20..0x7E only
            self.emit(b"%R1P,3080,0:0\r\n")
            return
        rpc, trid, crc, params = int(m.group(1)), int(m.group(2) or 0), m.group(3), m.group(4)
        with_crc = crc is not None
        if with_crc:
            s, e = m.span(3)
            if crc16_arc_bitwise(line[:s - 1] + line[e:]) != int(crc):
                self._reply(3101, trid, 0, [], True)
                return
        handler = self._handlers.get(rpc)
        if handler is None:
            self._reply(3081, trid, 0, [], with_crc)
            return
        fields = params.decode("ascii").split(",") if params else []
        try:
            rc, values = handler(fields)
        except _BadParam:
            rc, values = 2, []
        if self._script[rpc]:
            rc, keep = self._script[rpc].popleft()
            values = values if keep else []
        self._reply(0, trid, rc, values, with_crc)

    def _reply(self, rc_com: int, trid: int, rc: int, values: list[str], with_crc: bool) -> None:
        body = ",".join([str(rc), *values])
        head = f"%R1P,{rc_com},{trid}"
        if with_crc:
            head += f",{crc16_arc_bitwise(f'{head}:{body}'.encode('ascii'))}"
        self.emit(f"{head}:{body}\r\n".encode("ascii"))

    def _d(self, x: float) -> str:
        return f"{x:.{self.precision}f}"

    @staticmethod
    def _n(fields: list[str], n: int) -> None:
        if len(fields) != n or "" in fields:
            raise _BadParam(fields)

    # -- what the telescope reads ----------------------------------------------------------------------------------
    def _read_angles(self) -> tuple[float, float]:
        if self.pointing is not None:
            hz, v = self.pointing
            sig = 0.15e-5
            return (hz + self.rng.normal(0, sig)) % TWO_PI, v + self.rng.normal(0, sig)
        return self.world.sight(self.station, self.face)

    def _distance_m(self) -> float | None:
        fn = getattr(self.world, "slope_distance_m", None)
        return None if fn is None else float(fn(self.station))

    # -- handlers: (rc, values) ------------------------------------------------------------------------------------
    def _null(self, f):
        return 0, []

    def _set_precision(self, f):
        self._n(f, 1)
        n = _int(f[0])
        if not 0 <= n <= 15:
            return 2, []
        self.precision = n
        return 0, []

    def _get_precision(self, f):
        self._n(f, 0)
        return 0, [str(self.precision)]

    def _sw_version(self, f):
        return 0, [str(x) for x in self.geocom_version]

    def _fw_version(self, f):
        return 0, [str(x) for x in self.firmware]

    def _switch_on(self, f):
        return 5, []                                    # already on (DMPACK)

    def _instrument_no(self, f):
        return 0, [str(self.serial_no)]

    def _instrument_name(self, f):
        return 0, ['"' + self.instrument_name.replace("\\", "\\\\").replace('"', '\\"') + '"']

    def _date_time(self, f):
        t = time.gmtime()
        return 0, [str(t.tm_year)] + [f"'{x:02x}'" for x in (t.tm_mon, t.tm_mday, t.tm_hour, t.tm_min, t.tm_sec)]

    def _int_temp(self, f):
        return 0, [self._d(21.5)]

    def _inc_mode(self, f) -> int:
        self._n(f, 1)
        mode = _int(f[0])
        if mode not in (0, 1, 2):
            raise _BadParam(f)
        return mode

    def _angle5(self, f):
        self._inc_mode(f)
        hz, v = self._read_angles()
        return 0, [self._d(hz), self._d(v)]

    def _angle1(self, f):
        self._inc_mode(f)
        hz, v = self._read_angles()
        t_ms = int(self.clock() * 1000) & 0x7FFFFFFF
        xinc, linc = self.rng.normal(0, 2e-6, 2) if self.incline_on else (0.0, 0.0)
        acc = 1.5e-6
        return 0, [self._d(hz), self._d(v), self._d(acc), str(t_ms), self._d(xinc), self._d(linc), self._d(acc),
                   str(t_ms), str(self.face - 1)]

    def _set_incline(self, f):
        self._n(f, 1)
        if f[0] not in ("0", "1"):
            raise _BadParam(f)
        self.incline_on = f[0] == "1"
        return 0, []

    def _get_incline(self, f):
        return 0, ["1" if self.incline_on else "0"]

    def _get_ang_switch(self, f):
        return 0, ["1" if b else "0" for b in self.ang_switch]

    def _set_ang_switch(self, f):
        self._n(f, 4)
        if any(x not in ("0", "1") for x in f):
            raise _BadParam(f)
        self.ang_switch = [x == "1" for x in f]
        return 0, []

    def _do_measure(self, f):
        self._n(f, 2)
        prog, _inc = _int(f[0]), _int(f[1])
        if prog in (1, 2, 6, 8, 10):
            self.distance_ready = self._distance_m() is not None
            return (0 if self.distance_ready else 1292), []
        if prog == 3:
            self.distance_ready = False
        elif prog not in (0, 4, 11):
            return 2, []
        return 0, []

    def _simple_mea(self, f):
        self._n(f, 2)
        _int(f[0]), _int(f[1])
        hz, v = self._read_angles()
        if not self.distance_ready:
            return 1285, [self._d(hz), self._d(v), self._d(0.0)]
        return 0, [self._d(hz), self._d(v), self._d(self._distance_m())]

    def _quick_dist(self, f):
        hz, v = self._read_angles()
        d = self._distance_m()
        if d is None:
            return 1285, [self._d(hz), self._d(v), self._d(0.0)]
        return 0, [self._d(hz), self._d(v), self._d(d)]

    def _get_face(self, f):
        return 0, [str(self.face - 1)]

    def _make_positioning(self, f):
        self._n(f, 5)
        hz, v, pos, atr, dummy = _num(f[0]), _num(f[1]), _int(f[2]), _int(f[3]), _int(f[4])
        if not self.motorised:
            return 5, []
        if pos not in (0, 1, 2) or atr not in (0, 1) or dummy != 0:
            return 2, []
        self.face = 2 if math.pi < (v % TWO_PI) < TWO_PI else 1
        self.pointing = None if atr == 1 else (hz % TWO_PI, v % TWO_PI)
        return 0, []

    def _change_face(self, f):
        self._n(f, 3)
        if not self.motorised:
            return 5, []
        self.face = 3 - self.face
        if self.pointing is not None:
            hz, v = self.pointing
            self.pointing = ((hz + math.pi) % TWO_PI, (TWO_PI - v) % TWO_PI)
        return 0, []

    def _bap_meas(self, f):
        self._n(f, 1)
        prog = _int(f[0])
        hz, v = self._read_angles()
        d = self._distance_m()
        if d is None or prog in (0, 1):
            return 1285, [self._d(hz), self._d(v), self._d(0.0), str(prog)]
        return 0, [self._d(hz), self._d(v), self._d(d), str(prog)]
