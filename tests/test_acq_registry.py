"""Registries by name: theodolite drivers, encoder taps, emulated device kinds; URL errors are one line."""
from __future__ import annotations

import pytest
import serial

from acq.drivers import drivers, open_theodolite
from acq.drivers.base import Theodolite
from acq.emulate import registry
from acq.encoders import open_tap
from acq.link import SerialLink, register_url_handlers
from calib.errors import RobocalError


def test_driver_modules_are_discovered():
    assert set(drivers()) == {"geocom", "gsi"}


@pytest.mark.parametrize("kind,url", [("geocom", "robocal://geocom?seed=2"), ("gsi", "robocal://gsi?seed=2")])
def test_every_driver_satisfies_the_protocol(kind, url):
    with open_theodolite(kind, url) as t:
        assert isinstance(t, Theodolite)
        r = t.angles()
        assert 0 <= r.hz_rad < 6.3 and r.raw


def test_open_tap_by_name_and_errors():
    with pytest.raises(RobocalError, match="unknown encoder tap kind 'usb'"):
        open_tap("usb")
    with pytest.raises(RobocalError, match="missing option 'channel'"):
        open_tap("can", interface="virtual")


def test_emulator_kinds_and_url_errors():
    register_url_handlers()
    assert set(registry.KINDS) >= {"geocom", "gsi", "serialtap", "slcan"}
    with pytest.raises(serial.SerialException, match="unknown device kind 'xyz'"):
        serial.serial_for_url("robocal://xyz")
    with pytest.raises(serial.SerialException, match="not a int"):
        serial.serial_for_url("robocal://geocom?seed=abc")
    with pytest.raises(RobocalError) as ei:
        SerialLink("robocal://instance/none-such", name="theodolite A")
    assert str(ei.value) == ("theodolite A: open: cannot open robocal://instance/none-such: "
                             "no emulated instance named 'none-such'")


def test_device_path_that_does_not_exist():
    with pytest.raises(RobocalError, match="^theodolite A: open: cannot open /dev/does-not-exist"):
        open_theodolite("geocom", "/dev/does-not-exist", name="theodolite A")
