"""Fuzz targets: every byte boundary of the acquisition side, each with the exceptions that count as a clean rejection.

One table serves the hypothesis property tests (``tests/test_acq_fuzz.py``, modest counts in CI) and
``benchmarks/fuzz.py`` (~100,000 inputs).  A target takes bytes; it returns normally (accepted), raises one of its
``rejects`` (a clean rejection: the message a user would see), or anything else -- a crash.  The emulator targets
also check what the device answers against the protocol (GeoComPy's own reply grammar where available), so a
reply shape another client cannot parse is a crash too.
"""
from __future__ import annotations

import math
import random
import re
from dataclasses import dataclass
from typing import Callable
from urllib.parse import parse_qsl

from acq.drivers import geocom_codec as gc
from acq.drivers import gsi_codec as gsi
from acq.errors import DeviceError
from calib.errors import RobocalError

#: a healthy instrument's reply body per RPC (after ``%R1P,0,<trid>:``)
GEOCOM_GOOD = {
    0: "0", 107: "0", 108: "0,15", 110: "0,3,50,0", 5003: "0,1234", 5004: '0,"TM30 0.5"', 5034: "0,2,20,1",
    5011: "0,21.5", 2006: "0", 2007: "0,1", 2008: "0", 2026: "0,0", 2107: "0,1.0,1.5",
    2003: "0,1.0,1.5,0.000001,100,0.00001,0.00001,0.000001,100,0", 2108: "0,1.0,1.5,30.5",
    17017: "0,1.0,1.5,30.5,2", 9027: "0", 9028: "0",
}

#: every GeoCOM driver call, by name (each takes the driver)
GEOCOM_CALLS: dict[str, Callable] = {
    "connect": lambda d: d.connect(),
    "identify": lambda d: d.identify(),
    "internal temperature": lambda d: d.internal_temperature_c(),
    "face": lambda d: d.face(),
    "incline switch": lambda d: d.incline_switch(),
    "set incline switch": lambda d: d.set_incline_switch(True),
    "angles": lambda d: d.angles(),
    "angles with inclination": lambda d: d.angles_with_inclination(),
    "do measure": lambda d: d.do_measure(),
    "simple measurement": lambda d: d.simple_measurement(),
    "measure distance": lambda d: d.measure_distance_angle(),
    "position": lambda d: d.position(1.0, 1.5),
    "change face": lambda d: d.change_face(),
    "double precision": lambda d: d.double_precision(),
}

GSI_GOOD = {b"c": b"?", b"GET/I/WI12": b"*12....+0000000000640054", b"GET/I/WI13": b"*13....+00000000TC1100__",
            b"CONF/137": b"0137/0001", b"SET/137/1": b"?", b"SET/137/0": b"?",
            b"GET/M/WI21/WI22": b"*21.102+0000000017920860 22.102+0000000007567500"}
GSI_CALLS: dict[str, Callable] = {
    "connect": lambda d: d.connect(),
    "identify": lambda d: d.identify(),
    "word length": lambda d: d.word_length(),
    "set word length": lambda d: d.set_word_length(True),
    "angles": lambda d: d.angles(),
    "read block": lambda d: d.read_block(0.01),
}


@dataclass(frozen=True)
class Target:
    name: str
    run: Callable[[bytes], object]
    rejects: tuple[type[BaseException], ...]
    seeds: tuple[bytes, ...]


def check_reading(out) -> None:
    """A value a driver returns is physical: finite angles in [0, 2 pi), a positive finite distance, face 1 or 2."""
    import math
    if isinstance(out, float):
        assert math.isfinite(out), out
    if hasattr(out, "hz_rad"):
        assert 0 <= out.hz_rad < math.tau and 0 <= out.v_rad < math.tau and out.face in (1, 2), out
        assert out.slope_distance_m is None or 0 < out.slope_distance_m < math.inf, out


# -- codecs -----------------------------------------------------------------------------------------------------------
def _geocom_reply(data: bytes) -> None:
    try:
        gc.decode_reply(data, expect_checksum=True)
    except gc.CodecError:
        pass
    rep = gc.decode_reply(data)
    for sp in gc.RPCS.values():
        if len(sp.reply) == len(rep.fields):
            try:
                gc.decode_values(sp, rep.fields)
            except gc.CodecError:
                pass


def _gsi_block(data: bytes) -> None:
    for w in gsi.parse_block(data):
        for read in (w.angle_rad, w.length_m, w.text):
            try:
                read()
            except gsi.GsiError:
                pass


def _cobs_frame(data: bytes) -> None:
    from acq.encoders.cobs_codec import decode_frame
    decode_frame(data)


def _serial_tap_stream(data: bytes) -> None:
    from acq.encoders.serial_tap import SerialTap

    class _Link:
        name = "encoder tap"

        def close(self) -> None:
            pass
    tap = SerialTap(_Link())
    for i in range(0, len(data), 7):                 # arrives in pieces, as from a port
        tap._bytes(data[i:i + 7])


def _can_frames(data: bytes) -> None:
    import can

    from acq.encoders.can_tap import CanTap
    tap = CanTap(lambda: None)
    for i in range(0, len(data) - 2, 11):
        fid = 0x0FF + data[i] % 6                    # 0x0FF .. 0x104: the tap's ids and their neighbours
        chunk = data[i + 2:i + 2 + data[i + 1] % 9]
        tap._handle(can.Message(arbitration_id=fid, data=chunk, is_extended_id=False,
                                is_error_frame=data[i + 1] == 0xFF))


# -- driver calls on arbitrary replies --------------------------------------------------------------------------------
def _pieces(data: bytes) -> list[bytes]:
    return data[1:].split(b"\n") if len(data) > 1 else []


def _geocom_call(data: bytes) -> None:
    from acq.drivers.geocom import GeoComTheodolite
    from tests.fakes.faults import ScriptedLink, geocom_answer
    pieces = _pieces(data)

    def body(rpc: int) -> str:
        return pieces.pop(0).decode("latin-1") if pieces else GEOCOM_GOOD.get(rpc, "0")
    d = GeoComTheodolite(ScriptedLink(geocom_answer(body), name="theodolite T"), name="theodolite T",
                         retry_delay_s=0.0)
    names = sorted(GEOCOM_CALLS)
    check_reading(GEOCOM_CALLS[names[data[0] % len(names)] if data else "angles"](d))


def _gsi_call(data: bytes) -> None:
    from acq.drivers.gsi import GsiTheodolite
    from tests.fakes.faults import ScriptedLink
    pieces = _pieces(data)

    def answer(line: bytes) -> bytes:
        return pieces.pop(0) if pieces else GSI_GOOD.get(line, b"@W427")
    link = ScriptedLink(answer, name="theodolite T")
    link._out += b"\r\n".join(_pieces(data)[-2:]) + b"\r\n"          # what a streaming instrument sent
    d = GsiTheodolite(link, name="theodolite T", timeout_s=0.01)
    names = sorted(GSI_CALLS)
    check_reading(GSI_CALLS[names[data[0] % len(names)] if data else "angles"](d))


# -- emulator request parsers, with their replies checked against the protocol ---------------------------------------
def _reply_grammar() -> re.Pattern[bytes]:
    """GeoComPy's reply regex (an independent reading of the grammar) when installed, else protocols.md §1.3's."""
    try:
        from geocompy.geo import GeoCom
        return re.compile(GeoCom._R1P.pattern.encode())
    except (ImportError, AttributeError):
        return re.compile(rb"^%R1P,(\d+),(\d+)(?:,(\d+))?:(\d+)(?:,(.*))?$")


_R1P = _reply_grammar()
_DEVICES: dict[str, object] = {}


def _device(kind: str):
    """One device per kind and process (the world costs ~0.5 s to build); its state carries over, as a real one's."""
    if kind not in _DEVICES:
        from sim.emulate.factories import make_world
        from sim.emulate.geocom_device import GeoComDevice
        from sim.emulate.gsi_device import GsiDevice
        from sim.emulate.slcan_device import SlcanTapDevice
        w = make_world(None, noise=True)
        _DEVICES.update(geocom=GeoComDevice(w, "A"), gsi=GsiDevice(w, "B", stream_hz=20.0),
                        slcan=SlcanTapDevice(w, w.robot, rate_hz=100.0))
    dev = _DEVICES[kind]
    dev.read_output()
    dev._inbuf.clear()
    return dev


def _geocom_emulator(data: bytes) -> None:
    dev = _device("geocom")
    dev.feed(data + b"\r\n")
    for line in dev.read_output().split(b"\r\n")[:-1]:
        assert line == b"?" or _R1P.match(line), f"reply outside the GeoCOM grammar: {line[:80]!r}"
        m = _R1P.match(line)
        if m and m.group(3) is not None:
            s, e = m.span(3)
            assert gc.crc16_arc(line[:s - 1] + line[e:]) == int(m.group(3)), f"bad reply CRC: {line[:80]!r}"


def _gsi_emulator(data: bytes) -> None:
    dev = _device("gsi")
    dev.feed(data + b"\r\n")
    dev.tick()
    for line in dev.read_output().split(b"\r\n")[:-1]:
        if line == b"?" or re.fullmatch(rb"@[WE]\d+|\d{4}/\d{4}", line):
            continue
        assert all(w.known for w in gsi.parse_block(line)), f"reply outside the GSI grammar: {line[:80]!r}"


def _slcan_emulator(data: bytes) -> None:
    dev = _device("slcan")
    dev.feed(data + b"\r")
    dev.tick()
    out = dev.read_output()
    assert not out or out.endswith((b"\r", b"\a")), f"SLCAN reply not terminated: {out[-40:]!r}"


def _url_options(data: bytes) -> None:
    from sim.emulate.factories import _take
    options = dict(parse_qsl(data.decode("latin-1"), keep_blank_values=True))
    _take(options, ("seed", "station", "noise", "motorised", "name", "serial", "scenario", "wordlen", "unit",
                    "stream_hz", "rate_hz"), "fuzz")


# -- GSI against GeoComPy's reader and writer (software nobody here wrote) -------------------------------------------
#: point-name and remark characters both readers accept (GeoComPy refuses '/' in them; robocal reads it)
NAME_CHARS = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_?.-+"
_QUANTUM_RAD = {"2": 1e-5 * math.pi / 200, "3": math.radians(1e-5), "4": math.radians(0.1 / 3600)}


def gsi_cross_check(data: bytes) -> None:
    """A random block (seeded by ``data``) written by GeoComPy and read by robocal, and written by robocal and read
    by GeoComPy: point name, Hz, V, slope distance and remark agree to the unit's last digit."""
    try:
        from geocompy.data import Angle
        from geocompy.gsi import gsiformat as gf
    except ImportError:
        return
    rng = random.Random(data)
    name = rng.choice(NAME_CHARS[:52]) + "".join(rng.choice(NAME_CHARS) for _ in range(rng.randint(0, 6)))
    # (a leading sign would be moved by GeoComPy's zfill padding: remarks start with a letter too)
    remark = rng.choice(NAME_CHARS[:52]) + "".join(rng.choice(NAME_CHARS) for _ in range(rng.randint(0, 7)))
    hz, v = rng.uniform(0, math.tau), rng.uniform(0, math.tau)
    sd = round(rng.uniform(0.001, 999.0), 3)
    gsi16 = rng.random() < 0.5
    unit = rng.choice(["2", "3", "4"])
    theirs_unit = {"2": gf.GsiUnit.GON, "3": gf.GsiUnit.DEG, "4": gf.GsiUnit.DMS}[unit]
    # GeoComPy writes, robocal reads
    block = gf.GsiBlock(name, "measurement", gf.GsiHorizontalAngleWord(Angle(hz, "rad")),
                        gf.GsiVerticalAngleWord(Angle(v, "rad")), gf.GsiSlopeDistanceWord(sd),
                        gf.GsiRemark1Word(remark), address=rng.randrange(10000))
    line = block.serialize(gsi16=gsi16, angleunit=theirs_unit, distunit=gf.GsiUnit.MILLI, endl=False)
    words = {w.wi: w for w in gsi.parse_block(line)}
    assert all(w.known for w in words.values()), line
    _agree(line, words[11].text(), name, words[21].angle_rad(), hz, words[22].angle_rad(), v, unit)
    assert words[31].length_m() == sd and words[71].text() == remark, line
    # robocal writes, GeoComPy reads
    ours = (("*" if gsi16 else "") + gsi.format_word(11, f"{rng.randrange(10000):04d}", name, gsi16)
            + gsi.format_word(21, "10" + unit, gsi.angle_value(hz, _UNIT_NAME[unit]), gsi16)
            + gsi.format_word(22, "10" + unit, gsi.angle_value(v, _UNIT_NAME[unit]), gsi16)
            + gsi.format_word(31, ".00", round(sd * 1000), gsi16))
    theirs = gf.GsiBlock.parse(ours, keep_unknowns=True)
    _agree(ours, theirs.value, name, theirs.get_word(gf.GsiHorizontalAngleWord).value.asunit("rad"), hz,
           theirs.get_word(gf.GsiVerticalAngleWord).value.asunit("rad"), v, unit)
    assert abs(theirs.get_word(gf.GsiSlopeDistanceWord).value - sd) < 1e-9, ours


_UNIT_NAME = {"2": "gon", "3": "deg", "4": "dms"}


def _agree(line: str, got_name: str, name: str, got_hz: float, hz: float, got_v: float, v: float,
           unit: str) -> None:
    q = _QUANTUM_RAD[unit] * 0.5 + 1e-12
    assert got_name == name, (line, got_name, name)
    for got, want in ((got_hz, hz), (got_v, v)):
        diff = (got - want + math.pi) % math.tau - math.pi          # 400.00000 gon and 0 are the same direction
        assert abs(diff) <= q, (line, got, want, diff)


def _geocom_seeds() -> tuple[bytes, ...]:
    reqs = [b"%R1Q,0:", b"%R1Q,0,7:", b"%R1Q,108:", b"%R1Q,107:6", b"%R1Q,2107:1", b"%R1Q,2003,3:1",
            b"%R1Q,2108:5000,1", b"%R1Q,2008:1,1", b"%R1Q,9027:1.0,1.5,0,0,0", b"%R1Q,9028:0,0,0", b"%R1Q,17017:2",
            b"%R1Q,5004:", b"%R1Q,5008:", b"%R1Q,2016:1,1,1,1", b"%R1Q,2006:1", b"c", b"\n"]
    with_crc = [gc.encode_request(2107, ["1"], 3, checksum=True).rstrip(), gc.encode_request(0, [], 0, True).rstrip()]
    return tuple(reqs + with_crc)


def _call_seeds(calls: dict, replies: dict[str, list[bytes]]) -> tuple[bytes, ...]:
    """Call index byte, then the replies (one per request, ``\\n``-separated; the rest healthy)."""
    names = sorted(calls)
    return tuple([bytes([i]) for i in range(len(names))] +
                 [bytes([names.index(n)]) + b"\n".join(r) for n, r in replies.items()])


GSI_LINES = (b"110001+00000001 21.322+03496940 22.322+09364360 31..00+00030485 51..1.+0000+000 ",
             b"*110002+00000000GDEM5415 21.024+0000000003545100 22.024+0000000009117510 31...0+0000000000013825 ",
             b"*11....+00000000000P0001 21.324+0000000024943030 22.324+0000000008336237 ",
             b"110012+PT_4/7?A 21.102+17920860 71....+AB/CD?_x 22.102+07567500 41....+?..00012 ")

TARGETS: dict[str, Target] = {t.name: t for t in [
    Target("geocom reply codec", _geocom_reply, (gc.CodecError,),
           (b"%R1P,0,0:0,4.358392574848940,1.470950229078506", b"%R1P,0,3,40194:0,4.358392574848940,1.634123456789010",
            b"%R1P,0,0:0,1996,'07','19','10','13','2f'", b'%R1P,0,0:0,"TM30 \\"0.5\\""', b"%R1P,3081,5:0")),
    Target("gsi block codec", _gsi_block, (gsi.GsiError,), GSI_LINES),
    Target("gsi online reply codec", lambda b: gsi.parse_online_reply(b), (gsi.GsiError,),
           (b"?", b"@W427", b"0137/0001") + GSI_LINES),
    Target("cobs tap frame codec", _cobs_frame, (ValueError,),
           (bytes.fromhex("0701020140e20103102701053cf6ffff010101030743010201010107ffffffff169c"),)),
    Target("serial tap stream", _serial_tap_stream, (),
           (bytes.fromhex("0701020140e20103102701053cf6ffff010101030743010201010107ffffffff169c00") * 3,)),
    Target("can tap frames", _can_frames, (), (bytes(range(64)),)),
    Target("geocom driver calls", _geocom_call, (DeviceError,), _call_seeds(GEOCOM_CALLS, {
        "angles": [b"0,1.0,1.5"], "measure distance": [b"1285,1.0,1.5,30.5,2"],
        "identify": [b'0,"TS16"', b"0,77", b"0,3,50,0", b"0,2,20,1"], "connect": [b"0", b"0,15"]})),
    Target("gsi driver calls", _gsi_call, (DeviceError,), _call_seeds(GSI_CALLS, {
        "angles": [b"21.102+17920860 22.102+07567500"], "read block": [GSI_LINES[0], GSI_LINES[1]]})),
    Target("geocom emulator requests", _geocom_emulator, (), _geocom_seeds()),
    Target("gsi emulator requests", _gsi_emulator, (),
           (b"GET/M/WI21/WI22", b"GET/I/WI12", b"SET/137/0", b"CONF/137", b"PUT/21.102+17920860", b"c")),
    Target("slcan emulator commands", _slcan_emulator, (), (b"S6", b"O", b"t10380011223344556677", b"C", b"V")),
    Target("gsi vs geocompy", gsi_cross_check, (), (b"0", b"1", b"2")),
    Target("emulator url options", _url_options, (RobocalError,),
           (b"seed=3&station=A&noise=1", b"rate_hz=500", b"stream_hz=2.5&wordlen=8&unit=dms", b"serial=77")),
]}

#: bytes that broke parsers elsewhere: huge integers, non-finite numbers, separators, the full GSI character set
TOKENS = (b"9" * 4301, b"1e400", b"-1e999", b"nan", b"inf", b"-5", b"1e308", b"0x7fffffffffff", b"\x00", b"\r\n",
          b"\n", b",", b":", b"%R1P,", b"%R1Q,", b'"', b"'", b"\\", b"*", b" ", b"/", b"?", b"_", b"\xff", b"-0",
          b"40000000", b"400.00000", b"6.283185307179586", b"+", b"-", b"1285", b"1288", b"3081", b"....", b"&", b"=")


def mutate(rng: random.Random, seed: bytes, seeds: tuple[bytes, ...]) -> bytes:
    """One to four random edits of ``seed``: flips, token inserts, deletions, duplications, splices."""
    data = bytearray(seed)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        pos = rng.randint(0, len(data))
        if op == 0 and data:
            data[min(pos, len(data) - 1)] ^= 1 << rng.randrange(8)
        elif op == 1:
            data[pos:pos] = rng.choice(TOKENS)
        elif op == 2:
            del data[pos:pos + rng.randint(1, 8)]
        elif op == 3:
            data[pos:pos] = data[pos:pos + rng.randint(1, 16)]
        elif op == 4:
            data[pos:pos + rng.randint(0, 4)] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 6)))
        elif op == 5:
            other = rng.choice(seeds)
            cut = rng.randint(0, len(other))
            data = data[:pos] + bytearray(other[cut:])
        else:
            data = data[:pos]
    return bytes(data)


def generate(rng: random.Random, target: Target) -> bytes:
    """An input for ``target``: mostly mutated seeds, sometimes random bytes."""
    if rng.random() < 0.1:
        return bytes(rng.randrange(256) for _ in range(rng.randint(0, 120)))
    return mutate(rng, rng.choice(target.seeds), target.seeds)


def outcome(target: Target, data: bytes) -> str:
    """'accepted' or 'rejected'; anything else propagates (a crash)."""
    try:
        target.run(data)
    except target.rejects:
        return "rejected"
    return "accepted"
