"""GeoCOM ASCII: pure request encoding and reply decoding (no I/O), per protocols.md §1.2-1.6.

Request ``%R1Q,<rpc>,<trid>[,<crc>]:<params>\\r\\n``; reply ``%R1P,<rc_com>,<trid>[,<crc>]:<rc>[,<values>]\\r\\n``.
The optional CRC is CRC-16/ARC in decimal over the frame without the CRC field and without the terminator
(empirical, GeoComPy).  Everything is strict: a reply that does not follow the grammar raises :class:`CodecError`,
so a garbled reply can never become a reading.  Angles cross this boundary in radians, as on the wire.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from enum import IntEnum
from typing import Callable, Sequence

TERM = b"\r\n"
MAX_TRID = 2 ** 15


class CodecError(ValueError):
    """A frame or value that does not follow the GeoCOM grammar; the message is the cause, for an error line."""


# -- CRC-16/ARC (table driven; the emulator has its own bitwise copy on purpose) -------------------------------------
def _arc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        table.append(crc)
    return table


_ARC = _arc_table()


def crc16_arc(data: bytes) -> int:
    """CRC-16/ARC: poly 0x8005 reflected, init 0, no xorout; check(b"123456789") == 0xBB3D."""
    crc = 0
    for b in data:
        crc = (crc >> 8) ^ _ARC[(crc ^ b) & 0xFF]
    return crc


# -- values -------------------------------------------------------------------------------------------------------
def fmt_double(x: float, decimals: int = 12) -> str:
    """A double as plain decimal (>= 10 decimals keeps 1e-10 rad); no exponent, no spaces."""
    if not math.isfinite(x):
        raise CodecError(f"cannot send non-finite number {x!r}")
    text = f"{x:.{decimals}f}"
    return "0." + "0" * decimals if text.strip("-0.") == "" else text


def fmt_long(n: int) -> str:
    return f"{int(n):d}"


def fmt_bool(b: bool) -> str:
    return "1" if b else "0"


def fmt_string(s: str) -> str:
    out = []
    for ch in s:
        if ch in '\\"%~':
            out.append("\\" + ch)
        elif 0x20 <= ord(ch) <= 0x7E:
            out.append(ch)
        elif ord(ch) <= 0xFF:
            out.append(f"\\x{ord(ch):02X}")
        else:
            raise CodecError(f"character {ch!r} cannot be sent in a GeoCOM string")
    return '"' + "".join(out) + '"'


_DOUBLE = re.compile(r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?\Z")
_LONG = re.compile(r"[-+]?\d+\Z")
_HEX = re.compile(r"0[xX][0-9a-fA-F]+\Z")
_BYTE = re.compile(r"'([0-9a-fA-F]{2})'\Z")


def parse_double(s: str) -> float:
    """A finite double: ``1e400`` (inf after float()) is not a number any instrument sends."""
    if len(s) > 64 or not _DOUBLE.match(s):
        raise CodecError(f"{s[:40]!r} is not a GeoCOM double")
    x = float(s)
    if not math.isfinite(x):
        raise CodecError(f"{s[:40]!r} is out of the range of a double")
    return x


#: a GeoCOM long is 32 bit: 10 decimal digits (plus sign) or 8 hex digits at most
_LONG_MAX_CHARS = 11


def parse_long(s: str) -> int:
    if len(s) <= _LONG_MAX_CHARS and _LONG.match(s):
        return int(s)
    if len(s) <= 10 and _HEX.match(s):
        return int(s, 16)
    raise CodecError(f"{s[:40]!r} is not a GeoCOM long")


def parse_bool(s: str) -> bool:
    if s not in ("0", "1"):
        raise CodecError(f"{s!r} is not a GeoCOM boolean (0/1)")
    return s == "1"


def parse_byte(s: str) -> int:
    m = _BYTE.match(s)
    if not m:
        raise CodecError(f"{s!r} is not a GeoCOM byte ('hh')")
    return int(m.group(1), 16)


def parse_string(s: str) -> str:
    if len(s) < 2 or s[0] != '"' or s[-1] != '"':
        raise CodecError(f"{s!r} is not a quoted GeoCOM string")
    body, out, i = s[1:-1], [], 0
    while i < len(body):
        ch = body[i]
        if ch == "\\":
            if body[i + 1:i + 2] == "x" and re.match(r"[0-9a-fA-F]{2}", body[i + 2:i + 4]):
                out.append(chr(int(body[i + 2:i + 4], 16)))
                i += 4
                continue
            if i + 1 < len(body):
                out.append(body[i + 1])
                i += 2
                continue
            raise CodecError(f"{s!r} ends in a lone backslash")
        if ch == '"':
            raise CodecError(f"{s!r} has an unescaped quote")
        out.append(ch)
        i += 1
    return "".join(out)


class IncPrg(IntEnum):
    """TMC_INCLINE_PRG: how the instrument gets the inclination for its corrections."""
    MEA = 0
    AUTO = 1
    PLANE = 2


class MeasPrg(IntEnum):
    """TMC_MEASURE_PRG for TMC_DoMeasure."""
    STOP = 0
    DEF_DIST = 1
    CLEAR = 3
    SIGNAL = 4
    DO_MEASURE = 6
    RTRK_DIST = 8
    RED_TRK_DIST = 10
    FREQUENCY = 11


class BapPrg(IntEnum):
    """BAP_MEASURE_PRG for BAP_MeasDistanceAngle."""
    NO_MEAS = 0
    NO_DIST = 1
    DEF_DIST = 2
    CLEAR_DIST = 5
    STOP_TRK = 6


class PosMode(IntEnum):
    NORMAL = 0
    PRECISE = 1
    FAST = 2


class AtrMode(IntEnum):
    POSITION = 0
    TARGET = 1


PARSERS: dict[str, Callable[[str], object]] = {
    "double": parse_double, "long": parse_long, "bool": parse_bool, "byte": parse_byte, "string": parse_string,
}


# -- RPC table ----------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RpcSpec:
    """One remote procedure: its reply value types, its timeout and whether repeating it is harmless."""

    rpc: int
    name: str
    reply: tuple[str, ...] = ()
    timeout_s: float = 3.0
    idempotent: bool = True


_SPECS = [
    RpcSpec(0, "COM_NullProc"),
    RpcSpec(107, "COM_SetDoublePrecision"),
    RpcSpec(108, "COM_GetDoublePrecision", ("long",)),
    RpcSpec(110, "COM_GetSWVersion", ("long", "long", "long")),
    RpcSpec(111, "COM_SwitchOnTPS", timeout_s=30.0),
    RpcSpec(112, "COM_SwitchOffTPS", timeout_s=10.0),
    RpcSpec(2003, "TMC_GetAngle1", ("double", "double", "double", "long", "double", "double", "double", "long",
                                    "long")),
    RpcSpec(2006, "TMC_SetInclineSwitch"),
    RpcSpec(2007, "TMC_GetInclineSwitch", ("bool",)),
    RpcSpec(2008, "TMC_DoMeasure", idempotent=False),
    RpcSpec(2014, "TMC_GetAngSwitch", ("bool", "bool", "bool", "bool")),
    RpcSpec(2016, "TMC_SetAngSwitch"),
    RpcSpec(2026, "TMC_GetFace", ("long",)),
    RpcSpec(2107, "TMC_GetAngle5", ("double", "double")),
    RpcSpec(2108, "TMC_GetSimpleMea", ("double", "double", "double"), timeout_s=20.0),
    RpcSpec(2117, "TMC_QuickDist", ("double", "double", "double"), timeout_s=20.0),
    RpcSpec(5003, "CSV_GetInstrumentNo", ("long",)),
    RpcSpec(5004, "CSV_GetInstrumentName", ("string",)),
    RpcSpec(5008, "CSV_GetDateTime", ("long", "byte", "byte", "byte", "byte", "byte")),
    RpcSpec(5011, "CSV_GetIntTemp", ("double",)),
    RpcSpec(5034, "CSV_GetSWVersion", ("long", "long", "long")),
    RpcSpec(9027, "AUT_MakePositioning", timeout_s=30.0),
    RpcSpec(9028, "AUT_ChangeFace", timeout_s=30.0, idempotent=False),
    RpcSpec(17017, "BAP_MeasDistanceAngle", ("double", "double", "double", "long"), timeout_s=30.0,
            idempotent=False),
]
RPCS: dict[int, RpcSpec] = {s.rpc: s for s in _SPECS}


def spec(rpc: int) -> RpcSpec:
    return RPCS.get(rpc) or RpcSpec(rpc, f"RPC {rpc}")


# -- frames -------------------------------------------------------------------------------------------------------
def encode_request(rpc: int, params: Sequence[str] = (), trid: int | None = None, checksum: bool = False) -> bytes:
    """The request frame with terminator.  ``params`` are already formatted (fmt_* helpers)."""
    if not 0 <= rpc <= 65535:
        raise CodecError(f"RPC number {rpc} outside 0..65535")
    if trid is None and checksum:
        trid = 0
    head = f"%R1Q,{rpc}" + ("" if trid is None else f",{trid}")
    body = ",".join(params)
    if checksum:
        crc = crc16_arc(f"{head}:{body}".encode("ascii"))
        head += f",{crc}"
    return f"{head}:{body}".encode("ascii") + TERM


@dataclass(frozen=True)
class Reply:
    """A decoded reply frame; ``fields`` are the raw value strings after the RC (strings still quoted)."""

    rc_com: int
    trid: int
    rc: int
    fields: tuple[str, ...]
    crc: int | None
    raw: bytes


#: the reply grammar of protocols.md §1.3: the RPC return code after the colon is never missing
_REPLY = re.compile(r"%R1P,(\d{1,5}),(\d{1,5})(?:,(\d{1,5}))?:(\d{1,5})(?:,(.*))?\Z")


def split_fields(text: str) -> tuple[str, ...]:
    """Split on commas outside double-quoted strings (a string may contain a comma)."""
    if '"' not in text:                     # no string (every angle reply): the commas all separate
        return tuple(text.split(","))
    out, cur, quoted, esc = [], [], False, False
    for ch in text:
        if esc:
            cur.append(ch)
            esc = False
        elif ch == "\\" and quoted:
            cur.append(ch)
            esc = True
        elif ch == '"':
            cur.append(ch)
            quoted = not quoted
        elif ch == "," and not quoted:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    if quoted:
        raise CodecError("unterminated string in reply")
    out.append("".join(cur))
    return tuple(out)


def decode_reply(frame: bytes, expect_checksum: bool = False) -> Reply:
    """Decode one reply line (terminator already removed).  Raises CodecError on any deviation from the grammar."""
    try:
        text = frame.decode("ascii")
    except UnicodeDecodeError:
        raise CodecError(f"non-ASCII bytes in reply {frame[:60]!r}") from None
    if not text.isprintable():              # ASCII already: printable is exactly 0x20..0x7E
        raise CodecError(f"control characters in reply {frame[:60]!r}")
    m = _REPLY.match(text)
    if not m:
        raise CodecError(f"not a GeoCOM reply: {text[:60]!r}")
    rc_com, trid, crc, rc, values = m.groups()
    if crc is not None:
        start, end = m.span(3)
        if crc16_arc((text[:start - 1] + text[end:]).encode("ascii")) != int(crc):
            raise CodecError(f"checksum mismatch in reply {text[:60]!r}")
    elif expect_checksum and not (3072 <= int(rc_com) <= 3110 and values is None):
        # only a bare communication error (e.g. 3110 NO_CHECKSUM) may come back without the requested CRC
        raise CodecError(f"reply without the checksum that was requested: {text[:60]!r}")
    fields = split_fields(values) if values is not None else ()
    return Reply(int(rc_com), int(trid), int(rc), fields, None if crc is None else int(crc), frame)


def decode_values(rpc_spec: RpcSpec, fields: Sequence[str]) -> tuple:
    """Typed values of a reply; the count must match the RPC's reply exactly."""
    if len(fields) != len(rpc_spec.reply):
        raise CodecError(f"{rpc_spec.name} reply has {len(fields)} values, expected {len(rpc_spec.reply)}")
    return tuple([PARSERS[t](f) for t, f in zip(rpc_spec.reply, fields)])
