"""Benchmark: how fast the serial encoder tap decodes its byte stream, before and after issue 18 item 6.

Same stream, same run, interleaved repeats.  *before*: the former pure-Python primitives (table-driven CRC-16 loop
and byte-loop COBS decoder, kept in ``tests/fakes/serial_tap_codec.py``) swapped into the production codec;
*after*: the production codec (``binascii.crc_hqx`` and the ``cobs`` package's C extension).  Two levels:

* codec: ``decode_frame`` on every 0x00-delimited frame of the stream (COBS, CRC, unpack);
* reader: the tap reader's byte path ``SerialTap._bytes`` fed in 4 KiB reads, as from a port (split on 0x00, decode,
  sequence check, joint conversion), without the thread and the link.

The stream: ``--frames`` frames (35 bytes each on the wire) of a moving arm, written by the production encoder and
checked against the independent writer.  Prints frames/s and MB/s (wire bytes), median and spread over
``--repeats``; the machine's load average, as others' work shares the cores.

    python benchmarks/bench_tap_serial.py                    # 20,000 frames, 7 repeats
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from contextlib import contextmanager

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from acq.encoders import cobs_codec  # noqa: E402
from acq.encoders.cobs_codec import TapFrame, decode_frame, encode_frame  # noqa: E402
from acq.encoders.sample import JointConverter  # noqa: E402
from acq.encoders.serial_tap import SerialTap  # noqa: E402
from calib.robot import load_robot  # noqa: E402
from tests.fakes.serial_tap_codec import (legacy_cobs_decode, legacy_crc16_ccitt_false,  # noqa: E402
                                          serial_frame_simple)

READ_BYTES = 4096


@contextmanager
def primitives(variant: str):
    """Run the production codec with the former pure-Python CRC and COBS (``before``) or as it is (``after``)."""
    saved = cobs_codec.crc16_ccitt_false, cobs_codec.cobs_decode
    if variant == "before":
        cobs_codec.crc16_ccitt_false, cobs_codec.cobs_decode = legacy_crc16_ccitt_false, legacy_cobs_decode
    try:
        yield
    finally:
        cobs_codec.crc16_ccitt_false, cobs_codec.cobs_decode = saved


def make_stream(n: int, seed: int) -> bytes:
    """n frames of six encoder counts following a smooth random motion (as the tap would see a moving arm)."""
    rng = np.random.default_rng(seed)
    walk = np.cumsum(rng.integers(-400, 401, size=(n, 6)), axis=0) + rng.integers(-2 ** 30, 2 ** 30, size=6)
    frames = []
    for i, counts in enumerate(walk.tolist()):
        f = encode_frame(TapFrame(1, i & 0xFFFF, (i * 500) & 0xFFFFFFFF, tuple(counts)))
        if i < 200:
            assert f == serial_frame_simple(1, i & 0xFFFF, (i * 500) & 0xFFFFFFFF, counts), "writers disagree"
        frames.append(f)
    return b"".join(frames)


class _Link:
    name = "encoder tap (benchmark)"

    def close(self) -> None:
        pass


def run_codec(stream: bytes) -> int:
    return sum(1 for chunk in stream.split(b"\x00")[:-1] if decode_frame(chunk).version)


def run_reader(stream: bytes, robot) -> int:
    tap = SerialTap(_Link(), converter=JointConverter(robot))
    got = [0]
    tap._sink = lambda s: got.__setitem__(0, got[0] + 1)
    for i in range(0, len(stream), READ_BYTES):
        tap._bytes(stream[i:i + READ_BYTES])
    assert tap.stats.bad_frames == 0 and tap.stats.lost_samples == 0, tap.stats
    return got[0]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20_000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--seed", type=int, default=18)
    a = ap.parse_args(argv)
    robot = load_robot()
    stream = make_stream(a.frames, a.seed)
    levels = {"codec": lambda: run_codec(stream), "reader": lambda: run_reader(stream, robot)}
    times: dict[tuple[str, str], list[float]] = {(lv, v): [] for lv in levels for v in ("before", "after")}
    for _ in range(a.repeats):                                   # interleaved: load drifts hit both alike
        for (lv, v), ts in times.items():
            with primitives(v):
                t0 = time.perf_counter()
                n = levels[lv]()
                ts.append(time.perf_counter() - t0)
            assert n == a.frames, f"{lv}/{v}: {n} of {a.frames} frames decoded"
    mb = len(stream) / 1e6
    print(f"serial tap decode: {a.frames} frames, {len(stream)} bytes on the wire, {a.repeats} interleaved repeats, "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    print(f"  {'level':<8}{'variant':<9}{'frames/s median':>17}{'(min-max)':>22}{'MB/s':>8}{'us/frame':>10}")
    for (lv, v), ts in times.items():
        med = statistics.median(ts)
        print(f"  {lv:<8}{v:<9}{a.frames / med:>17,.0f}{f'({a.frames / max(ts):,.0f}-{a.frames / min(ts):,.0f})':>22}"
              f"{mb / med:>8.2f}{med / a.frames * 1e6:>10.2f}")
    for lv in levels:
        ratio = statistics.median(times[(lv, "before")]) / statistics.median(times[(lv, "after")])
        print(f"  {lv}: after is {ratio:.1f}x the frames/s of before")
    return 0


if __name__ == "__main__":
    sys.exit(main())
