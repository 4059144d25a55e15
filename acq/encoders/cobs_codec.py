"""Serial tap framing: ``COBS(payload ‖ CRC-16/CCITT-FALSE LE) ‖ 0x00`` (protocols.md §6.4).  Pure.

Why COBS: 0x00 never occurs inside a frame, so the receiver resynchronises at the next 0x00 after any garbage or a
mid-frame start, with a fixed 1-byte overhead; the CRC then rejects whatever survived by chance.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

PAYLOAD = struct.Struct("<BHI6i")        # ver u8 | seq u16 | t_us u32 | j1..j6 i32
FRAME_LEN = PAYLOAD.size + 2             # 33 bytes decoded
VERSION = 1


class FrameError(ValueError):
    pass


def _ccitt_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return table


_CCITT = _ccitt_table()


def crc16_ccitt_false(data: bytes) -> int:
    """Poly 0x1021, init 0xFFFF, no reflection, no xorout; check(b"123456789") == 0x29B1."""
    crc = 0xFFFF
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ _CCITT[((crc >> 8) ^ b) & 0xFF]
    return crc


def cobs_encode(data: bytes) -> bytes:
    out = bytearray([0])
    code_at, code = 0, 1
    for b in data:
        if b:
            out.append(b)
            code += 1
        if not b or code == 0xFF:
            out[code_at] = code
            code_at, code = len(out), 1
            out.append(0)
    out[code_at] = code
    return bytes(out)


def cobs_decode(data: bytes) -> bytes:
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


@dataclass(frozen=True)
class TapFrame:
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
