"""The CAN encoder tap: DBC vs the emulator's own packing, python-can virtual bus, SLCAN over a pty, losses."""
from __future__ import annotations

import time

import can
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from acq.clock import SimClock
from sim.emulate.can_node import CanTapNode
from sim.emulate.pty_host import PtyHost
from sim.emulate.slcan_device import SlcanTapDevice
from sim.emulate.tap_device import RawSample, TapModel, can_frames, wrap_i32
from acq.encoders.assembler import SampleAssembler
from acq.encoders.can_codec import TapCanCodec, load_dbc
from acq.encoders.can_tap import CanTap, open_can_tap
from acq.encoders.sample import JointConverter, Unwrapper
from acq.errors import DeviceTimeout
from calib.loading import load_robot
from tests.fakes.faults import BusFaults, FaultyBus, LossySendBus
from tests.fakes.worlds import channel, quiet_world, until

ROBOT = load_robot()
i32 = st.integers(-2 ** 31, 2 ** 31 - 1)


def test_dbc_reference_frame():
    fid, data = TapCanCodec().encode("JointEnc12", {"J1_Counts": 10000, "J2_Counts": -2500})
    assert (fid, data.hex()) == (0x100, "102700003cf6ffff")
    assert {m.name for m in load_dbc().messages} == {"JointEnc12", "JointEnc34", "JointEnc56", "TapStatus"}


@settings(max_examples=100)
@given(seq=st.integers(0, 65535), t=st.integers(0, 2 ** 32 - 1), counts=st.tuples(*[i32] * 6),
       flags=st.integers(0, 255))
def test_emulator_packing_agrees_with_dbc(seq, t, counts, flags):
    codec = TapCanCodec()
    frames = can_frames(RawSample(seq, t, counts, flags, 0x3F))
    assert frames[0][0] == 0x103
    assert codec.decode_status(frames[0][1]) == (seq, t, flags, 0x3F)
    got = [codec.decode_data(fid, data) for fid, data in frames[1:]]
    assert got == [(0, counts[0:2]), (2, counts[2:4]), (4, counts[4:6])]



def test_kept_decodings_equal_cantools_every_time():
    """The codec keeps each distinct data frame's decoding (a pose repeats its frames): every answer, repeated, new
    or after the memo filled and started again, equals cantools' decoding of that frame by a fresh codec."""
    from acq.encoders import can_codec
    rng = np.random.default_rng(7)
    kept, fresh = TapCanCodec(), TapCanCodec()
    pool = [(fid, rng.integers(0, 256, 8, dtype=np.uint8).tobytes()) for fid in (0x100, 0x101, 0x102) for _ in range(40)]
    frames = [pool[i] for i in rng.integers(0, len(pool), 3000)]
    frames += [(0x101, int(i).to_bytes(8, "little", signed=True)) for i in range(can_codec.MEMO_FRAMES + 50)]
    frames += frames[:500] + [(fid, bytes(8)) for fid in (0x100, 0x101, 0x102, 0x100)]      # same bytes, other ids
    for fid, data in frames:
        assert kept.decode_data(fid, data) == fresh._decode_data(fid, data)
    assert 0 < len(kept._memo) <= can_codec.MEMO_FRAMES
    with pytest.raises(KeyError):
        kept.decode_data(0x7FF, bytes(8))

@settings(max_examples=50)
@given(st.lists(st.floats(-2.5, 2.5), min_size=6, max_size=6))
def test_counts_joint_round_trip(q):
    conv = JointConverter(ROBOT)
    counts = ROBOT.counts_from_joint(np.array(q))
    assert np.allclose(conv.joint_rad(counts), q, atol=1e-9)


def test_the_kept_conversion_follows_counts_and_offsets():
    """The converter keeps its last conversion (a window of one pose repeats its counts): the same counts give the
    same joints in a new array each time, other counts or offsets changed in place their own joints."""
    conv, fresh = JointConverter(ROBOT), JointConverter(ROBOT)
    a, b = (tuple(int(c) for c in np.rint(ROBOT.counts_from_joint(np.full(6, x)))) for x in (0.3, -0.4))
    first = conv.joint_rad(a)
    again = conv.joint_rad(a)
    assert np.array_equal(first, again) and first is not again
    first[:] = 0.0                                       # the caller's array: nothing kept changes
    assert np.array_equal(conv.joint_rad(a), fresh.joint_rad(a))
    assert np.array_equal(conv.joint_rad(b), fresh.joint_rad(b)) and not np.allclose(conv.joint_rad(b), again)
    conv.offsets_counts[:] = 1000.0
    fresh.offsets_counts[:] = 1000.0
    assert np.array_equal(conv.joint_rad(b), fresh.joint_rad(b))


def test_unwrapper_crosses_int32_and_u16():
    u = Unwrapper(32, signed=True)
    xs = [2 ** 31 - 3, 2 ** 31 - 1, wrap_i32(2 ** 31 + 2), wrap_i32(2 ** 31 + 10)]
    assert [u(x) for x in xs] == [2 ** 31 - 3, 2 ** 31 - 1, 2 ** 31 + 2, 2 ** 31 + 10]
    s = Unwrapper(16, signed=False)
    assert [s(x) for x in (65534, 65535, 0, 1)] == [65534, 65535, 65536, 65537]



@settings(max_examples=60)
@given(steps=st.lists(st.tuples(st.integers(0, 3), st.lists(st.one_of(st.just(0), st.integers(-2 ** 30, 2 ** 30)),
                                                             min_size=6, max_size=6)), min_size=1, max_size=40),
       start=st.lists(i32, min_size=6, max_size=6))
def test_unwrapped_counts_follow_the_true_counts_held_or_moving(steps, start):
    """Samples of a robot that holds still (the same counts repeated, taken without unwrapping again) and moves
    (across the int32 wrap too): every sample's unwrapped counts are the first wire counts plus the true motion."""
    asm = SampleAssembler()
    true, first, got, want = list(start), None, [], []
    seq = 0
    for held, move in steps:
        true = [t + m for t, m in zip(true, move)]
        first = first or list(true)
        for _ in range(1 + held):
            s = asm.whole(seq, seq * 2000, [wrap_i32(t) for t in true])
            seq += 1
            assert s.counts_wire == tuple(wrap_i32(t) for t in true)
            got.append(s.counts)
            want.append(tuple(wrap_i32(t0) + t - t0 for t0, t in zip(first, true)))
    assert got == want

def _frames(seq, counts=(1, 2, 3, 4, 5, 6)):
    return can_frames(RawSample(seq, 1000 * seq, counts))


def _feed(asm, codec, frames):
    out = []
    for fid, data in frames:
        if fid == 0x103:
            asm.status(*codec.decode_status(data))
        else:
            s = asm.data(*codec.decode_data(fid, data))
            if s is not None:
                out.append(s)
    return out


def test_assembler_counts_every_kind_of_loss():
    codec, asm = TapCanCodec(), SampleAssembler()
    frames = [f for seq in range(65533, 65536) for f in _frames(seq)] + [f for seq in range(0, 6) for f in _frames(seq)]
    # seq 65535..0 wraps cleanly; then lose: a data frame of seq 1, the status of seq 3, the whole of seq 4 (idx 28-31);
    # seq 3 (status lost) and seq 4 are seen as a gap of 2 when seq 5 arrives
    lost_idx = {4 * 4 + 2, 6 * 4 + 0}
    frames = [f for i, f in enumerate(frames) if i not in lost_idx and not 28 <= i < 32]
    samples = _feed(asm, codec, frames)
    st_ = asm.stats
    assert [s.seq for s in samples] == [65533, 65534, 65535, 65536, 65538, 65541]
    assert st_.incomplete_samples == 1 and st_.orphan_frames == 3 and st_.lost_samples == 2
    assert all(s.counts == (1, 2, 3, 4, 5, 6) for s in samples)


def test_virtual_bus_samples_match_the_world():
    """On a simulated clock: 0.1 s after the move the node has sent exactly 50 more samples at 500/s, each of the
    new pose, stamped 2 ms apart, and the reader delivers them all in order."""
    w = quiet_world()
    ch = channel()
    clock = SimClock()
    tap = open_can_tap("virtual", ch, robot=ROBOT)
    node = CanTapNode(can.Bus(interface="virtual", channel=ch), TapModel(w, ROBOT, rate_hz=500, clock=clock),
                      own_bus=True)
    with tap, node:
        first = tap.read(1.0)
        w.command(np.radians([-20, -45, 100, 10, -30, 45]))
        clock.sleep(0.1)
        after = [tap.read(2.0) for _ in range(50)]
    s = after[-1]
    expect = np.rint(ROBOT.counts_from_joint(w.joint_angles_rad())).astype(int)
    assert all(a.counts == tuple(expect) == a.counts_wire for a in after)
    assert first.counts != s.counts
    quantum = 2 * np.pi / (ROBOT.counts_per_rev * np.abs(ROBOT.gear_ratio))
    assert np.all(np.abs(s.joint_rad - w.joint_angles_rad()) < 2 * quantum.max())
    assert tap.stats.lost_samples == 0 and tap.stats.incomplete_samples == 0 and tap.stats.samples == 51
    assert s.t_device_us - first.t_device_us == 100_000 and s.seq == first.seq + 50
    assert np.all(np.abs(np.diff([a.t_device_us for a in after]) - 2000) <= 1)        # whole microseconds


def test_int32_wrap_is_unwrapped_and_raw_kept():
    w = quiet_world()
    ch = channel()
    offset = 2 ** 31 - 1 - int(np.rint(ROBOT.counts_from_joint(w.joint_angles_rad()))[0])   # j1 sits at INT32_MAX
    tap = open_can_tap("virtual", ch, robot=ROBOT)
    model = TapModel(w, ROBOT, rate_hz=400, count_offset=np.array([offset, 0, 0, 0, 0, 0]))
    with tap, CanTapNode(can.Bus(interface="virtual", channel=ch), model, own_bus=True):
        tap.read(1.0)
        q = w.joint_angles_rad()
        q[0] += np.radians(1.0) * np.sign(ROBOT.gear_ratio[0])   # +174 counts on motor 1: across the wrap
        w.command(q)
        for _ in range(200):
            s = tap.read(1.0)
            if s.counts_wire[0] < 0:
                break
    assert s.counts_wire[0] < 0 and s.counts[0] > 2 ** 31 - 1
    assert s.counts[0] - s.counts_wire[0] == 2 ** 32


def test_lost_frames_on_the_bus_are_counted_never_emitted():
    w = quiet_world()
    ch = channel()
    tap = open_can_tap("virtual", ch, robot=ROBOT)
    sender = LossySendBus(can.Bus(interface="virtual", channel=ch), lambda i, m: i % 37 == 5)
    clock = SimClock()
    st_ = tap.stats
    with tap, CanTapNode(sender, TapModel(w, ROBOT, rate_hz=512, clock=clock)):
        for _ in range(40):                # simulated, in steps of 1/64 s (exact in binary; the node keeps at most
            clock.sleep(1 / 64)            # 0.25 s of backlog): 0.625 s, 321 samples, 1284 frames
        assert until(lambda: st_.samples + st_.incomplete_samples + st_.lost_samples >= 321)
    sender.shutdown()
    lost = len(range(5, 1284, 37))         # frames 5, 42, ...: 35 frames, each in another sample
    assert sender.lost == lost == 35 and sender.index == 1284
    assert st_.samples == 321 - lost and st_.incomplete_samples + st_.lost_samples == lost


def test_bus_off_and_error_frames_then_recovery():
    w = quiet_world()
    ch = channel()
    faults = BusFaults(error_frames=3)
    tap = CanTap(lambda: FaultyBus(can.Bus(interface="virtual", channel=ch), faults), converter=JointConverter(ROBOT),
                 name="encoder tap (test)", reconnect_delay_s=0.05)
    with tap, CanTapNode(can.Bus(interface="virtual", channel=ch), TapModel(w, ROBOT, rate_hz=200), own_bus=True):
        tap.read(1.0)
        faults.bus_off = True
        assert until(lambda: tap.stats.bus_errors >= 1)
        assert "bus-off" in tap.stats.last_error
        while not tap._queue.empty():
            tap._queue.get_nowait()
        with pytest.raises(DeviceTimeout, match="encoder tap \\(test\\): read sample: .*bus-off"):
            tap.read(0.2)
        faults.bus_off = False
        s = tap.read(2.0)
    assert s.counts == tuple(np.rint(ROBOT.counts_from_joint(w.joint_angles_rad())).astype(int))
    assert tap.stats.error_frames == 3 and tap.stats.reconnects >= 1 and faults.opens >= 2


def test_python_can_slcan_reads_the_emulated_tap():
    w = quiet_world()
    dev = SlcanTapDevice(w, ROBOT, rate_hz=100)
    with PtyHost(dev) as host:
        bus = can.Bus(interface="slcan", channel=host.path, bitrate=1_000_000, sleep_after_open=0)
        try:
            msgs = []
            deadline = time.monotonic() + 30        # a guard against a hang: python-can reads a real pty
            while len(msgs) < 8 and time.monotonic() < deadline:
                m = bus.recv(0.5)
                if m is not None:
                    msgs.append(m)
            assert bus.get_version(1.0) == (10, 13)        # "V1013": hardware 10, software 13
        finally:
            bus.shutdown()
    assert dev.bitrate_code == "S8"
    codec, asm = TapCanCodec(), SampleAssembler(JointConverter(ROBOT))
    start = next(i for i, m in enumerate(msgs) if m.arbitration_id == 0x103)
    samples = _feed(asm, codec, [(m.arbitration_id, bytes(m.data)) for m in msgs[start:]])
    assert samples and samples[0].counts == tuple(np.rint(ROBOT.counts_from_joint(w.joint_angles_rad())).astype(int))


def test_our_reader_over_slcan_pty():
    """The stream over a pty, on a simulated clock: 0.25 s after the first sample exactly 64 more have arrived at
    256/s (steps of 1/64 s, each read before the next), none lost."""
    w = quiet_world()
    clock = SimClock()
    dev = SlcanTapDevice(w, ROBOT, rate_hz=256, clock=clock)
    with PtyHost(dev) as host:
        with open_can_tap("slcan", host.path, robot=ROBOT, bitrate=1_000_000, sleep_after_open=0) as tap:
            s = tap.read(2.0)
            assert until(lambda: tap.stats.samples == dev.model.seq)       # the reader has what was sent so far
            first = tap.stats.samples
            for k in range(1, 17):
                clock.sleep(1 / 64)
                assert until(lambda: tap.stats.samples >= first + 4 * k), (k, tap.stats.samples - first)
    assert np.allclose(s.joint_rad, w.joint_angles_rad(), atol=1e-3)
    assert tap.stats.samples - first == 64 and tap.stats.lost_samples == 0
