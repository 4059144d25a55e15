"""CAN bit stuffing and frame length against frames worked out by hand (ISO 11898-1: stuffing over SOF..CRC)."""
from __future__ import annotations

import pytest

from acq.encoders.can_bits import (crc15, frame_bits, stuff_bit_count, stuffable_bits, TRAILER_BITS,
                                   worst_case_frame_bits)


def _b(text: str) -> list[int]:
    return [int(c) for c in text if c in "01"]


# id 0x133, data FF 00 00 00 00 00 00 FF, written out field by field; the CRC-15 0x185F is the value the CanOverhead
# project's tests give for this frame (not computed with this code)
FRAME_133 = _b("0 001 0011 0011 0 0 0 1000 11111111" + " 00000000" * 6 + " 11111111 001 1000 0101 1111")
# where the stuff bits go (s = stuff bit), counted by hand: after the first five 1s of the first data byte, then in
# the 48 zeros one after every five zeros (9; the stuff 1 opens no run of zeros), after five 1s of the last byte, and
# after the last CRC bit, which completes a run of five 1s
STUFFED_133 = ("0 001 0011 0011 0 0 0 1000 11111s111 00000s00000s00000s00000s00000s00000s00000s00000s00000s000"
               " 11111s111 001 1000 0101 1111s")


def test_hand_computed_frame():
    assert stuffable_bits(0x133, bytes.fromhex("ff000000000000ff")) == FRAME_133
    assert crc15(FRAME_133[:-15]) == 0x185F
    assert _b(STUFFED_133.replace("s", "")) == FRAME_133
    assert stuff_bit_count(FRAME_133) == STUFFED_133.count("s") == 12
    assert frame_bits(0x133, bytes.fromhex("ff000000000000ff")) == len(FRAME_133) + 12 + TRAILER_BITS == 123


def test_all_dominant_frame_stuffs_every_fifth_bit():
    bits = stuffable_bits(0, b"")                 # 34 zeros: SOF, id, RTR, IDE, r0, DLC 0, CRC 0
    assert bits == [0] * 34
    assert stuff_bit_count(bits) == 6 and frame_bits(0, b"") == 34 + 6 + 13


@pytest.mark.parametrize("bits,n", [("11111", 1), ("111110000", 2), ("1110101010", 0), ("1111", 0),
                                    ("000001111100000", 3), ("0000011110000", 3)])
def test_stuff_bit_runs(bits, n):
    assert stuff_bit_count(_b(bits)) == n


def test_bounds_of_an_eight_byte_frame():
    assert len(stuffable_bits(0x100, bytes(8))) + TRAILER_BITS == 111
    assert worst_case_frame_bits(8) == 135
    assert 111 <= frame_bits(0x7FF, b"\xaa" * 8) <= 135


def test_refuses_what_is_no_standard_frame():
    with pytest.raises(ValueError, match="id 0x800"):
        stuffable_bits(0x800, b"")
    with pytest.raises(ValueError, match="9 data bytes"):
        stuffable_bits(1, bytes(9))
