"""``robocal://`` for :func:`serial.serial_for_url`: a pyserial port whose other end is an emulated device.

Why a port class and not a fake driver: the driver under test stays byte-for-byte the production code (terminators,
timeouts, retries all run); only the far end changes.  Modelled on pyserial's ``protocol_loop``: ``write`` feeds the
device, ``read`` waits for its output, honouring ``timeout`` exactly like a real port.
"""
from __future__ import annotations

import time

from serial.serialutil import PortNotOpenError, SerialBase, SerialException, SerialTimeoutException

from sim.emulate import registry


class Serial(SerialBase):
    """A port onto an emulated device."""

    def open(self) -> None:
        if self.is_open:
            raise SerialException("port already open")
        if self._port is None:
            raise SerialException("port must be configured before it can be used")
        try:
            self._device, self._instance, self._generation = registry.resolve(self._port)
        except ValueError as exc:
            raise SerialException(str(exc)) from None
        self._rx = bytearray()
        self.is_open = True
        self._reconfigure_port()

    def _reconfigure_port(self) -> None:
        """Line settings do not matter to an in-process device."""

    def close(self) -> None:
        self.is_open = False

    def from_url(self, url: str) -> str:
        return url

    # -- liveness ---------------------------------------------------------------------------------------------------
    def _check(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()
        if self._instance is not None:
            s = registry.slot(self._instance)
            if s is None or s.generation != self._generation:
                raise SerialException(f"device reports readiness to read but returned no data "
                                      f"(emulated device {self._instance!r} unplugged)")

    def _pull(self) -> None:
        self._check()
        self._device.tick()
        out = self._device.read_output()
        if out:
            self._rx += out

    @property
    def synchronous(self) -> bool:
        """Nothing is ever in flight on this port when its device answers at once (:attr:`sim.emulate.device.
        DeviceBase.synchronous`): :meth:`acq.link.SerialLink.drain` need not wait for a quiet line."""
        return bool(getattr(self._device, "synchronous", False))

    # -- SerialBase API ---------------------------------------------------------------------------------------------
    @property
    def in_waiting(self) -> int:
        self._pull()
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        if len(self._rx) >= size:       # what was asked is here already (``in_waiting`` pulled it): no wait, no pull
            self._check()
            data = bytes(self._rx[:size])
            del self._rx[:size]
            return data
        self._pull()
        timeout = self._timeout
        deadline = None if timeout is None else time.monotonic() + timeout
        period = self._device.tick_period_s or 0.05
        while len(self._rx) < size:
            if deadline is not None:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
            else:
                remaining = period
            self._device.wait_output(min(remaining, period))
            self._pull()
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data) -> int:
        self._check()
        if self._write_timeout is not None and self._write_timeout < 0:
            raise SerialTimeoutException("write timeout")
        data = bytes(data)
        self._device.feed(data)
        return len(data)

    def flush(self) -> None:
        self._check()

    def reset_input_buffer(self) -> None:
        self._pull()
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        self._check()

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    def _update_break_state(self) -> None:
        pass
