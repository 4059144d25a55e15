"""The encoder tap over a plain serial link (COBS frames with CRC-16), through the same URL-opened SerialLink.

A reader thread splits the byte stream on 0x00, decodes, and feeds the shared :class:`SampleAssembler`, so sequence
gaps, bad frames and reconnects are counted exactly as on CAN.  The first fragment after opening is usually a partial
frame; it is skipped (counted as bad only if it is not the first).
"""
from __future__ import annotations

import time

from ..errors import DeviceError, LinkLost
from ..link import SerialLink, SerialSettings
from .cobs_codec import FrameError, decode_frame
from .sample import JointConverter
from .tap_base import TapReader


class SerialTap(TapReader):
    thread_prefix = "serial-tap"

    def __init__(self, link: SerialLink, *, converter: JointConverter | None = None, name: str | None = None,
                 reconnect_delay_s: float = 0.2, queue_size: int = 100_000):
        super().__init__(name or link.name, converter, queue_size, reconnect_delay_s)
        self.link = link
        self._buf = bytearray()
        self._synced = False

    def _shutdown(self) -> None:
        self.link.close()

    def _run(self) -> None:
        t0 = time.thread_time()
        while not self._stop.is_set():
            try:
                if not self.link.is_open:
                    if self._stop.wait(self.reconnect_delay_s):
                        break
                    self.link.reopen()
                    self.stats.reconnects += 1
                    self.assembler.reset()
                    self._buf.clear()
                    self._synced = False
                data = self.link.read_some(0.1, "read frames")
            except LinkLost as exc:
                self.stats.bus_errors += 1
                self.stats.last_error = exc.cause
                continue
            except DeviceError as exc:
                self.stats.last_error = exc.cause
                continue
            if data:
                self._bytes(data)
            self.cpu_s = time.thread_time() - t0
        self.cpu_s = time.thread_time() - t0

    def _bytes(self, data: bytes) -> None:
        self._buf += data
        while True:
            i = self._buf.find(0)
            if i < 0:
                if len(self._buf) > 4096:
                    self._buf.clear()
                    self.stats.bad_frames += 1
                return
            chunk = bytes(self._buf[:i])
            del self._buf[:i + 1]
            if not self._synced:
                self._synced = True
                try:
                    f = decode_frame(chunk)
                except FrameError:
                    continue                      # the tail of a frame sent before we opened: not an error
                self._frame(f)
                continue
            if not chunk:
                continue
            self.stats.frames += 1
            try:
                f = decode_frame(chunk)
            except FrameError as exc:
                self.stats.bad_frames += 1
                self.stats.last_error = str(exc)
                continue
            self._frame(f)

    def _frame(self, f) -> None:
        self._deliver(self.assembler.whole(f.seq, f.t_us, f.counts))


def open_serial_tap(url: str, *, robot=None, name: str | None = None, baudrate: int = 921600) -> SerialTap:
    """A SerialTap on ``url`` (device path, pty, ``robocal://serialtap``...); call ``start()`` or use ``with``."""
    link = SerialLink(url, name=name or f"encoder tap ({url})", settings=SerialSettings(baudrate=baudrate))
    return SerialTap(link, converter=JointConverter(robot) if robot is not None else None)
