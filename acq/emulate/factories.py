"""Factories behind ``robocal://<kind>?...`` URLs and ``robocal emulate``: a device on the demo world.

Options come as strings (URL query); each factory says which it understands and rejects the others, so a typo in a
URL is an error rather than a silently ignored setting.
"""
from __future__ import annotations

from typing import Callable

from calib.errors import RobocalError

from .world import World, demo_world


def _take(options: dict[str, str], allowed: dict[str, type], kind: str) -> dict:
    unknown = set(options) - set(allowed)
    if unknown:
        raise RobocalError(f"emulator {kind}: unknown option(s) {', '.join(sorted(unknown))} "
                           f"(known: {', '.join(allowed)})")
    out = {}
    for key, typ in allowed.items():
        if key in options:
            text = options[key]
            try:
                out[key] = (text.lower() in ("1", "true", "yes", "on")) if typ is bool else typ(text)
            except ValueError:
                raise RobocalError(f"emulator {kind}: option {key}={text!r} is not a {typ.__name__}") from None
    return out


#: how URL-made devices get their world: (seed, noise) -> World.  The twin replaces it with set_world_factory().
_WORLD_FACTORY: Callable[[int, bool], World] = lambda seed, noise: demo_world(seed=seed, noise=noise)


def set_world_factory(factory: Callable[[int, bool], World]) -> None:
    """Make ``robocal://geocom?seed=3`` (and the other kinds) build their world with ``factory(seed, noise)``."""
    global _WORLD_FACTORY
    _WORLD_FACTORY = factory


def _world(o: dict, world: World | None) -> World:
    return world if world is not None else _WORLD_FACTORY(o.get("seed", 0), o.get("noise", True))


def geocom(options: dict[str, str], world: World | None = None):
    from .geocom_device import GeoComDevice
    o = _take(options, {"seed": int, "station": str, "noise": bool, "motorised": bool, "name": str,
                        "serial": int}, "geocom")
    kw = {}
    if "name" in o:
        kw["instrument_name"] = o["name"]
    if "serial" in o:
        kw["serial_no"] = o["serial"]
    return GeoComDevice(_world(o, world), o.get("station", "A"), motorised=o.get("motorised", True),
                        seed=o.get("seed", 0), **kw)


def gsi(options: dict[str, str], world: World | None = None):
    from .gsi_device import GsiDevice
    o = _take(options, {"seed": int, "station": str, "noise": bool, "wordlen": int, "unit": str,
                        "stream_hz": float, "serial": int}, "gsi")
    kw = {}
    if "serial" in o:
        kw["serial_no"] = o["serial"]
    return GsiDevice(_world(o, world), o.get("station", "B"), gsi16=o.get("wordlen", 16) == 16,
                     angle_unit=o.get("unit", "gon"), stream_hz=o.get("stream_hz", 0.0), **kw)


def serial_tap(options: dict[str, str], world: World | None = None):
    from .tap_device import SerialTapDevice
    o = _take(options, {"seed": int, "noise": bool, "rate_hz": float}, "serialtap")
    w = _world(o, world)
    return SerialTapDevice(w, _robot(w), rate_hz=o.get("rate_hz", 500.0))


def slcan_tap(options: dict[str, str], world: World | None = None):
    from .slcan_device import SlcanTapDevice
    o = _take(options, {"seed": int, "noise": bool, "rate_hz": float}, "slcan")
    w = _world(o, world)
    return SlcanTapDevice(w, _robot(w), rate_hz=o.get("rate_hz", 100.0))


def _robot(world: World):
    robot = getattr(world, "robot", None)
    if robot is None:
        from calib.robot import load_robot
        robot = load_robot()
    return robot
