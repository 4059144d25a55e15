"""Benchmark: the CPU an ISO 9283 measurement costs in the emulated demo, beside a Chapter 6 pose measurement measured
in the same run (the baseline: the same runner, drivers, checks and store, one pose and one target each).

Why: ``robocal demo`` must stay quick (issue 26: the whole demo under 2.5 s on the 2-core machine) and ISO 9283 adds
5 poses x cycles x 2 runs measurements; this prints what one costs, so the demo's cycle count (``DEMO_ISO_CYCLES``)
can be chosen from a figure, and what 300 (the standard's 30 cycles) would cost.  Each measurement is a runner step:
approach move, move, both stations in both faces, the acceptance checks, the commit.  Process CPU time (all
threads: the emulated instruments run in this process), one BLAS thread.

    python benchmarks/bench_iso9283.py [--runs 3] [--steps 40]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _cpu_per_step(db: Path, keep, limit: int) -> tuple[float, int]:
    """CPU seconds per step of the demo's steps that ``keep`` selects (at most ``limit``), recorded alone."""
    from app.demo import build_demo
    chosen: list[str] = []

    def pick(step) -> bool:
        if keep(step) and len(chosen) < limit:
            chosen.append(step.key)
            return True
        return False

    d = build_demo(db, steps_filter=pick)
    try:
        t = time.process_time()
        state = d.runner.run()
        cpu = time.process_time() - t
    finally:
        d.close()
    assert state == "finished", state
    return cpu / max(len(chosen), 1), len(chosen)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--steps", type=int, default=40, help="measurements of each kind per run")
    a = ap.parse_args(argv)
    print("ISO 9283 measurement vs pose-set measurement, CPU per step; load average %.2f %.2f %.2f; cpu count %d"
          % (*os.getloadavg(), os.cpu_count()))
    iso, poses = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(a.runs):
            c_iso, n_iso = _cpu_per_step(Path(tmp) / f"iso{k}.db",
                                         lambda s: s.procedure == "iso9283" and not s.setup.get("command"), a.steps)
            c_pose, n_pose = _cpu_per_step(Path(tmp) / f"poses{k}.db", lambda s: s.procedure == "poses", a.steps)
            iso.append(c_iso)
            poses.append(c_pose)
            print(f"  run {k + 1}: ISO 9283 {1e3 * c_iso:.1f} ms/step ({n_iso} steps), "
                  f"pose set {1e3 * c_pose:.1f} ms/step ({n_pose} steps)")
    from acq.session.plans import DEMO_ISO_CYCLES
    m_iso, m_pose = statistics.median(iso), statistics.median(poses)
    print(f"median: ISO 9283 {1e3 * m_iso:.1f} ms CPU per measurement, baseline (pose set) {1e3 * m_pose:.1f} ms; "
          f"the demo's {2 * 5 * DEMO_ISO_CYCLES} ({DEMO_ISO_CYCLES} cycles) {2 * 5 * DEMO_ISO_CYCLES * m_iso:.2f} s, "
          f"the standard's 300 (30 cycles) {300 * m_iso:.2f} s")
    print("load average %.2f %.2f %.2f" % os.getloadavg())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
