"""Worlds for tests: the one world (the twin of the default scenario) with or without reading noise."""
from __future__ import annotations

import time
import uuid
from typing import Callable

from sim.emulate.factories import make_world


def quiet_world(seed: int = 0):
    """The default scenario without reading noise or gross errors: emulator readings equal ``true_sight`` to the
    reply's precision."""
    return make_world(None, seed=seed, noise=False)


def noisy_world(seed: int = 0):
    return make_world(None, seed=seed, noise=True)


def until(condition: Callable[[], bool], timeout_s: float = 10.0) -> bool:
    """Whether ``condition()`` came true within ``timeout_s`` of real time, polled: for a reader thread to take
    delivery of what a simulated clock already sent.  What is asserted afterwards is set by the simulated time, not
    by how fast the machine is; the real-time bound only keeps a broken reader from hanging the test."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


def channel() -> str:
    """A fresh python-can virtual channel name, so parallel tests never hear each other."""
    return f"t-{uuid.uuid4().hex[:12]}"
