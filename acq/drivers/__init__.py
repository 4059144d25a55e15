"""Theodolite drivers, found by name: ``open_theodolite("geocom", url)``.

A driver is a module in this package that defines ``DRIVER_NAME`` and ``open_driver(url, **options)``; it is found
by scanning the package, so a third vendor is one new module (no if/elif chain, nothing else to edit).  Codecs
(``*_codec``) and helpers without ``DRIVER_NAME`` are skipped.
"""
from __future__ import annotations

import importlib
import pkgutil
from functools import lru_cache
from typing import Callable

from calib.errors import RobocalError

from .base import AngleReading, DeviceInfo, Theodolite


@lru_cache(maxsize=None)
def drivers() -> dict[str, Callable[..., Theodolite]]:
    found: dict[str, Callable[..., Theodolite]] = {}
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_") or info.name.endswith("_codec") or info.name in ("base", "geocom_codes"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        name = getattr(mod, "DRIVER_NAME", None)
        if name and hasattr(mod, "open_driver"):
            found[name] = mod.open_driver
    return found


def open_theodolite(kind: str, url: str, **options) -> Theodolite:
    """Open a theodolite of protocol ``kind`` on ``url`` (device path, socket://, spy://, pty, robocal://...)."""
    try:
        opener = drivers()[kind]
    except KeyError:
        raise RobocalError(f"unknown theodolite driver {kind!r} (known: {', '.join(sorted(drivers()))})") from None
    return opener(url, **options)


__all__ = ["AngleReading", "DeviceInfo", "Theodolite", "drivers", "open_theodolite"]
