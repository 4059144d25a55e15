"""Factories behind ``robocal://<kind>?...`` URLs and ``robocal emulate``: a device on the twin's world.

One world (issue 13, contract C5): every emulated instrument observes a :class:`~sim.emulate.twin_world.TwinWorld`
on :class:`sim.twin.Twin` built from a scenario TOML (``scenario=PATH``; the default scenario by default), so a URL
instrument, ``robocal emulate`` and the demo all see the same simulated robot.

Options come as strings (URL query); each factory says which it understands and checks every value before a device
exists (a typo, a 4,301-digit number, a rate of 0, NaN or 1e308 is refused when the port opens, never in a server
thread later).
"""
from __future__ import annotations

import argparse
import dataclasses
import threading
from pathlib import Path
from typing import Callable

from acq import argtypes as at
from calib.errors import RobocalError
from sim.emulate.geocom_device import GeoComDevice
from sim.emulate.gsi_device import GsiDevice, MAX_STREAM_HZ
from sim.emulate.slcan_device import SlcanTapDevice
from sim.emulate.tap_device import MAX_RATE_HZ, SerialTapDevice
from sim.emulate.twin_world import TwinWorld

from sim.emulate.world import World
from sim.twin import Twin, load_scenario

_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def parse_bool(raw: str) -> bool:
    """A switch: 1/true/yes/on or 0/false/no/off (anything else is an error, not a silent False)."""
    text = raw.strip().lower()
    if text in _TRUE or text in _FALSE:
        return text in _TRUE
    raise argparse.ArgumentTypeError(f"must be one of {'/'.join(_TRUE + _FALSE)}, got {raw!r}")


def _types() -> dict[str, Callable[[str], object]]:
    """Option name -> checking converter (the command line's own types, so both say the same)."""
    return {
        "seed": at.seed_int, "station": str, "noise": parse_bool, "motorised": parse_bool, "name": str,
        "serial": at.int_range(0, 2 ** 31 - 1), "scenario": str, "wordlen": at.int_range(8, 16),
        "unit": str, "stream_hz": at.float_range(0.0, MAX_STREAM_HZ),
        "rate_hz": at.float_range(0.0, MAX_RATE_HZ, low_open=True),
    }


def _take(options: dict[str, str], allowed: tuple[str, ...], kind: str) -> dict:
    unknown = set(options) - set(allowed)
    if unknown:
        raise RobocalError(f"emulator {kind}: unknown option(s) {', '.join(sorted(unknown))} "
                           f"(known: {', '.join(allowed)})")
    types = _types()
    out = {}
    for key in allowed:
        if key in options:
            try:
                out[key] = types[key](options[key])
            except (argparse.ArgumentTypeError, ValueError) as exc:
                raise RobocalError(f"emulator {kind}: option {key} {exc}") from None
    return out


def make_world(scenario: str | None = None, seed: int = 0, noise: bool = True, q0_deg=None):
    """The one world of every emulated instrument: a TwinWorld on the twin of ``scenario`` (None: the default).

    ``noise=False`` gives the same scenario without reading noise and gross errors (tests compare readings with
    ``true_sight``); ``q0_deg`` is the pose the robot holds (default READY).
    """
    sc = load_scenario(scenario or None)
    if not noise:
        sc = dataclasses.replace(sc, angle_noise=False, gross_rate=0.0)
    return TwinWorld(Twin(sc, seed=seed), q0_deg, seed=seed)


def demo_world(seed: int | None = 0, noise: bool = True, scenario: str | None = None):
    """The world of ``robocal://`` URLs and ``robocal emulate`` (kept name): the twin of the default scenario."""
    return make_world(scenario, seed=seed or 0, noise=noise)


_WORLD = ("seed", "noise", "scenario")
#: URL instruments of one process with the same (scenario, seed, noise) share one world: the theodolites and the
#: tap of a session opened by URL observe the same robot, not three copies of it
_SHARED: dict[tuple, World] = {}
_SHARED_LOCK = threading.Lock()


def shared_world(scenario: str | None = None, seed: int = 0, noise: bool = True) -> World:
    """The process's world for these options (made on first use by :func:`make_world`)."""
    key = (str(Path(scenario).resolve()) if scenario else None, seed, noise)
    with _SHARED_LOCK:
        if key not in _SHARED:
            _SHARED[key] = make_world(scenario, seed=seed, noise=noise)
        return _SHARED[key]


def _world(o: dict, world: World | None) -> World:
    if world is not None:
        return world
    return shared_world(o.get("scenario"), seed=o.get("seed", 0), noise=o.get("noise", True))


def geocom(options: dict[str, str], world: World | None = None):
    o = _take(options, _WORLD + ("station", "motorised", "name", "serial"), "geocom")
    kw = {}
    if "name" in o:
        kw["instrument_name"] = o["name"]
    if "serial" in o:
        kw["serial_no"] = o["serial"]
    return GeoComDevice(_world(o, world), o.get("station", "A"), motorised=o.get("motorised", True),
                        seed=o.get("seed", 0), **kw)


def gsi(options: dict[str, str], world: World | None = None):
    o = _take(options, _WORLD + ("station", "wordlen", "unit", "stream_hz", "serial"), "gsi")
    if o.get("wordlen", 16) not in (8, 16):
        raise RobocalError(f"emulator gsi: option wordlen must be 8 or 16, got {options['wordlen']!r}")
    kw = {}
    if "serial" in o:
        kw["serial_no"] = o["serial"]
    return GsiDevice(_world(o, world), o.get("station", "B"), gsi16=o.get("wordlen", 16) == 16,
                     angle_unit=o.get("unit", "gon"), stream_hz=o.get("stream_hz", 0.0), **kw)


def serial_tap(options: dict[str, str], world: World | None = None):
    o = _take(options, _WORLD + ("rate_hz",), "serialtap")
    w = _world(o, world)
    return SerialTapDevice(w, w.robot, rate_hz=o.get("rate_hz", 500.0))


def slcan_tap(options: dict[str, str], world: World | None = None):
    o = _take(options, _WORLD + ("rate_hz",), "slcan")
    w = _world(o, world)
    return SlcanTapDevice(w, w.robot, rate_hz=o.get("rate_hz", 100.0))
