"""Benchmark: the CAN tap reader at 8,000 frames/s and at the real limit of a 1 Mbit/s bus.

The sender is the emulated tap (``sim.emulate.can_node.CanTapNode``), *paced*: its schedule (``TapModel``) owes
``rate / 4`` samples per second of 4 frames each (status + three joint-pair frames, 8 data bytes each) and it sends
what is owed every millisecond.  The bus is python-can's ``virtual`` bus, which has no bit rate: the bus load printed
is what these frames would take on a real 1 Mbit/s bus, counted with stuff bits (``acq.encoders.can_bits``):

* the tap's actual frames, bit by bit (ISO 11898 stuffing over SOF..CRC, plus trailer and 3-bit intermission),
  averaged over the frames of the same arm pose; that average sets the real bus limit ``1e6 / mean bits`` frames/s;
* the worst case (135 bits for an 8-byte frame), which no schedule may rely on.

Each run: frames sent and received, frames lost, samples decoded, sequence gaps, incomplete samples, reader CPU.  The
reader is the production ``acq.encoders.can_tap.CanTap``; sender and reader share this process (and its GIL), so the
reader's figures include that contention: a real bus is cheaper for the reader.

    python benchmarks/bench_tap_can.py --seconds 60                  # 8000 frames/s, then the bus limit
    python benchmarks/bench_tap_can.py --seconds 5 --rates 8000,limit,12000
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
import uuid
from dataclasses import dataclass

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import can  # noqa: E402

from sim.emulate.can_node import CanTapNode  # noqa: E402
from sim.emulate.tap_device import TapModel, can_frames  # noqa: E402
from sim.emulate.factories import demo_world  # noqa: E402
from acq.encoders.can_bits import frame_bits, worst_case_frame_bits  # noqa: E402
from acq.encoders.can_tap import open_can_tap  # noqa: E402

BIT_RATE = 1_000_000
FRAMES_PER_SAMPLE = 4


@dataclass
class Run:
    fps_asked: float
    seconds: float
    frames_sent: int
    frames_received: int
    samples_sent: int
    samples_decoded: int
    lost_samples: int
    incomplete_samples: int
    orphan_frames: int
    sender_skipped: int
    reader_cpu_s: float

    @property
    def fps_sent(self) -> float:
        return self.frames_sent / self.seconds

    @property
    def ok(self) -> bool:
        return (self.frames_received == self.frames_sent and self.samples_decoded == self.samples_sent
                and self.lost_samples == self.incomplete_samples == self.orphan_frames == self.sender_skipped == 0)


def frame_bit_counts(world, n_samples: int = 500) -> list[int]:
    """Wire bits of the tap's frames for ``n_samples`` samples of this world (seq and time stamp advancing)."""
    t = [0.0]
    model = TapModel(world, world.robot, rate_hz=2000.0, clock=lambda: t[0])
    bits = []
    for _ in range(n_samples):
        t[0] += 0.0005
        bits += [frame_bits(fid, data) for fid, data in can_frames(model.latch())]
    return bits


def run_once(world, fps: float, seconds: float, interface: str, channel: str | None) -> Run:
    channel = channel or f"bench-{uuid.uuid4().hex[:8]}"
    tap = open_can_tap(interface, channel, robot=world.robot)
    model = TapModel(world, world.robot, rate_hz=fps / FRAMES_PER_SAMPLE, max_backlog_s=5.0)
    node = CanTapNode(can.Bus(interface=interface, channel=channel), model, own_bus=True)
    tap.start()
    t0 = time.perf_counter()
    node.start()
    time.sleep(seconds)
    node.stop()
    sent_s = time.perf_counter() - t0
    deadline = time.monotonic() + 5
    while tap.stats.frames < node.frames_sent and time.monotonic() < deadline:
        time.sleep(0.01)
    tap.stop()
    st = tap.stats
    return Run(fps, sent_s, node.frames_sent, st.frames, model.seq, st.samples, st.lost_samples,
               st.incomplete_samples, st.orphan_frames, model.skipped, tap.cpu_s)


def parse_rates(text: str, limit_fps: float) -> list[float]:
    return [limit_fps if r.strip() == "limit" else float(r) for r in text.split(",")]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="how long each run sends (default 60)")
    ap.add_argument("--rates", default="8000,limit",
                    help="comma-separated paced sender rates in CAN frames/s; 'limit' = the 1 Mbit/s bus limit of "
                         "the tap's frames (default 8000,limit)")
    ap.add_argument("--fps", type=float, default=None, help="one paced run at this many frames/s (as --rates FPS)")
    ap.add_argument("--interface", default="virtual", help="python-can interface (default virtual)")
    ap.add_argument("--channel", default=None, help="channel (default: a fresh virtual channel per run)")
    a = ap.parse_args(argv)

    world = demo_world(seed=0, noise=False)
    bits = frame_bit_counts(world)
    mean_bits, worst = statistics.fmean(bits), worst_case_frame_bits(8)
    limit_fps = BIT_RATE / mean_bits
    print(f"tap frames on the wire: mean {mean_bits:.1f} bits (min {min(bits)}, max {max(bits)}; 111 unstuffed, "
          f"{worst} worst case) -> a 1 Mbit/s bus carries at most {limit_fps:,.0f} of them per second "
          f"({BIT_RATE / worst:,.0f} frames/s in the worst case)")
    print(f"sender: the emulated tap, paced ({FRAMES_PER_SAMPLE} frames per sample, sent every 1 ms); "
          f"bus: python-can {a.interface} (no bit rate of its own); load average {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores")
    head = (f"  {'asked f/s':>10}{'sent f/s':>10}{'load %':>8}{'worst %':>9}{'sent':>9}{'received':>10}{'lost':>6}"
            f"{'samples':>9}{'decoded':>9}{'gaps':>6}{'incompl':>8}{'reader CPU %':>13}{'us/frame':>9}  result")
    print(head)
    all_ok = True
    for fps in parse_rates(a.rates if a.fps is None else str(a.fps), limit_fps):
        r = run_once(world, fps, a.seconds, a.interface, a.channel)
        all_ok &= r.ok
        print(f"  {r.fps_asked:>10,.0f}{r.fps_sent:>10,.0f}{r.fps_sent * mean_bits / BIT_RATE * 100:>8.1f}"
              f"{r.fps_sent * worst / BIT_RATE * 100:>9.1f}{r.frames_sent:>9}{r.frames_received:>10}"
              f"{r.frames_sent - r.frames_received:>6}{r.samples_sent:>9}{r.samples_decoded:>9}{r.lost_samples:>6}"
              f"{r.incomplete_samples:>8}{r.reader_cpu_s / r.seconds * 100:>13.1f}"
              f"{r.reader_cpu_s / max(r.frames_received, 1) * 1e6:>9.1f}  {'PASS' if r.ok else 'FAIL'}")
    print("  load % = the tap's actual frames with stuff bits; worst % = every frame at its worst-case length; "
          "above 100 % a real 1 Mbit/s bus could not carry the rate")
    return 0 if all_ok else 1


if __name__ == "__main__":
    sys.exit(main())
