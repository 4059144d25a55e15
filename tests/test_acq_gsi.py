"""GSI-8/16 words, GSI Online driver and the emulated GSI theodolite (URL and pty, stream and requests)."""
from __future__ import annotations

import math
import uuid

import pytest
from hypothesis import given, strategies as st

from acq.drivers import gsi_codec as gsi
from acq.drivers.gsi import GsiTheodolite
from sim.emulate import registry
from sim.emulate.gsi_device import GsiDevice
from sim.emulate.pty_host import PtyHost
from acq.errors import DeviceTimeout, InstrumentError, ProtocolError
from tests.fakes.faults import FaultyDevice
from tests.fakes.worlds import quiet_world

GON = math.pi / 200


@pytest.mark.parametrize("line,point,hz,v,sd", [
    ("110001+00000001 21.322+03496940 22.322+09364360 31..00+00030485 51..1.+0000+000 87..10+00001500 "
     "81..00+00515836 82..00+00525871 83..00+00003079 71....+00000001 32..10+00030333 ",
     "1", 34.96940 * GON, 93.64360 * GON, 30.485),
    ("*110002+00000000GDEM5415 21.024+0000000003545100 22.024+0000000009117510 31...0+0000000000013825 "
     "51....+000000000017+000 87...0+0000000000001300 88...0+0000000000001324 ",
     "GDEM5415", math.radians(35 + 45 / 60 + 10 / 3600), math.radians(91 + 17 / 60 + 51 / 3600), 13.825),
    ("*11....+00000000000P0001 21.324+0000000024943030 22.324+0000000008336237 31..06+0000000000073493 "
     "51....+000000000000+000 87..16+0000000000000000 ", "P0001", 4.358392574848940, None, 7.3493),
])
def test_real_gsi_lines(line, point, hz, v, sd):
    words = {w.wi: w for w in gsi.parse_block(line)}
    assert words[11].text() == point
    assert abs(words[21].angle_rad() - hz) < 1e-9
    if v is not None:
        assert abs(words[22].angle_rad() - v) < 1e-9
    assert abs(words[31].length_m() - sd) < 1e-12


@pytest.mark.parametrize("bad", [
    "21.102+1792086", "21.102+17920860X", "21.102*17920860 ", "*21.102+17920860 ", "21.102+1792\x010860 ",
    "21.10Z+17920860 ",
])
def test_malformed_gsi_never_becomes_a_value(bad):
    with pytest.raises(gsi.GsiError):
        words = gsi.parse_block(bad)
        assert [w.known for w in words] == [False]
        words[0].angle_rad()


def test_unknown_word_keeps_the_rest_of_its_block():
    """'/' in a remark, '?' in a DNA code, '_' in a point name are read; a word that breaks the grammar is kept as
    unknown (raw characters) and its neighbours still count."""
    line = ("110012+PT_4/7?A 21.102+17920860 71....+AB/CD?_x 22.1x2+07567500 31..00+00003387 "
            "41....+?..00012 ")
    words = gsi.parse_block(line)
    assert [w.wi for w in words] == [11, 21, 71, 22, 31, 41]
    assert words[0].text() == "PT_4/7?A" and words[2].text() == "AB/CD?_x" and words[5].text() == "?..00012"
    assert abs(words[1].angle_rad() - 179.20860 * GON) < 1e-12 and words[4].length_m() == 3.387
    unknown = words[3]
    assert (unknown.known, unknown.raw) == (False, "22.1x2+07567500 ")
    with pytest.raises(gsi.GsiError, match="does not follow the GSI grammar"):
        unknown.angle_rad()
    with pytest.raises(gsi.GsiError, match="not numeric"):
        gsi.parse_block("22.102+0756Z500 ")[0].angle_rad()
    bad_byte = gsi.parse_block(b"21.102+17920860 22.102+075\xe97500 ")
    assert bad_byte[0].known and not bad_byte[1].known


def test_exactly_400_gon_is_a_valid_reading():
    from acq.drivers.gsi import _reading
    r = _reading("theodolite B", "GET/M/WI21/WI22", gsi.parse_block("21.102+40000000 ")[0].angle_rad(),
                 100 * GON, 0.0, 0.0, b"")
    assert r.hz_rad == 0.0
    with pytest.raises(ProtocolError, match="outside 0..400 gon"):
        _reading("theodolite B", "GET/M/WI21/WI22", gsi.parse_block("21.102+40000001 ")[0].angle_rad(),
                 100 * GON, 0.0, 0.0, b"")
    with pytest.raises(ProtocolError, match="outside 0..400 gon"):
        _reading("theodolite B", "GET/M/WI21/WI22", gsi.parse_block("22.102-00000001 ")[0].angle_rad(),
                 100 * GON, 0.0, 0.0, b"")


@given(st.floats(0, 2 * math.pi - 1e-6), st.sampled_from(["gon", "deg", "dms"]), st.booleans())
def test_angle_word_round_trip(rad, unit, gsi16):
    word = gsi.format_word(21, "10" + gsi.ANGLE_UNIT_CODE[unit], gsi.angle_value(rad, unit), gsi16)
    back = gsi.parse_block(("*" if gsi16 else "") + word)[0].angle_rad()
    quantum = {"gon": 1e-5 * GON, "deg": math.radians(1e-5), "dms": math.radians(0.1 / 3600)}[unit]
    assert abs(back - rad) <= quantum


# -- emulator transcript ---------------------------------------------------------------------------------------------
def _ask(dev, line):
    dev.feed(line)
    return dev.read_output()


def test_emulator_transcript():
    dev = GsiDevice(quiet_world(), "B", gsi16=False)
    assert _ask(dev, b"c\r\n") == b"?\r\n"
    assert _ask(dev, b"a\r\n") == b"?\r\n"
    assert _ask(dev, b"CONF/137\r\n") == b"0137/0000\r\n"
    assert _ask(dev, b"NONSENSE\r\n") == b"@W427\r\n"
    out = _ask(dev, b"GET/M/WI21\r\n")
    hz, _ = dev.world.true_sight("B", 1)
    assert out == f"21.102+{round(hz / GON * 1e5):08d}\r\n".encode()
    assert _ask(dev, b"SET/137/1\r\n") == b"?\r\n"
    assert _ask(dev, b"GET/I/WI12\r\n") == b"*12....+0000000000640054\r\n"


# -- driver ---------------------------------------------------------------------------------------------------------
@pytest.fixture
def rig():
    name = f"gsi-{uuid.uuid4().hex[:8]}"
    dev = GsiDevice(quiet_world(), "B", gsi16=True)
    faulty = FaultyDevice(dev)
    url = registry.publish(name, faulty)
    drv = GsiTheodolite.open(url, name="theodolite B")
    yield drv, dev, faulty
    drv.close()
    registry.withdraw(name)


@pytest.mark.parametrize("gsi16", [True, False])
def test_driver_angles_match_world(rig, gsi16):
    drv, dev, _ = rig
    drv.set_word_length(gsi16)
    assert drv.word_length() == (16 if gsi16 else 8)
    r = drv.angles()
    hz, v = dev.world.true_sight("B", 1)
    assert abs(r.hz_rad - hz) <= 0.6e-5 * GON and abs(r.v_rad - v) <= 0.6e-5 * GON
    assert r.face == 1 and r.raw.startswith(b"*" if gsi16 else b"21.")
    info = drv.identify()
    assert (info.serial, info.name) == ("640054", "TC1100")


def test_driver_garbled_and_warning(rig):
    drv, dev, faulty = rig
    faulty.garble_next_reply(position=3)
    faulty.garble_next_reply(position=3)
    with pytest.raises(ProtocolError, match="theodolite B: GET/M/WI21/WI22: garbled"):
        drv.angles()
    with pytest.raises(InstrumentError, match="@W427") as ei:
        drv.request(b"GET/M/WI99\r\n", "GET/M/WI99")
    assert ei.value.code == 427


def test_driver_silent_device(rig):
    drv, _, faulty = rig
    faulty.silent = True
    with pytest.raises(DeviceTimeout, match="theodolite B: GET/M/WI21/WI22: no reply"):
        drv.request(gsi.get_command([21, 22]), "GET/M/WI21/WI22", timeout_s=0.1)


def test_stream_over_pty():
    w = quiet_world()
    with PtyHost(GsiDevice(w, "B", gsi16=False, angle_unit="dms", stream_hz=20)) as host:
        with GsiTheodolite.open(host.path, handshake=False) as drv:
            blocks = [drv.read_block(2.0) for _ in range(3)]
    hz, v = w.true_sight("B", 1)
    for b in blocks:
        assert abs(b.hz_rad - hz) <= math.radians(0.06 / 3600) and abs(b.v_rad - v) <= math.radians(0.06 / 3600)
        assert abs(b.slope_distance_m - w.slope_distance_m("B")) <= 0.0006
