"""The encoder tap over CAN, through any python-can interface (socketcan, slcan, virtual, ...).

Why a reader thread with its own loop around ``bus.recv(timeout)`` rather than ``can.Notifier``: a Notifier thread
dies on the first bus error (python-can #907/#1039); here errors become counted events, the bus is reopened with
backoff, and samples keep flowing.  The thread checks a stop Event, so ``stop()`` always returns promptly.
"""
from __future__ import annotations

import time
from typing import Callable

import can

from ..errors import BusError
from .can_codec import STATUS_ID, TapCanCodec
from .sample import JointConverter
from .tap_base import TapReader

BusFactory = Callable[[], can.BusABC]


class CanTap(TapReader):
    """Samples from the tap's CAN frames.  ``bus_factory`` (re)opens the bus, so a bus-off can be recovered from."""

    thread_prefix = "can-tap"
    pollable = True
    #: longest a receive waits before the loop looks at the stop flag again: how long ``stop()`` can take (python-can
    #: has no way to wake a waiting ``recv``); 20 ms keeps a session's shutdown quick at 50 idle wake-ups a second
    poll_s = 0.02

    def __init__(self, bus_factory: BusFactory, *, converter: JointConverter | None = None, name: str = "encoder tap",
                 queue_size: int = 100_000, reconnect_delay_s: float = 0.2):
        super().__init__(name, converter, queue_size, reconnect_delay_s)
        self._factory = bus_factory
        self.codec = TapCanCodec()
        self._tap_ids = self.codec.frame_ids
        self._bus: can.BusABC | None = None

    def check(self) -> None:
        """Raise BusError if the reader is currently without a bus (for a Require-style precondition)."""
        if self._bus is None and self.stats.last_error:
            raise BusError(self.name, "receive", self.stats.last_error)

    # -- thread -------------------------------------------------------------------------------------------------------
    def _prepare(self) -> None:
        self._open()

    def _shutdown(self) -> None:
        self._close_bus()

    def _open(self) -> None:
        try:
            self._bus = self._factory()
        except (can.CanError, OSError, ValueError) as exc:
            raise BusError(self.name, "open bus", _why(exc)) from None

    def _close_bus(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            try:
                bus.shutdown()
            except Exception:                               # noqa: BLE001 - best effort on a broken interface
                pass

    def _run(self) -> None:
        t0 = time.thread_time()
        try:
            while not self._stop.is_set():
                if self._bus is None:
                    if not self._reconnect():
                        continue
                self._receive(self.poll_s)
                self.cpu_s = time.thread_time() - t0
        finally:
            self.cpu_s = time.thread_time() - t0

    def poll(self) -> int:
        """Handle every frame waiting on the bus now, in the caller's thread (a reader started without its thread:
        :meth:`TapReader.start`); returns how many were received.  Why: on a simulated clock the emulated node has
        sent a window's frames before anyone waits for them, so the reader thread only added two thread hand-offs
        per encoder window -- under other processes' load each one a scheduler slice, most of a demo's wall time."""
        n = 0
        receive = self._receive
        while self._bus is not None and receive(0.0):
            n += 1
        return n

    def _receive(self, timeout_s: float) -> bool:
        """One frame from the bus (waiting up to ``timeout_s``) through :meth:`_handle`; False when none came (or
        the bus failed: counted, closed for the thread's reconnect)."""
        try:
            msg = self._bus.recv(timeout_s)
        except (can.CanError, OSError, ValueError) as exc:
            self.stats.bus_errors += 1
            self.stats.last_error = _why(exc)
            self._close_bus()
            return False
        if msg is None:
            return False
        self._handle(msg)
        return True

    def _reconnect(self) -> bool:
        if self._stop.wait(self.reconnect_delay_s):
            return False
        try:
            self._bus = self._factory()
        except (can.CanError, OSError, ValueError) as exc:
            self.stats.last_error = _why(exc)
            return False
        self.stats.reconnects += 1              # last_error stays until a good frame proves the bus healthy
        self.assembler.reset()
        return True

    def _handle(self, msg: can.Message) -> None:
        st = self.stats
        if msg.is_error_frame:
            st.error_frames += 1
            return
        fid = msg.arbitration_id
        if fid not in self._tap_ids or msg.is_extended_id or msg.is_remote_frame:
            return
        st.frames += 1
        data = msg.data
        if msg.dlc != 8 or len(data) != 8:
            st.bad_frames += 1
            return
        data = bytes(data)
        if st.last_error:
            st.last_error = ""
        try:
            if fid == STATUS_ID:
                self.assembler.status(*self.codec.decode_status(data))
                return
            first, counts = self.codec.decode_data(fid, data)
            sample = self.assembler.data(first, counts)
        except (ValueError, KeyError) as exc:
            st.bad_frames += 1
            st.last_error = _why(exc)
            return
        if sample is not None:
            self._deliver(sample)


def _why(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def open_can_tap(interface: str, channel: str, *, robot=None, name: str | None = None, **bus_kwargs) -> CanTap:
    """A started-on-demand CanTap on ``can.Bus(interface=..., channel=..., **bus_kwargs)``.

    ``robot`` (calib.robot.Robot) enables joint angles on every sample; raw counts are kept regardless.
    """
    def factory() -> can.BusABC:
        return can.Bus(interface=interface, channel=channel, **bus_kwargs)

    conv = JointConverter(robot) if robot is not None else None
    return CanTap(factory, converter=conv, name=name or f"encoder tap ({interface}:{channel})")
