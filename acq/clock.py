"""Clocks for sessions and emulators: real time for real devices and a human at the keyboard, simulated time for an
emulated bench nobody watches.

Why: an emulated session spent most of its wall time sleeping -- waiting for encoder windows the emulator could fill
at once.  Everything that waits or stamps time in a session (the rig's capture window, the emulated tap's sample
schedule and device timestamps) takes a :class:`Clock`, so the same code runs a real cell in real time and the demo
as fast as the CPU allows:

* :class:`RealClock`: ``time.monotonic`` and ``time.sleep``; real devices, and the TUI's ``--emulate`` (human pace):
  emulators on it run their own threads as before.
* :class:`SimClock`: time only moves when someone sleeps on it.  :meth:`SimClock.sleep` advances it at once, then
  runs what the clock drives (the emulated tap sends the samples its schedule owes for the elapsed time) and waits,
  in real time, until the registered *drains* report the pipeline empty (the real tap reader received them), so the
  sleeper wakes to exactly what a real wait would have delivered.

A clock is also callable (``clock()`` is ``clock.now()``), so it plugs into every ``clock: Callable[[], float]``
parameter of the emulators and readers.
"""
from __future__ import annotations

import threading
import time
from typing import Callable, Protocol, runtime_checkable

#: called with the clock's new time after each advance of a simulated clock
Tick = Callable[[float], None]


@runtime_checkable
class Clock(Protocol):
    simulated: bool

    def now(self) -> float: ...

    def __call__(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


class Driven:
    """Handle of a tick or drain a :class:`SimClock` runs; :meth:`stop` removes it (idempotent)."""

    def __init__(self, stop: Callable[[], None]):
        self._stop = stop

    def stop(self) -> None:
        stop, self._stop = self._stop, (lambda: None)
        stop()


class RealClock:
    """Host monotonic time (emulators on it keep their own threads, paced by the host)."""

    simulated = False

    def now(self) -> float:
        return time.monotonic()

    __call__ = now

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class SimClock:
    """Simulated time (seconds, from ``start_s``): advanced by :meth:`sleep`, never by the host.

    ``drive(tick, ...)`` registers ``tick(now)`` to run in the sleeper's thread after every advance; ``add_drain(fn)``
    registers ``fn()`` to run after the ticks -- it blocks (in real time, bounded) until what the ticks produced has
    been consumed.  Thread-safe; ticks and drains run one advance at a time.
    """

    simulated = True

    def __init__(self, start_s: float = 0.0):
        self._t = float(start_s)
        self._lock = threading.RLock()
        self._ticks: list[Tick] = []
        self._drains: list[Callable[[], None]] = []

    def now(self) -> float:
        return self._t

    __call__ = now

    def sleep(self, seconds: float) -> None:
        self.advance(seconds)

    def advance(self, seconds: float) -> float:
        """Move time on by ``seconds`` (>= 0), run the ticks, then the drains; the new time."""
        with self._lock:
            self._t += max(float(seconds), 0.0)
            now = self._t
            for tick in list(self._ticks):
                tick(now)
            for drain in list(self._drains):
                drain()
            return now

    def drive(self, tick: Tick) -> Driven:
        """Run ``tick(now)`` after every advance (until the handle is stopped)."""
        return self._register(self._ticks, tick)

    def add_drain(self, drain: Callable[[], None]) -> Driven:
        """Run ``drain()`` after the ticks of every advance (until the handle is stopped)."""
        return self._register(self._drains, drain)

    def _register(self, where: list, fn) -> Driven:
        with self._lock:
            where.append(fn)

        def end() -> None:
            with self._lock:
                if fn in where:
                    where.remove(fn)
        return Driven(end)
