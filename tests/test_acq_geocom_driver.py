"""The GeoCOM driver against the emulated theodolite over ``robocal://`` URLs, healthy and faulty."""
from __future__ import annotations

import time
import uuid

import numpy as np
import pytest

from acq.drivers import geocom_codec as gc
from acq.drivers import open_theodolite
from acq.drivers.geocom import GeoComTheodolite
from sim.emulate import registry
from sim.emulate.geocom_device import GeoComDevice
from acq.errors import DeviceTimeout, InstrumentError, LinkLost, ProtocolError
from tests.fakes.faults import FaultyDevice
from tests.fakes.worlds import noisy_world, quiet_world


@pytest.fixture
def rig():
    """(driver, device, faulty wrapper, instance name) on a published instance, torn down after the test."""
    name = f"gc-{uuid.uuid4().hex[:8]}"
    dev = GeoComDevice(quiet_world(), "A")
    faulty = FaultyDevice(dev, seed=1)
    url = registry.publish(name, faulty)
    drv = GeoComTheodolite.open(url, name=f"theodolite A ({url})", attempts=2)
    yield drv, dev, faulty, name
    drv.close()
    registry.withdraw(name)


def test_open_by_registry_name_and_identify():
    with open_theodolite("geocom", "robocal://geocom?seed=3&name=TS16&serial=1234") as t:
        info = t.identify()
    assert (info.driver, info.name, info.serial, info.protocol_version) == ("geocom", "TS16", "1234", "3.50.0")


def test_unknown_driver_and_bad_url_are_one_line_errors():
    from calib.errors import RobocalError
    with pytest.raises(RobocalError, match="unknown theodolite driver 'nope'"):
        open_theodolite("nope", "robocal://geocom")
    with pytest.raises(LinkLost, match="cannot open robocal://geocom.*unknown option"):
        open_theodolite("geocom", "robocal://geocom?bogus=1")


def test_angles_match_the_world(rig):
    drv, dev, _, _ = rig
    r = drv.angles()
    hz, v = dev.world.true_sight("A", 1)
    assert abs(r.hz_rad - hz) < 1e-12 and abs(r.v_rad - v) < 1e-12
    assert r.raw.startswith(b"%R1P,0,") and r.warnings == ()
    r1 = drv.angles_with_inclination()
    assert r1.face == 1 and abs(r1.hz_rad - hz) < 1e-12 and r1.angle_accuracy_rad > 0


def test_noisy_world_reads_within_noise():
    w = noisy_world(seed=5)
    with GeoComTheodolite.open("robocal://instance/" + _pub(GeoComDevice(w, "B"))) as d:
        hz = np.array([d.angles().hz_rad for _ in range(30)])
    true_hz, _ = w.true_sight("B", 1)
    sig = w.stations["B"].sigma_hz_rad
    assert np.std(hz) > 0.2 * sig                     # noise is there
    assert abs(np.mean(hz) - true_hz) < 4 * sig / np.sqrt(30) + 1e-12


def _pub(dev) -> str:
    name = f"x-{uuid.uuid4().hex[:8]}"
    registry.publish(name, dev)
    return name


def test_face_two_by_change_face(rig):
    drv, dev, _, _ = rig
    drv.change_face()
    assert drv.face() == 2
    r = drv.angles_with_inclination()
    hz2, v2 = dev.world.true_sight("A", 2)
    assert r.face == 2 and abs(r.hz_rad - hz2) < 1e-12 and abs(r.v_rad - v2) < 1e-12


def test_positioning_turns_the_telescope(rig):
    drv, _, _, _ = rig
    drv.position(1.25, 1.5)
    r = drv.angles()
    assert abs(r.hz_rad - 1.25) < 2e-5 and abs(r.v_rad - 1.5) < 2e-5
    drv.position(1.25, 1.5, atr=gc.AtrMode.TARGET)      # lock onto the target again


def test_incline_switch_round_trip(rig):
    drv, _, _, _ = rig
    drv.set_incline_switch(False)
    assert drv.incline_switch() is False
    drv.set_incline_switch(True)
    assert drv.incline_switch() is True


def test_distance_after_do_measure(rig):
    drv, dev, _, _ = rig
    assert drv.simple_measurement().slope_distance_m is None
    drv.do_measure()
    assert abs(drv.simple_measurement().slope_distance_m - dev.world.slope_distance_m("A")) < 1e-9


def test_checksum_mode():
    w = quiet_world()
    dev = GeoComDevice(w, "A")
    with GeoComTheodolite.open("robocal://instance/" + _pub(dev), checksum=True) as d:
        r = d.angles()
    import re
    reqs = [q for q in dev.requests if q.startswith(b"%R1Q")]
    assert reqs and all(re.match(rb"%R1Q,\d+,\d+,\d+:", q) for q in reqs)       # every request carries a CRC
    assert abs(r.hz_rad - w.true_sight("A", 1)[0]) < 1e-12


# -- return codes ------------------------------------------------------------------------------------------------
def test_error_return_code_names_device_command_and_cause(rig):
    drv, dev, _, _ = rig
    dev.script_rc(2107, 1290)
    with pytest.raises(InstrumentError) as ei:
        drv.angles()
    e = ei.value
    assert e.code == 1290 and "theodolite A" in str(e) and "TMC_GetAngle5 (RPC 2107)" in str(e)
    assert "TMC_ANGLE_ERROR" in str(e) and "\n" not in str(e)


@pytest.mark.parametrize("code", [1283, 1284, 1288, 1289])
def test_warning_codes_keep_values(rig, code):
    drv, dev, _, _ = rig
    dev.script_rc(2107, code)
    r = drv.angles()
    assert r.warnings and str(code) in r.warnings[0]
    assert abs(r.hz_rad - dev.world.true_sight("A", 1)[0]) < 1e-12


def test_busy_is_retried_even_for_do_measure(rig):
    drv, dev, _, _ = rig
    dev.script_rc(2008, 1293)
    drv.do_measure()
    assert drv.retries == 1


def test_non_idempotent_command_is_not_repeated_on_timeout(rig):
    drv, dev, faulty, _ = rig
    faulty.drop_next_reply()
    with pytest.raises(DeviceTimeout):
        drv.request(9028, ["0", "0", "0"], timeout_s=0.2)
    assert sum(1 for q in dev.requests if q.startswith(b"%R1Q,9028")) == 1


def test_unknown_rpc(rig):
    drv, _, _, _ = rig
    with pytest.raises(InstrumentError, match="3081 GRC_COM_PROC_UNAVAIL") as ei:
        drv.request(4242)
    assert ei.value.code == 3081


# -- link faults ---------------------------------------------------------------------------------------------------
def test_silent_device_times_out_with_a_clear_error(rig):
    drv, _, faulty, _ = rig
    faulty.silent = True
    t0 = time.monotonic()
    with pytest.raises(DeviceTimeout) as ei:
        drv.request(2107, ["1"], timeout_s=0.2)
    # the driver's deadline is a real serial timeout on the host clock (a real port has no other), so this one bound
    # stays on the wall clock: it only tells a give-up (2 x 0.2 s) from a hang, hence generous for a loaded machine
    assert time.monotonic() - t0 < 30.0
    assert sum(1 for sent in faulty.swallowed if sent.startswith(b"%R1Q,2107")) == 2      # both attempts, no more
    msg = str(ei.value)
    assert "theodolite A" in msg and "TMC_GetAngle5" in msg and "no reply" in msg and "2 attempts" in msg


def test_dropped_reply_is_retried_and_stale_reply_discarded(rig):
    drv, _, faulty, _ = rig
    faulty.hold_next_reply()                  # the first reply arrives with the second request: after the give-up
    r = drv.request(2107, ["1"], timeout_s=0.2, attempts=3)
    assert len(r.values) == 2 and drv.retries == 1 and drv.stale_replies == 1


def test_garbled_reply_is_never_a_reading(rig):
    drv, dev, faulty, _ = rig
    faulty.garble_next_reply(position=0)      # '%' -> '$': not a reply
    faulty.garble_next_reply(position=0)
    with pytest.raises(ProtocolError, match="garbled reply"):
        drv.angles()


def test_garbled_reply_recovers_on_retry(rig):
    drv, dev, faulty, _ = rig
    faulty.garble_next_reply(position=3)
    r = drv.angles()
    assert abs(r.hz_rad - dev.world.true_sight("A", 1)[0]) < 1e-12 and drv.retries == 1


def test_wrong_crc_is_detected_and_retried():
    dev = GeoComDevice(quiet_world(), "A")
    faulty = FaultyDevice(dev)
    with GeoComTheodolite.open("robocal://instance/" + _pub(faulty), checksum=True) as d:
        faulty.wrong_crc_next_reply()
        faulty.wrong_crc_next_reply()
        with pytest.raises(ProtocolError, match="checksum mismatch"):
            d.angles()
        faulty.wrong_crc_next_reply()
        assert d.angles().hz_rad > 0 and d.retries == 2


def test_random_garbling_with_crc_never_yields_a_wrong_reading():
    w = quiet_world()
    dev = GeoComDevice(w, "A")
    faulty = FaultyDevice(dev, seed=11)
    hz, v = w.true_sight("A", 1)
    with GeoComTheodolite.open("robocal://instance/" + _pub(faulty), checksum=True, attempts=1) as d:
        faulty.garble_byte_prob = 0.01
        good = bad = 0
        for _ in range(150):
            try:
                r = d.request(2107, ["1"], timeout_s=0.05)
            except (ProtocolError, DeviceTimeout, InstrumentError):
                bad += 1
                continue
            good += 1
            assert abs(r.values[0] - hz) < 1e-12 and abs(r.values[1] - v) < 1e-12
    assert good > 20 and bad > 5


def test_unplug_mid_frame_then_reconnect(rig):
    drv, _, faulty, name = rig
    faulty.unplug_mid_frame(10, lambda: registry.unplug(name), delay_s=0.0)
    with pytest.raises(LinkLost) as ei:                  # a pulled cable is a lost link, never a mere timeout
        drv.request(2107, ["1"], attempts=1, timeout_s=0.3)
    assert "theodolite A" in str(ei.value)
    with pytest.raises(LinkLost, match="unplugged"):      # still unplugged: reopening fails clearly
        drv.angles()
    registry.replug(name)
    r = drv.angles()                                     # reconnects by itself
    assert r.hz_rad > 0


def test_latency_within_timeout_is_fine(rig):
    drv, dev, faulty, _ = rig
    faulty.latency_s = 0.05
    t0 = time.monotonic()
    r = drv.angles()
    assert time.monotonic() - t0 >= 0.05      # the latency was applied (a lower bound: no load can break it)
    assert drv.retries == 0 and drv.stale_replies == 0 and abs(r.hz_rad - dev.world.true_sight("A", 1)[0]) < 1e-12


def test_drain_waits_for_a_quiet_line_only_where_bytes_can_be_in_flight(monkeypatch):
    """An emulator answering in the writer's thread has nothing on the cable: the handshake's drain does not sleep
    for a quiet line.  Behind a faulty cable (latency: bytes in flight) the same drain waits as on a real port."""
    import acq.link
    naps = []
    monkeypatch.setattr(acq.link.time, "sleep", lambda s: naps.append(s))
    for wrap, sleeps in ((lambda d: d, False), (FaultyDevice, True)):
        name = f"gc-{uuid.uuid4().hex[:8]}"
        url = registry.publish(name, wrap(GeoComDevice(quiet_world(), "A")))
        try:
            naps.clear()
            drv = GeoComTheodolite.open(url, name="theodolite A")        # the handshake drains 0.02 s
            assert drv.link._port.synchronous is not sleeps
            assert bool(naps) is sleeps
            assert drv.angles().face == 1                                  # and the link works as before
            drv.close()
        finally:
            registry.withdraw(name)
