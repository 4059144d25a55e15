"""Device faults as one-line operator errors.

Every fault on an instrument link names the device (role and URL), the command that was running and the cause, so an
operator reading ``robocal: error: ...`` knows which cable, which request and what went wrong without a traceback.
The classes let the session layer branch: a timeout may be retried, a lost link needs a reconnect, an instrument
error (a GeoCOM return code) needs the operator, a protocol error means the reply must not be recorded.
"""
from __future__ import annotations

from calib.errors import RobocalError


class DeviceError(RobocalError):
    """A fault on an instrument link: ``<device>: <command>: <cause>``."""

    def __init__(self, device: str, command: str, cause: str):
        super().__init__(f"{device}: {command}: {cause}")
        self.device, self.command, self.cause = device, command, cause


class DeviceTimeout(DeviceError):
    """No (complete) reply within the call's timeout: silent device, wrong baud rate, cable, or a slow operation."""


class LinkLost(DeviceError):
    """The port went away (USB unplugged, pty closed, socket reset); :meth:`reconnect` may bring it back."""


class ProtocolError(DeviceError):
    """A reply that does not follow the grammar (garbled bytes, bad checksum, wrong field count): never recorded."""


class InstrumentError(DeviceError):
    """The instrument answered with an error return code (GeoCOM RC, GSI ``@E``); ``code`` keeps the number."""

    def __init__(self, device: str, command: str, cause: str, code: int):
        super().__init__(device, command, cause)
        self.code = code


class BusError(DeviceError):
    """A CAN bus fault (bus-off, error frames, interface gone)."""
