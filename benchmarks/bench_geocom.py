"""Benchmark: GeoCOM request/reply overhead per call, beyond the wire time at 115200 baud.

Runs the production driver (acq.drivers.geocom) against the emulated theodolite over a real pty (or the in-process
``robocal://`` URL).  A pty moves bytes without baud-rate delay, so the measured round trip *is* the overhead:
driver encode/decode + OS + emulator.  The wire time a real 115200 baud 8N1 line would add (10 bits per byte, request
plus reply) is printed next to it.

    python benchmarks/bench_geocom.py --calls 2000
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from acq.drivers import geocom_codec as gc  # noqa: E402
from acq.drivers.geocom import GeoComTheodolite  # noqa: E402
from sim.emulate.geocom_device import GeoComDevice  # noqa: E402
from sim.emulate.pty_host import PtyHost  # noqa: E402
from sim.emulate import registry  # noqa: E402
from sim.emulate.factories import demo_world  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--transport", choices=("pty", "url"), default="pty")
    ap.add_argument("--baud", type=int, default=115200)
    ap.add_argument("--checksum", action="store_true")
    a = ap.parse_args(argv)

    dev = GeoComDevice(demo_world(seed=0), "A")
    host = None
    if a.transport == "pty":
        host = PtyHost(dev)
        url = host.path
    else:
        url = registry.publish("bench", dev)
    results = {}
    with GeoComTheodolite.open(url, baudrate=a.baud, checksum=a.checksum) as d:
        for rpc, params, label in ((0, [], "COM_NullProc"), (2107, ["1"], "TMC_GetAngle5"),
                                   (2003, ["1"], "TMC_GetAngle1")):
            times = []
            nbytes = 0
            for _ in range(a.calls):
                t0 = time.perf_counter()
                r = d.request(rpc, params)
                times.append(time.perf_counter() - t0)
            req = gc.encode_request(rpc, params, 1234, a.checksum)
            nbytes = len(req) + len(r.reply.raw) + 2
            wire = nbytes * 10 / a.baud
            results[label] = (statistics.median(times), sorted(times)[int(0.99 * len(times))], wire, nbytes)
    if host:
        host.close()
    cpu_codec = _codec_cost()
    w = demo_world(seed=0)
    t0 = time.perf_counter()
    for _ in range(200):
        w.sight("A", 1)
    world_ms = (time.perf_counter() - t0) / 200 * 1e3
    print(f"transport            {a.transport}  checksum={a.checksum}  calls/rpc={a.calls}")
    print(f"{'rpc':16s} {'bytes':>5s} {'wire_ms@' + str(a.baud):>15s} {'overhead_ms_p50':>16s} {'p99':>8s}")
    for label, (p50, p99, wire, n) in results.items():
        print(f"{label:16s} {n:5d} {wire * 1e3:15.3f} {p50 * 1e3:16.3f} {p99 * 1e3:8.3f}")
    print(f"emulator_world_ms    {world_ms:.3f} per sight (inside the angle calls' figures; not driver overhead)")
    print(f"codec_only_us        encode+decode of a TMC_GetAngle5 pair: {cpu_codec * 1e6:.1f}")
    return 0


def _codec_cost(n: int = 20000) -> float:
    reply = b"%R1P,0,3:0,4.358392574848940,1.470950229078506"
    t0 = time.perf_counter()
    for i in range(n):
        gc.encode_request(2107, ["1"], i % 1000)
        gc.decode_values(gc.RPCS[2107], gc.decode_reply(reply).fields)
    return (time.perf_counter() - t0) / n


if __name__ == "__main__":
    sys.exit(main())
