"""A runner that stops at the first step of a real plan and waits for the operator: what the TUI shows then must
be readable at any terminal size (snapshot tests).  Deterministic: fixed readings, a tap whose sample never changes."""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from acq.session.runner import Event, Request
from acq.session.steps import Step


@dataclass
class StillSample:
    counts: tuple
    joint_rad: tuple


class StillTap:
    stats = type("S", (), {"frames": 1200, "bad_frames": 0, "reconnects": 0, "last_error": "", "lost_samples": 0})()

    def latest(self):
        return StillSample((0, -21563, -13427, 0, 0, 0), tuple(np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0])))


class StillRig:
    tap = StillTap()


class StillRunner:
    """Emits the first step of ``steps`` with one face-I reading per station, then asks for its set-up until paused or
    aborted (every answer kept in ``answers``)."""

    def __init__(self, operator, steps: list[Step]):
        self.operator = operator
        self.steps = steps
        self.rig = StillRig()
        self.stations = {}
        self._subs = []
        self._abort = threading.Event()
        self._thread = None
        self.answers = []                  # what the operator answered, in order (entry tests read them)

    def subscribe(self, cb):
        self._subs.append(cb)

    def _emit(self, kind, **data):
        for cb in self._subs:
            cb(Event(kind, data))

    def start(self):
        self._thread = threading.Thread(target=self.run, daemon=True)
        self._thread.start()

    def run(self):
        s = self.steps[0]
        self._emit("state", old="idle", new="waiting")
        self._emit("step_started", key=s.key, procedure=s.procedure, title=s.title, instruction=s.instruction,
                   index=0, total=len(self.steps), attempt=1, pose_deg=s.pose_deg,
                   targets=[t.name for t in s.targets], inputs=[i.name for i in s.inputs])
        for st, hz in (("A", 109.32074), ("B", 259.32700)):
            self._emit("reading", key=s.key, station=st, target=s.targets[0].name if s.targets else "",
                       face=1, repeat=0, hz_deg=hz, v_deg=71.18386)
        while not self._abort.is_set():
            ans = self.operator.ask(Request("setup", s, 1, ("continue", "skip", "pause", "abort")))
            self.answers.append(ans)
            if ans.action in ("pause", "abort"):
                return

    def request_abort(self):
        self._abort.set()

    def join(self, timeout=None):
        if self._thread is not None:
            self._thread.join(timeout)
