"""GeoCOM codec and emulator grammar, byte for byte against protocols.md §1, and against each other."""
from __future__ import annotations

import re

import pytest
from hypothesis import given, settings, strategies as st

from acq.drivers import geocom_codec as gc
from acq.drivers.geocom_codes import RETURN_CODES, describe
from sim.emulate.geocom_device import GeoComDevice, crc16_arc_bitwise
from tests.fakes.worlds import quiet_world


def test_crc_check_value_both_implementations():
    assert gc.crc16_arc(b"123456789") == 0xBB3D
    assert crc16_arc_bitwise(b"123456789") == 0xBB3D


@given(st.binary(max_size=200))
def test_crc_driver_and_emulator_agree(data):
    assert gc.crc16_arc(data) == crc16_arc_bitwise(data)


@pytest.mark.parametrize("rpc,params,trid,frame", [
    (0, [], 0, b"%R1Q,0,0,10948:\r\n"),
    (2107, ["1"], 3, b"%R1Q,2107,3,2646:1\r\n"),
])
def test_request_with_crc_matches_reference(rpc, params, trid, frame):
    assert gc.encode_request(rpc, params, trid, checksum=True) == frame


def test_request_without_crc():
    assert gc.encode_request(0) == b"%R1Q,0:\r\n"
    assert gc.encode_request(2108, ["5000", "1"], 7) == b"%R1Q,2108,7:5000,1\r\n"


def test_reference_replies_decode():
    r = gc.decode_reply(b"%R1P,0,0,18235:0", expect_checksum=True)
    assert (r.rc_com, r.trid, r.rc, r.fields, r.crc) == (0, 0, 0, (), 18235)
    r = gc.decode_reply(b"%R1P,0,3,40194:0,4.358392574848940,1.634123456789010", expect_checksum=True)
    assert gc.decode_values(gc.RPCS[2107], r.fields) == (4.358392574848940, 1.634123456789010)
    r = gc.decode_reply(b"%R1P,0,0:0,1996,'07','19','10','13','2f'")
    # bytes are hex (TPS1200 manual §3.2.1, GeoComPy Byte.parse): the manual's example is 1996-07-25 16:19:47
    assert gc.decode_values(gc.RPCS[5008], r.fields) == (1996, 0x07, 0x19, 0x10, 0x13, 0x2F)
    r = gc.decode_reply(b"%R1P,3081,5:0")
    assert (r.rc_com, r.trid, r.rc) == (3081, 5, 0)


@pytest.mark.parametrize("bad", [
    b"%R1P,0,0:", b"%R1P,0,0", b"%R1Q,0,0:0", b"R1P,0,0:0", b"%R1P,0,0:0,1.5\x00", b"%R1P,0,0:0,\xff",
    b"%R1P,0,0,12345:0", b"%R1P, 0,0:0", b"%R1P,0,0:0,1.0,2.0,", b"%R1P,3081,5:", b"%R1P,0,0:0,1e400,1.0",
    b"%R1P,0,0:0,1.0,-1e999", b"%R1P,0,0:0,inf,1.0", b"%R1P,0,0:0,nan,1.0",
])
def test_garbage_is_rejected(bad):
    with pytest.raises(gc.CodecError):
        r = gc.decode_reply(bad)
        gc.decode_values(gc.RPCS[2107], r.fields)


def test_missing_requested_checksum_is_an_error():
    for frame in (b"%R1P,0,0:0", b"%R1P,43,40194:0,4.358392574848940,1.634123456789010", b"%R1P,3101,0:0,1"):
        with pytest.raises(gc.CodecError):
            gc.decode_reply(frame, expect_checksum=True)
    assert gc.decode_reply(b"%R1P,3110,4:0", expect_checksum=True).rc_com == 3110    # instrument without CRC


@settings(max_examples=200)
@given(pos=st.integers(0, 60), xor=st.integers(1, 255))
def test_any_single_byte_corruption_is_detected_with_crc(pos, xor):
    frame = bytearray(b"%R1P,0,3,40194:0,4.358392574848940,1.634123456789010")
    pos %= len(frame)
    frame[pos] ^= xor
    with pytest.raises(gc.CodecError):
        r = gc.decode_reply(bytes(frame), expect_checksum=True)
        gc.decode_values(gc.RPCS[2107], r.fields)


@given(st.text(alphabet=st.characters(min_codepoint=1, max_codepoint=255), max_size=40))
def test_string_round_trip(s):
    enc = gc.fmt_string(s)
    assert all(0x20 <= ord(c) <= 0x7E for c in enc)
    assert gc.parse_string(enc) == s
    assert gc.split_fields(enc + "," + enc) == (enc, enc)


@given(st.floats(-10, 10, allow_nan=False))
def test_double_format_keeps_1e10(x):
    assert abs(gc.parse_double(gc.fmt_double(x)) - x) <= 1e-12


def test_every_tabled_code_has_severity_and_text():
    for code, rc in RETURN_CODES.items():
        assert rc.code == code and rc.text and rc.severity in ("ok", "warning", "info", "error")
    assert describe(0).usable and describe(1285).usable and not describe(1290).usable
    assert describe(775).name.startswith("EDM") and not describe(775).usable
    assert not describe(60000).usable and "60000" in describe(60000).text


# -- the emulator's own grammar, byte for byte ---------------------------------------------------------------------
def _ask(dev: GeoComDevice, line: bytes) -> bytes:
    dev.feed(line)
    return dev.read_output()


def _with_crc(head: bytes, body: bytes) -> bytes:
    return head + b"," + str(crc16_arc_bitwise(head + b":" + body)).encode() + b":" + body + b"\r\n"


@pytest.fixture
def dev():
    return GeoComDevice(quiet_world(), "A")


@pytest.mark.parametrize("req,rep", [
    (b"%R1Q,0:\r\n", b"%R1P,0,0:0\r\n"),
    (b"%R1Q,0,7:\r\n", b"%R1P,0,7:0\r\n"),
    (b"%R1Q,108:\r\n", b"%R1P,0,0:0,15\r\n"),
    (b"%R1Q,110:\r\n", b"%R1P,0,0:0,3,50,0\r\n"),
    (b"%R1Q,5003:\r\n", b"%R1P,0,0:0,3216936\r\n"),
    (b"%R1Q,5004:\r\n", b'%R1P,0,0:0,"TM30 0.5"\r\n'),
    (b"%R1Q,2007:\r\n", b"%R1P,0,0:0,1\r\n"),
    (b"%R1Q,2006:1\r\n", b"%R1P,0,0:0\r\n"),
    (b"%R1Q,2008:1,1\r\n", b"%R1P,0,0:0\r\n"),
    (b"%R1Q,0,0,10948:\r\n", b"%R1P,0,0,18235:0\r\n"),
    (b"%R1Q,0,0,10949:\r\n", _with_crc(b"%R1P,3101,0", b"0")),
    (b"%R1Q,4242,5:\r\n", b"%R1P,3081,5:0\r\n"),
    (_with_crc(b"%R1Q,4242,5", b""), _with_crc(b"%R1P,3081,5", b"0")),
    (b"hello\r\n", b"%R1P,3080,0:0\r\n"),
    (b"%R1Q,107:" + b"9" * 4301 + b"\r\n", b"%R1P,0,0:2\r\n"),
    (b"%R1Q,9027:1e400,1.5,0,0,0\r\n", b"%R1P,0,0:2\r\n"),
    (b"%R1Q,9027:nan,1.5,0,0,0\r\n", b"%R1P,0,0:2\r\n"),
    (b"%R1Q," + b"9" * 4301 + b":\r\n", b"%R1P,3080,0:0\r\n"),
    (b"c\r\n", b"?\r\n"),
    (b"\n\r\n\r\n", b""),
    (b"%R1Q,2107:9\r\n", b"%R1P,0,0:2\r\n"),
    (b"%R1Q,9027:1.0,1.5\r\n", b"%R1P,0,0:2\r\n"),
])
def test_emulator_transcript(dev, req, rep):
    assert _ask(dev, req) == rep


def test_emulator_precision_and_angles(dev):
    assert _ask(dev, b"%R1Q,107:6\r\n") == b"%R1P,0,0:0\r\n"
    out = _ask(dev, b"%R1Q,2107,9:1\r\n")
    m = re.fullmatch(rb"%R1P,0,9:0,(\d+\.\d{6}),(\d+\.\d{6})\r\n", out)
    assert m, out
    hz, v = dev.world.true_sight("A", 1)
    assert abs(float(m.group(1)) - hz) <= 5e-7 and abs(float(m.group(2)) - v) <= 5e-7


def test_emulator_simple_mea_needs_do_measure(dev):
    assert _ask(dev, b"%R1Q,2108:5000,1\r\n").startswith(b"%R1P,0,0:1285,")
    _ask(dev, b"%R1Q,2008:1,1\r\n")
    out = _ask(dev, b"%R1Q,2108:5000,1\r\n")
    assert out.startswith(b"%R1P,0,0:0,")
    assert abs(float(out.split(b",")[-1]) - dev.world.slope_distance_m("A")) < 1e-9
    _ask(dev, b"%R1Q,2008:3,1\r\n")
    assert _ask(dev, b"%R1Q,2108:5000,1\r\n").startswith(b"%R1P,0,0:1285,")


def test_emulator_split_and_joined_writes(dev):
    dev.feed(b"%R1Q,0,1:")
    assert dev.read_output() == b""
    dev.feed(b"\r\n%R1Q,0,2:\r\n%R1Q,0,3:\r\n")
    assert dev.read_output() == b"%R1P,0,1:0\r\n%R1P,0,2:0\r\n%R1P,0,3:0\r\n"
