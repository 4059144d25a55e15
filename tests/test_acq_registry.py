"""Registries by name: theodolite drivers, encoder taps, emulated device kinds; URL errors are one line."""
from __future__ import annotations

import pytest
import serial

from acq.drivers import drivers, open_theodolite
from acq.drivers.base import Theodolite
from sim.emulate import registry
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
    with pytest.raises(serial.SerialException, match="option seed must be a whole number, got 'abc'"):
        serial.serial_for_url("robocal://geocom?seed=abc")
    with pytest.raises(RobocalError) as ei:
        SerialLink("robocal://instance/none-such", name="theodolite A")
    assert str(ei.value) == ("theodolite A: open: cannot open robocal://instance/none-such: "
                             "no emulated instance named 'none-such'")


def test_device_path_that_does_not_exist():
    with pytest.raises(RobocalError, match="^theodolite A: open: cannot open /dev/does-not-exist"):
        open_theodolite("geocom", "/dev/does-not-exist", name="theodolite A")


@pytest.mark.parametrize("url,why", [
    ("robocal://serialtap?rate_hz=1e308", "option rate_hz must be in"),
    ("robocal://serialtap?rate_hz=0", "option rate_hz must be in"),
    ("robocal://slcan?rate_hz=nan", "option rate_hz must be a finite number"),
    ("robocal://slcan?rate_hz=inf", "option rate_hz must be a finite number"),
    ("robocal://serialtap?rate_hz=-5", "option rate_hz must be in"),
    ("robocal://gsi?stream_hz=1e308", "option stream_hz must be in"),
    ("robocal://gsi?wordlen=12", "wordlen must be 8 or 16"),
    ("robocal://gsi?unit=grad", "angle unit 'grad'"),
    ("robocal://geocom?station=Z", "no station 'Z' in the world \\(stations: A, B\\)"),
    ("robocal://gsi?station=Z", "no station 'Z'"),
    ("robocal://geocom?seed=" + "9" * 4301, "option seed must be a whole number of at most 18 digits"),
    ("robocal://geocom?noise=maybe", "option noise must be one of"),
    ("robocal://geocom?serial=-1", "option serial must be a whole number"),
    ("robocal://geocom?scenario=/nonexistent/s.toml", "s.toml"),
])
def test_bad_emulator_options_are_refused_when_the_port_opens(url, why):
    register_url_handlers()
    with pytest.raises(serial.SerialException, match=why) as ei:
        serial.serial_for_url(url)
    assert "\n" not in str(ei.value)


def test_url_instruments_observe_the_twin_of_a_chosen_scenario(tmp_path):
    """C5: robocal:// URLs run on TwinWorld; ``scenario=`` selects the twin (here: its stations moved)."""
    from acq.drivers import open_theodolite
    from sim.emulate.twin_world import TwinWorld
    import importlib.resources as res

    text = (res.files("calib") / "data" / "twin_default.toml").read_text(encoding="utf-8")
    moved = tmp_path / "moved.toml"
    moved.write_text(text.replace("L_mm = 1609.9", "L_mm = 2400.0"), encoding="utf-8")
    with open_theodolite("geocom", "robocal://geocom?noise=0&station=B") as a, \
            open_theodolite("geocom", f"robocal://geocom?noise=0&station=B&scenario={moved}") as b:
        r0, r1 = a.angles(), b.angles()
    assert isinstance(registry.make_device("geocom", {}).world, TwinWorld)
    assert abs(r0.hz_rad - r1.hz_rad) > 1e-3          # another base line: station B reads another angle


def test_url_instruments_of_one_process_share_one_world():
    a = registry.make_device("geocom", {"station": "A", "seed": "5"})
    b = registry.make_device("gsi", {"station": "B", "seed": "5"})
    tap = registry.make_device("serialtap", {"seed": "5"})
    other = registry.make_device("geocom", {"station": "A", "seed": "6"})
    assert a.world is b.world is tap.model.world and other.world is not a.world
