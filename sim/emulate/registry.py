"""Emulated devices by name, so a URL or a command line can make one, and named instances tests can reach.

``robocal://<kind>?k=v&...`` builds a fresh device of ``kind`` (a registry entry below: one new line per emulator).
``robocal://instance/<name>`` attaches to a device published with :func:`publish` (tests use it to inject faults
and to simulate unplug/replug: ports opened before :func:`unplug` fail on their next read or write, new opens fail
until :func:`replug`).
"""
from __future__ import annotations

import importlib
import threading
from dataclasses import dataclass
from typing import Callable
from urllib.parse import parse_qsl, urlsplit

from calib.errors import RobocalError

from sim.emulate.device import ByteDevice

#: kind -> "module:factory"; a factory takes the URL query as a dict of strings
KINDS: dict[str, str] = {
    "geocom": "sim.emulate.factories:geocom",
    "gsi": "sim.emulate.factories:gsi",
    "serialtap": "sim.emulate.factories:serial_tap",
    "slcan": "sim.emulate.factories:slcan_tap",
}


@dataclass
class Slot:
    device: ByteDevice
    generation: int = 0
    plugged: bool = True


_SLOTS: dict[str, Slot] = {}
_LOCK = threading.Lock()


def make_device(kind: str, options: dict[str, str]) -> ByteDevice:
    try:
        target = KINDS[kind]
    except KeyError:
        raise RobocalError(f"emulator: unknown device kind {kind!r} (known: {', '.join(KINDS)})") from None
    mod, fn = target.split(":")
    factory: Callable[[dict[str, str]], ByteDevice] = getattr(importlib.import_module(mod), fn)
    return factory(dict(options))


def publish(name: str, device: ByteDevice) -> str:
    """Make ``device`` reachable as ``robocal://instance/<name>``; returns that URL."""
    with _LOCK:
        _SLOTS[name] = Slot(device)
    return f"robocal://instance/{name}"


def withdraw(name: str) -> None:
    with _LOCK:
        _SLOTS.pop(name, None)


def unplug(name: str) -> None:
    with _LOCK:
        slot = _SLOTS[name]
        slot.plugged = False
        slot.generation += 1


def replug(name: str) -> None:
    with _LOCK:
        _SLOTS[name].plugged = True


def slot(name: str) -> Slot | None:
    return _SLOTS.get(name)


def resolve(url: str) -> tuple[ByteDevice, str | None, int]:
    """(device, instance name or None, generation) for a ``robocal://`` URL; ValueError if malformed."""
    parts = urlsplit(url)
    if parts.scheme != "robocal":
        raise ValueError(f"not a robocal:// URL: {url!r}")
    if parts.netloc == "instance":
        name = parts.path.strip("/")
        with _LOCK:
            s = _SLOTS.get(name)
            if s is None:
                raise ValueError(f"no emulated instance named {name!r}")
            if not s.plugged:
                raise ValueError(f"emulated device {name!r} is unplugged")
            return s.device, name, s.generation
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    try:
        return make_device(parts.netloc, options), None, 0
    except RobocalError as exc:
        raise ValueError(str(exc)) from None
