"""Fault injection around the emulated devices, for the reliability tests.

:class:`FaultyDevice` wraps any byte device (GeoCOM, GSI, serial tap, SLCAN) and sits behind the same harnesses
(``robocal://instance/<name>`` or a :class:`~sim.emulate.pty_host.PtyHost`): latency, dropped and garbled bytes,
wrong CRC, a silent device, unplug in the middle of a frame.  Return-code faults use the device's own hook
(``GeoComDevice.script_rc``) because a real instrument chooses the code, not the cable.

:class:`BusFaults` + :class:`FaultyBus` wrap a python-can bus on the receive side: bus-off (recv raises), error
frames, lost frames.  :class:`LossySendBus` loses frames on the send side of the emulated tap.
"""
from __future__ import annotations

import random
import re
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable

import can


class FaultyDevice:
    """A byte device whose output passes through a faulty cable."""

    def __init__(self, inner, *, seed: int = 0):
        self.inner = inner
        self.label = f"faulty-{inner.label}"
        self.rng = random.Random(seed)
        self.latency_s = 0.0
        self.drop_byte_prob = 0.0
        self.garble_byte_prob = 0.0
        self.silent = False                     # swallows requests: nothing ever comes back
        self.swallowed: list[bytes] = []        # what a silent device was sent (the attempts, counted by the tests)
        self._held: bytes | None = None         # a reply held back until the next request (hold_next_reply)
        self._delayed: deque[tuple[float, bytes]] = deque()
        self._once: deque[tuple] = deque()
        self._pending_unplug: tuple[float, Callable[[], None]] | None = None
        self._lock = threading.RLock()
        self.log: list[str] = []

    # -- one-shot faults, applied to the next non-empty output chunk -------------------------------------------------
    def drop_next_reply(self) -> None:
        self._once.append(("drop",))

    def garble_next_reply(self, position: int | None = None) -> None:
        self._once.append(("garble", position))

    def wrong_crc_next_reply(self) -> None:
        self._once.append(("crc",))

    def hold_next_reply(self) -> None:
        """The next reply is held back until the caller sends its next request: it arrives after the caller gave up
        on it, a stale reply ahead of the fresh one.  Ordered by that event, not by a delay on the host clock, so a
        loaded machine cannot reorder it."""
        self._once.append(("hold",))

    def unplug_mid_frame(self, after_bytes: int, unplug: Callable[[], None], delay_s: float = 0.05) -> None:
        """Deliver only the first ``after_bytes`` of the next reply, then call ``unplug`` (pull the cable)."""
        self._once.append(("unplug", after_bytes, unplug, delay_s))

    # -- ByteDevice ----------------------------------------------------------------------------------------------------
    @property
    def tick_period_s(self):
        return self.inner.tick_period_s

    def feed(self, data: bytes) -> None:
        if self.silent:
            self.swallowed.append(data)
            return
        if self._held is not None and data.strip(b"\r\n"):      # a request (not the resync's bare LF)
            with self._lock:
                self._delayed.append((time.monotonic(), self._held))
                self._held = None
        self.inner.feed(data)

    def tick(self, now: float | None = None) -> None:
        self.inner.tick(now)

    def _mangle(self, chunk: bytes) -> bytes:
        if self._once:
            action = self._once.popleft()
            kind = action[0]
            self.log.append(kind)
            if kind == "drop":
                return b""
            if kind == "hold":
                self._held = chunk
                return b""
            if kind == "garble":
                b = bytearray(chunk)
                pos = action[1] if action[1] is not None else self.rng.randrange(max(1, len(b) - 2))
                b[pos % len(b)] ^= 0x01 << self.rng.randrange(7) or 1
                return bytes(b)
            if kind == "crc":
                return re.sub(rb"^(%R1P,\d+,\d+,)(\d+)", lambda m: m.group(1) + str((int(m.group(2)) + 1) % 65536)
                              .encode(), chunk, count=1)
            if kind == "unplug":
                _, n, fn, delay = action
                self._pending_unplug = (time.monotonic() + delay, fn)
                return chunk[:n]
        if self.drop_byte_prob or self.garble_byte_prob:
            out = bytearray()
            for byte in chunk:
                r = self.rng.random()
                if r < self.drop_byte_prob:
                    continue
                if r < self.drop_byte_prob + self.garble_byte_prob:
                    byte ^= 1 << self.rng.randrange(8)
                out.append(byte)
            return bytes(out)
        return chunk

    def _pump(self) -> None:
        with self._lock:
            if self._pending_unplug and time.monotonic() >= self._pending_unplug[0]:
                fn = self._pending_unplug[1]
                self._pending_unplug = None
                fn()
            chunk = self.inner.read_output()
            if chunk:
                chunk = self._mangle(chunk)
                if chunk:
                    self._delayed.append((time.monotonic() + self.latency_s, chunk))

    def read_output(self) -> bytes:
        self._pump()
        out = []
        now = time.monotonic()
        with self._lock:
            while self._delayed and self._delayed[0][0] <= now:
                out.append(self._delayed.popleft()[1])
        return b"".join(out)

    def wait_output(self, timeout_s: float) -> bool:
        end = time.monotonic() + timeout_s
        while True:
            self._pump()
            now = time.monotonic()
            with self._lock:
                if self._delayed and self._delayed[0][0] <= now:
                    return True
                nxt = self._delayed[0][0] if self._delayed else None
            if now >= end:
                return False
            if nxt is not None:
                time.sleep(max(0.0, min(nxt, end) - now))
            else:
                self.inner.wait_output(min(end - now, 0.01))


class ScriptedLink:
    """An in-memory link (SerialLink's write/read_until/drain/reopen) whose instrument answers each request line with
    ``answer(line) -> reply line`` (None: silence).  For driver tests on arbitrary replies without a port or a
    thread: a call costs microseconds, so hypothesis can try thousands."""

    def __init__(self, answer: Callable[[bytes], bytes | None], name: str = "theodolite T"):
        self.answer = answer
        self.name = self.url = name
        self.is_open = True
        self.requests: list[bytes] = []
        self._out = bytearray()

    def write(self, data: bytes, command: str) -> None:
        for line in data.split(b"\r\n"):
            if line.strip(b"\n"):
                self.requests.append(line.strip(b"\n"))
                reply = self.answer(line.strip(b"\n"))
                if reply is not None:
                    self._out += reply + b"\r\n"

    def read_until(self, terminator: bytes, timeout_s: float, command: str) -> bytes:
        from acq.errors import DeviceTimeout
        i = self._out.find(terminator)
        if i < 0:
            self._out.clear()
            raise DeviceTimeout(self.name, command, "no reply")
        frame = bytes(self._out[:i])
        del self._out[:i + len(terminator)]
        return frame

    def drain(self, quiet_s: float = 0.0) -> bytes:
        out = bytes(self._out)
        self._out.clear()
        return out

    def reopen(self) -> None:
        self.is_open = True

    def close(self) -> None:
        self.is_open = False


def geocom_answer(body: Callable[[int], str]) -> Callable[[bytes], bytes | None]:
    """A GeoCOM instrument answering RPC ``rpc`` with ``%R1P,0,<trid>:<body(rpc)>`` (TrId echoed)."""
    def answer(line: bytes) -> bytes | None:
        m = re.match(rb"%R1Q,(\d+)(?:,(\d+))?", line)
        if not m:
            return None
        return f"%R1P,0,{int(m.group(2) or 0)}:".encode() + body(int(m.group(1))).encode("latin-1")
    return answer


# -- CAN --------------------------------------------------------------------------------------------------------------
@dataclass
class BusFaults:
    """Shared switches for every FaultyBus a factory hands out (a reconnect gets the same faults)."""

    bus_off: bool = False
    error_frames: int = 0                       # inject this many error frames on the next recv calls
    lose: Callable[[can.Message], bool] = field(default=lambda m: False)
    opens: int = 0
    lost: int = 0


class FaultyBus:
    """Receive-side wrapper: ``recv`` raises while bus-off, returns injected error frames, loses frames."""

    def __init__(self, inner: can.BusABC, faults: BusFaults):
        self.inner = inner
        self.faults = faults
        faults.opens += 1

    def recv(self, timeout: float | None = None):
        f = self.faults
        if f.bus_off:
            time.sleep(min(timeout or 0.0, 0.01))
            raise can.CanOperationError("bus-off: transmit error counter above 255")
        if f.error_frames > 0:
            f.error_frames -= 1
            return can.Message(is_error_frame=True, arbitration_id=0x20000004, dlc=8, data=bytes(8))
        while True:
            msg = self.inner.recv(timeout)
            if msg is None or not f.lose(msg):
                return msg
            f.lost += 1

    def send(self, msg, timeout=None):
        self.inner.send(msg, timeout)

    def shutdown(self) -> None:
        self.inner.shutdown()


class LossySendBus:
    """Send-side wrapper for the emulated tap node: ``lose(index, msg)`` decides which frames never reach the bus."""

    def __init__(self, inner: can.BusABC, lose: Callable[[int, can.Message], bool]):
        self.inner = inner
        self.lose = lose
        self.index = 0
        self.lost = 0

    def send(self, msg, timeout=None):
        i = self.index
        self.index += 1
        if self.lose(i, msg):
            self.lost += 1
            return
        self.inner.send(msg, timeout)

    def shutdown(self) -> None:
        self.inner.shutdown()
