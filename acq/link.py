"""The byte link every serial driver talks through: a pyserial port opened from a URL, with deadlines.

Why one class: the drivers must run unchanged on a device path, ``socket://``, ``spy://``, a pty and the emulator URL
``robocal://...``, so the port is always opened with :func:`serial.serial_for_url`; and every fault of the port
(unplug, timeout) must turn into one :class:`~acq.errors.DeviceError` that names the device and the command.  The
drivers never see a pyserial exception.

The port's own read timeout stays short and fixed (changing it costs a termios call on POSIX); the deadline of a call
is enforced here, in a loop, so every call has a timeout and a silent device can never hang the caller.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import serial

from .errors import DeviceTimeout, LinkLost

#: package holding ``protocol_robocal`` so ``robocal://geocom?seed=3`` opens an emulated instrument
URL_HANDLER_PACKAGE = "sim.emulate.urlhandler"
_POLL_S = 0.02


def register_url_handlers() -> None:
    """Make ``robocal://`` URLs known to :func:`serial.serial_for_url` (idempotent)."""
    if URL_HANDLER_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(URL_HANDLER_PACKAGE)


@dataclass(frozen=True)
class SerialSettings:
    """Line settings; GeoCOM is always 8N1 without flow control, GSI instruments vary (keep them configurable)."""

    baudrate: int = 19200
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1


class SerialLink:
    """A reopenable serial port with deadline-based reads.  ``name`` is how errors name the device."""

    def __init__(self, url: str, *, name: str | None = None, settings: SerialSettings = SerialSettings(),
                 open_now: bool = True):
        self.url = url
        self.name = name or url
        self.settings = settings
        self._port: serial.SerialBase | None = None
        self._buf = bytearray()
        if open_now:
            self.open()

    # -- lifecycle ------------------------------------------------------------------------------------------------
    def open(self) -> None:
        register_url_handlers()
        s = self.settings
        try:
            self._port = serial.serial_for_url(self.url, baudrate=s.baudrate, bytesize=s.bytesize, parity=s.parity,
                                               stopbits=s.stopbits, timeout=_POLL_S, write_timeout=2.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkLost(self.name, "open", f"cannot open {self.url}: {_why(exc)}") from None
        self._buf.clear()

    def reopen(self) -> None:
        """Close whatever is left of the port and open the URL again (after an unplug)."""
        self.close()
        self.open()

    def close(self) -> None:
        port, self._port = self._port, None
        if port is not None:
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass

    @property
    def is_open(self) -> bool:
        return self._port is not None

    def __enter__(self) -> "SerialLink":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- I/O ------------------------------------------------------------------------------------------------------
    def _need_port(self, command: str) -> serial.SerialBase:
        if self._port is None:
            raise LinkLost(self.name, command, "port is closed")
        return self._port

    def write(self, data: bytes, command: str) -> None:
        port = self._need_port(command)
        try:
            port.write(data)
            port.flush()
        except serial.SerialTimeoutException:
            raise DeviceTimeout(self.name, command, "write timed out (flow control or cable?)") from None
        except (serial.SerialException, OSError) as exc:
            self.close()
            raise LinkLost(self.name, command, f"link lost while writing: {_why(exc)}") from None

    def read_some(self, timeout_s: float, command: str) -> bytes:
        """Whatever arrives within ``timeout_s`` (possibly nothing), plus anything buffered by earlier reads."""
        if self._buf:
            out = bytes(self._buf)
            self._buf.clear()
            return out
        port = self._need_port(command)
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                data = port.read(max(1, port.in_waiting))
            except (serial.SerialException, OSError) as exc:
                self.close()
                raise LinkLost(self.name, command, f"link lost while reading: {_why(exc)}") from None
            if data or time.monotonic() >= deadline:
                return data

    def read_until(self, terminator: bytes, timeout_s: float, command: str, max_len: int = 8192) -> bytes:
        """One frame ending with ``terminator`` (returned without it); DeviceTimeout if none completes in time.

        A partial frame is kept on timeout: the rest may still arrive and the caller's resync drains it.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            i = self._buf.find(terminator)
            if i >= 0:
                frame = bytes(self._buf[:i])
                del self._buf[:i + len(terminator)]
                return frame
            if len(self._buf) > max_len:
                self._buf.clear()
                raise DeviceTimeout(self.name, command, f"no {terminator!r} terminator within {max_len} bytes")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                got = f"; {len(self._buf)} bytes of an incomplete reply" if self._buf else ""
                raise DeviceTimeout(self.name, command, f"no reply within {timeout_s:g} s{got}")
            port = self._need_port(command)
            try:
                data = port.read(max(1, port.in_waiting))
            except (serial.SerialException, OSError) as exc:
                self.close()
                raise LinkLost(self.name, command, f"link lost while reading: {_why(exc)}") from None
            self._buf += data

    def drain(self, quiet_s: float = 0.0) -> bytes:
        """Discard buffered and pending input (after a timeout, before a resync); returns what was thrown away.

        ``quiet_s``: how long the line must stay quiet -- bytes still on the cable.  A port that says it is
        ``synchronous`` (an in-process emulator answering in the writer's thread: no cable, nothing in flight)
        has everything it will send already waiting, so it is drained without the wait."""
        dropped = bytes(self._buf)
        self._buf.clear()
        if self._port is None:
            return dropped
        if getattr(self._port, "synchronous", False):
            quiet_s = 0.0
        try:
            end = time.monotonic() + quiet_s
            while True:
                n = self._port.in_waiting
                if n:
                    dropped += self._port.read(n)
                elif time.monotonic() >= end:
                    break
                else:
                    time.sleep(0.005)
            self._port.reset_input_buffer()
        except (serial.SerialException, OSError):
            self.close()
        return dropped


def _why(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text
