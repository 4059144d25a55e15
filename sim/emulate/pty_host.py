"""Host an emulated device on a real pseudo-terminal, so any program opens it as a serial device path.

Why: the URL handler runs in-process; a pty exercises the real ``serialposix`` termios path and lets third-party
software (GeoComPy, python-can's ``slcan``) talk to the emulator.  One thread shuttles bytes between the master side
and the device and ticks streaming devices.  The host keeps its own handle on the slave open so the line stays up
between client connections; :meth:`unplug` closes the master, which a client sees as an I/O error, like a pulled USB
adapter.  Output written while nobody reads is dropped when the tty buffer is full (a real device does not block).
"""
from __future__ import annotations

import errno
import os
import pty
import select
import threading
import tty
from typing import Callable

from sim.emulate.device import ByteDevice

#: called with (host, exception) when a host's server thread dies of an exception: the owner decides (the
#: ``robocal emulate`` command stops the process with one line and a non-zero exit)
FailureHook = Callable[[object, BaseException], None]


class PtyHost:
    """``PtyHost(device).path`` is a device path (``/dev/pts/N``) that behaves like the instrument."""

    def __init__(self, device: ByteDevice, *, start: bool = True, on_failure: FailureHook | None = None):
        self.device = device
        self.on_failure = on_failure
        self.failure: BaseException | None = None
        self._master, self._slave = pty.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"pty-{device.label}", daemon=True)
        self.bytes_in = 0
        self.bytes_out = 0
        self.dropped_out = 0
        if start:
            self._thread.start()

    def _run(self) -> None:
        run_guarded(self, self._serve)

    def _serve(self) -> None:
        period = self.device.tick_period_s or 0.05
        pending = b""
        while not self._stop.is_set():
            try:
                r, _, _ = select.select([self._master], [], [], min(period, 0.05))
            except (OSError, ValueError):
                if self._stop.is_set():             # closed by close()/unplug(): the normal end
                    return
                raise
            if r:
                try:
                    data = os.read(self._master, 65536)
                except BlockingIOError:
                    data = b""
                except OSError:
                    data = b""                      # EIO: no client has the slave open right now
                if data:
                    self.bytes_in += len(data)
                    self.device.feed(data)
            self.device.tick()
            pending += self.device.read_output()
            if pending:
                pending = self._write(pending)

    def _write(self, data: bytes) -> bytes:
        try:
            n = os.write(self._master, data)
        except BlockingIOError:
            n = 0
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EIO):
                n = 0
            else:
                return b""
        self.bytes_out += n
        rest = data[n:]
        if len(rest) > 65536:                      # nobody reading: drop the oldest, like a device's UART
            self.dropped_out += len(rest)
            rest = b""
        return rest

    def describe(self) -> str:
        return f"the pty server of {self.device.label} on {self.path}"

    def unplug(self) -> None:
        """Pull the cable: the thread stops and both ends close; clients get an I/O error."""
        self.close()

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(1.0)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> "PtyHost":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def run_guarded(host, serve: Callable[[], None]) -> None:
    """Run a host's serving loop; an exception is kept on ``host.failure`` and reported to ``host.on_failure``
    instead of dying silently in its thread while the process goes on."""
    try:
        serve()
    except BaseException as exc:            # noqa: BLE001 -- reported to the owner, never swallowed
        if host._stop.is_set():             # the owner is closing the host: its fds go away under the loop
            return
        host.failure = exc
        if host.on_failure is not None:
            host.on_failure(host, exc)
        else:
            raise
