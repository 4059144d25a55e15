"""A stand-in for the session runner, for TUI tests that need conditions a real rig cannot make on demand:
a flood of live values (a CAN bus at its limit) while records and prompts keep coming."""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from acq.session.runner import Event, Request
from acq.session.steps import Step, TargetSpec


@dataclass
class FakeSample:
    counts: tuple
    joint_rad: tuple | None


class FloodTap:
    """``latest()`` changes at ``rate_hz`` from its own thread, like a tap reader on a bus at its limit."""

    def __init__(self, rate_hz: float = 8000.0):
        self.rate_hz = rate_hz
        self.updates = 0
        self._latest = None
        self._stop = threading.Event()
        self._counted = threading.Condition()
        self.stats = type("S", (), {"frames": 0, "bad_frames": 0, "reconnects": 0, "last_error": ""})()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        period = 1.0 / self.rate_hz
        nxt = time.perf_counter()
        while not self._stop.is_set():
            c = tuple(int((self.updates + 1) * k) for k in range(1, 7))
            self._latest = FakeSample(c, tuple(np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0])))
            self.stats.frames += 4
            with self._counted:
                self.updates += 1
                self._counted.notify_all()
            nxt += period
            delay = nxt - time.perf_counter()
            if delay > 0:
                time.sleep(delay)

    def latest(self):
        return self._latest

    def wait_updates(self, n: int, timeout_s: float = 60.0) -> bool:
        """Block until the tap has made ``n`` updates in all (an event, not a time: however loaded the machine);
        False if the guard ``timeout_s`` ran out first."""
        with self._counted:
            return self._counted.wait_for(lambda: self.updates >= n, timeout_s)

    def start(self):
        self._thread.start()

    def stop(self):
        self._stop.set()


class FakeRig:
    def __init__(self, tap):
        self.tap = tap


class FakeRunner:
    """Emits ``n_steps`` steps of events, asks the operator once per step, and floods readings in between.
    ``updates_per_step``: the k-th question waits until the tap has made k times this many updates (the flood is
    seen to run by its count, not by a time it was given)."""

    def __init__(self, operator, n_steps: int = 5, readings_per_step: int = 200, rate_hz: float = 8000.0,
                 updates_per_step: int = 0):
        self.operator = operator
        self.steps = [Step(key=f"fake/{i:02d}", procedure="poses", title=f"Fake pose {i + 1}",
                           instruction="Hold still.", targets=(TargetSpec("P", tool_mm=(0.0, 0.0, 0.0)),))
                      for i in range(n_steps)]
        self.readings_per_step = readings_per_step
        self.updates_per_step = updates_per_step
        self.rig = FakeRig(FloodTap(rate_hz))
        self.stations = {}
        self._subs = []
        self._abort = threading.Event()
        self._thread = None
        self.asked = 0

    def subscribe(self, cb):
        self._subs.append(cb)

    def _emit(self, kind, **data):
        for cb in self._subs:
            cb(Event(kind, data))

    def start(self):
        self.rig.tap.start()
        self._thread = threading.Thread(target=self.run, daemon=True)
        self._thread.start()

    def run(self):
        self._emit("state", old="idle", new="running")
        for i, s in enumerate(self.steps):
            self._emit("step_started", key=s.key, procedure=s.procedure, title=s.title, instruction=s.instruction,
                       index=i, total=len(self.steps), attempt=1)
            for r in range(self.readings_per_step):
                self._emit("reading", key=s.key, station="AB"[r % 2], target="P", face=1, repeat=r,
                           hz_deg=10.0 + r * 1e-4, v_deg=90.0)
            if self.updates_per_step:
                self.rig.tap.wait_updates((i + 1) * self.updates_per_step)
            ans = self.operator.ask(Request("decision", s, 1, ("accept", "repeat", "skip", "pause", "abort")))
            self.asked += 1
            if ans.action == "abort" or self._abort.is_set():
                self._emit("finished", exit_status="aborted", error=None)
                return
            self._emit("step_saved", key=s.key, status="accepted", attempts=1)
        self._emit("finished", exit_status="success", error=None)

    def request_abort(self):
        self._abort.set()

    def join(self, timeout=None):
        if self._thread is not None:
            self._thread.join(timeout)
        self.rig.tap.stop()
