"""Where the emulated instruments get their truth: an injected :class:`World`.

There is one world (issue 13): :class:`~sim.emulate.twin_world.TwinWorld` on :class:`sim.twin.Twin`, built by
:func:`sim.emulate.factories.make_world` from a scenario (this module imports nothing of the package: every
device and the factories depend on it, not the other way).  The protocol stays so a device only depends on the two
questions it asks, both "now":

* ``joint_angles_rad()`` -> the robot's joint readings (the encoder tap turns them into counts with
  ``robot.counts_from_joint``);
* ``sight(station_name, face)`` -> what that theodolite reads on the current target: ``(hz_rad, v_rad)``, instrument
  errors and reading noise included.  ``face`` is 1 (face I) or 2 (face II), as in :mod:`calib.theodolite`.

Optional extras a device uses when present: ``stations`` (names, so a device refuses an unknown station at start),
``robot`` and ``slope_distance_m(station_name)`` (EDM).  Implementations must be thread-safe: the tap and two
theodolites run in different threads.
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from calib.errors import RobocalError


@runtime_checkable
class World(Protocol):
    """What an emulated instrument may ask about the world."""

    def joint_angles_rad(self) -> np.ndarray: ...

    def sight(self, station_name: str, face: int) -> tuple[float, float]: ...


def check_station(world: World, station: str, device: str) -> None:
    """Refuse at start a station the world does not have (instead of failing on the first request)."""
    stations = getattr(world, "stations", None)
    if stations is not None and station not in stations:
        raise RobocalError(f"emulator {device}: no station {station!r} in the world "
                           f"(stations: {', '.join(map(str, stations))})")
