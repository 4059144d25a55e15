"""``robocal emulate``: first output line says where to connect; it serves until interrupted."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import can
import pytest

from app.cli import main
from acq.drivers import open_theodolite
from acq.encoders.can_codec import TapCanCodec

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _start(*argv):
    p = subprocess.Popen([sys.executable, "-m", "app.cli", "emulate", *argv], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    first = p.stdout.readline().strip()
    return p, first


def _stop(p):
    p.send_signal(signal.SIGINT)
    try:
        rc = p.wait(30)         # a guard against a hang, not a bound: it exits in ~0.1 s on a quiet machine
    except subprocess.TimeoutExpired:
        p.kill()
        raise
    return rc


def test_emulate_geocom_pty_serves_our_driver():
    p, where = _start("geocom", "--pty", "--seed", "4", "--duration", "30")
    try:
        assert where.startswith("/dev/"), (where, p.stderr.read() if p.poll() is not None else "")
        with open_theodolite("geocom", where, name="theodolite A") as t:
            assert t.identify().name == "TM30 0.5"
            r = t.angles()
            assert 0 <= r.hz_rad < 6.3 and 0 < r.v_rad < 3.2
    finally:
        rc = _stop(p)
    assert rc == 0


def test_emulate_gsi_tcp():
    p, where = _start("gsi", "--tcp", "0", "--gsi8", "--duration", "30")
    try:
        assert where.startswith("socket://127.0.0.1:")
        with open_theodolite("gsi", where) as t:
            assert t.word_length() == 8 and t.angles().face == 1
    finally:
        assert _stop(p) == 0


def test_emulate_tap_slcan_pty_for_python_can():
    p, where = _start("tap", "--slcan-pty", "--rate-hz", "100", "--duration", "30")
    try:
        assert where.startswith("/dev/")
        bus = can.Bus(interface="slcan", channel=where, bitrate=500_000, sleep_after_open=0)
        try:
            ids = set()
            deadline = time.monotonic() + 30        # a guard against a hang: python-can reads a real pty
            while len(ids) < 4 and time.monotonic() < deadline:
                m = bus.recv(0.5)
                if m is not None:
                    ids.add(m.arbitration_id)
        finally:
            bus.shutdown()
        assert ids == {0x100, 0x101, 0x102, 0x103} and all(TapCanCodec().is_tap_frame(i) for i in ids)
    finally:
        assert _stop(p) == 0


def test_emulate_bad_combination_is_one_line_error(capsys):
    assert main(["emulate", "tap", "--pty"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("robocal: error: emulate tap:") and err.count("\n") == 1


def test_emulate_bad_tcp_port_is_one_line():
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "app.cli", "emulate", "geocom", "--tcp", "99999"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "a TCP port is 0..65535" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("argv,why", [
    (["tap", "--rate-hz", "0"], "--rate-hz must be in (0, 10000]"),
    (["tap", "--rate-hz", "nan"], "--rate-hz must be a finite number"),
    (["tap", "--rate-hz", "inf"], "--rate-hz must be a finite number"),
    (["tap", "--rate-hz", "-5"], "--rate-hz must be in"),
    (["tap", "--rate-hz", "1e308"], "--rate-hz must be in"),
    (["gsi", "--stream-hz", "-1"], "--stream-hz must be in [0, 100]"),
    (["geocom", "--duration", "-1"], "--duration must be positive"),
    (["geocom", "--seed", "9" * 4301], "--seed must be a whole number of at most 18 digits"),
    (["geocom", "--tcp", "9" * 4301], "--tcp must be a whole number of at most 18 digits"),
    (["geocom", "--q-deg", "500", "0", "0", "0", "0", "0"], "joint 1 = 500 deg is outside its limits"),
    (["geocom", "--q-deg", "0", "0"], "--q-deg needs 6 joint angles"),
    (["geocom", "--station", "Z"], "--station 'Z': the scenario has stations A, B"),
    (["gsi", "--station", "Z"], "--station 'Z'"),
    (["geocom", "--scenario", "/nonexistent/s.toml"], "--scenario file not found"),
])
def test_bad_options_are_refused_at_start(capsys, argv, why):
    assert main(["emulate", *argv, "--duration", "5"] if "--duration" not in argv else ["emulate", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("robocal: error: emulate") and why in err and err.count("\n") == 1, err


def test_a_failing_server_thread_takes_the_process_down(capsys, monkeypatch):
    from sim.emulate.geocom_device import GeoComDevice

    def broken(self, now=None):
        raise RuntimeError("the device broke")
    monkeypatch.setattr(GeoComDevice, "tick", broken)
    t0 = time.monotonic()
    assert main(["emulate", "geocom", "--pty", "--duration", "120"]) == 3
    # wall clock: the pty server runs on the host clock; the bound only says the process went down at the failure,
    # not at the end of its --duration (it takes ~1 s), so it is generous for a loaded machine
    assert time.monotonic() - t0 < 120
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "emulate" in err and "ServerFailed" in err
    assert "the pty server of geocom" in err and "RuntimeError: the device broke" in err


def test_bad_requests_get_the_protocols_own_replies_and_the_server_lives_on():
    import socket
    p, where = _start("geocom", "--tcp", "0", "--duration", "30")
    try:
        host, port = where.removeprefix("socket://").split(":")
        with socket.create_connection((host, int(port)), timeout=5) as s:
            f = s.makefile("rwb")
            for req, rep in ((b"%R1Q,107:" + b"9" * 4301, b"%R1P,0,0:2"), (b"%R1Q,4242,5:", b"%R1P,3081,5:0"),
                             (b"%R1Q," + b"9" * 4301 + b":", b"%R1P,3080,0:0"),
                             (b"%R1Q,9027:1e400,1,0,0,0", b"%R1P,0,0:2"), (b"%R1Q,0,9:", b"%R1P,0,9:0")):
                f.write(req + b"\r\n")
                f.flush()
                assert f.readline().rstrip(b"\r\n") == rep
        assert p.poll() is None
    finally:
        assert _stop(p) == 0


def test_emulate_runs_on_the_twin_of_the_chosen_scenario(tmp_path):
    import importlib.resources as res
    text = (res.files("calib") / "data" / "twin_default.toml").read_text(encoding="utf-8")
    moved = tmp_path / "moved.toml"
    moved.write_text(text.replace("L_mm = 1609.9", "L_mm = 2400.0"), encoding="utf-8")
    readings = []
    for extra in ([], ["--scenario", str(moved)]):
        p, where = _start("geocom", "--tcp", "0", "--no-noise", "--station", "B", "--duration", "30", *extra)
        try:
            with open_theodolite("geocom", where) as t:
                readings.append(t.angles().hz_rad)
        finally:
            assert _stop(p) == 0
    from sim.emulate.factories import make_world
    assert abs(readings[0] - make_world(None, noise=False).true_sight("B", 1)[0]) < 1e-12
    assert abs(readings[0] - readings[1]) > 1e-3


def test_tcp_host_reports_a_failing_device_to_its_owner():
    import socket
    import threading as th

    from sim.emulate.geocom_device import GeoComDevice
    from sim.emulate.tcp_host import TcpHost
    from tests.fakes.worlds import quiet_world

    class Broken(GeoComDevice):
        def on_line(self, line):
            raise RuntimeError("parser bug")
    seen = th.Event()
    got = []
    host = TcpHost(Broken(quiet_world(), "A"), on_failure=lambda h, exc: (got.append((h, exc)), seen.set()))
    try:
        with socket.create_connection((host.host, host.port), timeout=5) as s:
            s.sendall(b"%R1Q,0:\r\n")
            assert seen.wait(5)
    finally:
        host.close()
    assert got[0][0] is host and isinstance(host.failure, RuntimeError)
    assert host.describe().startswith("the TCP server of geocom on socket://")
