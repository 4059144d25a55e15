"""Benchmark: the CAN tap reader on a saturated 1 Mbit/s bus.

A CAN 2.0A data frame with 8 bytes is 111 bits before bit stuffing (up to ~135 with worst-case stuffing), so a
saturated 1 Mbit/s bus carries ~7,400-9,000 frames/s.  The emulated tap sends ``--fps`` frames per second (4 frames
per sample) on a python-can ``virtual`` bus for ``--seconds``; the reader (acq.encoders.can_tap.CanTap, the
production code) must deliver every sample, with no sequence gap and no incomplete sample.  Both run in this
process, so the figures include the sender's share of the GIL: a real bus is cheaper for the reader.

    python benchmarks/bench_tap_can.py --seconds 60          # the acceptance run
    python benchmarks/bench_tap_can.py --seconds 5           # quick look
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import uuid

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import can  # noqa: E402

from acq.emulate.can_node import CanTapNode  # noqa: E402
from acq.emulate.tap_device import TapModel  # noqa: E402
from acq.emulate.world import demo_world  # noqa: E402
from acq.encoders.can_tap import open_can_tap  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="how long to run (default 60)")
    ap.add_argument("--fps", type=float, default=8000.0, help="CAN frames per second (default 8000)")
    ap.add_argument("--interface", default="virtual", help="python-can interface (default virtual)")
    ap.add_argument("--channel", default=None, help="channel (default: a fresh virtual channel)")
    a = ap.parse_args(argv)

    world = demo_world(seed=0, noise=False)
    channel = a.channel or f"bench-{uuid.uuid4().hex[:8]}"
    tap = open_can_tap(a.interface, channel, robot=world.robot)
    seqs = []
    last = [None]
    gaps = [0]

    def sink(sample):
        if last[0] is not None and sample.seq != last[0] + 1:
            gaps[0] += 1
        last[0] = sample.seq
        seqs.append(sample.seq)

    model = TapModel(world, world.robot, rate_hz=a.fps / 4, max_backlog_s=5.0)
    node = CanTapNode(can.Bus(interface=a.interface, channel=channel), model, own_bus=True)
    tap.start(sink)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    node.start()
    time.sleep(a.seconds)
    node.stop()
    sent_samples = model.seq
    deadline = time.monotonic() + 5
    while tap.stats.samples < sent_samples and time.monotonic() < deadline:
        time.sleep(0.01)
    wall = time.perf_counter() - wall0
    cpu = time.process_time() - cpu0
    tap.stop()
    st = tap.stats
    fps = st.frames / a.seconds
    ok = (st.samples == sent_samples and st.lost_samples == 0 and st.incomplete_samples == 0
          and st.orphan_frames == 0 and gaps[0] == 0 and model.skipped == 0)
    print(f"duration_s            {a.seconds:.1f}")
    print(f"frames_sent           {node.frames_sent}")
    print(f"frames_received       {st.frames}")
    print(f"frames_per_s          {fps:.0f}")
    print(f"bus_load_1Mbit_pct    {fps * 111 / 1e6 * 100:.1f} (111 bits/frame, no stuffing)")
    print(f"samples_sent          {sent_samples}")
    print(f"samples_received      {st.samples}")
    print(f"lost_samples          {st.lost_samples}")
    print(f"incomplete_samples    {st.incomplete_samples}")
    print(f"orphan_frames         {st.orphan_frames}")
    print(f"sender_skipped        {model.skipped}")
    print(f"reader_cpu_s          {tap.cpu_s:.2f}")
    print(f"reader_cpu_pct_core   {tap.cpu_s / a.seconds * 100:.1f}")
    print(f"reader_us_per_frame   {tap.cpu_s / max(st.frames, 1) * 1e6:.1f}")
    print(f"process_cpu_pct_core  {cpu / wall * 100:.1f} (reader + emulated sender)")
    print(f"result                {'PASS' if ok and fps >= 7000 else 'FAIL'}")
    return 0 if ok and fps >= 7000 else 1


if __name__ == "__main__":
    sys.exit(main())
