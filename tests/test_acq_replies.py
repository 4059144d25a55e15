"""Every instrument reply ends in a value or a DeviceError naming device, command and cause (issue 17 item 4).

The instrument here is a script (:class:`tests.fakes.faults.ScriptedLink`), so a test can send what no emulator
would: a warning code alone, a distance flagged invalid, ``1e400``, a negative distance, and -- under hypothesis --
arbitrary bytes to every driver call.
"""
from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from acq.drivers.geocom import GeoComTheodolite
from acq.drivers.gsi import GsiTheodolite
from acq.errors import DeviceError, InstrumentError, ProtocolError
from tests.fakes.faults import ScriptedLink, geocom_answer
from tests.fakes.fuzz_targets import GEOCOM_CALLS, GEOCOM_GOOD, GSI_CALLS, GSI_GOOD, check_reading

GOOD, CALLS = GEOCOM_GOOD, GEOCOM_CALLS


def _driver(bodies: dict[int, str]) -> GeoComTheodolite:
    link = ScriptedLink(geocom_answer(lambda rpc: bodies.get(rpc, GOOD.get(rpc, "0"))))
    return GeoComTheodolite(link, name="theodolite T", retry_delay_s=0.0)


def test_the_healthy_script_gives_values():
    d = _driver({})
    assert d.measure_distance_angle().slope_distance_m == 30.5 and d.face() == 1 and d.identify().name == "TM30 0.5"


@pytest.mark.parametrize("code", [1283, 1284, 1285, 1288, 1289])
@pytest.mark.parametrize("call,rpc", [("face", 2026), ("identify", 5004), ("identify", 110),
                                      ("internal temperature", 5011), ("incline switch", 2007), ("connect", 108),
                                      ("measure distance", 17017), ("simple measurement", 2108), ("angles", 2107),
                                      ("angles with inclination", 2003)])
def test_a_warning_without_values_is_an_instrument_error(call, rpc, code):
    d = _driver({rpc: str(code)})
    with pytest.raises(InstrumentError) as ei:
        CALLS[call](d)
    msg = str(ei.value)
    assert ei.value.code == code and msg.startswith("theodolite T: ") and f"(RPC {rpc})" in msg
    assert str(code) in msg and "without values" in msg and "\n" not in msg


@pytest.mark.parametrize("code,valid", [(0, True), (1283, True), (1284, True), (1285, False), (1288, False),
                                        (1289, False)])
@pytest.mark.parametrize("call,rpc,body", [("measure distance", 17017, "1.0,1.5,30.5,2"),
                                           ("simple measurement", 2108, "1.0,1.5,30.5")])
def test_a_distance_the_instrument_marks_invalid_is_never_returned(call, rpc, body, code, valid):
    r = CALLS[call](_driver({rpc: f"{code},{body}"}))
    assert (r.hz_rad, r.v_rad) == (1.0, 1.5)
    assert r.slope_distance_m == (30.5 if valid else None)
    assert bool(r.warnings) == (code != 0)


@pytest.mark.parametrize("call,rpc,body,what", [
    ("measure distance", 17017, "0,1.0,1.5,-30.5,2", "slope distance"),
    ("measure distance", 17017, "0,1.0,1.5,1e400,2", "out of the range"),
    ("simple measurement", 2108, "0,1.0,1.5,0.0", "slope distance"),
    ("simple measurement", 2108, "0,1.0,1.5,1e9", "slope distance"),
    ("internal temperature", 5011, "0,1e400", "out of the range"),
    ("internal temperature", 5011, "0,999.0", "internal temperature"),
    ("angles", 2107, "0,7.0,1.5", "Hz"),
    ("angles", 2107, "0,1.0,-0.5", "V"),
    ("angles", 2107, "0,inf,1.5", "not a GeoCOM double"),
    ("angles with inclination", 2003, "0,1.0,1.5,-1,100,0,0,0,100,0", "accuracy"),
    ("angles with inclination", 2003, "0,1.0,1.5,0,100,9,0,0,100,0", "inclination"),
    ("angles with inclination", 2003, "0,1.0,1.5,0,100,0,0,0,100,7", "face 7"),
    ("face", 2026, "0,2", "face 2"),
    ("double precision", 108, "0,99", "double precision"),
    ("identify", 5003, "0," + "9" * 4301, "not a GeoCOM long"),
])
def test_implausible_values_are_device_errors(call, rpc, body, what):
    with pytest.raises(ProtocolError, match=what) as ei:
        CALLS[call](_driver({rpc: body}))
    assert str(ei.value).startswith("theodolite T: ") and f"(RPC {rpc})" in str(ei.value)


def test_exactly_two_pi_is_a_valid_angle():
    r = _driver({2107: f"0,{math.tau!r},{math.tau!r}"}).angles()
    assert r.hz_rad == 0.0 and r.v_rad == 0.0


# -- property tests: any reply, every call --------------------------------------------------------------------------
_num = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-10 ** 12, 10 ** 12).map(str),
                 st.sampled_from(["1e400", "-0", "0x1F", "'2f'", '"x"', "", "1.5.5", "9" * 40]))
_codes = st.sampled_from([0, 0, 0, 1, 2, 5, 13, 1283, 1284, 1285, 1288, 1289, 1290, 1293, 3077, 3081, 8704, 9217,
                          65535, 99999])
_body = st.one_of(
    st.builds(lambda c, vs: ",".join([str(c), *vs]), _codes, st.lists(_num, max_size=10)),
    st.text(alphabet=st.characters(min_codepoint=0, max_codepoint=255), max_size=60),
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(call=st.sampled_from(sorted(CALLS)), bodies=st.dictionaries(st.sampled_from(sorted(GOOD)), _body, max_size=6))
def test_every_geocom_call_on_arbitrary_replies_gives_a_value_or_a_device_error(call, bodies):
    try:
        out = CALLS[call](_driver(bodies))
    except DeviceError as exc:
        assert str(exc).startswith("theodolite T: ") and "\n" not in str(exc)
        return
    check_reading(out)


# -- GSI --------------------------------------------------------------------------------------------------------------
def _gsi(replies: dict[bytes, bytes], stream: bytes = b"") -> GsiTheodolite:
    link = ScriptedLink(lambda line: replies.get(line, GSI_GOOD.get(line, b"@W427")))
    link._out += stream
    return GsiTheodolite(link, name="theodolite T", timeout_s=0.01)


def test_gsi_healthy_script():
    d = _gsi({})
    assert d.identify().name == "TC1100__" and abs(d.angles().hz_rad - 179.2086 * math.pi / 200) < 1e-12
    b = _gsi({}, b"110001+0000P_/1 21.102+40000000 22.102+10000000 31..00+00030485 \r\n").read_block(0.01)
    assert (b.hz_rad, b.slope_distance_m) == (0.0, 30.485)


@pytest.mark.parametrize("line,what", [
    (b"21.102+17920860 22.102-07567500 ", "V = -"),
    (b"21.102+17920860 22.102+07567500 31..00-00003387 ", "slope distance"),
    (b"21.102+17920860 22.1x2+07567500 ", r"\[22\] missing or unreadable"),
    (b"21.102+17920860 ", r"\[22\] missing"),
])
def test_gsi_block_faults_are_device_errors(line, what):
    with pytest.raises(ProtocolError, match=what):
        _gsi({}, line + b"\r\n").read_block(0.01)


_gsi_line = st.one_of(
    st.binary(max_size=80),
    st.lists(st.sampled_from(["21.102+17920860 ", "22.102+07567500 ", "31..00+00003387 ", "22.102-00000001 ",
                              "21.1x2+1792086/ ", "11....+PT_?/1__ ", "21.102+40000001 ", "31..09+00003387 ",
                              "12....+00640054 ", "13....+TC1100.. ", "41....+?..00012 "]),
             max_size=6).map(lambda ws: "".join(ws).encode()),
    st.sampled_from([b"?", b"@W427", b"@E999", b"0137/0001", b"0137/0009", b"*", b""]),
)


@settings(max_examples=300, deadline=None)
@given(call=st.sampled_from(sorted(GSI_CALLS)), line=_gsi_line, which=st.sampled_from(sorted(GSI_GOOD)))
def test_every_gsi_call_on_arbitrary_replies_gives_a_value_or_a_device_error(call, line, which):
    line = line.replace(b"\r\n", b"")
    try:
        out = GSI_CALLS[call](_gsi({which: line}, line + b"\r\n"))
    except DeviceError as exc:
        assert str(exc).startswith("theodolite T: ") and "\n" not in str(exc)
        return
    check_reading(out)


# -- the session runner gets a warning as a device fault (repeat / skip / pause) --------------------------------------
def test_a_warning_without_values_reaches_the_runner_as_a_device_fault(tmp_path):
    from sim.emulate import registry
    from app.demo import build_demo
    from acq.session.headless import ScriptedOperator

    seen = {}

    class Operator(ScriptedOperator):
        def ask(self, req):
            if req.kind == "setup" and req.step.key.endswith("/D") and "scripted" not in seen:
                registry.slot(self.demo.names[0]).device.script_rc(2107, 1283, with_values=False)
                seen["scripted"] = True
            if req.kind == "decision" and any(c.name == "device" for c in req.checks):
                seen["fault"] = [c.message for c in req.checks]
                seen["actions"] = req.choices
            return super().ask(req)

    op = Operator()
    demo = build_demo(tmp_path / "w.db", seed=2, operator=op, steps_filter=lambda s: s.key.startswith("ruler/p0"))
    op.demo = demo
    try:
        state = demo.runner.run()
    finally:
        demo.close()
    assert state == "finished"
    msg = seen["fault"][0]
    assert "TMC_GetAngle5 (RPC 2107)" in msg and "1283" in msg and "without values" in msg
    assert {"repeat", "skip", "pause"} <= set(seen["actions"])
