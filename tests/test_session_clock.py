"""Simulated time for emulated sessions (issue 18 item 4): the emulated tap's windows come from a SimClock's advances
through the real CAN reader, a real session and the TUI's ``--emulate`` keep real time.  No wall-time assertions:
what is checked is which clock runs what, and that a simulated window holds exactly its own samples."""
from __future__ import annotations

import can
import numpy as np
import pytest

from acq.clock import RealClock, SimClock
from sim.emulate.can_node import CanTapNode
from sim.emulate.tap_device import TapModel
from acq.encoders.can_tap import open_can_tap
from app.demo import _tap_drain, build_demo
from acq.session.rig import Rig
from calib.loading import load_robot
from tests.fakes.worlds import channel, quiet_world

ROBOT = load_robot()


def test_sim_clock_moves_only_when_slept_on_and_runs_ticks_then_drains():
    clock, seen = SimClock(5.0), []
    tick = clock.drive(lambda now: seen.append(("tick", now)))
    clock.add_drain(lambda: seen.append(("drain", clock.now())))
    assert clock() == clock.now() == 5.0
    clock.sleep(0.25)
    assert seen == [("tick", 5.25), ("drain", 5.25)]
    tick.stop()
    tick.stop()                                     # idempotent
    clock.sleep(-1.0)                               # time never runs backwards
    assert clock.now() == 5.25 and seen[-1] == ("drain", 5.25) and len(seen) == 3
    assert clock.simulated and not RealClock().simulated


def _sim_rig(rate_hz: float = 500.0):
    clock = SimClock()
    ch = channel()
    node = CanTapNode(can.Bus(interface="virtual", channel=ch),
                      TapModel(quiet_world(), ROBOT, rate_hz=rate_hz, clock=clock), own_bus=True)
    rig = Rig({}, open_can_tap("virtual", ch, robot=ROBOT), clock=clock)
    rig.start()                                         # the reader listens before the node's first sample
    node.start()
    clock.add_drain(_tap_drain(rig, node))
    return clock, node, rig


def test_simulated_capture_holds_its_window_through_the_real_reader():
    clock, node, rig = _sim_rig(500.0)
    try:
        assert node._thread.ident is None              # no sender thread: the clock drives the node
        assert rig.tap.polled and rig.tap._thread is None   # no reader thread: the clock's thread hands it the frames
        cap = rig.capture(0.02, settle_s=0.02)
        # settle 20 ms then a 20 ms window at 500 samples/s: the window's 10 samples, none of the settle's
        assert clock.now() == 0.04
        assert cap.n == 10 and rig.received == node.samples_sent == 21
        assert np.all(np.diff(cap.seq) == 1) and np.all(np.diff(cap.t_device_us) == 2000)
        assert cap.seq[0] == 11 and cap.t_device_us[0] == 22_000 and cap.t_device_us[-1] == 40_000
        clock.sleep(1.0)                                # time passing between captures is not captured
        cap = rig.capture(0.01, settle_s=0.0, min_samples=8)
        assert cap.n >= 8 and cap.seq[0] > 21 + 490
    finally:
        rig.close()
        node.stop()


class _SlowRig:
    """A rig whose tap reader has delivered ``received`` samples and gets no further while the drain waits."""

    def __init__(self, received: int):
        self.received = received

    def wait_received(self, n: int, timeout_s: float) -> bool:
        return self.received >= n


class _Node:
    samples_sent = 5


def test_a_late_reader_fails_the_attempt_and_is_waited_for_again_never_written_off():
    """A virtual bus loses nothing, it is only late: samples written off would land in the next window, stamped
    before its move, and bias that reading silently.  The drain fails the attempt as a device timeout instead, and
    the next wait (the repeated capture's start) waits for every sample sent again."""
    from acq.errors import DeviceTimeout

    rig = _SlowRig(received=3)
    drain = _tap_drain(rig, _Node(), timeout_s=0.01)
    with pytest.raises(DeviceTimeout, match="3 of the 5 samples"):
        drain()
    with pytest.raises(DeviceTimeout):             # still behind: still waited for, never written off
        drain()
    rig.received = 5                                # the stragglers arrive: the next window opens after them
    drain()


def test_a_polled_reader_short_of_what_the_node_sent_fails_at_once():
    """Polled (the simulated clock: no reader thread), every frame the node sent is on the bus when the drain runs;
    a reader still short then is short of frames the bus lost: a device timeout at once, not a wait for frames that
    cannot come.  The real reader still decodes every frame (the counts are the bus's)."""
    from acq.errors import DeviceTimeout
    clock, node, rig = _sim_rig(500.0)
    try:
        clock.sleep(0.01)
        assert rig.received == node.samples_sent == 6
        node.samples_sent += 1                      # one sample the bus "lost"
        with pytest.raises(DeviceTimeout, match="7 of the 8 samples"):
            clock.sleep(0.002)                      # one more sample sent and read: still one short
    finally:
        rig.close()
        node.stop()


def test_demo_is_simulated_and_the_tui_emulation_real(tmp_path, monkeypatch):
    plan = {"procedures": ["ruler"], "ruler": {"repeats": 1}, "seed": 1}
    d = build_demo(tmp_path / "s.db", seed=1, plan=plan)
    try:
        assert d.runner.rig.clock.simulated
    finally:
        d.close()
    import app.demo as demo
    from app.commands.session import emulated_builder

    class Built(Exception):
        pass

    def fake_build_demo(*args, **kw):
        raise Built(kw["clock"])
    monkeypatch.setattr(demo, "build_demo", fake_build_demo)
    with pytest.raises(Built) as got:
        emulated_builder(str(tmp_path / "t.db"), 1)(None)
    assert isinstance(got.value.args[0], RealClock)
