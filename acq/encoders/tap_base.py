"""What every encoder-tap reader shares, whatever the transport (CAN, serial): the reader thread's life cycle,
the sample queue, the latest sample for live displays, and the operator-facing timeout.

Subclasses implement ``_run`` (the thread's loop, which calls :meth:`TapReader._deliver` for every assembled
sample), and optionally ``_prepare`` (before the thread starts) and ``_shutdown`` (after it stopped).
"""
from __future__ import annotations

import queue
import threading
from typing import Callable

from ..errors import DeviceTimeout
from .assembler import SampleAssembler
from .sample import EncoderSample, JointConverter, TapStats


class TapReader:
    thread_prefix = "tap"
    #: whether the reader can run without its thread, its caller handing it the waiting frames (``poll()``)
    pollable = False

    def __init__(self, name: str, converter: JointConverter | None = None, queue_size: int = 100_000,
                 reconnect_delay_s: float = 0.2):
        self.name = name
        self.stats = TapStats()
        self.assembler = SampleAssembler(converter, self.stats)
        self.reconnect_delay_s = reconnect_delay_s
        self._queue: queue.Queue[EncoderSample] = queue.Queue(queue_size)
        self._latest: EncoderSample | None = None
        self._sink: Callable[[EncoderSample], None] | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.cpu_s = 0.0                                   # reader thread CPU time (benchmarks)
        self.overflow = 0                                  # samples dropped from the queue (sink still saw them)
        self.polled = False                                # started without its thread: fed by poll()

    # -- control ------------------------------------------------------------------------------------------------------
    def start(self, sink: Callable[[EncoderSample], None] | None = None, thread: bool = True):
        """Start the reader thread; ``sink`` (optional) is called in that thread for every sample.  ``thread=False``
        (a :attr:`pollable` reader): open the link only, the caller hands the reader what arrived with ``poll()``
        (the sink then runs in the caller's thread)."""
        if self._thread is None and not self.polled:
            self._sink = sink
            self._prepare()
            if not thread and self.pollable:
                self.polled = True
                return self
            self._thread = threading.Thread(target=self._run, name=f"{self.thread_prefix}-{self.name}", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None
        self.polled = False
        self._shutdown()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def latest(self) -> EncoderSample | None:
        return self._latest

    def read(self, timeout_s: float = 1.0) -> EncoderSample:
        """The next sample in order; DeviceTimeout naming the tap if none arrives in time."""
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            cause = f"no complete sample within {timeout_s:g} s"
            if self.stats.last_error:
                cause += f" (last error: {self.stats.last_error})"
            raise DeviceTimeout(self.name, "read sample", cause) from None

    # -- for subclasses ----------------------------------------------------------------------------------------------
    def _prepare(self) -> None:
        """Before the thread starts (open the bus, ...)."""

    def _shutdown(self) -> None:
        """After the thread stopped (close the bus or link)."""

    def _run(self) -> None:
        raise NotImplementedError

    def _deliver(self, sample: EncoderSample) -> None:
        self._latest = sample
        try:
            self._queue.put_nowait(sample)
        except queue.Full:
            self.overflow += 1
        if self._sink is not None:
            self._sink(sample)
