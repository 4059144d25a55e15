"""The serial (COBS + CRC-16) encoder tap: reference vectors, independent writer vs reader, faults."""
from __future__ import annotations

import uuid

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from acq.clock import SimClock
from sim.emulate import registry
from sim.emulate.pty_host import PtyHost
from sim.emulate.tap_device import RawSample, SerialTapDevice, serial_frame
from acq.encoders.cobs_codec import (FrameError, TapFrame, cobs_decode, cobs_encode, crc16_ccitt_false,
                                     decode_frame, encode_frame)
from acq.encoders.serial_tap import open_serial_tap
from calib.loading import load_robot
from tests.fakes.faults import FaultyDevice
from tests.fakes.serial_tap_codec import (cobs_encode_simple, crc16_ccitt_false_bitwise, legacy_cobs_decode,
                                          legacy_crc16_ccitt_false, serial_frame_simple)
from tests.fakes.worlds import quiet_world, until

ROBOT = load_robot()
WIRE = bytes.fromhex("07 01 02 01 40 e2 01 03 10 27 01 05 3c f6 ff ff 01 01 01 03 07 43 01 02 01 01 01 07 ff ff ff ff"
                     " 16 9c 00")


@pytest.mark.parametrize("raw,enc", [("00", "0101"), ("0000", "010101"), ("11220033", "0311220233"),
                                     ("11223344", "0511223344"), ("11000000", "0211010101")])
def test_cobs_reference_vectors(raw, enc):
    assert cobs_encode(bytes.fromhex(raw)).hex() == enc == cobs_encode_simple(bytes.fromhex(raw)).hex()
    assert cobs_decode(bytes.fromhex(enc)).hex() == raw


def test_crc_and_reference_frame():
    assert crc16_ccitt_false(b"123456789") == 0x29B1 == crc16_ccitt_false_bitwise(b"123456789")
    counts = (10000, -2500, 0, 17159, 1, -1)
    assert encode_frame(TapFrame(1, 0x0102, 123456, counts)) == WIRE
    assert serial_frame(RawSample(0x0102, 123456, counts)) == WIRE
    assert decode_frame(WIRE[:-1]).counts == counts


@settings(max_examples=100)
@given(st.binary(max_size=600))
def test_cobs_round_trip_both_writers(data):
    for enc in (cobs_encode(data), cobs_encode_simple(data)):
        assert 0 not in enc and cobs_decode(enc) == data


def test_crc_hqx_is_crc16_ccitt_false():
    """The codec's CRC is binascii.crc_hqx with init 0xFFFF: the catalogue check value and the former table loop."""
    import binascii
    assert binascii.crc_hqx(b"123456789", 0xFFFF) == 0x29B1
    data = bytes(range(256)) * 3
    assert crc16_ccitt_false(data) == legacy_crc16_ccitt_false(data) == crc16_ccitt_false_bitwise(data)


@settings(max_examples=300)
@given(st.one_of(st.binary(max_size=80), st.binary(min_size=1, max_size=80).map(lambda b: b.replace(b"\0", b"\1"))))
def test_cobs_decode_agrees_with_the_former_decoder(data):
    """Same output on every frame, and the same message on every damaged one, as the hand-written decoder."""
    try:
        want = legacy_cobs_decode(data)
    except FrameError as exc:
        with pytest.raises(FrameError, match=str(exc)):
            cobs_decode(data)
    else:
        assert cobs_decode(data) == want


@settings(max_examples=100)
@given(seq=st.integers(0, 0xFFFF), t_us=st.integers(0, 0xFFFFFFFF),
       counts=st.tuples(*[st.integers(-2 ** 31, 2 ** 31 - 1)] * 6))
def test_emulated_tap_frames_equal_the_independent_writer(seq, t_us, counts):
    assert serial_frame(RawSample(seq, t_us, counts)) == serial_frame_simple(1, seq, t_us, counts)


@settings(max_examples=200)
@given(pos=st.integers(0, 32), xor=st.integers(1, 255))
def test_any_corrupted_byte_is_rejected(pos, xor):
    b = bytearray(WIRE[:-1])
    b[pos] ^= xor
    if 0 in b:                    # a 0x00 would split the frame: the receiver sees two short frames
        return
    with pytest.raises(FrameError):
        decode_frame(bytes(b))


def _tap(url):
    return open_serial_tap(url, robot=ROBOT, name="encoder tap (serial)")


def test_serial_tap_over_url_matches_world():
    w = quiet_world()
    name = f"st-{uuid.uuid4().hex[:8]}"
    clock = SimClock()
    url = registry.publish(name, SerialTapDevice(w, ROBOT, rate_hz=512, clock=clock))
    with _tap(url) as tap:
        s = tap.read(1.0)
        for k in range(1, 21):               # 20 steps of 1/64 s (exact in binary) of simulated time: 8 samples each
            clock.sleep(1 / 64)
            assert until(lambda: tap.stats.samples >= 1 + 8 * k)
    registry.withdraw(name)
    assert s.counts == tuple(np.rint(ROBOT.counts_from_joint(w.joint_angles_rad())).astype(int))
    assert np.allclose(s.joint_rad, w.joint_angles_rad(), atol=2e-4)
    assert tap.stats.samples == 161 and tap.stats.lost_samples == 0 and tap.stats.bad_frames == 0


def test_serial_tap_over_pty_with_garbled_and_dropped_bytes():
    w = quiet_world()
    clock = SimClock()
    inner = SerialTapDevice(w, ROBOT, rate_hz=512, clock=clock)
    dev = FaultyDevice(inner, seed=3)
    dev.garble_byte_prob = 0.002
    dev.drop_byte_prob = 0.001
    expect = tuple(np.rint(ROBOT.counts_from_joint(w.joint_angles_rad())).astype(int))
    with PtyHost(dev) as host:
        tap = _tap(host.path)
        got = []
        tap.start(got.append)
        try:
            assert until(lambda: inner.model.seq >= 1)                       # the tap streams from t = 0
            for k in range(1, 65):           # 1 s of simulated time in steps of 1/64 s: 512 more samples
                clock.sleep(1 / 64)
                assert until(lambda: inner.model.seq >= 1 + 8 * k)          # the device has sent them
            assert until(lambda: tap.stats.samples + tap.stats.lost_samples >= 450 and tap.stats.bad_frames > 0)
        finally:
            tap.stop()
    st_ = tap.stats
    assert got and all(s.counts == expect for s in got)          # nothing garbled ever comes out
    assert st_.bad_frames > 0 and st_.lost_samples >= st_.bad_frames // 2


def test_serial_tap_reconnects_after_unplug():
    w = quiet_world()
    name = f"st-{uuid.uuid4().hex[:8]}"
    url = registry.publish(name, SerialTapDevice(w, ROBOT, rate_hz=200))
    tap = open_serial_tap(url, robot=ROBOT)
    tap.reconnect_delay_s = 0.05
    with tap:
        tap.read(1.0)
        registry.unplug(name)
        assert until(lambda: tap.stats.bus_errors >= 1)
        assert "unplugged" in tap.stats.last_error
        registry.replug(name)
        assert until(lambda: tap.stats.reconnects >= 1)
        while not tap._queue.empty():
            tap._queue.get_nowait()
        s = tap.read(1.0)
    registry.withdraw(name)
    assert tap.stats.reconnects >= 1 and s.joint_rad is not None
