"""``robocal emulate``: first output line says where to connect; it serves until interrupted."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import can

from acq.cli import main
from acq.drivers import open_theodolite
from acq.encoders.can_codec import TapCanCodec

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _start(*argv):
    p = subprocess.Popen([sys.executable, "-m", "acq.cli", "emulate", *argv], cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    first = p.stdout.readline().strip()
    return p, first


def _stop(p):
    p.send_signal(signal.SIGINT)
    try:
        rc = p.wait(5)
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
            deadline = time.monotonic() + 5
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
    r = subprocess.run([sys.executable, "-m", "acq.cli", "emulate", "geocom", "--tcp", "99999"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "a TCP port is 0..65535" in r.stderr and "Traceback" not in r.stderr
