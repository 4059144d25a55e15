"""The Puma joint-encoder tap: six motor-encoder counts per sample, timestamped, sequence-numbered.

Two transports, one sample model (:class:`~acq.encoders.sample.EncoderSample`) and one loss accounting
(:class:`~acq.encoders.assembler.SampleAssembler`):

* ``open_tap("can", interface="socketcan", channel="can0", robot=robot)`` -> :class:`~acq.encoders.can_tap.CanTap`
  (frames from the shipped ``puma_tap.dbc``, decoded with cantools, any python-can interface);
* ``open_tap("serial", url="/dev/ttyUSB0", robot=robot)`` -> :class:`~acq.encoders.serial_tap.SerialTap`
  (COBS + CRC-16 frames over any ``serial_for_url`` URL).

Both: ``start(sink=None)``, ``read(timeout_s)``, ``latest()``, ``stats``, ``stop()``; usable as context managers.
"""
from __future__ import annotations

from typing import Callable

from calib.errors import RobocalError

from .sample import EncoderSample, JointConverter, TapStats


def _can(**kw):
    # python-can and cantools cost ~0.3 s at import; only a CAN tap needs them
    from .can_tap import open_can_tap
    return open_can_tap(kw.pop("interface"), kw.pop("channel"), **kw)


def _serial(**kw):
    # a transport loads only when its tap opens (pyserial and acq.link here), as CAN's does
    from .serial_tap import open_serial_tap
    return open_serial_tap(kw.pop("url"), **kw)


TAPS: dict[str, Callable[..., object]] = {"can": _can, "serial": _serial}


def open_tap(kind: str, **options):
    try:
        opener = TAPS[kind]
    except KeyError:
        raise RobocalError(f"unknown encoder tap kind {kind!r} (known: {', '.join(TAPS)})") from None
    try:
        return opener(**options)
    except KeyError as exc:
        raise RobocalError(f"encoder tap {kind!r}: missing option {exc.args[0]!r}") from None


__all__ = ["EncoderSample", "JointConverter", "TapStats", "TAPS", "open_tap"]
