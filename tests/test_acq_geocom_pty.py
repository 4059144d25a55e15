"""GeoCOM over a real pty: our driver, and the third-party client GeoComPy (interoperability)."""
from __future__ import annotations

import pytest

from tests.dev_extra import require

from acq.drivers.geocom import GeoComTheodolite
from sim.emulate.geocom_device import GeoComDevice
from sim.emulate.pty_host import PtyHost
from acq.errors import LinkLost
from tests.fakes.faults import FaultyDevice
from tests.fakes.worlds import quiet_world

geocompy_comm = require("geocompy.communication", "geocompy")
geocompy_geo = require("geocompy.geo", "geocompy")


def test_driver_over_pty():
    w = quiet_world()
    with PtyHost(GeoComDevice(w, "A")) as host:
        assert host.path.startswith("/dev/")
        with GeoComTheodolite.open(host.path, baudrate=115200) as d:
            r = d.angles_with_inclination()
            assert d.identify().name == "TM30 0.5"
    hz, v = w.true_sight("A", 1)
    assert abs(r.hz_rad - hz) < 1e-12 and abs(r.v_rad - v) < 1e-12 and r.face == 1


@pytest.mark.parametrize("checksum", [False, True])
def test_geocompy_connects_and_reads_the_twin(checksum):
    w = quiet_world()
    dev = GeoComDevice(w, "B", instrument_name="TS16 1", serial_no=777)
    with PtyHost(dev) as host:
        with geocompy_comm.open_serial(host.path, speed=19200, timeout=3) as conn:
            tps = geocompy_geo.GeoCom(conn, checksum=checksum, attempts=1)
            name = tps.csv.get_instrument_name()
            angle = tps.tmc.get_angle()
            full = tps.tmc.get_angle_inclination()
            face = tps.tmc.get_face()
            unknown = tps.request(4242)          # an RPC the emulator does not know: a reply GeoComPy can parse
    # the connect sequence of GeoComPy 1.0: LF, 0, 108, 5004, 5003, 110, 5034
    rpcs = [int(q.split(b",")[1].split(b":")[0]) for q in dev.requests if q.startswith(b"%R1Q")]
    assert rpcs[:6] == [0, 108, 5004, 5003, 110, 5034]
    if checksum:
        assert all(q.count(b",") >= 3 for q in dev.requests if q.startswith(b"%R1Q"))
    assert name.params == "TS16 1"
    assert angle.error == 0 and full.error == 0 and angle.trans == int(angle.cmd.split(",")[2].split(":")[0])
    hz, v = w.true_sight("B", 1)
    assert abs(float(angle.params[0]) - hz) < 1e-12 and abs(float(angle.params[1]) - v) < 1e-12
    assert abs(float(full.params[0]) - hz) < 1e-12
    assert face.params.value == 0 and face.error == 0
    from geocompy.geo.gctypes import GeoComCode
    assert unknown.error == GeoComCode.COM_PROC_UNAVAIL, unknown


def test_pty_unplug_mid_frame_is_a_clear_link_error():
    dev = GeoComDevice(quiet_world(), "A")
    faulty = FaultyDevice(dev)
    host = PtyHost(faulty)
    try:
        d = GeoComTheodolite.open(host.path, name="theodolite A", reconnect=False)
        faulty.unplug_mid_frame(12, host.unplug, delay_s=0.02)
        with pytest.raises(LinkLost) as ei:              # the pty closed under the reader: a lost link, not a timeout
            d.request(2107, ["1"], timeout_s=1.0, attempts=1)
        assert str(ei.value).startswith("theodolite A: TMC_GetAngle5 (RPC 2107): ")
        with pytest.raises(LinkLost):
            d.request(2107, ["1"], timeout_s=0.3, attempts=1)
    finally:
        host.close()
