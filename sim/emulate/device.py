"""The device side of an emulated instrument: a byte state machine with no I/O.

Why: the same device object must sit behind a pyserial URL, a real pty, and a fault-injecting wrapper, so it only
takes bytes (:meth:`feed`), produces bytes (:meth:`read_output`) and advances streams when told the time
(:meth:`tick`).  Harnesses own threads and file descriptors; devices own protocol state.  Output waits in a buffer
guarded by a condition so a harness can block until the device has something to say.
"""
from __future__ import annotations

import threading
import time
from typing import Callable, Protocol, runtime_checkable


@runtime_checkable
class ByteDevice(Protocol):
    label: str

    def feed(self, data: bytes) -> None: ...

    def read_output(self) -> bytes: ...

    def wait_output(self, timeout_s: float) -> bool: ...

    def tick(self, now: float | None = None) -> None: ...

    @property
    def tick_period_s(self) -> float | None: ...


class DeviceBase:
    """Output buffer, clock and line framing shared by the emulators (each parses its own grammar)."""

    label = "device"

    def __init__(self, clock: Callable[[], float] = time.monotonic):
        self.clock = clock
        self._out = bytearray()
        self._cv = threading.Condition()
        self._waiting = 0                       # threads in wait_output: only they need a notify
        self._inbuf = bytearray()
        self.lock = threading.RLock()           # feed/tick from different threads (pty host, URL port)

    # -- output ------------------------------------------------------------------------------------------------------
    def emit(self, data: bytes) -> None:
        with self._cv:
            self._out += data
            if self._waiting:
                self._cv.notify_all()

    def read_output(self) -> bytes:
        if not self._out:               # nothing to take (a reader polls far more often than a device answers)
            return b""
        with self._cv:
            out = bytes(self._out)
            self._out.clear()
            return out

    def wait_output(self, timeout_s: float) -> bool:
        with self._cv:
            if not self._out:
                self._waiting += 1
                try:
                    self._cv.wait(timeout_s)
                finally:
                    self._waiting -= 1
            return bool(self._out)

    # -- input ---------------------------------------------------------------------------------------------------------
    def feed(self, data: bytes) -> None:
        with self.lock:
            self._inbuf += data
            self._lines()

    def _lines(self) -> None:
        """Default framing: lines ending in LF; CR stripped; each complete line goes to :meth:`on_line`."""
        while True:
            i = self._inbuf.find(b"\n")
            if i < 0:
                if len(self._inbuf) > 4096:          # garbage without a terminator: drop it like a real UART buffer
                    self._inbuf.clear()
                return
            line = bytes(self._inbuf[:i]).strip(b"\r")
            del self._inbuf[:i + 1]
            self.on_line(line)

    def on_line(self, line: bytes) -> None:     # pragma: no cover - overridden
        pass

    # -- streams ---------------------------------------------------------------------------------------------------
    tick_period_s: float | None = None

    @property
    def synchronous(self) -> bool:
        """True when everything the device will say in answer to its input is in its output buffer as soon as
        :meth:`feed` returns (it answers in the caller's thread and streams nothing on its own): a port onto it has
        no bytes in flight to wait for.  A wrapper that delays output (a faulty cable) does not say so."""
        return self.tick_period_s is None

    def tick(self, now: float | None = None) -> None:
        pass
