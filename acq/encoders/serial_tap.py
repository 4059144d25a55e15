"""The encoder tap over a plain serial link (COBS frames with CRC-16), through the same URL-opened SerialLink.

A reader thread splits the byte stream on 0x00, decodes, and feeds the shared :class:`SampleAssembler`, so sequence
gaps, bad frames and reconnects are counted exactly as on CAN.  The first fragment after opening is usually a partial
frame; it is skipped (counted as bad only if it is not the first).
"""
from __future__ import annotations

import queue
import threading
import time
from typing import Callable

from ..errors import DeviceError, DeviceTimeout, LinkLost
from ..link import SerialLink, SerialSettings
from .assembler import SampleAssembler
from .cobs_codec import FrameError, decode_frame
from .sample import EncoderSample, JointConverter, TapStats


class SerialTap:
    def __init__(self, link: SerialLink, *, converter: JointConverter | None = None, name: str | None = None,
                 reconnect_delay_s: float = 0.2, queue_size: int = 100_000):
        self.link = link
        self.name = name or link.name
        self.stats = TapStats()
        self.assembler = SampleAssembler(converter, self.stats)
        self.reconnect_delay_s = reconnect_delay_s
        self._queue: queue.Queue[EncoderSample] = queue.Queue(queue_size)
        self._latest: EncoderSample | None = None
        self._sink: Callable[[EncoderSample], None] | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._buf = bytearray()
        self._synced = False
        self.cpu_s = 0.0

    def start(self, sink: Callable[[EncoderSample], None] | None = None) -> "SerialTap":
        if self._thread is None:
            self._sink = sink
            self._thread = threading.Thread(target=self._run, name=f"serial-tap-{self.name}", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None
        self.link.close()

    def __enter__(self) -> "SerialTap":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def latest(self) -> EncoderSample | None:
        return self._latest

    def read(self, timeout_s: float = 1.0) -> EncoderSample:
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            cause = f"no complete sample within {timeout_s:g} s"
            if self.stats.last_error:
                cause += f" (last error: {self.stats.last_error})"
            raise DeviceTimeout(self.name, "read sample", cause) from None

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
        s = self.assembler.whole(f.seq, f.t_us, f.counts)
        self._latest = s
        try:
            self._queue.put_nowait(s)
        except queue.Full:
            pass
        if self._sink is not None:
            self._sink(s)


def open_serial_tap(url: str, *, robot=None, name: str | None = None, baudrate: int = 921600) -> SerialTap:
    """A SerialTap on ``url`` (device path, pty, ``robocal://serialtap``...); call ``start()`` or use ``with``."""
    link = SerialLink(url, name=name or f"encoder tap ({url})", settings=SerialSettings(baudrate=baudrate))
    return SerialTap(link, converter=JointConverter(robot) if robot is not None else None)
