"""The rig keeps the face it left a motorised telescope in (no question to the instrument for a sighting in that
face, nor before turning it to the other) and still notices a telescope turned by hand in between: the reading's own
face disagrees, the rig turns it back and reads again, so a reading is never stored under the wrong face."""
from __future__ import annotations

import uuid

import pytest

from acq.drivers.geocom import GeoComTheodolite
from sim.emulate import registry
from sim.emulate.geocom_device import GeoComDevice
from acq.session.rig import Rig
from tests.fakes.worlds import quiet_world


class CountingDriver:
    """The real driver, counting the face questions it is asked."""

    def __init__(self, drv):
        self.drv, self.asked = drv, 0

    def face(self):
        self.asked += 1
        return self.drv.face()

    def __getattr__(self, name):
        return getattr(self.drv, name)


@pytest.fixture
def station():
    name = f"rig-face-{uuid.uuid4().hex[:8]}"
    url = registry.publish(name, GeoComDevice(quiet_world(), "A"))
    drv = GeoComTheodolite.open(url, name="theodolite A")
    yield CountingDriver(drv)
    drv.close()
    registry.withdraw(name)


def test_a_known_face_is_not_asked_again(station):
    rig = Rig({"A": station})
    for face in (1, 1, 2, 2, 1):
        rig.face("A", face)
        assert rig.sight("A").face == face
    assert station.asked == 1                      # once, when the rig did not know it: not per change or sighting


def test_a_telescope_turned_by_hand_is_turned_back_before_the_reading(station):
    rig = Rig({"A": station})
    rig.face("A", 2)
    assert rig.sight("A").face == 2
    station.drv.change_face()                      # someone turns it behind the rig's back: face I now
    rig.face("A", 2)                               # the rig believes face II: no question ...
    r = rig.sight("A")
    assert r.face == 2                             # ... but the reading said face I, so it was turned back and re-read
    assert station.drv.face() == 2
