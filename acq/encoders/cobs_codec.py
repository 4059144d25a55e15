"""Serial tap framing: ``COBS(payload ‖ CRC-16/CCITT-FALSE LE) ‖ 0x00`` (protocols.md §6.4).  Pure.

Why COBS: 0x00 never occurs inside a frame, so the receiver resynchronises at the next 0x00 after any garbage or a
mid-frame start, with a fixed 1-byte overhead; the CRC then rejects whatever survived by chance.

Why these calls: the CRC is the C ``binascii.crc_hqx`` (CRC-16/CCITT-FALSE is its polynomial with init 0xFFFF) and
COBS is the C extension of the ``cobs`` package (Cheshire & Baker's basic COBS): the emulated tap and the driver
both frame through this module, so the wire format is written once (``benchmarks/bench_tap_serial.py`` shows the
decode rate against the former pure-Python loops, kept in ``tests/fakes/serial_tap_codec.py``).
"""
from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass

from cobs import cobs as _cobs

PAYLOAD = struct.Struct("<BHI6i")        # ver u8 | seq u16 | t_us u32 | j1..j6 i32
FRAME_LEN = PAYLOAD.size + 2             # 33 bytes decoded
VERSION = 1


class FrameError(ValueError):
    pass


def crc16_ccitt_false(data: bytes) -> int:
    """Poly 0x1021, init 0xFFFF, no reflection, no xorout; check(b"123456789") == 0x29B1."""
    return binascii.crc_hqx(data, 0xFFFF)


def cobs_encode(data: bytes) -> bytes:
    """COBS without the 0x00 delimiter (a trailing run of exactly 254 non-zero bytes ends without a 0x01 block;
    decoders accept both forms)."""
    return _cobs.encode(data)


def cobs_decode(data: bytes) -> bytes:
    """Inverse of :func:`cobs_encode`; FrameError saying what is wrong with a damaged frame."""
    try:
        return _cobs.decode(data)
    except _cobs.DecodeError:
        raise FrameError(_cobs_fault(data)) from None


def _cobs_fault(data: bytes) -> str:
    """Why ``data`` is no COBS frame: walks the block codes (only on the error path, for the message)."""
    i, n = 0, len(data)
    while i < n:
        code = data[i]
        if code == 0:
            return "zero byte inside a COBS frame"
        end = i + code
        if end > n:
            return "COBS block runs past the end of the frame"
        if 0 in data[i + 1:end]:
            return "zero byte inside a COBS block"
        i = end
    return "not a COBS frame"


@dataclass(frozen=True)
class TapFrame:
    """One serial tap frame's payload: format version, sample counter, tap clock (us) and the six counts."""

    version: int
    seq: int
    t_us: int
    counts: tuple[int, ...]


def encode_frame(f: TapFrame) -> bytes:
    payload = PAYLOAD.pack(f.version, f.seq & 0xFFFF, f.t_us & 0xFFFFFFFF, *f.counts)
    return cobs_encode(payload + struct.pack("<H", crc16_ccitt_false(payload))) + b"\x00"


def decode_frame(encoded: bytes) -> TapFrame:
    """One frame without its 0x00 delimiter; FrameError on wrong length, bad CRC or unknown version."""
    raw = cobs_decode(encoded)
    if len(raw) != FRAME_LEN:
        raise FrameError(f"frame of {len(raw)} bytes, expected {FRAME_LEN}")
    payload, (crc,) = raw[:-2], struct.unpack("<H", raw[-2:])
    if crc16_ccitt_false(payload) != crc:
        raise FrameError("CRC mismatch")
    ver, seq, t_us, *counts = PAYLOAD.unpack(payload)
    if ver != VERSION:
        raise FrameError(f"unknown frame version {ver}")
    return TapFrame(ver, seq, t_us, tuple(counts))
