"""Worlds for tests: the demo world with or without noise, and a world whose truth a test can move."""
from __future__ import annotations

import uuid

from acq.emulate.world import KinematicWorld, demo_world


def quiet_world(seed: int = 0) -> KinematicWorld:
    """Demo world without reading noise: emulator readings equal ``true_sight`` to the reply's precision."""
    return demo_world(seed=seed, noise=False)


def noisy_world(seed: int = 0) -> KinematicWorld:
    return demo_world(seed=seed, noise=True)


def channel() -> str:
    """A fresh python-can virtual channel name, so parallel tests never hear each other."""
    return f"t-{uuid.uuid4().hex[:12]}"
