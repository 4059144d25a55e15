"""Worlds for tests: the one world (the twin of the default scenario) with or without reading noise."""
from __future__ import annotations

import uuid

from acq.emulate.factories import make_world


def quiet_world(seed: int = 0):
    """The default scenario without reading noise or gross errors: emulator readings equal ``true_sight`` to the
    reply's precision."""
    return make_world(None, seed=seed, noise=False)


def noisy_world(seed: int = 0):
    return make_world(None, seed=seed, noise=True)


def channel() -> str:
    """A fresh python-can virtual channel name, so parallel tests never hear each other."""
    return f"t-{uuid.uuid4().hex[:12]}"
