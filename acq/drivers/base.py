"""What every theodolite driver returns and offers, whatever its wire protocol.

Units: radians inside (``*_rad`` fields); degrees and gon only appear in the codecs.  Each reading keeps the exact
reply frame (``raw``) so a fixed decoder can re-derive it offline, and both clocks (wall for the record, monotonic for
ordering and intervals).  Face uses the calib convention: 1 = face I, 2 = face II.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from ..errors import DeviceError

if TYPE_CHECKING:
    from ..link import SerialLink


@dataclass(frozen=True)
class DeviceInfo:
    """Identity snapshot for the session record."""

    driver: str
    url: str
    name: str = ""
    serial: str = ""
    firmware: str = ""
    protocol_version: str = ""


@dataclass(frozen=True)
class AngleReading:
    """One Hz/V reading.  ``warnings`` carries instrument warnings that leave the values usable (GeoCOM 1283...)."""

    device: str
    command: str
    hz_rad: float
    v_rad: float
    t_wall: float
    t_mono: float
    face: int | None = None                     # 1 = face I, 2 = face II (None: the protocol does not say)
    angle_accuracy_rad: float | None = None
    incline_cross_rad: float | None = None
    incline_length_rad: float | None = None
    t_device_ms: int | None = None
    slope_distance_m: float | None = None
    warnings: tuple[str, ...] = ()
    raw: bytes = field(default=b"", repr=False)


@runtime_checkable
class Theodolite(Protocol):
    """The minimum the session layer needs from any theodolite driver."""

    name: str

    def identify(self) -> DeviceInfo: ...

    def angles(self) -> AngleReading: ...

    def close(self) -> None: ...


class SerialInstrument:
    """The life cycle every driver on a :class:`acq.link.SerialLink` shares: open and handshake (closing the port
    again if the handshake fails, so a failed open never leaks a port), close, and use as a context manager."""

    link: "SerialLink"

    def connect(self) -> None:
        """The protocol's handshake; drivers override it."""

    @classmethod
    def _open_on(cls, link, handshake: bool, **options):
        dev = cls(link, **options)
        if handshake:
            try:
                dev.connect()
            except DeviceError:
                link.close()
                raise
        return dev

    def close(self) -> None:
        self.link.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
