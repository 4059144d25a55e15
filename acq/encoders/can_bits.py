"""How many bits a classic CAN 2.0A data frame occupies on the wire, stuff bits included (ISO 11898-1).  Pure.

Why: a bus-load figure that ignores stuff bits flatters the bus.  A sender that puts five equal bits in a row must
insert one complementary bit, from the start of frame to the end of the CRC sequence; the stuff bit counts in the
next run.  The fixed trailer (CRC delimiter, ACK slot, ACK delimiter, 7-bit end of frame) and the 3-bit intermission
before the next frame are not stuffed.  An 8-byte frame is 111 bits unstuffed and at most 135 bits stuffed.
"""
from __future__ import annotations

CRC15_POLY = 0x4599
#: CRC delimiter + ACK slot + ACK delimiter + end of frame + intermission: never stuffed
TRAILER_BITS = 1 + 1 + 1 + 7 + 3


def _bits(value: int, width: int) -> list[int]:
    return [(value >> i) & 1 for i in range(width - 1, -1, -1)]


def crc15(bits: list[int]) -> int:
    """The CAN CRC-15 (x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1, init 0) over SOF..data, bit by bit."""
    crc = 0
    for b in bits:
        nxt = b ^ (crc >> 14)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= CRC15_POLY
    return crc


def stuffable_bits(can_id: int, data: bytes) -> list[int]:
    """SOF, 11-bit identifier, RTR, IDE, r0, DLC, data and CRC-15 of a standard data frame, before stuffing."""
    if not 0 <= can_id < 2 ** 11 or len(data) > 8:
        raise ValueError(f"not a classic standard CAN data frame: id 0x{can_id:x}, {len(data)} data bytes")
    head = [0] + _bits(can_id, 11) + [0, 0, 0] + _bits(len(data), 4)
    for byte in data:
        head += _bits(byte, 8)
    return head + _bits(crc15(head), 15)


def stuff_bit_count(bits: list[int]) -> int:
    """Stuff bits a transmitter inserts into ``bits`` (after every fifth equal bit, the stuff bit starting the next
    run; also after the last bit when it completes a run of five)."""
    count, run, last = 0, 0, None
    for b in bits:
        if b == last:
            run += 1
        else:
            last, run = b, 1
        if run == 5:
            count += 1
            last, run = 1 - b, 1              # the complementary stuff bit opens the next run
    return count


def frame_bits(can_id: int, data: bytes) -> int:
    """Bits the frame holds the bus, stuff bits, trailer and intermission included."""
    bits = stuffable_bits(can_id, data)
    return len(bits) + stuff_bit_count(bits) + TRAILER_BITS


def _stuffable_len(n_data: int) -> int:
    """Bits from SOF to the end of the CRC of a standard data frame of ``n_data`` bytes, before stuffing."""
    return 1 + 11 + 3 + 4 + 8 * n_data + 15


def unstuffed_frame_bits(n_data: int) -> int:
    """The shortest a standard data frame of ``n_data`` bytes can be: no stuff bit (111 bits for 8 bytes)."""
    return _stuffable_len(n_data) + TRAILER_BITS


def worst_case_frame_bits(n_data: int) -> int:
    """The longest a standard data frame of ``n_data`` bytes can be: a stuff bit after every 4 bits past the first."""
    n = _stuffable_len(n_data)
    return n + (n - 1) // 4 + TRAILER_BITS
