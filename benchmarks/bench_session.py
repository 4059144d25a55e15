"""Benchmark: the session layer's two costs that grow with a session -- reprocessing a full demo session, and the
store's ingest rate for encoder streams compared with what the CAN tap can deliver.

* reprocess: ``robocal demo``'s session (every procedure, 48 poses) reprocessed from its database, seconds per run
  (the shipped examples/demo-session.db by default; ``--record`` makes a fresh one first);
* ingest: steps written exactly as the runner writes them (:meth:`SessionStore.write_step`, one transaction and one
  commit per step, each with one encoder chunk of ``n`` 6-joint samples), for a few chunk sizes.  The tap sends 4 CAN
  frames per 6-joint sample; a 1 Mbit/s bus at its limit carries 7,407-9,009 frames/s (135-111 bits per 8-byte frame,
  stuff bits and intermission included: :mod:`acq.encoders.can_bits`; the tap's own frames average about 122 bits, so
  about 8,200 frames/s), i.e. ~1,850-2,250 samples/s.  The figure that matters is the margin: frames/s the store takes over frames/s the bus
  can bring.

    python benchmarks/bench_session.py                 # both, on the shipped example
    python benchmarks/bench_session.py --record        # record a fresh demo session first (a few seconds)
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from acq.encoders.can_bits import unstuffed_frame_bits, worst_case_frame_bits  # noqa: E402
from acq.session.store import SessionStore, StepRecord  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BUS_BIT_RATE = 1_000_000
#: a 1 Mbit/s bus at its limit, 8-byte frames: the longest (all stuff bits) and the shortest (none) frame
BUS_FRAMES_S = (BUS_BIT_RATE / worst_case_frame_bits(8), BUS_BIT_RATE / unstuffed_frame_bits(8))
FRAMES_PER_SAMPLE = 4                 # the tap: 4 frames per 6-joint sample


def bench_reprocess(db: Path, runs: int) -> list[float]:
    from app.reprocess import reprocess
    out = []
    for _ in range(runs):
        t0 = time.perf_counter()
        reprocess(str(db))
        out.append(time.perf_counter() - t0)
    return out


def bench_ingest(path: Path, samples_per_step: int, steps: int) -> tuple[float, float]:
    """(samples/s, commits/s) writing ``steps`` steps of one chunk of ``samples_per_step`` samples each."""
    store = SessionStore.create(path, "ingest benchmark", {"procedures": []}, {}, operator="bench")
    dev = store.add_device("encoder tap", "bench", "", {})
    rng = np.random.default_rng(0)
    n = samples_per_step
    counts = rng.integers(-10_000_000, 10_000_000, (n, 6), dtype=np.int64)
    t0 = time.perf_counter()
    for i in range(steps):
        ch = {"attempt": 1, "device_id": dev, "phase": "settle", "seq": np.arange(i * n, (i + 1) * n),
              "t_device_us": np.arange(n, dtype=np.int64) * 500, "t_mono_s": time.monotonic() + np.arange(n) * 5e-4,
              "counts_wire": counts, "counts": counts}
        store.write_step(StepRecord(f"bench/{i:05d}", "bench", "bench", "", "accepted", 1, time.time(), time.time(),
                                    {}, chunks=[ch]))
    dt = time.perf_counter() - t0
    store.close()
    return n * steps / dt, steps / dt


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", default=str(ROOT / "examples" / "demo-session.db"), help="session to reprocess")
    ap.add_argument("--record", action="store_true", help="record a fresh demo session to reprocess")
    ap.add_argument("--runs", type=int, default=3, help="reprocessing runs (default 3)")
    ap.add_argument("--seconds", type=float, default=2.0, help="target duration of each ingest case (default 2)")
    a = ap.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        db = Path(a.db)
        if a.record:
            from app.demo import build_demo
            db = Path(tmp) / "demo.db"
            t0 = time.perf_counter()
            d = build_demo(db, seed=0)
            try:
                d.runner.run()
            finally:
                d.close()
            print(f"recorded demo session: {time.perf_counter() - t0:.1f} s")
        ts = bench_reprocess(db, a.runs)
        print(f"reprocess {db.name}: best {min(ts):.2f} s, median {float(np.median(ts)):.2f} s over {len(ts)} runs")

        lo, hi = (f / FRAMES_PER_SAMPLE for f in BUS_FRAMES_S)
        print(f"\nstore ingest, one commit per step (bus: {BUS_FRAMES_S[0]:.0f}-{BUS_FRAMES_S[1]:.0f} frames/s = "
              f"{lo:.0f}-{hi:.0f} samples/s)")
        print(f"{'samples/step':>12} {'steps/s':>9} {'samples/s':>11} {'frames/s':>10} {'x bus':>7}")
        for n in (10, 100, 1000, 10000):
            probe = max(5, int(200 / max(1, n // 100)))
            s_rate, c_rate = bench_ingest(Path(tmp) / f"probe{n}.db", n, probe)       # calibrate the case length
            steps = max(5, int(a.seconds * c_rate))
            s_rate, c_rate = bench_ingest(Path(tmp) / f"ingest{n}.db", n, steps)
            frames = s_rate * FRAMES_PER_SAMPLE
            print(f"{n:>12} {c_rate:>9.0f} {s_rate:>11.0f} {frames:>10.0f} {frames / BUS_FRAMES_S[1]:>7.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
