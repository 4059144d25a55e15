"""The emulated tap as a node on a python-can bus (normally ``virtual``): frames sent on the tap's schedule.

Any bus object with ``send(msg)`` works, so tests wrap the bus to lose frames or inject errors, and a real
``socketcan`` vcan channel works the same way when one exists.

On a real clock (the model's default) a thread sends what the schedule owes every period.  On a simulated clock
(:class:`acq.clock.SimClock`, the demo) there is no thread: the clock calls :meth:`CanTapNode.pump` each time it
advances, and the frames of the elapsed window go out at once, stamped with their scheduled times.
"""
from __future__ import annotations

import queue
import threading
import time

import can
from can.interfaces.virtual import VirtualBus

from sim.emulate.pty_host import FailureHook, run_guarded
from sim.emulate.tap_device import TapModel, can_frames


class CanTapNode:
    def __init__(self, bus: can.BusABC, model: TapModel, *, own_bus: bool = False,
                 on_failure: FailureHook | None = None):
        self.bus = bus
        self.on_failure = on_failure
        self.failure: BaseException | None = None
        self.model = model
        self.own_bus = own_bus
        self.frames_sent = 0
        self.send_errors = 0
        self.samples_sent = 0               # samples whose four frames all went out (a lossless bus delivers them)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="can-tap-node", daemon=True)
        self._driven = None

    def start(self) -> "CanTapNode":
        clock = self.model.clock
        if getattr(clock, "simulated", False):
            self._driven = clock.drive(self.pump)
            self.pump(clock.now())              # the tap streams from now on, like a node powered up now
        else:
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._driven is not None:
            self._driven.stop()
        if self._thread.is_alive():
            self._thread.join(2.0)
        if self.own_bus:
            self.bus.shutdown()

    def __enter__(self) -> "CanTapNode":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def describe(self) -> str:
        return f"the CAN tap node on {getattr(self.bus, 'channel_info', 'its bus')}"

    def close(self) -> None:
        self.stop()

    def _run(self) -> None:
        run_guarded(self, self._serve)

    def _serve(self) -> None:
        period = 1.0 / self.model.rate_hz
        step = max(period, 0.001)
        while not self._stop.is_set():
            self.pump()
            self._stop.wait(step)
            time.sleep(0)

    def pump(self, now_s: float | None = None) -> int:
        """Send the samples the schedule owes at ``now_s`` seconds (default the model's clock), the last one stamped
        ``now_s`` and the others a period apart before it; returns how many."""
        n = self.model.due(now_s)
        if n and now_s is not None:
            period = 1.0 / self.model.rate_hz
            times = [now_s - (n - 1 - k) * period for k in range(n)]
        else:
            times = [None] * n
        for t_s in times:
            ok = True
            for fid, data in can_frames(self.model.latch(t_s)):
                try:
                    self.bus.send(can.Message(arbitration_id=fid, data=data, is_extended_id=False))
                    self.frames_sent += 1
                except can.CanError:
                    self.send_errors += 1
                    ok = False
            self.samples_sent += ok
        return n


class SenderVirtualBus(VirtualBus):
    """python-can's ``virtual`` bus for a sender that never touches a message after sending it (the emulated tap
    builds a fresh one per frame): a lone receiver (the tap reader) gets the sent message itself, stamped with the
    fields python-can gives a copy (timestamp, channel, is_rx); several receivers each get a new
    :class:`can.Message` made from the sent one's fields.  python-can's own ``send`` runs ``copy.deepcopy`` for
    each (5-8x slower: the payload's bytearray goes through ``copyreg``; a third of the demo's encoder emulation).
    Same channel semantics otherwise (timestamps, own messages, a full queue)."""

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        timestamp = msg.timestamp if self.preserve_timestamps else time.time()
        receivers = [q for q in self.channel if q is not self.queue or self.receive_own_messages]
        if len(receivers) == 1:         # the one receiver takes the sent message itself, stamped as a copy would be
            msg.timestamp, msg.channel, msg.is_rx = timestamp, self.channel_id, receivers[0] is not self.queue
            try:
                receivers[0].put(msg, block=True, timeout=timeout)
            except queue.Full:
                raise can.CanOperationError("Could not send message to one or more recipients") from None
            return
        all_sent = True
        for bus_queue in receivers:
            copy = can.Message(timestamp=timestamp, arbitration_id=msg.arbitration_id,
                               is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                               is_error_frame=msg.is_error_frame, channel=self.channel_id, dlc=msg.dlc,
                               data=bytes(msg.data), is_fd=msg.is_fd, is_rx=bus_queue is not self.queue,
                               bitrate_switch=msg.bitrate_switch, error_state_indicator=msg.error_state_indicator)
            try:
                bus_queue.put(copy, block=True, timeout=timeout)
            except queue.Full:
                all_sent = False
        if not all_sent:
            raise can.CanOperationError("Could not send message to one or more recipients")
