"""The bridge between the session runner's thread and the Textual app's thread.

Device I/O and the runner live in the runner's thread; widgets only in the app's.  Three channels cross:

* **records** (every runner event: steps, readings, checks, saves, logs) are posted as :class:`RunnerEvent` messages,
  in order, never dropped — Textual's ``post_message`` is thread-safe and queues;
* **live values** (the latest theodolite angles and encoder counts) go through :class:`LiveValues`, a coalescing
  store the app samples on a timer, so a CAN bus at its limit cannot flood the interface;
* **prompts**: the runner calls :meth:`TuiOperator.ask` and blocks on a future that the app completes when the operator
  answers; closing the app answers ``abort`` so the runner never hangs.
"""
from __future__ import annotations

import threading
from concurrent.futures import Future
from typing import Any

from textual.message import Message

from acq.session.runner import Answer, Event, Request


class RunnerEvent(Message):
    """One runner event, in order."""

    def __init__(self, event: Event) -> None:
        super().__init__()
        self.event = event


class OperatorPrompt(Message):
    """The runner waits for the operator."""

    def __init__(self, request: Request, future: "Future[Answer]") -> None:
        super().__init__()
        self.request = request
        self.future = future


class LiveValues:
    """Latest value per key, written from any thread, read by the UI timer (coalescing: only the newest counts)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._values: dict[str, Any] = {}
        self.updates = 0

    def put(self, key: str, value: Any) -> None:
        with self._lock:
            self._values[key] = value
            self.updates += 1

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._values)


class TuiOperator:
    """The runner's :class:`acq.session.runner.Operator`, answered from the TUI."""

    def __init__(self) -> None:
        self.app = None
        self.closed = threading.Event()

    def ask(self, request: Request) -> Answer:
        if self.closed.is_set() or self.app is None:
            return Answer("abort")
        fut: Future[Answer] = Future()
        self.app.post_message(OperatorPrompt(request, fut))
        while True:
            try:
                return fut.result(timeout=0.2)
            except TimeoutError:
                if self.closed.is_set():
                    return Answer("abort")
