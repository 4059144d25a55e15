"""The headless front end: a scripted operator and a console/progress subscriber.

:class:`ScriptedOperator` answers the runner's requests from a script, so tests and automation drive exactly the
procedures an operator would.  The script is a dict (also loadable from JSON):

* ``"policy"``: what to do after the checks when nothing specific is scripted -- ``"auto"`` (accept when every check
  passed, else repeat up to ``max_repeats`` times, then accept with a note), or ``"accept"``;
* ``"answers"``: step key -> list of actions consumed in order at that step's decisions (``accept``, ``repeat``,
  ``skip``, ``pause``, ``abort``), e.g. ``{"sweep/j2/01": ["repeat", "accept"]}``;
* ``"setup"``: step key -> action at the setup prompt (``skip``, ``pause``, ``abort``);
* ``"pause_after"``: number of decisions after which to answer ``pause`` (tests of resume).

Operator inputs (loads, dial gauges, tilts) come from ``inputs(step) -> dict``, what the operator reads off the
bench -- the demo passes a reader of its emulated bench (the mass it hung, its gauges, its levels).  The plan's values
are never entered in their place: without a reader, a step that needs a value is refused by the runner.
"""
from __future__ import annotations

from typing import Callable

from .runner import Answer, Event, Request
from .steps import Step


class ScriptedOperator:
    def __init__(self, script: dict | None = None, inputs: Callable[[Step], dict] | None = None):
        s = script or {}
        self.policy = s.get("policy", "auto")
        self.max_repeats = int(s.get("max_repeats", 1))
        self.answers = {k: list(v) for k, v in s.get("answers", {}).items()}
        self.setup_answers = dict(s.get("setup", {}))
        self.pause_after = s.get("pause_after")
        self.inputs = inputs
        self.decisions = 0
        self.log: list[tuple[str, int, str]] = []

    def ask(self, req: Request) -> Answer:
        step = req.step
        if req.kind == "setup":
            act = self.setup_answers.get(step.key, "continue")
            values = dict(self.inputs(step)) if self.inputs is not None else {}
            self.log.append((step.key, req.attempt, f"setup:{act}"))
            return Answer(act, values)
        self.decisions += 1
        if self.pause_after is not None and self.decisions > self.pause_after:
            self.log.append((step.key, req.attempt, "pause"))
            return Answer("pause")
        queued = self.answers.get(step.key)
        if queued:
            act = queued.pop(0)
        elif self.policy == "accept" or all(c.passed for c in req.checks):
            act = "accept"
        elif req.attempt <= self.max_repeats:
            act = "repeat"
        else:
            act = "accept"
        if act == "accept" and "accept" not in req.choices:     # a device fault: nothing to accept
            act = "repeat" if req.attempt <= self.max_repeats else "skip"
        note = ""
        failed = [c.name for c in req.checks if not c.passed]
        if act == "accept" and failed:
            note = "accepted with failed checks: " + ", ".join(failed)
        self.log.append((step.key, req.attempt, act))
        return Answer(act, note=note)


class ProgressPrinter:
    """Subscriber that drives an :class:`acq.progress` bar (or nothing) from runner events."""

    def __init__(self, update: Callable[[int, int, str], None] | None = None):
        self.update = update
        self.saved = 0
        self.total = 0
        self.failed_checks = 0
        self.preflight_lines: list[str] = []
        self.error: str | None = None                 # why the session ended, when it failed

    def __call__(self, ev: Event) -> None:
        if ev.kind == "session":
            self.total = ev.data["total"]
            self.saved = ev.data["done"]
        elif ev.kind in ("step_saved",):
            self.saved += 1
            if self.update:
                self.update(self.saved, self.total, ev.data["key"])
        elif ev.kind == "preflight":
            self.preflight_lines = list(ev.data["lines"])
        elif ev.kind == "check" and not ev.data["passed"]:
            self.failed_checks += 1
        elif ev.kind == "finished":
            self.error = ev.data.get("error")
