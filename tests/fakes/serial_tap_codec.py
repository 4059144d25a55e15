"""Hand-written serial-tap framing primitives, independent of ``acq.encoders.cobs_codec``.

* the independent writer for tests: CRC-16/CCITT-FALSE bit by bit and COBS straight from Cheshire & Baker (they
  check the driver's C-backed codec against a second reading of protocols.md §6.4);
* the former pure-Python codec (table-driven CRC, byte-loop COBS decoder with its error messages): the baseline of
  ``benchmarks/bench_tap_serial.py`` and the reference the codec's decode must keep agreeing with.
"""
from __future__ import annotations

import struct

from acq.encoders.cobs_codec import FrameError

_PAYLOAD = struct.Struct("<BHI6i")


def crc16_ccitt_false_bitwise(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), bit by bit; check(b"123456789") == 0x29B1."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def cobs_encode_simple(data: bytes) -> bytes:
    """Consistent Overhead Byte Stuffing, written straight from Cheshire & Baker (no 0x00 in the output)."""
    out = bytearray()
    block = bytearray()
    for b in data:
        if b == 0:
            out.append(len(block) + 1)
            out += block
            block.clear()
        else:
            block.append(b)
            if len(block) == 254:
                out.append(255)
                out += block
                block.clear()
    out.append(len(block) + 1)
    out += block
    return bytes(out)


def serial_frame_simple(version: int, seq: int, t_us: int, counts) -> bytes:
    """One whole tap frame with its 0x00 delimiter, by the independent writer."""
    payload = _PAYLOAD.pack(version, seq, t_us, *counts)
    return cobs_encode_simple(payload + struct.pack("<H", crc16_ccitt_false_bitwise(payload))) + b"\x00"


# -- the former codec (pure Python, until issue 18) -------------------------------------------------------------------
def _ccitt_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return table


_CCITT = _ccitt_table()


def legacy_crc16_ccitt_false(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ _CCITT[((crc >> 8) ^ b) & 0xFF]
    return crc


def legacy_cobs_decode(data: bytes) -> bytes:
    out = bytearray()
    i, n = 0, len(data)
    while i < n:
        code = data[i]
        if code == 0:
            raise FrameError("zero byte inside a COBS frame")
        end = i + code
        if end > n:
            raise FrameError("COBS block runs past the end of the frame")
        block = data[i + 1:end]
        if 0 in block:
            raise FrameError("zero byte inside a COBS block")
        out += block
        i = end
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)
